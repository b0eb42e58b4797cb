// proposed: the paper's filter (its section 3, docs/paper.md; Gruzdev, Frolov, Ignatenko). Each
// illumination layer, direct D and indirect I separately, is filtered by the adaptive-manifold
// filter (denoisers/am/adaptive_manifold.h) whose guide is the layer's non-local-means vector
// (denoisers/nlm_space.h), the shading normal and the depth, each group scaled by its own
// sigma; the image is composed as F = (D' + I') * T + R' + E (formula 1).
//   - Reflections (paper 3.2): reflection level k (refl<k>.*) is filtered the same way with its
//     own guides, and composed bottom-up: R'_{k-1} = tint_k * ((D'_k + I'_k) T_k + R'_k + E_k);
//     the deepest level's R passes through.
//   - Edges (paper 3.1): for every pixel of G (frame.edges), the slice at that pixel is
//     evaluated 16 times, once with each sub-pixel's NLM vector (the pixel's patch with the
//     sub-pixel's illumination at its centre), normal and depth as guide; each result is
//     multiplied by that sub-pixel's albedo and the 16 are averaged: formula 1 per sub-pixel.
//     Only the slice depends on the pixel's guide, so the filter runs once (AmQuery).
//
// Parameters: the ParamSpec list at the end of this file, the only place they are documented
// (`denoisebench list methods` prints it); how the defaults were chosen and what was tried:
// docs/method-defaults.md. The ablation switches (nlm_space, geometry, edge_subpixels,
// reflections, filter_color) turn off one part each, for the experiment's ablation table.
//
// One frame runs in three steps: plan (plan_levels: the levels present, each reflection level's
// box and guides, the jobs that filter each level's layers and smooth its tint), run the jobs
// concurrently (run_jobs), compose the levels bottom-up (compose_levels).
#include <algorithm>
#include <atomic>
#include <cmath>
#include <filesystem>
#include <functional>

#include <opencv2/imgproc.hpp>
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <spdlog/spdlog.h>

#include "core/env.h"
#include "core/errors.h"
#include "denoisers/am/adaptive_manifold.h"
#include "denoisers/am/opencl.h"
#include "denoisers/hdr_mapping.h"
#include "denoisers/illumination.h"
#include "denoisers/method.h"
#include "denoisers/nlm_space.h"
#include "denoisers/proposed_capture.h"
#include "denoisers/proposed_opencl.h"

namespace dnb {
namespace {

class Proposed final : public Method {
 public:
  explicit Proposed(const Params& p)
      : sigma_nlm_(float(p.f("sigma_nlm"))),
        nlm_spp_exponent_(float(p.f("nlm_spp_exponent"))),
        outlier_spp_exponent_(float(p.f("outlier_spp_exponent"))),
        sigma_normal_(float(p.f("sigma_normal"))),
        sigma_depth_(float(p.f("sigma_depth"))),
        firefly_ratio_(float(p.f("firefly_ratio"))),
        sigma_nlm_direct_(float(p.f("sigma_nlm_direct"))),
        nlm_direct_spp_exponent_(float(p.f("nlm_direct_spp_exponent"))),
        firefly_sigma_(float(p.f("firefly_sigma"))),
        detail_guard_(float(p.f("detail_guard"))),
        use_nlm_(p.b("nlm_space")),
        use_geometry_(p.b("geometry")),
        use_edges_(p.b("edge_subpixels")),
        use_reflections_(p.b("reflections")),
        reflection_sum_(p.b("reflection_sum")),
        filter_color_(p.b("filter_color")),
        opencl_(p.s("device") != "cpu"),
        pipeline_(p.s("device") == "opencl"),
        tint_radius_(p.i("tint_radius")),
        reflection_downsample_(p.i("reflection_downsample")) {
    std::string why;
    if (opencl_ && !am_opencl_available(&why)) throw InputError("proposed: device=opencl: " + why);
    am_.sigma_s = p.f("sigma_s");
    am_.sigma_r = p.f("sigma_r");
    am_.tree_height = p.i("tree_height");
    am_.downsample = p.i("downsample");
    am_.pca_iterations = p.i("pca_iterations");
    am_.adjust_outliers = p.b("adjust_outliers");
    nlm_.dims = p.i("nlm_dims");
    nlm_.radius = p.i("nlm_radius");
    nlm_.patch_sigma = float(p.f("nlm_patch_sigma"));
    nlm_.samples = p.i("nlm_samples");
  }

  // The split (D, I, T, R, E) is what the paper filters; a frame without it (another renderer's:
  // pbrt-v4, Mitsuba 3) gets its colour filtered in NLM space instead, as filter_color = true
  // would, recorded as illumination_split 0. One of the two must be there (execute says which).
  std::vector<std::string> required_layers() const override {
    if (filter_color_) return {layer::kNormal, layer::kDepth, layer::kColor};
    return {layer::kNormal, layer::kDepth};
  }
  std::vector<std::string> optional_layers() const override {
    if (filter_color_) return {};
    auto l = illumination_layers();
    l.push_back(layer::kColor);
    l.push_back(layer::kVariance);  // the detail guard's noise level
    if (use_reflections_)  // every layer has_level() asks for, at every level a frame may hold
      for (int k = 1; k <= layer::kMaxLevels; ++k)
        for (const char* base : kLevelLayers) l.push_back(layer::at_level(k, base));
    return l;
  }

