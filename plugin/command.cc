#include "plugin/command.h"

#include <nlohmann/json.hpp>

#include "plugin/git_revision.h"  // generated in the build folder
#include "plugin/report_evidence.h"

namespace watergs {

std::string Version() { return WATERGS_VERSION_TEXT; }

std::string GitCommit() { return WATERGS_GIT_COMMIT; }

int GitDirty() { return WATERGS_GIT_DIRTY; }

std::string VersionLine() {
  return "watergs " + Version() + ", commit " + GitCommit() +
         (GitDirty() == 1 ? " with uncommitted changes" : "");
}

namespace {

nlohmann::json ProvenanceOf(const std::string& command) {
  return {{"command", command},
          {"version", Version()},
          {"commit", GitCommit()},
          {"dirty", GitDirty() < 0 ? nlohmann::json()
                                   : nlohmann::json(GitDirty() == 1)}};
}

}  // namespace

nlohmann::json Provenance(int argc, char** argv) {
  return ProvenanceOf(CommandLine(argc, argv));
}

nlohmann::json ProgramProvenance(int argc, char** argv) {
  std::string command;
  for (int i = 0; i < argc; ++i) {
    command += (i == 0 ? "" : " ") + ShellQuote(argv[i]);
  }
  return ProvenanceOf(command);
}

std::string WithProvenance(const std::string& json_object, int indent, int argc,
                           char** argv) {
  nlohmann::json j = nlohmann::json::parse(json_object);
  j["provenance"] = Provenance(argc, argv);
  return j.dump(indent) + "\n";
}

std::map<std::string, Command>& CommandRegistry() {
  static std::map<std::string, Command> registry;
  return registry;
}

}  // namespace watergs
