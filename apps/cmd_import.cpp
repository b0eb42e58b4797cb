// denoisebench import FORMAT IN.exr -o FRAME.exr [--spp N] [--layer NAME]: another renderer's
// output as a frame in the harness's layout (interop/import.h), saying what it kept and what it
// had to leave out.
#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include "apps/args.h"
#include "apps/commands.h"
#include "core/atomic_file.h"
#include "core/exr_io.h"
#include "interop/import.h"
#include "methods/denoise.h"
#include "methods/plugins.h"

namespace dnb::app {

void add_import(CLI::App& app, Action& action) {
  auto* cmd = app.add_subcommand("import", "Write another renderer's EXR (Blender Cycles, pbrt-v4, Mitsuba 3, or any "
                                           "through a mapping file) as an AOV frame in the harness's layout");
  struct Opts {
    std::string format, input, output, layer, second;
    int spp = 0;
    bool json = false;
  };
  auto o = std::make_shared<Opts>();
  cmd->add_option("FORMAT", o->format,
                  fmt::format("{} or map:FILE.toml (docs/importing.md)", fmt::join(interop::preset_names(), ", ")))
      ->required();
  cmd->add_option("IN", o->input, "the renderer's EXR")->required();
  cmd->add_option("-o,--output", o->output, "the frame to write (EXR), written atomically")->required();
  cmd->add_option("--spp", o->spp, "the frame's samples per pixel (over any the file records; foreign files often record none; with --second, each file's)")
      ->check(in_bounds(bounds::kSpp));
  cmd->add_option("--second", o->second,
                  "a second render of the same view with another seed: the two become the frame's half buffers "
                  "(half0.*, half1.*) and give the variances the files lack, so nfor, svgf and kpcn can run");
  cmd->add_option("--layer", o->layer, "the prefix of the passes (a Cycles view layer's name) when the file holds several");
  cmd->add_flag("--json", o->json, "print the report as JSON");
  // The methods listed as able to run on the frame include the plug-ins `denoise` would load.
  auto plugins = add_plugins_option(cmd);
  cmd->callback([&action, o, plugins] {
    action = [o, plugins] {
      load_plugins(*plugins);
      require_exr_output(o->output);
      // The frame and its edge file both replace what is there: neither may be the input.
      require_output_is_not_input(o->output, {{"input", o->input}});
      require_output_is_not_input(edges_path(o->output), {{"input", o->input}});
      if (!o->second.empty()) {
        require_output_is_not_input(o->output, {{"second", o->second}});
        require_output_is_not_input(edges_path(o->output), {{"second", o->second}});
      }
      const interop::ImportMapping mapping = interop::mapping_for(o->format);
      const interop::ImportOptions options{.spp = o->spp, .prefix = o->layer};
      interop::Imported im = o->second.empty() ? interop::import_frame(o->input, mapping, options)
                                               : interop::import_frame_pair(o->input, o->second, mapping, options);
      write_frame(im.frame, o->output);
      const interop::ImportReport& r = im.report;
      const auto methods = methods_for_frame(im.frame);
      if (o->json) {
        nlohmann::json j;
        j["format"] = r.format;
        j["input"] = o->input;
        j["output"] = o->output;
        j["prefix"] = r.prefix;
        j["spp"] = r.spp;
        j["spp_source"] = r.spp_source;
        for (const auto& [l, how] : r.kept) j["kept"][l] = how;
        j["left_out"] = nlohmann::json::object();
        for (const auto& [l, why] : r.left_out) j["left_out"][l] = why;
        j["unmapped_channels"] = r.unmapped;
        j["composition_rel_rms"] = r.composition_rel_rms ? nlohmann::json(*r.composition_rel_rms) : nlohmann::json(nullptr);
        j["warnings"] = r.warnings;
        j["methods"] = methods;
        fmt::print("{}\n", j.dump(2));
        return 0;
      }
      fmt::print("import {} '{}' -> '{}' ({}x{}{})\n", r.format, o->input, o->output, im.frame.width(), im.frame.height(),
                 r.prefix.empty() ? "" : fmt::format(", passes of '{}'", r.prefix));
      for (const auto& [l, how] : r.kept) fmt::print("  kept      {:<18} <- {}\n", l, how);
      for (const auto& [l, why] : r.left_out) fmt::print("  left out  {:<18} {}\n", l, why);
      if (!r.unmapped.empty()) fmt::print("  unused channels   {}\n", fmt::join(r.unmapped, ", "));
      fmt::print("  spp       {}\n", r.spp > 0 ? fmt::format("{} (from {})", r.spp, r.spp_source)
                                       : std::string("unknown (give --spp N: methods whose settings follow the sample count "
                                                     "would use their 256-spp defaults, and say so)"));
      if (r.composition_rel_rms)
        fmt::print("  check     (D + I) * T + R + E = colour to {:.3g} relative RMS\n", *r.composition_rel_rms);
      for (const auto& w : r.warnings) fmt::print("  warning   {}\n", w);
      fmt::print("  methods that can run on it: {}\n", methods.empty() ? std::string("none") : fmt::format("{}", fmt::join(methods, ", ")));
      return 0;
    };
  });
}

}  // namespace dnb::app