  MethodResult execute(const MethodInput& in) override {
    MethodResult r;
    const AovFrame& f = *in.frame;
    Plan plan;
    plan_settings(f, plan, r.stats);
    std::vector<std::string> absent;
    for (const auto& n : illumination_layers())
      if (!f.has(n)) absent.push_back(n);
    if (!filter_color_ && !absent.empty() && !f.has(layer::kColor))
      throw InputError(fmt::format("the frame has neither the illumination split (no {}) nor a colour layer (R, G, B)",
                                   fmt::join(absent, ", ")));
    // Three ways to run: the paper's split; another renderer's frame with an albedo but no split
    // (pbrt-v4, Mitsuba 3): the untextured light is the colour over the albedo, F = L * T, filtered
    // as the paper filters D + I, and what no albedo carries (emitters, the background) stays as R,
    // unfiltered; or the colour itself (filter_color, or a frame with neither split nor albedo).
    const bool demodulated = !filter_color_ && !absent.empty() && f.has(layer::kAlbedo);
    const bool colour_only = filter_color_ || (!absent.empty() && !demodulated);
    r.stats.counters["illumination_split"] = (!filter_color_ && absent.empty()) ? 1 : 0;
    r.stats.counters["albedo_demodulated"] = demodulated ? 1 : 0;
    if (!filter_color_ && !absent.empty())
      spdlog::warn("proposed: the frame has no {} layer{}: filtering {}", fmt::format("{}", fmt::join(absent, ", ")),
                   absent.size() > 1 ? "s" : "",
                   demodulated ? "the colour demodulated by the albedo (F / T)" : "its colour (no albedo either; as filter_color = true)");
    if (colour_only) {
      const Image depth = use_geometry_ ? normalized_depth(f, 0) : Image();
      r.image = filter_layer(f, 0, f.layer(layer::kColor), depth, plan.sigma_nlm, plan.am, r.stats, nullptr).image;
      guard_details(f, r.image, r.stats);
      return r;
    }
    // device = opencl on the paper's split: the whole filter on the device (proposed_opencl.h).
    // Elsewhere (another renderer's frame, the ablations, the cut light given back), and with
    // device = opencl_core, only the adaptive-manifold core runs there, each call with its own
    // upload and read-back.
    r.stats.counters["device_pipeline"] = 0;
    if (pipeline_ && !demodulated && use_nlm_ && use_geometry_ && !(firefly_sigma_ > 0)) {
      r.stats.counters["device_pipeline"] = 1;
      r.image = run_on_device(f, plan, r.stats);
      return r;
    }
    const AovFrame split = demodulated ? demodulate(f) : AovFrame();
    const AovFrame& fs = demodulated ? split : f;
    plan_levels(fs, plan, r.stats);
    plan.jobs.insert(plan.jobs.begin(), plan.tint_jobs.begin(), plan.tint_jobs.end());
    run_jobs(r.stats, plan.jobs);
    r.image = compose_levels(fs, plan, r.stats);
    guard_details(f, r.image, r.stats);
    // DENOISEBENCH_PROPOSED_CAPTURE=FILE: the frame, its device plan and this output, for the
    // device pipeline's driver on another machine (proposed_capture.h); the first run writes it,
    // later ones (a benchmark's repetitions) leave it.
    if (const char* path = env::get("PROPOSED_CAPTURE");
        path && *path && !demodulated && use_nlm_ && use_geometry_ && !std::filesystem::exists(path)) {
      MethodStats unused;
      write_proposed_capture(path, f, device_plan(f, plan, unused), r.image);
    }
    return r;
  }

 private:
  // F = (D + I) * T + R + E for a frame that has only F and T: I = F / T where the albedo is
  // at least kMinAlbedo, D = E = 0, and R the rest (F where the albedo is below it).
  static constexpr float kMinAlbedo = 1e-3f;
  static AovFrame demodulate(const AovFrame& f) {
    AovFrame d(f.width(), f.height());
    d.meta = f.meta;
    for (const char* l : {layer::kColor, layer::kAlbedo, layer::kNormal, layer::kDepth}) d.set(l, f.layer(l));
    const Image& c = f.layer(layer::kColor);
    const Image& t = f.layer(layer::kAlbedo);
    Image& ind = d.add(layer::kIndirect, 3);
    Image& refl = d.add(layer::kReflection, 3);
    d.add(layer::kDirect, 3);
    d.add(layer::kEmission, 3);
    for (std::size_t k = 0; k < c.size(); ++k) {
      if (t.data()[k] >= kMinAlbedo) ind.data()[k] = c.data()[k] / t.data()[k];
      else refl.data()[k] = c.data()[k];
    }
    return d;
  }

  // smooth_tint's same-surface test: unit normals within 0.1 (about 6 degrees) and depths
  // within 1% of the median depth. A coated surface's expected tint (its Fresnel term) changes
  // slowly within such a neighbourhood; across a crease or a silhouette the test fails.
  static constexpr float kTintNormalDistance = 0.1f;
  static constexpr float kTintDepthDistance = 0.01f;
  using Box = PixelBox;
  // Runs the jobs concurrently, each with its own stats; their stats go into `into` in job
  // order: phases appended (they overlapped in time), counters summed (firefly pixels) except
  // the guide's channel count, which is set.
  static void run_jobs(MethodStats& into, const std::vector<std::function<void(MethodStats&)>>& jobs) {
    std::vector<MethodStats> stats(jobs.size());
    tbb::parallel_for(std::size_t(0), jobs.size(), [&](std::size_t j) { jobs[j](stats[j]); }, tbb::simple_partitioner());
    for (const MethodStats& st : stats) {
      for (const auto& ph : st.phases) into.phases.push_back(ph);
      for (const auto& [name, v] : st.counters) {
        if (name == "guide_channels") into.counters[name] = v;
        else into.counters[name] += v;
      }
    }
  }
  static Image cropped(const Image& im, const Box& b) { return to_image(im.cview().crop(b.x, b.y, b.w, b.h)); }
  static void paste(const Image& part, const Box& b, Image& whole) {
    for (int y = 0; y < b.h; ++y)
      std::copy(part.pixel(0, y), part.pixel(0, y) + std::size_t(b.w) * part.channels(), whole.pixel(b.x, b.y + y));
  }

  struct Filtered {
    Image image;
    std::vector<float> queries;  // 3 floats per edge sub-pixel, when asked
  };

