// Two renders of one view with different seeds as one frame with half buffers and variances
// (interop/import.h, import_frame_pair): what the tracer's own frames carry, so that the methods
// that need them (nfor: half buffers; svgf: direct and indirect variances; kpcn: the variance of
// the colour) run on other renderers' frames too.
#include <algorithm>
#include <cmath>

#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include "core/errors.h"
#include "interop/import.h"

namespace dnb::interop {
namespace {

// (a - b)^2 / 4 per value: the variance of the mean (a + b) / 2 of two independent estimates of
// equal variance, unbiased, from one degree of freedom per value.
Image pair_variance(const Image& a, const Image& b) {
  Image v(a.width(), a.height(), a.channels());
  for (std::size_t k = 0; k < v.size(); ++k) {
    const double d = double(a.data()[k]) - b.data()[k];
    v.data()[k] = float(d * d / 4);
  }
  return v;
}

// The layers whose halves the tracer's frames carry (core/aov_frame.h's table, `halves`).
bool has_halves(const std::string& name) {
  const layer::Info* i = layer::find(name);
  return i && i->halves;
}

}  // namespace

Imported combine_halves(Imported first, Imported second, const std::string& first_path, const std::string& second_path) {
  AovFrame& a = first.frame;
  const AovFrame& b = second.frame;
  if (a.width() != b.width() || a.height() != b.height())
    throw InputError(fmt::format("'{}' is {}x{} but '{}' is {}x{}: the two halves of a frame are renders of one size",
                                 second_path, b.width(), b.height(), first_path, a.width(), a.height()));
  for (const auto& [name, image] : a.layers())
    if (!b.has(name))
      throw InputError(fmt::format("'{}' has no layer '{}', which '{}' has: the two halves need the same passes",
                                   second_path, name, first_path));
  for (const auto& [name, image] : b.layers())
    if (!a.has(name))
      throw InputError(fmt::format("'{}' has no layer '{}', which '{}' has: the two halves need the same passes",
                                   first_path, name, second_path));
  for (const auto& [name, image] : a.layers())
    if (name.rfind("half", 0) == 0)
      throw InputError(fmt::format("'{}' already has half buffers ('{}'): give two single renders", first_path, name));
  const Image& ca = a.layer(layer::kColor);
  const Image& cb = b.layer(layer::kColor);
  if (std::equal(ca.data(), ca.data() + ca.size(), cb.data()))
    throw InputError(fmt::format("'{}' and '{}' have the same colour, value for value: not two independent renders "
                                 "(render the second with another seed)",
                                 first_path, second_path));

  const int spp_a = a.meta.spp, spp_b = b.meta.spp;
  AovFrame out(a.width(), a.height());
  const bool own_variance = a.has(layer::kVariance);
  for (const auto& [name, la] : a.layers()) {
    const Image& lb = b.layer(name);
    Image m(la.width(), la.height(), la.channels());
    const bool variance = name == layer::kVariance || name == layer::kDirectVariance || name == layer::kIndirectVariance;
    // A variance of each file's mean: that of the mean of the two is their sum over 4.
    for (std::size_t k = 0; k < m.size(); ++k)
      m.data()[k] = variance ? (la.data()[k] + lb.data()[k]) / 4 : (la.data()[k] + lb.data()[k]) / 2;
    out.set(name, std::move(m));
    if (has_halves(name)) {
      out.set(layer::at_half(0, name), la);
      out.set(layer::at_half(1, name), lb);
    }
  }
  // The variances the files do not carry, from the difference of the two.
  const std::pair<const char*, const char*> derived[] = {{layer::kVariance, layer::kColor},
                                                         {layer::kDirectVariance, layer::kDirect},
                                                         {layer::kIndirectVariance, layer::kIndirect}};
  std::vector<std::string> made;
  for (const auto& [var, of] : derived)
    if (!out.has(var) && a.has(of)) {
      out.set(var, pair_variance(a.layer(of), b.layer(of)));
      made.push_back(var);
    }

  out.meta = a.meta;
  out.meta.spp = spp_a > 0 && spp_b > 0 ? spp_a + spp_b : 0;
  out.meta.extra["import.second"] = second_path;
  out.meta.extra["import.halves"] = "half0: " + first_path + ", half1: " + second_path;
  if (!made.empty())
    out.meta.extra["import.pair_variance"] = fmt::format("{}: (a - b)^2 / 4 of the two files (1 degree of freedom a value)",
                                                         fmt::join(made, ", "));
  first.frame = std::move(out);
  ImportReport& r = first.report;
  r.spp = first.frame.meta.spp;
  if (r.spp == 0) r.spp_source = "unknown";
  else r.spp_source = fmt::format("{} + {} ({}, {})", spp_a, spp_b, r.spp_source, second.report.spp_source);
  for (const auto& w : second.report.warnings) r.warnings.push_back(fmt::format("'{}': {}", second_path, w));
  if (second.report.composition_rel_rms && r.composition_rel_rms)
    r.composition_rel_rms = std::max(*r.composition_rel_rms, *second.report.composition_rel_rms);
  r.kept.emplace_back("half0.*, half1.*", fmt::format("'{}' and '{}' (their mean is every layer)", first_path, second_path));
  for (const auto& v : made) r.kept.emplace_back(v, "(a - b)^2 / 4 of the two files' values");
  if (own_variance) r.kept.emplace_back(layer::kVariance, "the files' own, their sum over 4");
  return first;
}

Imported import_frame_pair(const std::string& first, const std::string& second, const ImportMapping& mapping,
                           const ImportOptions& options) {
  return combine_halves(import_frame(first, mapping, options), import_frame(second, mapping, options), first, second);
}

}  // namespace dnb::interop
