#include "plugin/option_parser.h"

#include <charconv>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <sstream>

#include "gaussian/util/error.h"

namespace po = boost::program_options;

namespace watergs {
namespace {

// Boost builds its messages by replacing "%value%"-style placeholders until
// none is left, which never ends when a token from the input holds one (a
// hang found by fuzzing --project_path files). Percent signs in the tokens
// are shown percent-encoded ("%25") instead.
struct BoostErrorTokens : po::error_with_option_name {
  static void Defuse(po::error_with_option_name& error) {
    auto& tokens = error.*&BoostErrorTokens::m_substitutions;
    for (auto& [placeholder, token] : tokens) {
      std::string defused;
      for (const char c : token)
        defused += c == '%' ? "%25" : std::string(1, c);
      token = std::move(defused);
    }
  }
};

// The error's one-line message, safe to build whatever the input held.
std::string Message(po::error& error) {
  if (auto* named = dynamic_cast<po::error_with_option_name*>(&error)) {
    BoostErrorTokens::Defuse(*named);
  }
  return error.what();
}

}  // namespace

OptionParser::OptionParser(std::string command, std::string summary)
    : command_(std::move(command)),
      summary_(std::move(summary)),
      options_("Options") {
  options_.add_options()("help,h", "Print this help")(
      "project_path", po::value<std::string>(&project_path_),
      "An .ini file holding any of these options as `name = value`")(
      "device", po::value<std::string>(&device_text_)->default_value("auto"),
      "cpu, cuda or auto: CUDA when built with it and a GPU is visible, else "
      "the CPU (silently by default; a given --device auto says so once on "
      "stderr). The CUDA parity tests passed on an H200 (docs/cuda.md)");
}

std::string OptionParser::ShortestText(double value) {
  char text[64];
  const auto end = std::to_chars(text, text + sizeof(text), value).ptr;
  return std::string(text, end);
}

std::string OptionParser::ShortestText(float value) {
  char text[64];
  const auto end = std::to_chars(text, text + sizeof(text), value).ptr;
  return std::string(text, end);
}

void OptionParser::AddAlias(const std::string& alias, const std::string& name) {
  aliases_[alias] = name;
}

std::vector<std::string> OptionParser::ResolveAliases(int argc,
                                                      char** argv) const {
  std::vector<std::string> args(argv, argv + argc);
  for (size_t k = 1; k < args.size(); ++k) {
    for (const auto& [alias, name] : aliases_) {
      const std::string token = "--" + alias;
      if (args[k] == token) {
        args[k] = "--" + name;
      } else if (args[k].rfind(token + "=", 0) == 0) {
        args[k] = "--" + name + args[k].substr(token.size());
      }
    }
  }
  return args;
}

void OptionParser::AddFlag(const std::string& name, bool* value,
                           const std::string& help) {
  options_.add_options()(name.c_str(), po::bool_switch(value), help.c_str());
}

std::string OptionParser::Help() const {
  std::ostringstream out;
  out << "Usage: watergs " << command_ << " [options]\n"
      << summary_ << "\n\n"
      << options_;
  if (!aliases_.empty()) out << "\nAliases:\n";
  for (const auto& [alias, name] : aliases_) {
    out << "  --" << alias << " = --" << name << "\n";
  }
  return out.str();
}

bool OptionParser::Parse(int argc, char** argv) {
  po::variables_map vm;
  try {
    const std::vector<std::string> args = ResolveAliases(argc, argv);
    po::store(po::command_line_parser(
                  std::vector<std::string>(args.begin() + 1, args.end()))
                  .options(options_)
                  .run(),
              vm);
    if (vm.count("help")) {
      std::cout << Help();
      return false;
    }
    if (vm.count("project_path")) {
      const std::string ini = vm["project_path"].as<std::string>();
      if (!std::filesystem::is_regular_file(ini)) {
        FailAt(ini, "project file not found");
      }
      // Aliases as keys of `name = value` lines are renamed too.
      std::ifstream file(ini);
      std::stringstream in;
      for (std::string line; std::getline(file, line);) {
        const size_t start = line.find_first_not_of(" \t");
        for (const auto& [alias, name] : aliases_) {
          if (start == std::string::npos ||
              line.compare(start, alias.size(), alias) != 0) {
            continue;
          }
          const size_t after =
              line.find_first_not_of(" \t", start + alias.size());
          if (after != std::string::npos && line[after] == '=') {
            line.replace(start, alias.size(), name);
            break;
          }
        }
        in << line << "\n";
      }
      try {
        po::store(
            po::parse_config_file(in, options_, /*allow_unregistered=*/false),
            vm);
      } catch (po::error& e) {
        FailAt(ini, Message(e));
      }
    }
    po::notify(vm);
    for (const auto& [name, value] : vm) {
      if (!value.defaulted()) given_.insert(name);
    }
  } catch (po::error& e) {
    Fail("watergs " + command_ + ": " + Message(e) + " (see `watergs " +
         command_ + " -h`)");
  }
  // The default falls back to the CPU without a note: a CPU machine's
  // stderr stays for errors (one line each).
  if (given_.count("device")) {
    device_ = ResolveDevice(device_text_);
  } else {
    bool noted = true;
    device_ = ResolveDevice(device_text_, nullptr, &noted);
  }
  return true;
}

}  // namespace watergs