  using Job = std::function<void(MethodStats&)>;
  // One frame's work, planned before any of it runs: the spp-dependent settings, the levels to
  // filter (paper 3.2) with their guides, and the jobs that fill fd, fi and tints. The jobs
  // point into the plan and the frame, so the plan stays where it was made (no copies).
  struct Plan {
    float sigma_nlm = 0, sigma_direct = 0;  // NLM group sigmas for this frame's spp
    AmSettings am;                          // with eq. 11's strength for this frame's spp
    int levels = 0;                         // reflection levels filtered (0: level 0 only)
    bool edges = false;                     // level 0's edge sub-pixels are resolved
    std::vector<Filtered> fd, fi;           // each level's filtered direct and indirect layer
    std::vector<Image> depths;              // each level's depth over its median
    std::vector<AovFrame> subs;             // level k >= 1: its box's guides
    // The tint of level k's surface (named after the level it leads to: refl<k+1>.tint) carries
    // the noise of the tracer's per-sample lobe choice (illumination.h, smooth_tint); the level
    // under it is filtered, so that noise would reach the image unfiltered. tints[k] is it
    // smoothed (empty: the raw tint is used), also computed by a job.
    std::vector<Image> tints;
    std::vector<char> edge_mask;  // level 0's edge pixels: their tints stay their own
    float tint_band = 0;          // smooth_tint's noise band
    bool smooth_tints = false;
    std::vector<Job> jobs, tint_jobs;

    Plan() = default;
    Plan(const Plan&) = delete;
    Plan& operator=(const Plan&) = delete;
  };

  // The frame's sample count sets the NLM sigmas and eq. 11's strength.
  void plan_settings(const AovFrame& f, Plan& plan, MethodStats& stats) const {
    // A frame of unknown sample count (another renderer's, imported without --spp) gets the
    // settings of the 256-spp frames the defaults were tuned on; said, and recorded.
    if (f.meta.spp <= 0)
      spdlog::warn("proposed: the frame's sample count is unknown: using the settings for 256 spp (import it with --spp N)");
    stats.counters["assumed_spp"] = f.meta.spp > 0 ? 0 : 256;
    plan.sigma_nlm = nlm_sigma_for(f.meta.spp);
    stats.counters["sigma_nlm"] = plan.sigma_nlm;
    // Level 0's direct layer: its own sigma when given (sigma_nlm_direct > 0).
    plan.sigma_direct = sigma_nlm_direct_ > 0
                            ? sigma_nlm_direct_ * float(spp_scale(f.meta.spp, nlm_direct_spp_exponent_))
                            : plan.sigma_nlm;
    stats.counters["sigma_nlm_direct"] = plan.sigma_direct;
    plan.am = am_;
    plan.am.outlier_scale = spp_scale(f.meta.spp, -outlier_spp_exponent_);
    stats.counters["outlier_scale"] = plan.am.outlier_scale;
  }

  // The frame on the device: plan_levels' choices, for proposed_opencl().
  Image run_on_device(const AovFrame& f, const Plan& plan, MethodStats& stats) const {
    return proposed_opencl(f, device_plan(f, plan, stats), stats);
  }
  ProposedDevicePlan device_plan(const AovFrame& f, const Plan& plan, MethodStats& stats) const {
    ProposedDevicePlan d;
    d.am = plan.am;
    d.reflection_am = plan.am;
    if (reflection_downsample_ > 0) d.reflection_am.downsample = reflection_downsample_;
    d.nlm = nlm_;
    d.sigma_nlm = plan.sigma_nlm;
    d.sigma_direct = plan.sigma_direct;
    d.sigma_normal = sigma_normal_;
    d.sigma_depth = sigma_depth_;
    d.firefly_ratio = firefly_ratio_;
    if (use_reflections_)
      while (has_level(f, d.levels + 1)) ++d.levels;
    stats.counters["reflection_levels_filtered"] = d.levels;
    d.edges = use_edges_ && f.edges && !f.edges->pixels.empty();
    stats.counters["edge_subpixels_used"] = d.edges ? 1 : 0;
    d.reflection_sum = reflection_sum_;
    d.tint_radius = tint_radius_;
    d.tint_band = f.meta.spp > 0 ? 3.0f * 2.0f / std::sqrt(float(f.meta.spp)) : 0.0f;  // plan_levels' band
    d.smooth_tints = tint_radius_ > 0 && d.tint_band > 0;
    d.tint_normal_distance = kTintNormalDistance;
    d.tint_depth_distance = kTintDepthDistance;
    d.detail_guard = detail_guard_;
    return d;
  }

  // Every level's layers are filtered first, all as concurrent jobs (the levels do not depend
  // on each other: only their composition runs bottom-up). Each job is parallel inside, but
  // its serial steps between passes leave a core idle, which another job fills.
  void plan_levels(const AovFrame& f, Plan& plan, MethodStats& stats) const {
    // Levels present in the frame, deepest first (paper 3.2).
    if (use_reflections_)
      while (has_level(f, plan.levels + 1)) ++plan.levels;
    stats.counters["reflection_levels_filtered"] = plan.levels;
    const std::size_t n = std::size_t(plan.levels) + 1;
    plan.fd.resize(n);
    plan.fi.resize(n);
    plan.depths.resize(n);
    plan.subs.reserve(std::size_t(plan.levels));
    plan.edges = use_edges_ && f.edges && !f.edges->pixels.empty();
    stats.counters["edge_subpixels_used"] = plan.edges ? 1 : 0;  // a frame without them runs without
    plan.tints.resize(std::size_t(plan.levels));
    if (plan.levels > 0 && tint_radius_ > 0 && f.edges && !f.edges->pixels.empty()) {
      plan.edge_mask.assign(std::size_t(f.width()) * f.height(), 0);
      for (int px : f.edges->pixels) plan.edge_mask[std::size_t(px)] = 1;
    }
    // The noise band: 3 standard deviations of the lobe choice's noise at its largest (pc 0.2).
    plan.tint_band = f.meta.spp > 0 ? 3.0f * 2.0f / std::sqrt(float(f.meta.spp)) : 0.0f;
    plan.smooth_tints = tint_radius_ > 0 && plan.tint_band > 0;
    plan_level0(f, plan, stats);
    for (int k = 1; k <= plan.levels; ++k) plan_reflection_level(f, k, plan, stats);
  }

