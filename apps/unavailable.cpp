#include <fmt/format.h>

#include "apps/commands.h"

namespace dnb::app {

void add_unavailable(CLI::App& app, Action& action, const std::string& name, const std::string& what) {
  auto* cmd = app.add_subcommand(name, what + " (not available in this build yet)");
  cmd->allow_extras();
  cmd->callback([&action, name] {
    action = [name] {
      fmt::print(stderr, "denoisebench {}: not available in this build yet\n", name);
      return 2;
    };
  });
}

}  // namespace dnb::app
