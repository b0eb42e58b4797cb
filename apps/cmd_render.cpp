#include "apps/commands.h"

namespace dnb::app {

void add_render(CLI::App& app, Action& action) { add_unavailable(app, action, "render", "Render an AOV frame of a scene"); }

}  // namespace dnb::app