  // Level 0: the whole frame, its direct and indirect layers with the edge sub-pixels' queries.
  void plan_level0(const AovFrame& f, Plan& plan, MethodStats& stats) const {
    const Image& d = f.layer(layer::at_level(0, layer::kDirect));
    const Image& i = f.layer(layer::at_level(0, layer::kIndirect));
    Image& depth = plan.depths[0];
    if (use_geometry_) {
      ScopedPhase p(stats, "depth");
      depth = normalized_depth(f, 0);
    }
    plan.jobs.push_back([this, &f, &plan, dp = &d, zp = &depth](MethodStats& st) {
      plan.fd[0] = filter_layer(f, 0, *dp, *zp, plan.sigma_direct, plan.am, st, plan.edges ? &EdgeSample::direct : nullptr);
    });
    plan.jobs.push_back([this, &f, &plan, ip = &i, zp = &depth](MethodStats& st) {
      plan.fi[0] = filter_layer(f, 0, *ip, *zp, plan.sigma_nlm, plan.am, st, plan.edges ? &EdgeSample::indirect : nullptr);
    });
    if (plan.levels > 0 && plan.smooth_tints) push_tint_job(f, plan, 0, Box{0, 0, f.width(), f.height()}, &f, &depth);
  }

  // Reflection level k >= 1. It only shows where its tint is non-zero (it enters the level
  // above as tint_k * F'_k): filter the bounding box of those pixels plus a margin of 6 sigma_s
  // (the spatial kernel falls to 2e-4 there), and nothing for a level no pixel shows. Outside
  // the box F'_k stays 0, multiplied by a zero tint. Level 1 covers 10-19% of the built-in
  // scenes' pixels, level 2 under 2%.
  void plan_reflection_level(const AovFrame& f, int k, Plan& plan, MethodStats& stats) const {
    const Image& d = f.layer(layer::at_level(k, layer::kDirect));
    const Image& i = f.layer(layer::at_level(k, layer::kIndirect));
    Image& depth = plan.depths[std::size_t(k)];
    const Box box = nonzero_box(f.layer(layer::at_level(k, layer::kTint)), int(std::ceil(6.0 * plan.am.sigma_s)));
    stats.counters["level" + std::to_string(k) + "_filtered_fraction"] =
        double(box.w) * box.h / (double(f.width()) * f.height());
    Image* out_d = &plan.fd[std::size_t(k)].image;
    Image* out_i = &plan.fi[std::size_t(k)].image;
    *out_d = Image(f.width(), f.height(), 3);
    *out_i = Image(f.width(), f.height(), 3);
    if (box.empty()) return;
    AovFrame* sub = &plan.subs.emplace_back(box.w, box.h);  // reserved: the address stays
    sub->meta = f.meta;
    for (const char* base : {layer::kNormal, layer::kDepth}) {
      const std::string name = layer::at_level(k, base);
      sub->set(name, cropped(f.layer(name), box));
    }
    if (use_geometry_) {
      ScopedPhase p(stats, "depth_level" + std::to_string(k));
      depth = normalized_depth(*sub, k);  // over the median inside the box
    }
    const Image *dp = &d, *ip = &i, *zp = &depth;
    // The levels are seen through their tints (at most the mirror's 0.9, a coat's Fresnel
    // term 0.04-0.3 mostly): a coarser reduced grid costs them nothing measurable and saves
    // 8% of the whole filter (docs/method-defaults.md).
    AmSettings aml = plan.am;
    if (reflection_downsample_ > 0) aml.downsample = reflection_downsample_;
    const float sigma_nlm = plan.sigma_nlm;
    if (reflection_sum_) {
      plan.jobs.push_back([this, k, box, dp, ip, zp, sub, out_d, aml, sigma_nlm](MethodStats& st) {
        Image di = cropped(*dp, box);
        const Image ci = cropped(*ip, box);
        for (std::size_t j = 0; j < di.size(); ++j) di.data()[j] += ci.data()[j];
        paste(filter_layer(*sub, k, di, *zp, sigma_nlm, aml, st, nullptr).image, box, *out_d);
      });
    } else {
      plan.jobs.push_back([this, k, box, dp, zp, sub, out_d, aml, sigma_nlm](MethodStats& st) {
        paste(filter_layer(*sub, k, cropped(*dp, box), *zp, sigma_nlm, aml, st, nullptr).image, box, *out_d);
      });
      plan.jobs.push_back([this, k, box, ip, zp, sub, out_i, aml, sigma_nlm](MethodStats& st) {
        paste(filter_layer(*sub, k, cropped(*ip, box), *zp, sigma_nlm, aml, st, nullptr).image, box, *out_i);
      });
    }
    // Level k+1 shows only where level k does, so its tint is zero outside level k's box:
    // smoothed on the box, with the box's guides (the depth over the box's median).
    if (k < plan.levels && plan.smooth_tints) push_tint_job(f, plan, k, box, sub, zp);
  }

  // Queues the smoothing of level k's tint (layer k+1) on `box` of the frame, guided by level
  // k's normal in `guides` (the frame, or the box's crop of it) and `depth` (over the median;
  // empty: computed here, when the filters run without geometry).
  void push_tint_job(const AovFrame& f, Plan& plan, int k, Box box, const AovFrame* guides, const Image* depth) const {
    plan.tint_jobs.push_back([this, &f, &plan, k, box, guides, depth](MethodStats& st) {
      ScopedPhase p(st, "tint_level" + std::to_string(k + 1));
      const Image& full = f.layer(layer::at_level(k + 1, layer::kTint));
      const bool whole = box.w == f.width() && box.h == f.height();
      const Image z = depth->empty() ? normalized_depth(*guides, k) : Image();
      const std::vector<char>& edge_mask = plan.edge_mask;
      std::vector<char> keep;  // the edge mask on the box
      if (!edge_mask.empty() && !whole) {
        keep.resize(std::size_t(box.w) * box.h);
        for (int y = 0; y < box.h; ++y)
          std::copy_n(edge_mask.begin() + std::ptrdiff_t(std::size_t(box.y + y) * f.width() + box.x), box.w,
                      keep.begin() + std::ptrdiff_t(std::size_t(y) * box.w));
      }
      Image crop;
      const Image& tint = whole ? full : (crop = cropped(full, box));
      Image smoothed = smooth_tint(tint, guides->layer(layer::at_level(k, layer::kNormal)), depth->empty() ? z : *depth,
                                   tint_radius_, plan.tint_band, kTintNormalDistance, kTintDepthDistance,
                                   edge_mask.empty() ? nullptr : whole ? &edge_mask : &keep);
      if (!whole) {
        Image out = full;
        paste(smoothed, box, out);
        smoothed = std::move(out);
      }
      plan.tints[std::size_t(k)] = std::move(smoothed);
    });
  }

