// COLMAP-style command-line options on top of Boost.program_options:
// `--name value` flags, `-h/--help`, and `--project_path file.ini` holding the
// same options as `name = value` lines (command-line values win).
#pragma once

#include <boost/program_options.hpp>
#include <string>

#include "gaussian/device.h"

namespace watergs {

class OptionParser {
 public:
  // `command` and `summary` head the help text.
  OptionParser(std::string command, std::string summary);

  // Registers an option with a default value.
  template <typename T>
  void Add(const std::string& name, T* value, const std::string& help) {
    options_.add_options()(
        name.c_str(),
        boost::program_options::value<T>(value)->default_value(*value),
        help.c_str());
  }
  // Registers an option the user must give (on the command line or .ini).
  template <typename T>
  void AddRequired(const std::string& name, T* value, const std::string& help) {
    options_.add_options()(name.c_str(),
                           boost::program_options::value<T>(value)->required(),
                           help.c_str());
  }
  // Registers a flag that is true when present.
  void AddFlag(const std::string& name, bool* value, const std::string& help);

  // Parses argv (argv[0] = command name). Returns false if help was printed
  // and the command should exit 0. Throws Error with a one-line message for
  // unknown, missing or malformed options and unreadable project files.
  bool Parse(int argc, char** argv);

  // The help text.
  std::string Help() const;

  // The device `--device cpu|cuda|auto` (every command has it) resolved to;
  // valid after Parse.
  Device device() const { return device_; }

 private:
  std::string command_;
  std::string summary_;
  boost::program_options::options_description options_;
  std::string project_path_;
  // --device as typed, and what it resolved to.
  std::string device_text_ = "cpu";
  Device device_ = Device::kCpu;
};

}  // namespace watergs
