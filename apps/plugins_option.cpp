#include "apps/commands.h"

namespace dnb::app {

std::shared_ptr<std::vector<std::string>> add_plugins_option(CLI::App* cmd) {
  auto dirs = std::make_shared<std::vector<std::string>>();
  cmd->add_option("--plugins", *dirs,
                  "plug-in folder (repeatable), searched before $DENOISEBENCH_PLUGINS and the repository's plugins/");
  return dirs;
}

}  // namespace dnb::app