  // The levels composed bottom-up (formula 1, paper 3.2): F'_k = (D'_k + I'_k) T_k + R'_k + E_k
  // with R'_k = tint_{k+1} F'_{k+1} + (R_k - tint_{k+1} F_{k+1}); the deepest level's R passes
  // through. The bracket is the part of R that no level below explains, passed through unfiltered
  // as the deepest R is: the light of rough (non-delta) glossy and refracted lobes, which have no
  // level behind them (rough metal, frosted glass, a rough coat), and the product-of-means
  // remainder where the tint varies inside a pixel. Composed from the levels alone, those surfaces
  // would be black.
  Image compose_levels(const AovFrame& f, const Plan& plan, MethodStats& stats) const {
    Image below;  // F'_{k+1}: the composed, filtered level under the current one
    for (int k = plan.levels; k >= 0; --k) below = compose_level(f, plan, k, below, stats);
    return below;
  }

  // R_k - tint_{k+1} F_{k+1} of the unfiltered frame at element j (compose_levels' comment), with
  // F_{k+1} = (D + I) T + R + E of level k + 1; 0 when there is no level below.
  struct Unexplained {
    Unexplained(const AovFrame& f, int k, const Image* tint_below) : tint(tint_below) {
      if (!tint) return;
      refl = &f.layer(layer::at_level(k, layer::kReflection));
      d = &f.layer(layer::at_level(k + 1, layer::kDirect));
      i = &f.layer(layer::at_level(k + 1, layer::kIndirect));
      t = &f.layer(layer::at_level(k + 1, layer::kAlbedo));
      r = &f.layer(layer::at_level(k + 1, layer::kReflection));
      e = &f.layer(layer::at_level(k + 1, layer::kEmission));
    }
    float operator()(std::size_t j) const {
      if (!tint) return 0.0f;
      const float below = (d->data()[j] + i->data()[j]) * t->data()[j] + r->data()[j] + e->data()[j];
      return refl->data()[j] - tint->data()[j] * below;
    }
    const Image* tint;
    const Image *refl = nullptr, *d = nullptr, *i = nullptr, *t = nullptr, *r = nullptr, *e = nullptr;
  };

  Image compose_level(const AovFrame& f, const Plan& plan, int k, const Image& below, MethodStats& stats) const {
    const Filtered& fdk = plan.fd[std::size_t(k)];
    const Filtered& fik = plan.fi[std::size_t(k)];
    ScopedPhase p(stats, k == 0 ? "compose" : "compose_level" + std::to_string(k));
    Image out(f.width(), f.height(), 3);
    const Image& t = f.layer(layer::at_level(k, layer::kAlbedo));
    const Image& e = f.layer(layer::at_level(k, layer::kEmission));
    const Image& refl = f.layer(layer::at_level(k, layer::kReflection));
    const Image* raw_tint = k < plan.levels ? &f.layer(layer::at_level(k + 1, layer::kTint)) : nullptr;
    const Image* tint = raw_tint;
    if (tint && !plan.tints[std::size_t(k)].empty()) tint = &plan.tints[std::size_t(k)];
    const Unexplained unexplained(f, k, raw_tint);
    auto reflected = [&](std::size_t j) {
      return tint ? tint->data()[j] * below.data()[j] + unexplained(j) : refl.data()[j];
    };
    tbb::parallel_for(std::size_t(0), out.size(), [&](std::size_t j) {
      out.data()[j] = (fdk.image.data()[j] + fik.image.data()[j]) * t.data()[j] + reflected(j) + e.data()[j];
    });
    if (k != 0 || !plan.edges) return out;
    // Formula 1 per sub-pixel: mean over s of (D'_s + I'_s) T_s, plus the pixel's R' + E.
    const EdgeSubpixels& g = *f.edges;
    tbb::parallel_for(std::size_t(0), g.size(), [&](std::size_t n) {
      const std::size_t px = std::size_t(g.pixels[n]);
      const EdgeSample* sub = g.of(n);
      float* o = out.data() + px * 3;
      for (int c = 0; c < 3; ++c) {
        float sum = 0;
        for (int s = 0; s < EdgeSubpixels::kPerPixel; ++s) {
          const std::size_t q = (n * EdgeSubpixels::kPerPixel + s) * 3 + c;
          sum += (fdk.queries[q] + fik.queries[q]) * sub[s].albedo[c];
        }
        o[c] = sum / EdgeSubpixels::kPerPixel + reflected(px * 3 + c) + e.data()[px * 3 + c];
      }
    });
    stats.counters["edge_pixels"] = double(g.size());
    return out;
  }

  // The NLM group sigma for a frame of `spp` samples per pixel (0: unknown, e.g. a frame made
  // by hand without the metadata: sigma_nlm as given).
  float nlm_sigma_for(int spp) const { return sigma_nlm_ * float(spp_scale(spp, nlm_spp_exponent_)); }
  // (256 / spp)^exponent; 1 for an unknown sample count or exponent 0.
  static double spp_scale(int spp, double exponent) {
    if (spp <= 0 || exponent == 0.0) return 1.0;
    return std::pow(256.0 / double(spp), exponent);
  }

