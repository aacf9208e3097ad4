// The `watergs <command>` registry. Each command lives in
// plugin/commands/<name>.cc and registers itself with WATERGS_COMMAND.
#pragma once

#include <functional>
#include <map>
#include <string>

namespace watergs {

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
