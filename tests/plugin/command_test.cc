// What a JSON file says wrote it: Provenance (a `watergs` command) and
// ProgramProvenance (a benchmark of the same build), read without running a
// command.
#include "plugin/command.h"

#include <gtest/gtest.h>

#include <nlohmann/json.hpp>
#include <string>
#include <vector>

namespace watergs {
namespace {

// argv as main receives it, from strings the test keeps alive.
std::vector<char*> Argv(std::vector<std::string>& args) {
  std::vector<char*> argv;
  for (std::string& a : args) argv.push_back(a.data());
  return argv;
}

void ExpectNamesThisBuild(const nlohmann::json& provenance) {
  EXPECT_EQ(provenance["version"], Version()) << provenance;
  EXPECT_EQ(provenance["commit"], GitCommit()) << provenance;
  if (GitDirty() < 0) {
    EXPECT_TRUE(provenance["dirty"].is_null()) << provenance;
  } else {
    EXPECT_EQ(provenance["dirty"], GitDirty() == 1) << provenance;
  }
}

TEST(ProgramProvenance, TheWholeArgvQuotedAsTypedAndThisBuild) {
  std::vector<std::string> args = {"/tmp/my bench/raster_benchmark", "--json",
                                   "out file.json", "it's", "--threads=2"};
  std::vector<char*> argv = Argv(args);
  const nlohmann::json p = ProgramProvenance(argv.size(), argv.data());
  // Pasted into a shell, the command runs the same program with the same
  // arguments: spaces and quotes survive, plain words stay bare.
  EXPECT_EQ(p["command"],
            "'/tmp/my bench/raster_benchmark' --json 'out file.json' "
            "'it'\\''s' --threads=2")
      << p;
  ExpectNamesThisBuild(p);
}

TEST(ProgramProvenance, DiffersFromACommandsProvenanceOnlyInItsFirstWord) {
  std::vector<std::string> args = {"extract", "--json", "a b.json"};
  std::vector<char*> argv = Argv(args);
  const nlohmann::json command = Provenance(argv.size(), argv.data());
  const nlohmann::json program = ProgramProvenance(argv.size(), argv.data());
  EXPECT_EQ(command["command"], "watergs extract --json 'a b.json'") << command;
  EXPECT_EQ(program["command"], "extract --json 'a b.json'") << program;
  ExpectNamesThisBuild(command);
  ExpectNamesThisBuild(program);
}

TEST(ProgramProvenance, NoArgumentsIsAnEmptyCommandNotACrash) {
  const nlohmann::json p = ProgramProvenance(0, nullptr);
  EXPECT_EQ(p["command"], "") << p;
  ExpectNamesThisBuild(p);
}

TEST(WithProvenance, AddsTheBlockAndKeepsTheObject) {
  std::vector<std::string> args = {"eval", "--seed", "3"};
  std::vector<char*> argv = Argv(args);
  const std::string written = WithProvenance(
      R"({"ber": 0.25, "views": [1, 2]})", 2, argv.size(), argv.data());
  ASSERT_FALSE(written.empty());
  EXPECT_EQ(written.back(), '\n');
  const nlohmann::json j = nlohmann::json::parse(written);
  EXPECT_EQ(j["ber"], 0.25);
  EXPECT_EQ(j["views"], nlohmann::json({1, 2}));
  EXPECT_EQ(j["provenance"]["command"], "watergs eval --seed 3");
  ExpectNamesThisBuild(j["provenance"]);
}

}  // namespace
}  // namespace watergs