  static constexpr const char* kLevelLayers[] = {layer::kDirect,   layer::kIndirect, layer::kAlbedo, layer::kReflection,
                                                  layer::kEmission, layer::kNormal,   layer::kDepth,  layer::kTint};
  static bool has_level(const AovFrame& f, int k) {
    for (const char* base : kLevelLayers)
      if (!f.has(layer::at_level(k, base))) return false;
    return true;
  }

  // Filters `src` (a layer of level k) guided by [NLM vector, normal, depth] of that level. With
  // `sub` set (level 0), also answers one slice query per edge sub-pixel, its guide built from
  // the sub-pixel's value of that layer, normal and depth.
  Filtered filter_layer(const AovFrame& f, int level, const Image& layer_in, const Image& depth, float sigma_nlm,
                        const AmSettings& am, MethodStats& stats, float (EdgeSample::*sub)[3]) const {
    const std::string suffix = level == 0 ? "" : "_level" + std::to_string(level);
    FireflySplit ff;
    {
      ScopedPhase p(stats, "fireflies" + suffix);
      ff = split_fireflies(layer_in, firefly_ratio_, firefly_sigma_ > 0);  // excess only to give back
      stats.counters["firefly_pixels" + suffix] += double(ff.cut);
    }
    const Image& src = ff.kept;
    LayerGuide lg;
    {
      ScopedPhase p(stats, "nlm_space" + suffix);
      layer_guide(f, level, src, depth, sigma_nlm, lg);
    }
    const float sr = float(am.sigma_r);
    Image guide = make_guide(lg.groups, sr);
    stats.counters["guide_channels"] = guide.channels();

    EdgeQueries eq;
    if (sub) {
      ScopedPhase p(stats, "edge_guides");
      edge_queries(f, src, depth, lg, ff, guide.channels(), sr, sigma_nlm, sub, eq);
    }
    Filtered out;
    {
      ScopedPhase p(stats, "adaptive_manifolds" + suffix);
      out.image = opencl_ ? am_filter_opencl(src.cview(), guide.cview(), am, eq.queries, sub ? &out.queries : nullptr)
                          : am_filter(src.cview(), guide.cview(), am, eq.queries, sub ? &out.queries : nullptr);
    }
    if (ff.cut > 0 && firefly_sigma_ > 0) {
      ScopedPhase p(stats, "fireflies" + suffix);
      const Image spread = low_pass(ff.excess, firefly_sigma_);
      for (std::size_t k = 0; k < out.image.size(); ++k) out.image.data()[k] += spread.data()[k];
      if (sub) {
        const EdgeSubpixels& g = *f.edges;
        for (std::size_t n = 0; n < g.size(); ++n)
          for (int s = 0; s < EdgeSubpixels::kPerPixel; ++s)
            for (int c = 0; c < 3; ++c)
              out.queries[(n * EdgeSubpixels::kPerPixel + s) * 3 + c] += spread.data()[std::size_t(g.pixels[n]) * 3 + c];
      }
    }
    return out;
  }

  // A layer's guide groups: its NLM vectors (or, without nlm_space, its compressed
  // illumination), then the level's normal and depth. The groups view nlm and range, so a
  // LayerGuide is filled in place (layer_guide), never copied.
  struct LayerGuide {
    NlmSpace nlm;
    Image range;
    float range_scale = 1.0f;
    std::vector<GuideGroup> groups;
  };
  void layer_guide(const AovFrame& f, int level, const Image& src, const Image& depth, float sigma_nlm,
                   LayerGuide& lg) const {
    if (use_nlm_) {
      lg.nlm = nlm_space(src, nlm_);
      lg.groups.push_back({lg.nlm.vectors.cview(), sigma_nlm});
    } else {
      lg.range_scale = illumination_scale(src);
      lg.range = compressed_illumination(src, lg.range_scale);
      lg.groups.push_back({lg.range.cview(), sigma_nlm});
    }
    if (use_geometry_) {
      lg.groups.push_back({f.layer(layer::at_level(level, layer::kNormal)).cview(), sigma_normal_});
      lg.groups.push_back({depth.cview(), sigma_depth_});
    }
  }

  // Edge sub-pixel queries: the guide value each sub-pixel would have, scaled like the guide
  // (D channels); the queries point into guide and src.
  struct EdgeQueries {
    std::vector<AmQuery> queries;
    std::vector<float> guide, src;
  };
  void edge_queries(const AovFrame& f, const Image& src, const Image& depth, const LayerGuide& lg,
                    const FireflySplit& ff, int D, float sr, float sigma_nlm, float (EdgeSample::*sub)[3],
                    EdgeQueries& eq) const {
    const EdgeSubpixels& g = *f.edges;
    const std::size_t nq = g.size() * EdgeSubpixels::kPerPixel;
    eq.guide.resize(nq * D);
    eq.src.resize(nq * 3);
    eq.queries.resize(nq);
    const float depth_scale = depth.empty() ? 0.0f : depth_normaliser(f, depth);
    tbb::parallel_for(std::size_t(0), g.size(), [&](std::size_t n) {
      const int px = g.pixels[n];
      const int x = px % f.width(), y = px / f.width();
      constexpr int kSub = EdgeSubpixels::kPerPixel;
      const std::size_t q0 = n * kSub;
      for (int s = 0; s < kSub; ++s) {  // the sub-pixels' layer values
        float* v = eq.src.data() + (q0 + s) * 3;
        for (int k = 0; k < 3; ++k) v[k] = (g.of(n)[s].*sub)[k];
        if (firefly_ratio_ > 0) clamp_luminance(v, ff.bound[std::size_t(px)]);
      }
      if (use_nlm_) lg.nlm.vectors_with_centers(src, x, y, eq.src.data() + q0 * 3, kSub, eq.guide.data() + q0 * D, D);
      for (int s = 0; s < kSub; ++s) {
        const std::size_t q = q0 + s;
        const EdgeSample& e = g.of(n)[s];
        const float* v = eq.src.data() + q * 3;
        float* gq = eq.guide.data() + q * D;
        int c = 0;
        if (use_nlm_) {
          for (int k = 0; k < lg.nlm.vectors.channels(); ++k) gq[k] *= sr / sigma_nlm;
          c = lg.nlm.vectors.channels();
        } else {
          for (int k = 0; k < 3; ++k) gq[c++] = std::log1p(std::max(0.0f, v[k]) / lg.range_scale) * sr / sigma_nlm;
        }
        if (use_geometry_) {
          for (int k = 0; k < 3; ++k) gq[c++] = e.normal[k] * sr / sigma_normal_;
          gq[c++] = (e.depth > 0 && std::isfinite(e.depth) ? e.depth * depth_scale : 0.0f) * sr / sigma_depth_;
        }
        // The outlier adjustment (eq. 11) towards the sub-pixel's own value, always (also
        // with adjust_outliers = false, which concerns the image's pixels). Sub-pixel guides
        // (a second surface inside a silhouette pixel) are often far from every manifold,
        // and there the normalised slice is dominated by whatever manifold is least far:
        // without the adjustment the resolve raised the 8-bit MSE on G from 8.7 to 99
        // (conference, 256x192, 256 spp); with it, G falls to 8.0.
        eq.queries[q] = {x, y, gq, eq.src.data() + q * 3, true};
      }
    });
  }

