#include "apps/commands.h"

namespace dnb::app {

void add_run(CLI::App& app, Action& action) { add_unavailable(app, action, "run", "Run an experiment matrix from a config"); }

}  // namespace dnb::app
