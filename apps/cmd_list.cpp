#include "apps/commands.h"

namespace dnb::app {

void add_list(CLI::App& app, Action& action) { add_unavailable(app, action, "list", "List methods, scenes or metrics"); }

}  // namespace dnb::app