  // The detail guard (not in the paper; it keeps thin dark features): where the filter moved a
  // pixel further from its input than the pixel's own noise explains, it removed signal, not
  // noise (a 1-2 px dark groove or gap whose guide - NLM patch, normal, depth - looks like its
  // neighbours', so the slice fills it with their light). Each channel's change is clamped to
  // detail_guard standard deviations of the pixel's mean: F' = F + clamp(F' - F, +-k s).
  // s comes from the variance layer (the variance of the mean, from independent sample groups:
  // docs/references.md) in two steps that keep it honest where one pixel's estimate is not:
  //   - a floor: at least the 5x5 median of the neighbours' relative variance v / (F'^2 + e)
  //     times the pixel's own F'^2 + e (7 degrees of freedom per pixel, the tracer's 8 groups, miss the heavy
  //     tail of path-traced noise at low spp; relative, so that a dark groove does not get the
  //     band of the bright wall around it);
  //   - a calibration: s times max(1, 1.4826 median over 5x5 of |F' - F| / s), the robust
  //     spread of the filter's changes in units of the pixels' own s. Where the variance is
  //     underestimated over an area (rare bright paths that every pixel there missed; a frame
  //     whose variance layer is too small), the filter's changes are large everywhere around
  //     and the band widens with them; a feature of one or two pixels is less than half of the
  //     window and leaves the median, so it keeps its narrow band. (Not the same median of |F' - F|
  //     in absolute units: that gives a dark groove the band of the bright, noisier wall
  //     around it, and the groove is lost again.)
  // A firefly's change stays inside its own wide band (its variance is of its own size), so the
  // firefly cut is kept. A frame without variance or colour layers is left as filtered.
  // Measured: docs/method-defaults.md, "Detail guard".
  void guard_details(const AovFrame& f, Image& out, MethodStats& stats) const {
    stats.counters["detail_guard_used"] = 0;
    if (detail_guard_ <= 0 || !f.has(layer::kVariance) || !f.has(layer::kColor)) return;
    const Image& x = f.layer(layer::kColor);
    const Image& v = f.layer(layer::kVariance);
    if (x.channels() != out.channels() || v.channels() != out.channels()) return;
    ScopedPhase p(stats, "detail_guard");
    auto finite_or_0 = [](float a) { return std::isfinite(a) ? a : 0.0f; };
    // e: (1% of the frame's mean filtered value)^2, so the relative variance has no scale of its own.
    double mean = 0;
    for (std::size_t k = 0; k < out.size(); ++k) mean += finite_or_0(out.data()[k]);
    const float e = float(std::pow(0.01 * mean / double(std::max<std::size_t>(out.size(), 1)), 2)) + 1e-20f;
    const std::size_t n = out.size();
    Image work(v.width(), v.height(), v.channels()), med(v.width(), v.height(), v.channels());
    // (1) The floor from the neighbours' relative variance: sd = sqrt(max(v, median(rel) (F'^2 + e))).
    tbb::parallel_for(std::size_t(0), n, [&](std::size_t k) {
      const float o = finite_or_0(out.data()[k]);
      work.data()[k] = std::max(finite_or_0(v.data()[k]), 0.0f) / (o * o + e);
    });
    cv::medianBlur(as_mat(work), as_mat(med), 5);  // 32-bit float: OpenCV allows apertures 3 and 5
    Image sd(v.width(), v.height(), v.channels());
    tbb::parallel_for(std::size_t(0), n, [&](std::size_t k) {
      const float o = finite_or_0(out.data()[k]);
      sd.data()[k] = std::sqrt(std::max(std::max(finite_or_0(v.data()[k]), 0.0f), med.data()[k] * (o * o + e)));
      // (2) The filter's change in units of it, for the calibration.
      const float z = std::abs(o - finite_or_0(x.data()[k])) / sd.data()[k];
      work.data()[k] = std::isfinite(z) ? z : 0.0f;
    });
    cv::medianBlur(as_mat(work), as_mat(med), 5);
    std::atomic<std::int64_t> clamped{0};
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, n, 1 << 14), [&](const auto& r) {
      std::int64_t c = 0;
      for (std::size_t k = r.begin(); k != r.end(); ++k) {
        const float in = x.data()[k], o = out.data()[k];
        const float band = detail_guard_ * sd.data()[k] * std::max(1.0f, 1.4826f * med.data()[k]);
        if (!std::isfinite(in) || !std::isfinite(o) || !std::isfinite(band)) continue;
        const float g = std::clamp(o, in - band, in + band);
        c += g != o;
        out.data()[k] = g;
      }
      clamped += c;
    });
    stats.counters["detail_guard_used"] = 1;
    stats.counters["detail_guard_clamped_samples"] = double(clamped.load());
  }

