#include "apps/commands.h"

namespace dnb::app {

void add_reference(CLI::App& app, Action& action) { add_unavailable(app, action, "reference", "Render a converged, checkpointed reference"); }

}  // namespace dnb::app
