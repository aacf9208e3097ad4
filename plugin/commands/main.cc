// Entry point: `watergs <command> [options]`, dispatching to the registry.
#include <algorithm>
#include <cstring>
#include <exception>
#include <iostream>

#include "gaussian/util/error.h"
#include "plugin/command.h"

namespace {

void PrintCommands() {
  std::cout << "watergs: 3D Gaussian Splatting training and WATER-GS "
               "watermarking for COLMAP workspaces\n\n"
               "Usage: watergs <command> [options]   (`watergs help <command>` "
               "or `watergs <command> -h` for a command's options; "
               "`watergs --version`)\n\nCommands:\n";
  // The summaries in one column, two spaces after the longest name.
  size_t width = 0;
  for (const auto& [name, command] : watergs::CommandRegistry()) {
    width = std::max(width, name.size() + 2);
  }
  for (const auto& [name, command] : watergs::CommandRegistry()) {
    std::cout << "  " << name << std::string(width - name.size(), ' ')
              << command.summary << "\n";
  }
}

}  // namespace

int main(int argc, char** argv) {
  if (argc >= 2 && (!std::strcmp(argv[1], "--version") ||
                    !std::strcmp(argv[1], "version"))) {
    std::cout << "watergs " << watergs::Version() << "\ncommit "
              << watergs::GitCommit()
              << (watergs::GitDirty() == 1 ? " (uncommitted changes)" : "")
              << "\n";
    return 0;
  }
  // `watergs help <command>` is `watergs <command> -h`.
  char help_flag[] = "-h";
  char* help_argv[] = {nullptr, nullptr, help_flag, nullptr};
  if (argc >= 3 && !std::strcmp(argv[1], "help")) {
    help_argv[0] = argv[0];
    help_argv[1] = argv[2];
    argc = 3;
    argv = help_argv;
  }
  if (argc < 2 || !std::strcmp(argv[1], "help") ||
      !std::strcmp(argv[1], "-h") || !std::strcmp(argv[1], "--help")) {
    PrintCommands();
    return argc < 2 ? 1 : 0;
  }
  const auto& registry = watergs::CommandRegistry();
  const auto it = registry.find(argv[1]);
  if (it == registry.end()) {
    std::cerr << "error: unknown command `" << argv[1]
              << "` (run `watergs help` for the list)\n";
    return 1;
  }
  try {
    return it->second.run(argc - 1, argv + 1);
  } catch (const watergs::Error& e) {
    std::cerr << "error: " << e.what() << "\n";
    return 1;
  } catch (const std::bad_alloc&) {
    std::cerr << "error: out of memory\n";
    return 3;
  } catch (const std::exception& e) {
    std::cerr << "error: internal: " << e.what() << "\n";
    return 2;
  }
}
