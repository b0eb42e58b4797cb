// The colour-only renders of the plain path-tracing curve and of references (render.h): a
// pixel's colour sums over a range of its samples, and the running means at several sample
// counts from one pass. Sampling as in render.cpp (its top comment): the first N samples of any
// render are the N-spp render.
#include <algorithm>
#include <cmath>

#include "core/timer.h"
#include "tracer/pixel_sums.h"
#include "tracer/render_internal.h"

namespace dnb {
using namespace render_pass;

ColorSums render_color_sums(const Scene& scene, const RenderSettings& settings, int sample_begin, int sample_end) {
  check_settings(settings);
  if (sample_begin < 0 || sample_end > settings.spp || sample_begin > sample_end)
    throw InputError(fmt::format("sample range [{}, {}) is not inside [0, {})", sample_begin, sample_end,
                                 settings.spp));
  const int W = settings.width, H = settings.height;
  PathTracer tracer(scene, tracer_options(settings));
  const SampleSource src{scene, tracer, W, H, settings.seed};
  ColorSums out;
  out.width = W;
  out.height = H;
  out.samples = sample_end - sample_begin;
  for (int s = sample_begin; s < sample_end; ++s) ++out.group_samples[s % kGroups];
  out.sum.assign(std::size_t(W) * H * 3, 0.0);
  out.group_sum.assign(std::size_t(W) * H * 3 * kGroups, 0.0);
  std::atomic<std::int64_t> dropped{0};
  for_each_tile(W, H, settings.threads, [&](int x0, int y0, int x1, int y1) {
    SampleResult r;
    SampleTable table;
    std::int64_t tile_dropped = 0;
    for (int y = y0; y < y1; ++y)
      for (int x = x0; x < x1; ++x) {
        const std::uint64_t pixel = std::uint64_t(y) * W + x;
        double* s1 = &out.sum[pixel * 3];
        double* sg = &out.group_sum[pixel * 3 * kGroups];
        src.trace_samples(table, x, y, sample_begin, sample_end, r, [&](int s, const SampleResult& sr, float, float) {
          // A dropped sample counts as 0 (mean() divides by the attempted samples).
          Vec3 f{0, 0, 0};
          if (sample_finite(sr)) f = sr.level[0].color();
          else ++tile_dropped;
          double* g = sg + 3 * (s % kGroups);
          for (int c = 0; c < 3; ++c) {
            s1[c] += f[c];
            g[c] += f[c];
          }
        });
      }
    dropped += tile_dropped;
    if (settings.on_progress) settings.on_progress(std::int64_t(x1 - x0) * (y1 - y0) * (sample_end - sample_begin));
  });
  out.dropped = dropped.load();
  return out;
}

void render_color_prefixes(const Scene& scene, const RenderSettings& settings, const std::vector<int>& prefixes,
                           const std::function<void(std::size_t, Image, double)>& on_prefix) {
  check_settings(settings);
  for (std::size_t k = 0; k < prefixes.size(); ++k)
    if (prefixes[k] < 1 || (k > 0 && prefixes[k] <= prefixes[k - 1]) || prefixes[k] > settings.spp)
      throw InputError(fmt::format("render prefixes must rise from 1 to at most the spp ({}); got {} at position {}",
                                   settings.spp, prefixes[k], k + 1));
  Stopwatch clock;
  const int W = settings.width, H = settings.height;
  PathTracer tracer(scene, tracer_options(settings));
  const SampleSource src{scene, tracer, W, H, settings.seed};
  // Per pixel and group: the colour's sums and the finite samples, as render_tile keeps them
  // (GroupSums' colour and level-0 count), so that a prefix's image is made by the same
  // additions in the same order as render_frame's colour layer.
  struct GroupColor {
    double c[3] = {0, 0, 0};
    std::int64_t n = 0;
  };
  std::vector<GroupColor> groups(std::size_t(W) * H * kGroups);
  int done = 0;
  for (std::size_t k = 0; k < prefixes.size(); ++k) {
    const int begin = done, end = prefixes[k];
    Image color(W, H, 3);
    for_each_tile(W, H, settings.threads, [&](int x0, int y0, int x1, int y1) {
      SampleResult r;
      SampleTable table;
      for (int y = y0; y < y1; ++y)
        for (int x = x0; x < x1; ++x) {
          GroupColor* g = &groups[(std::size_t(y) * W + x) * kGroups];
          src.trace_samples(table, x, y, begin, end, r, [&](int s, const SampleResult& sr, float, float) {
            if (!sample_finite(sr)) return;
            const Vec3 f = sr.level[0].color();
            GroupColor& gs = g[s % kGroups];
            for (int c = 0; c < 3; ++c) gs.c[c] += double(f[c]);
            ++gs.n;
          });
          // add_groups' order: the groups' sums added to 0 in group order.
          double sum[3] = {0, 0, 0};
          std::int64_t n = 0;
          for (int j = 0; j < kGroups; ++j) {
            n += g[j].n;
            for (int c = 0; c < 3; ++c) sum[c] += g[j].c[c];
          }
          store(color, x, y, sum, n > 0 ? 1.0 / n : 0.0);
        }
      if (settings.on_progress) settings.on_progress(std::int64_t(x1 - x0) * (y1 - y0) * (end - begin));
    });
    done = end;
    on_prefix(k, std::move(color), clock.seconds());
  }
}

void ColorSums::add(const ColorSums& o) {
  if (sum.empty()) {
    *this = o;
    return;
  }
  if (o.width != width || o.height != height)
    throw WorkError(fmt::format("cannot add colour sums of {}x{} to {}x{}", o.width, o.height, width, height));
  samples += o.samples;
  for (int g = 0; g < kSampleGroups; ++g) group_samples[g] += o.group_samples[g];
  dropped += o.dropped;
  for (std::size_t i = 0; i < sum.size(); ++i) sum[i] += o.sum[i];
  for (std::size_t i = 0; i < group_sum.size(); ++i) group_sum[i] += o.group_sum[i];
}

Image ColorSums::mean() const {
  // `samples` counts per-pixel samples attempted; dropped samples (rare) are spread over the
  // image, so dividing by the attempted count biases by at most dropped / (pixels x samples).
  Image img(width, height, 3);
  const double inv = samples > 0 ? 1.0 / double(samples) : 0.0;
  for (std::size_t i = 0; i < sum.size(); ++i) img.data()[i] = float(sum[i] * inv);
  return img;
}

double ColorSums::variance_of_mean(std::size_t i) const {
  // pixel_sums.h's group_ratio_variance with weight 1 per sample.
  double a[kGroups], b[kGroups];
  std::int64_t n[kGroups];
  const std::size_t pixel = i / 3, c = i % 3;
  for (int g = 0; g < kGroups; ++g) {
    a[g] = group_sum[(pixel * kGroups + std::size_t(g)) * 3 + c];
    b[g] = double(group_samples[g]);
    n[g] = group_samples[g];
  }
  return group_ratio_variance(a, b, n, sum[i], double(samples));
}

Image ColorSums::variance_of_mean() const {
  Image img(width, height, 3);
  for (std::size_t i = 0; i < sum.size(); ++i) img.data()[i] = float(variance_of_mean(i));
  return img;
}

}  // namespace dnb
