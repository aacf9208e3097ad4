// The `watergs <command>` registry. Each command lives in
// plugin/commands/<name>.cc and registers itself with WATERGS_COMMAND. Also
// what the build was (version, git commit) and what wrote a JSON file.
#pragma once

#include <functional>
#include <map>
#include <nlohmann/json_fwd.hpp>
#include <string>

namespace watergs {

// The build: the version ("0.1.0"), the git commit the sources were at (40
// hex digits; "unknown" when built outside a git checkout) and whether the
// working tree differed from it (changed, staged or untracked files), read
// at build time (plugin/git_revision.cmake).
std::string Version();
std::string GitCommit();
// 1: uncommitted changes, 0: none, -1: unknown (no commit).
int GitDirty();
// "watergs 0.1.0, commit <40 hex>[ with uncommitted changes]" or
// "watergs 0.1.0, commit unknown": the generator line of reports.
std::string VersionLine();
// What wrote a JSON file, to repeat or trace it: {"command": the command as
// run, quoted ("watergs extract --input_path ..."), "version", "commit",
// "dirty": true / false, null when the commit is unknown}. argv[0] is the
// command's name, as the commands receive it.
nlohmann::json Provenance(int argc, char** argv);
// The same for a program of this build other than `watergs` (a benchmark):
// its whole argv, argv[0] its path as run, so the command reads as typed.
nlohmann::json ProgramProvenance(int argc, char** argv);
// `json_object`, a JSON object as nlohmann writes it with `indent`, with
// "provenance" (above) added, written again with `indent` and a newline.
std::string WithProvenance(const std::string& json_object, int indent, int argc,
                           char** argv);

struct Command {
  // What the user types after `watergs`.
  std::string name;
  // One line shown by `watergs help`.
  std::string summary;
  // Runs the command on its own arguments (argv[0] is the command name);
  // returns the exit code. Throws Error for bad input.
  std::function<int(int argc, char** argv)> run;
};

// All registered commands, sorted by name.
std::map<std::string, Command>& CommandRegistry();

struct CommandRegistrar {
  CommandRegistrar(const char* name, const char* summary,
                   int (*run)(int, char**)) {
    CommandRegistry()[name] = Command{name, summary, run};
  }
};

}  // namespace watergs

// WATERGS_COMMAND(model_info, "Prints ...", RunModelInfo);
#define WATERGS_COMMAND(name, summary, fn) \
  static ::watergs::CommandRegistrar watergs_command_##name(#name, summary, fn)
