// COLMAP-style command-line options on top of Boost.program_options:
// `--name value` flags, `-h/--help`, and `--project_path file.ini` holding the
// same options as `name = value` lines (command-line values win).
#pragma once

#include <boost/program_options.hpp>
#include <map>
#include <set>
#include <string>
#include <type_traits>
#include <vector>

#include "gaussian/device.h"

namespace watergs {

class OptionParser {
 public:
  // `command` and `summary` head the help text.
  OptionParser(std::string command, std::string summary);

  // Registers an option with a default value. Help shows a floating-point
  // default as written (0.3, not Boost's 0.29999999999999999).
  template <typename T>
  void Add(const std::string& name, T* value, const std::string& help) {
    if constexpr (std::is_floating_point_v<T>) {
      options_.add_options()(
          name.c_str(),
          boost::program_options::value<T>(value)->default_value(
              *value, ShortestText(*value)),
          help.c_str());
    } else {
      options_.add_options()(
          name.c_str(),
          boost::program_options::value<T>(value)->default_value(*value),
          help.c_str());
    }
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

  // Accepts `--alias` (on the command line and in the project file) as
  // another name of the registered option `name`, e.g. an option's name
  // before it was unified across commands. Help lists it.
  void AddAlias(const std::string& alias, const std::string& name);

  // Whether option `name` was given (on the command line or in the project
  // file) rather than left at its default; valid after Parse.
  bool Given(const std::string& name) const { return given_.count(name) > 0; }

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
  // The shortest text that reads back as `value` ("0.3").
  static std::string ShortestText(double value);
  static std::string ShortestText(float value);

  // `--alias` tokens of argv rewritten to their option's name.
  std::vector<std::string> ResolveAliases(int argc, char** argv) const;

  std::string command_;
  std::string summary_;
  // alias -> option name.
  std::map<std::string, std::string> aliases_;
  // Options given explicitly, filled by Parse.
  std::set<std::string> given_;
  boost::program_options::options_description options_;
  std::string project_path_;
  // --device as typed, and what it resolved to.
  std::string device_text_ = "cpu";
  Device device_ = Device::kCpu;
};

}  // namespace watergs
