#include "plugin/option_parser.h"

#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

#include "gaussian/device.h"
#include "gaussian/util/error.h"
#include "tests/plugin/synthetic_model.h"

namespace watergs {
namespace {

// Holds argv storage for a parse call.
struct Args {
  explicit Args(std::vector<std::string> words) : strings(std::move(words)) {
    for (auto& s : strings) pointers.push_back(s.data());
  }
  int argc() { return static_cast<int>(pointers.size()); }
  char** argv() { return pointers.data(); }
  std::vector<std::string> strings;
  std::vector<char*> pointers;
};

TEST(OptionParser, ReadsCommandLineValues) {
  std::string input;
  int iterations = 7;
  OptionParser parser("demo", "test");
  parser.AddRequired("input_path", &input, "in");
  parser.Add("iterations", &iterations, "n");
  Args args({"demo", "--input_path", "x.ply", "--iterations", "42"});
  ASSERT_TRUE(parser.Parse(args.argc(), args.argv()));
  EXPECT_EQ(input, "x.ply");
  EXPECT_EQ(iterations, 42);
}

TEST(OptionParser, ProjectFileFillsOptionsAndCommandLineWins) {
  const auto ini = std::filesystem::temp_directory_path() / "watergs_opt.ini";
  std::ofstream(ini) << "input_path = from_ini.ply\niterations = 5\n";
  std::string input;
  int iterations = 7;
  OptionParser parser("demo", "test");
  parser.AddRequired("input_path", &input, "in");
  parser.Add("iterations", &iterations, "n");
  Args args({"demo", "--project_path", ini.string(), "--iterations", "9"});
  ASSERT_TRUE(parser.Parse(args.argc(), args.argv()));
  EXPECT_EQ(input, "from_ini.ply");
  EXPECT_EQ(iterations, 9);
}

TEST(OptionParser, MissingRequiredOptionIsAnErrorNamingIt) {
  std::string input;
  OptionParser parser("demo", "test");
  parser.AddRequired("input_path", &input, "in");
  Args args({"demo"});
  try {
    parser.Parse(args.argc(), args.argv());
    FAIL() << "expected an error";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("input_path"), std::string::npos);
  }
}

TEST(OptionParser, MalformedValueAndUnknownOptionAreErrors) {
  int iterations = 1;
  OptionParser parser("demo", "test");
  parser.Add("iterations", &iterations, "n");
  Args bad_value({"demo", "--iterations", "many"});
  EXPECT_THROW(parser.Parse(bad_value.argc(), bad_value.argv()), Error);
  OptionParser parser2("demo", "test");
  parser2.Add("iterations", &iterations, "n");
  Args unknown({"demo", "--iteratons", "3"});
  EXPECT_THROW(parser2.Parse(unknown.argc(), unknown.argv()), Error);
}

// An alias sets the option it names, on the command line and in a project
// file; Given tells options typed from defaults; help lists the alias and
// shows a floating-point default as written.
TEST(OptionParser, AliasesGivenOptionsAndDefaultsAsWritten) {
  std::string sparse;
  double gamma = 0.3;
  int seed = 0;
  const auto make = [&](OptionParser* parser) {
    parser->Add("sparse_path", &sparse, "model");
    parser->AddAlias("input_path", "sparse_path");
    parser->Add("gamma", &gamma, "weight");
    parser->Add("seed", &seed, "seed");
  };
  OptionParser parser("demo", "test");
  make(&parser);
  Args args({"demo", "--input_path", "m", "--seed", "0"});
  ASSERT_TRUE(parser.Parse(args.argc(), args.argv()));
  EXPECT_EQ(sparse, "m");
  EXPECT_TRUE(parser.Given("sparse_path"));
  EXPECT_TRUE(parser.Given("seed"));  // typed, even if equal to the default
  EXPECT_FALSE(parser.Given("gamma"));
  EXPECT_NE(parser.Help().find("(=0.3)"), std::string::npos);
  EXPECT_NE(parser.Help().find("--input_path = --sparse_path (deprecated)"),
            std::string::npos);

  const auto ini =
      std::filesystem::temp_directory_path() / "watergs_alias_opt.ini";
  std::ofstream(ini) << "  input_path = from_ini\n";
  OptionParser from_ini("demo", "test");
  make(&from_ini);
  Args ini_args({"demo", "--project_path", ini.string()});
  ASSERT_TRUE(from_ini.Parse(ini_args.argc(), ini_args.argv()));
  EXPECT_EQ(sparse, "from_ini");

  OptionParser both("demo", "test");
  make(&both);
  Args twice({"demo", "--input_path=a", "--sparse_path", "b"});
  EXPECT_THROW(both.Parse(twice.argc(), twice.argv()), Error);
}

// An old name (AddAlias) works and prints exactly one notice line naming
// the new name, once however often it appears; the new name prints nothing.
TEST(OptionParser, DeprecatedNamePrintsOneNoticeNamingTheNewName) {
  std::string sparse;
  const auto parse = [&](std::vector<std::string> words) {
    OptionParser parser("demo", "test");
    parser.Add("sparse_path", &sparse, "model");
    parser.AddAlias("input_path", "sparse_path");
    Args args(std::move(words));
    ::testing::internal::CaptureStderr();
    EXPECT_TRUE(parser.Parse(args.argc(), args.argv()));
    return ::testing::internal::GetCapturedStderr();
  };
  EXPECT_EQ(parse({"demo", "--input_path", "old"}),
            "notice: --input_path is deprecated for demo; use --sparse_path\n");
  EXPECT_EQ(sparse, "old");
  EXPECT_EQ(parse({"demo", "--input_path=eq"}),
            "notice: --input_path is deprecated for demo; use --sparse_path\n");
  EXPECT_EQ(sparse, "eq");
  EXPECT_EQ(parse({"demo", "--sparse_path", "new"}), "");
  EXPECT_EQ(sparse, "new");
  const auto ini =
      std::filesystem::temp_directory_path() / "watergs_deprecated_opt.ini";
  std::ofstream(ini) << "input_path = from_ini\n";
  EXPECT_EQ(parse({"demo", "--project_path", ini.string()}),
            "notice: --input_path is deprecated for demo; use --sparse_path\n");
  EXPECT_EQ(sparse, "from_ini");

  // A help request says nothing about the names it was given with.
  OptionParser help("demo", "test");
  help.Add("sparse_path", &sparse, "model");
  help.AddAlias("input_path", "sparse_path");
  Args help_args({"demo", "--input_path", "x", "-h"});
  ::testing::internal::CaptureStdout();
  ::testing::internal::CaptureStderr();
  EXPECT_FALSE(help.Parse(help_args.argc(), help_args.argv()));
  EXPECT_EQ(::testing::internal::GetCapturedStderr(), "");
  EXPECT_NE(::testing::internal::GetCapturedStdout().find(
                "--input_path = --sparse_path (deprecated)"),
            std::string::npos);
}

// A boolean old name standing for `--name value` (train's --eval for
// --split train): set, it is that value with one notice; `--eval 0` leaves
// the option alone; with the new name as well it is an error.
TEST(OptionParser, BooleanAliasStandsForAValue) {
  std::string split;
  const auto parse = [&](std::vector<std::string> words) {
    split = "all";
    OptionParser parser("demo", "test");
    parser.Add("split", &split, "views");
    parser.AddAlias("eval", "split", "train");
    Args args(std::move(words));
    ::testing::internal::CaptureStderr();
    try {
      EXPECT_TRUE(parser.Parse(args.argc(), args.argv()));
    } catch (const Error&) {
      ::testing::internal::GetCapturedStderr();
      throw;
    }
    return ::testing::internal::GetCapturedStderr();
  };
  const std::string notice =
      "notice: --eval is deprecated for demo; use --split train\n";
  EXPECT_EQ(parse({"demo", "--eval"}), notice);
  EXPECT_EQ(split, "train");
  EXPECT_EQ(parse({"demo", "--eval", "1"}), notice);
  EXPECT_EQ(split, "train");
  EXPECT_EQ(parse({"demo", "--eval=0"}), notice);
  EXPECT_EQ(split, "all");
  EXPECT_EQ(parse({"demo", "--split", "train"}), "");
  EXPECT_EQ(split, "train");
  const auto ini =
      std::filesystem::temp_directory_path() / "watergs_bool_alias_opt.ini";
  std::ofstream(ini) << "eval = 1\n";
  EXPECT_EQ(parse({"demo", "--project_path", ini.string()}), notice);
  EXPECT_EQ(split, "train");
  EXPECT_THROW(parse({"demo", "--eval", "--split", "all"}), Error);
  EXPECT_THROW(parse({"demo", "--eval=maybe"}), Error);
}

// Every boolean takes the same forms, whatever its default and however it
// was registered (AddFlag or Add<bool>): `--x`, `--x 0|1`, `--x=false`,
// `x = 1` in a project file; help shows `--x [=0|1(=1)] (=default)`.
TEST(OptionParser, BooleansTakeOneStyle) {
  bool resume = false, refine = true;
  int seed = 0;
  const auto parse = [&](std::vector<std::string> words) {
    resume = false;
    refine = true;
    OptionParser parser("demo", "test");
    parser.AddFlag("resume", &resume, "continue");
    parser.Add("refine", &refine, "refine");
    parser.Add("seed", &seed, "seed");
    Args args(std::move(words));
    EXPECT_TRUE(parser.Parse(args.argc(), args.argv()));
    return parser.Help();
  };
  const std::string help = parse({"demo"});
  EXPECT_FALSE(resume);
  EXPECT_TRUE(refine);
  EXPECT_NE(help.find("--resume [=0|1(=1)] (=0)"), std::string::npos) << help;
  EXPECT_NE(help.find("--refine [=0|1(=1)] (=1)"), std::string::npos) << help;
  parse({"demo", "--resume", "--refine", "0", "--seed", "1"});
  EXPECT_TRUE(resume);
  EXPECT_FALSE(refine);
  EXPECT_EQ(seed, 1);
  parse({"demo", "--resume", "1", "--refine=false"});
  EXPECT_TRUE(resume);
  EXPECT_FALSE(refine);
  parse({"demo", "--resume=0", "--refine", "on"});
  EXPECT_FALSE(resume);
  EXPECT_TRUE(refine);
  const auto ini =
      std::filesystem::temp_directory_path() / "watergs_bool_opt.ini";
  std::ofstream(ini) << "resume = 1\nrefine = 0\n";
  parse({"demo", "--project_path", ini.string()});
  EXPECT_TRUE(resume);
  EXPECT_FALSE(refine);
  OptionParser bad("demo", "test");
  bad.AddFlag("resume", &resume, "continue");
  Args maybe({"demo", "--resume=maybe"});
  EXPECT_THROW(bad.Parse(maybe.argc(), maybe.argv()), Error);
}

TEST(OptionParser, MissingProjectFileNamesIt) {
  OptionParser parser("demo", "test");
  Args args({"demo", "--project_path", "/nonexistent/p.ini"});
  try {
    parser.Parse(args.argc(), args.argv());
    FAIL() << "expected an error";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("/nonexistent/p.ini"),
              std::string::npos);
  }
}

