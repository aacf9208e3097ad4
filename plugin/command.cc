#include "plugin/command.h"

namespace watergs {

std::map<std::string, Command>& CommandRegistry() {
  static std::map<std::string, Command> registry;
  return registry;
}

}  // namespace watergs
