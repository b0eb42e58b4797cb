#include "apps/commands.h"

namespace dnb::app {

void add_report(CLI::App& app, Action& action) { add_unavailable(app, action, "report", "Write tables, plots and the HTML report of a results folder"); }

}  // namespace dnb::app
