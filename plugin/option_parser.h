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
    if constexpr (std::is_same_v<T, bool>) {
      AddFlag(name, value, help);  // one boolean style (AddFlag)
    } else if constexpr (std::is_floating_point_v<T>) {
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
  // Registers a boolean, *value its default. Every boolean of every command
  // takes the same forms: `--name` alone sets it, `--name 0|1` (or
  // `=0|1`, true/false, yes/no, on/off) sets it either way, `name = 0|1` in
  // a project file. Add<bool> registers through here.
  void AddFlag(const std::string& name, bool* value, const std::string& help);

  // Accepts `--alias` (on the command line and in the project file) as
  // another name of the registered option `name`: an option's name before
  // it was unified across commands (docs/cli.md, "Option names"). Using it
  // prints one line on stderr, once a parse: "notice: --ALIAS is deprecated
  // for COMMAND; use --NAME". Help lists it.
  void AddAlias(const std::string& alias, const std::string& name);
  // Accepts the boolean `--alias` (`--alias`, `--alias 1`, `alias = 1`) as
  // `--name value`, e.g. train's `--eval` as `--split train`; `--alias 0`
  // leaves `name` alone. Deprecated as above ("...; use --name value").
  void AddAlias(const std::string& alias, const std::string& name,
                const std::string& value);

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

  // argv with `--alias` tokens rewritten to their option's name (adding
  // the names of the aliases used to `used`) and `--boolean 0|1` joined
  // into `--boolean=0|1`.
  std::vector<std::string> ResolveAliases(int argc, char** argv,
                                          std::set<std::string>* used) const;
  // The `--name` (`--name value`) an alias stands for.
  std::string Replacement(const std::string& alias) const;

  std::string command_;
  std::string summary_;
  // alias -> option name, and the value of aliases that stand for
  // `--name value`.
  std::map<std::string, std::string> aliases_;
  std::map<std::string, std::string> alias_values_;
  // The booleans (AddFlag).
  std::set<std::string> flags_;
  // Options given explicitly, filled by Parse.
  std::set<std::string> given_;
  boost::program_options::options_description options_;
  std::string project_path_;
  // --device as typed, and what it resolved to.
  std::string device_text_ = "cpu";
  Device device_ = Device::kCpu;
};

}  // namespace watergs
