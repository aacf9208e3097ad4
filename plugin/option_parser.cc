#include "plugin/option_parser.h"

#include <filesystem>
#include <fstream>
#include <iostream>
#include <sstream>

#include "gaussian/error.h"

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
      "device", po::value<std::string>(&device_text_)->default_value("cpu"),
      "cpu, cuda or auto (CUDA when built with it and a GPU is visible). "
      "The default stays cpu until the CUDA parity tests have passed on a "
      "GPU (README, CUDA backend)");
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
  return out.str();
}

bool OptionParser::Parse(int argc, char** argv) {
  po::variables_map vm;
  try {
    po::store(po::parse_command_line(argc, argv, options_), vm);
    if (vm.count("help")) {
      std::cout << Help();
      return false;
    }
    if (vm.count("project_path")) {
      const std::string ini = vm["project_path"].as<std::string>();
      if (!std::filesystem::is_regular_file(ini)) {
        FailAt(ini, "project file not found");
      }
      std::ifstream in(ini);
      try {
        po::store(
            po::parse_config_file(in, options_, /*allow_unregistered=*/false),
            vm);
      } catch (po::error& e) {
        FailAt(ini, Message(e));
      }
    }
    po::notify(vm);
  } catch (po::error& e) {
    Fail("watergs " + command_ + ": " + Message(e) + " (see `watergs " +
         command_ + " -h`)");
  }
  device_ = ResolveDevice(device_text_);
  return true;
}

}  // namespace watergs