TEST(OptionParser, HelpReturnsFalse) {
  OptionParser parser("demo", "test");
  Args args({"demo", "-h"});
  ::testing::internal::CaptureStdout();
  EXPECT_FALSE(parser.Parse(args.argc(), args.argv()));
  EXPECT_NE(
      ::testing::internal::GetCapturedStdout().find("Usage: watergs demo"),
      std::string::npos);
}

// The device a parse of `--device word` resolves to; rethrows its Error.
Device ParseDevice(const std::string& word) {
  OptionParser parser("demo", "test");
  Args args({"demo", "--device", word});
  EXPECT_TRUE(parser.Parse(args.argc(), args.argv()));
  return parser.device();
}

// The default is auto (a GPU when one is usable), falling back to the CPU
// without a word on stderr; cpu stays cpu.
TEST(OptionParser, DeviceDefaultsToAutoAndFallsBackQuietly) {
  OptionParser parser("demo", "test");
  Args args({"demo"});
  ::testing::internal::CaptureStderr();
  ASSERT_TRUE(parser.Parse(args.argc(), args.argv()));
  EXPECT_EQ(::testing::internal::GetCapturedStderr(), "");
  EXPECT_EQ(parser.device(), CudaAvailable() ? Device::kCuda : Device::kCpu);
  EXPECT_EQ(ParseDevice("cpu"), Device::kCpu);
  EXPECT_EQ(ParseDevice("auto"),
            CudaAvailable() ? Device::kCuda : Device::kCpu);
}

