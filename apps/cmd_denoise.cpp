#include "apps/commands.h"

namespace dnb::app {

void add_denoise(CLI::App& app, Action& action) { add_unavailable(app, action, "denoise", "Run a method on a frame"); }

}  // namespace dnb::app
