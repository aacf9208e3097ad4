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

// The words a boolean option takes (Boost's bool validator's).
bool IsBoolWord(const std::string& word) {
  for (const char* w : {"0", "1", "true", "false", "yes", "no", "on", "off"}) {
    if (word == w) return true;
  }
  return false;
}

bool TrueWord(const std::string& word) {
  return word == "1" || word == "true" || word == "yes" || word == "on" ||
         word.empty();
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

void OptionParser::AddAlias(const std::string& alias, const std::string& name,
                            const std::string& value) {
  aliases_[alias] = name;
  alias_values_[alias] = value;
}

std::string OptionParser::Replacement(const std::string& alias) const {
  const auto value = alias_values_.find(alias);
  return "--" + aliases_.at(alias) +
         (value == alias_values_.end() ? "" : " " + value->second);
}

std::vector<std::string> OptionParser::ResolveAliases(
    int argc, char** argv, std::set<std::string>* used) const {
  std::vector<std::string> out;
  if (argc > 0) out.push_back(argv[0]);
  for (int k = 1; k < argc; ++k) {
    std::string token = argv[k];
    const bool next_is_bool = k + 1 < argc && IsBoolWord(argv[k + 1]);
    if (token.rfind("--", 0) != 0) {
      out.push_back(token);
      continue;
    }
    const size_t equals = token.find('=');
    std::string key = token.substr(
        2, equals == std::string::npos ? std::string::npos : equals - 2);
    const auto alias = aliases_.find(key);
    if (alias != aliases_.end()) {
      used->insert(key);
      const auto value = alias_values_.find(key);
      if (value != alias_values_.end()) {
        // A boolean alias: `--alias [0|1]` or `--alias=0|1`.
        bool on = true;
        if (equals != std::string::npos) {
          if (!IsBoolWord(token.substr(equals + 1))) {
            throw po::invalid_option_value(token);
          }
          on = TrueWord(token.substr(equals + 1));
        } else if (next_is_bool) {
          on = TrueWord(argv[++k]);
        }
        if (on) {
          out.push_back("--" + alias->second);
          out.push_back(value->second);
        }
        continue;
      }
      key = alias->second;
      token = "--" + key +
              (equals == std::string::npos ? "" : token.substr(equals));
    }
    if (equals == std::string::npos && flags_.count(key) && next_is_bool) {
      token += "=" + std::string(argv[++k]);
    }
    out.push_back(token);
  }
  return out;
}

void OptionParser::AddFlag(const std::string& name, bool* value,
                           const std::string& help) {
  flags_.insert(name);
  options_.add_options()(name.c_str(),
                         po::value<bool>(value)
                             ->default_value(*value)
                             ->implicit_value(true)
                             ->value_name("0|1"),
                         help.c_str());
}

std::string OptionParser::Help() const {
  std::ostringstream out;
  out << "Usage: watergs " << command_ << " [options]\n"
      << summary_ << "\n\n"
      << options_;
  if (!aliases_.empty()) out << "\nAliases:\n";
  for (const auto& [alias, name] : aliases_) {
    out << "  --" << alias << " = " << Replacement(alias) << " (deprecated)\n";
  }
  return out.str();
}

bool OptionParser::Parse(int argc, char** argv) {
  po::variables_map vm;
  try {
    std::set<std::string> used;
    const std::vector<std::string> args = ResolveAliases(argc, argv, &used);
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
            used.insert(alias);
            const auto value = alias_values_.find(alias);
            if (value == alias_values_.end()) {
              line.replace(start, alias.size(), name);
            } else {
              // A boolean alias: `alias = 1` is `name = value`.
              std::string word = line.substr(after + 1);
              word.erase(0, word.find_first_not_of(" \t"));
              word.erase(word.find_last_not_of(" \t\r") + 1);
              line = TrueWord(word) ? name + " = " + value->second : "";
            }
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
    // One line per deprecated name used, once the options parsed (an
    // error stays one line).
    for (const std::string& alias : used) {
      std::cerr << "notice: --" << alias << " is deprecated for " << command_
                << "; use " << Replacement(alias) << "\n";
    }
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