// --device auto on a machine without a usable GPU runs on the CPU and says
// so (with why) on one line, once however often the device is resolved.
TEST(OptionParser, AutoSaysOnceThatItFallsBackToTheCpu) {
  std::string why;
  const bool cuda = CudaAvailable(&why);
  std::ostringstream note;
  bool noted = false;
  for (int i = 0; i < 3; ++i) {
    EXPECT_EQ(ResolveDevice("auto", &note, &noted),
              cuda ? Device::kCuda : Device::kCpu);
  }
  if (cuda) {
    EXPECT_EQ(note.str(), "");
    return;
  }
  EXPECT_EQ(note.str(),
            "watergs: --device auto: running on the CPU (" + why + ")\n");
  // cpu and cuda never write the note.
  std::ostringstream quiet;
  bool quiet_noted = false;
  EXPECT_EQ(ResolveDevice("cpu", &quiet, &quiet_noted), Device::kCpu);
  EXPECT_THROW(ResolveDevice("cuda", &quiet, &quiet_noted), Error);
  EXPECT_EQ(quiet.str(), "");
}

// The help says what --device takes, that auto is the default and when it
// speaks.
TEST(OptionParser, HelpStatesTheDeviceDefault) {
  OptionParser parser("demo", "test");
  Args args({"demo", "-h"});
  ::testing::internal::CaptureStdout();
  EXPECT_FALSE(parser.Parse(args.argc(), args.argv()));
  const std::string help = ::testing::internal::GetCapturedStdout();
  for (const char* text : {"cpu, cuda or auto", "(=auto)",
                           "silently by default", "says so once"}) {
    EXPECT_NE(help.find(text), std::string::npos) << text << "\n" << help;
  }
}