  // Gaussian low-pass (OpenCV), mirrored border so that light near the frame's edge stays.
  static Image low_pass(const Image& im, float sigma) {
    Image out(im.width(), im.height(), im.channels());
    const cv::Mat a(im.height(), im.width(), CV_32FC(im.channels()), const_cast<float*>(im.data()));
    cv::Mat b(out.height(), out.width(), CV_32FC(out.channels()), out.data());
    cv::GaussianBlur(a, b, cv::Size(0, 0), sigma, sigma, cv::BORDER_REFLECT);
    return out;
  }

  // 1 / median depth, as normalized_depth() applied it.
  static float depth_normaliser(const AovFrame& f, const Image& normalized) {
    const Image& z = f.layer(layer::kDepth);
    for (std::size_t k = 0; k < z.size(); ++k)
      if (normalized.data()[k] > 0 && z.data()[k] > 0) return normalized.data()[k] / z.data()[k];
    return 1.0f;
  }

  AmSettings am_;
  NlmSpaceSettings nlm_;
  float sigma_nlm_, nlm_spp_exponent_, outlier_spp_exponent_, sigma_normal_, sigma_depth_, firefly_ratio_, sigma_nlm_direct_, nlm_direct_spp_exponent_, firefly_sigma_, detail_guard_;
  bool use_nlm_, use_geometry_, use_edges_, use_reflections_, reflection_sum_, filter_color_, opencl_;
  bool pipeline_;  // device = opencl: the whole filter on the device where it can (else the core)
  int tint_radius_;
  int reflection_downsample_;
};

}  // namespace

MethodInfo proposed_method() {
  return {
      .name = "proposed",
      .description = "the paper's filter: D and I in NLM space, adaptive manifolds guided by normal and depth, edge sub-pixels, reflection levels",
      .kind = MethodKind::Filter,
      .params =
          {
              {"sigma_s", ParamType::Float, "4", "spatial standard deviation, pixels", 1.0, 512.0},
              {"sigma_r", ParamType::Float, "0.4", "AM range sigma (tree height, reduced grid); groups scale to it", 1e-3, 1.0},
              {"tree_height", ParamType::Int, "4", "manifold tree height (2^h - 1 manifolds); 0: from sigma_s and sigma_r", 0.0, 12.0},
              {"downsample", ParamType::Int, "2", "AM reduced-grid factor (1, 2, 4, ...); 0: from sigma_s and sigma_r", 0.0, 64.0},
              {"pca_iterations", ParamType::Int, "2", "power-iteration steps of each manifold split", 1.0, 100.0},
              {"adjust_outliers", ParamType::Bool, "true", "Gastal and Oliveira's outlier adjustment (eq. 11)"},
              {"outlier_spp_exponent", ParamType::Float, "0.5", "eq. 11's strength scales as (frame spp / 256)^this; 0: fixed", 0.0, 4.0},
              {"sigma_nlm", ParamType::Float, "0.05", "NLM-vector group sigma at 256 spp, log(1 + lum/mean) units", 1e-4, 1e3},
              {"nlm_spp_exponent", ParamType::Float, "1", "sigma_nlm scales as (256 / frame spp)^this; 0: fixed", 0.0, 4.0},
              {"sigma_normal", ParamType::Float, "0.3", "normal group sigma (unit vectors)", 1e-4, 1e3},
              {"sigma_depth", ParamType::Float, "0.02", "depth group sigma, units of the median depth", 1e-4, 1e3},
              {"nlm_dims", ParamType::Int, "3", "PCA dimensions of the NLM vector", 1.0, 49.0},
              {"nlm_radius", ParamType::Int, "3", "NLM patch radius (3: 7x7)", 1.0, 3.0},
              {"nlm_patch_sigma", ParamType::Float, "2", "Gaussian weight of the patch pixels, pixels", 0.1, 100.0},
              {"nlm_samples", ParamType::Int, "4096", "patches drawn to estimate the PCA", 16.0, 1e6},
              {"sigma_nlm_direct", ParamType::Float, "0.0075", "NLM-vector group sigma of level 0's direct layer at 256 spp; 0: sigma_nlm", 0.0, 1e3},
              {"nlm_direct_spp_exponent", ParamType::Float, "0.25", "sigma_nlm_direct scales as (256 / frame spp)^this", 0.0, 4.0},
              {"firefly_ratio", ParamType::Float, "3", "cut a pixel brighter than this times its brightest neighbour; 0: off", 0.0, 1e6},
              {"firefly_sigma", ParamType::Float, "0", "the cut light comes back low-passed with this sigma, pixels; 0: dropped", 0.0, 1e4},
              {"detail_guard", ParamType::Float, "3", "clamp each pixel's change to this many standard deviations of its mean (variance layer); 0: off", 0.0, 1e3},
              {"nlm_space", ParamType::Bool, "true", "ablation: false guides by the compressed illumination itself"},
              {"geometry", ParamType::Bool, "true", "ablation: false drops the normal and depth guides"},
              {"edge_subpixels", ParamType::Bool, "true", "ablation: false filters edge pixels like any other"},
              {"reflections", ParamType::Bool, "true", "ablation: false leaves R unfiltered"},
              {"tint_radius", ParamType::Int, "2", "reflection tints: mean over the same-surface pixels of a (2r+1)^2 window within the lobe-choice noise band; 0: raw", 0.0, 8.0},
              {"reflection_downsample", ParamType::Int, "4", "AM reduced-grid factor (1, 2, 4, ...) of the reflection levels; 0: as downsample", 0.0, 64.0},
              {"reflection_sum", ParamType::Bool, "false", "reflection levels: filter D + I as one layer (half the work)"},
              {"filter_color", ParamType::Bool, "false", "ablation: filter the colour instead of the illumination"},
              {"device", ParamType::String, "cpu", "where it runs: cpu; opencl (kernels, e.g. PoCL or a GPU: the whole filter on the illumination split, the adaptive-manifold core elsewhere); opencl_core (the core alone, each call with its own upload and read-back)", {}, {},
               {"cpu", "opencl", "opencl_core"}},
          },
      .create = [](const Params& p) { return std::make_unique<Proposed>(p); },
  };
}

}  // namespace dnb