TEST(OptionParser, CudaWithoutCudaAndUnknownDevicesAreOneLineErrors) {
  std::string why;
  if (CudaAvailable(&why)) {
    EXPECT_EQ(ParseDevice("cuda"), Device::kCuda);
  } else {
    try {
      ParseDevice("cuda");
      FAIL() << "expected an error";
    } catch (const Error& e) {
      const std::string message = e.what();
      EXPECT_NE(message.find("--device cuda: " + why), std::string::npos)
          << message;
      EXPECT_EQ(message.find('\n'), std::string::npos) << message;
    }
  }
  try {
    ParseDevice("gpu\n0");
    FAIL() << "expected an error";
  } catch (const Error& e) {
    const std::string message = e.what();
    EXPECT_NE(message.find("--device: expected cpu, cuda or auto, got 'gpu"),
              std::string::npos)
        << message;
    EXPECT_EQ(message.find('\n'), std::string::npos) << message;
  }
}

// Every registered command takes --device (the help lists it).
TEST(OptionParser, EveryCommandTakesDevice) {
  const std::string bin = testing::WatergsBin();
  const testing::CommandResult help = testing::RunCommand(bin + " help");
  ASSERT_EQ(help.exit_code, 0) << help.output;
  const size_t list = help.output.find("Commands:\n");
  ASSERT_NE(list, std::string::npos) << help.output;
  std::istringstream lines(help.output.substr(list + 10));
  std::string line;
  int commands = 0;
  while (std::getline(lines, line)) {
    std::istringstream words(line);
    std::string name;
    if (!(words >> name)) continue;
    ++commands;
    const testing::CommandResult run =
        testing::RunCommand(bin + " " + name + " -h");
    EXPECT_EQ(run.exit_code, 0) << name << ": " << run.output;
    EXPECT_NE(run.output.find("--device"), std::string::npos)
        << name << ": " << run.output;
  }
  EXPECT_GE(commands, 10);
}

}  // namespace
}  // namespace watergs
