// The pixels of a scene a renderer back-end renders (experiment/frame_sources.h, BackendScene):
// its input frames (two halves), its plain curve (increments) and its reference (blocks), every
// render through the render cache (docs/renderers.md, "What a run renders").
#include <algorithm>
#include <cmath>

#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include "core/atomic_file.h"
#include "core/build_info.h"
#include "core/errors.h"
#include "core/exr_io.h"
#include "experiment/frame_sources.h"
#include "interop/import.h"

namespace dnb::experiment {

namespace {

// SplitMix64's finaliser: a bijection of 64-bit words whose outputs for neighbouring inputs are
// unrelated.
std::uint64_t mix(std::uint64_t z) {
  z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ULL;
  z = (z ^ (z >> 27)) * 0x94d049bb133111ebULL;
  return z ^ (z >> 31);
}

// The key of one render of the back-end kept in the cache (kind "renderer-frame").
CacheKey render_key(const BackendScene& b, const RenderSettings& s, std::uint32_t seed, const std::vector<std::string>& layers) {
  std::vector<std::pair<std::string, std::string>> parts = {{"backend_seed", std::to_string(seed)}};
  for (const auto& l : layers) parts.emplace_back("layer." + l, "1");
  return b.key("renderer-frame", s, parts);
}

AovFrame cached_render(Cache& cache, const BackendScene& b, const RenderSettings& s, std::uint32_t seed,
                       const std::vector<std::string>& layers, bool use_cache, bool* hit) {
  const CacheKey key = render_key(b, s, seed, layers);
  if (!use_cache) cache.remove(key);
  return cached_frame(cache, key, [&] { return b.backend->render(b.request(s, seed, layers)); }, hit);
}

// The layers of an input frame: every layer the back-end makes.
std::vector<std::string> input_layers(const BackendScene& b) { return b.backend->manifest().layers; }

}  // namespace

std::uint32_t backend_seed(const std::string& stream, std::uint64_t seed, int index) {
  std::uint64_t h = 0x6a09e667f3bcc908ULL;  // the stream's characters, not std::hash (which differs between builds)
  for (unsigned char c : stream) h = mix(h ^ c);
  h = mix(h ^ seed);
  h = mix(h ^ std::uint64_t(std::int64_t(index)));
  return std::uint32_t(h >> 33);  // 31 bits: a renderer that reads the seed as a signed int takes it too
}

interop::RenderRequest BackendScene::request(const RenderSettings& s, std::uint32_t seed, std::vector<std::string> layers) const {
  interop::RenderRequest r;
  r.scene = file;
  std::tie(r.width, r.height, r.spp, r.max_depth, r.threads) = std::tuple(s.width, s.height, s.spp, s.max_depth, s.threads);
  r.seed = seed;
  r.layers = std::move(layers);
  return r;
}

CacheKey BackendScene::key(const std::string& kind, const RenderSettings& s,
                           const std::vector<std::pair<std::string, std::string>>& parts) const {
  CacheKey k(kind);
  k.add("renderer", backend->manifest().name).add("renderer_identity", identity).add("scene_file", file_hash);
  k.add("width", s.width).add("height", s.height).add("spp", s.spp).add("seed", s.seed).add("max_depth", s.max_depth);
  for (const auto& [name, value] : parts) k.add(name, value);
  return k;
}

InputFrame::InputFrame(Cache& cache, const BackendScene& b, RenderSettings settings, bool use_cache, int reference_spp)
    : use_cache_(use_cache) {
  const std::uint32_t s0 = backend_seed("half0", settings.seed, 0), s1 = backend_seed("half1", settings.seed, 0);
  std::vector<std::pair<std::string, std::string>> parts = {{"half0_seed", std::to_string(s0)},
                                                            {"half1_seed", std::to_string(s1)}};
  for (const auto& l : input_layers(b)) parts.emplace_back("layer." + l, "1");
  const CacheKey key = b.key("renderer-input", settings, parts);
  identity_ = {{"input", key.digest()}, {"ref", reference_spp}};
  load_ = [this, &cache, &b, settings, key, s0, s1](bool* hit) {
    if (!use_cache_) cache.remove(key);
    AovFrame f = cached_frame(
        cache, key,
        [&] {
          RenderSettings half = settings;
          half.spp = settings.spp / 2;
          const auto layers = input_layers(b);
          // Each half alone, not through the cache: the frame made of both is what is kept.
          AovFrame h0 = b.backend->render(b.request(half, s0, layers));
          AovFrame h1 = b.backend->render(b.request(half, s1, layers));
          const double seconds = h0.meta.render_seconds + h1.meta.render_seconds;
          const std::string p0 = fmt::format("{} (half 0, seed {})", b.file, s0);
          const std::string p1 = fmt::format("{} (half 1, seed {})", b.file, s1);
          AovFrame both = interop::combine_halves({std::move(h0), {}}, {std::move(h1), {}}, p0, p1).frame;
          both.meta.scene = b.file;
          both.meta.spp = settings.spp;
          both.meta.seed = settings.seed;
          both.meta.render_seconds = seconds;
          both.meta.build_version = build_version_and_revision();
          return both;
        },
        hit);
    return std::pair(std::move(f), cache.entry_dir(key) + "/frame.exr");
  };
}

void PlainCurve::load_backend() {
  const BackendScene& b = *backend_;
  // Increment k renders prefixes_[k] - prefixes_[k - 1] samples; point k is the spp-weighted
  // mean of increments 0..k.
  bool all_hit = true;
  Image sum;
  double seconds = 0;
  int previous = 0;
  for (std::size_t k = 0; k < prefixes_.size(); ++k) {
    RenderSettings s = input_settings(config_, prefixes_[k] - previous, config_.seed);
    bool hit = false;
    AovFrame f = cached_render(cache_, b, s, backend_seed("curve", config_.seed, int(k)), {layer::kColor}, use_cache_, &hit);
    all_hit = all_hit && hit;
    const Image& c = f.layer(layer::kColor);
    if (sum.empty()) sum = Image(c.width(), c.height(), 3);
    for (std::size_t i = 0; i < c.size(); ++i) sum.data()[i] += c.data()[i] * float(s.spp);
    seconds += f.meta.render_seconds;
    Image point(c.width(), c.height(), 3);
    for (std::size_t i = 0; i < c.size(); ++i) point.data()[i] = sum.data()[i] / float(prefixes_[k]);
    points_[prefixes_[k]] = {std::move(point), seconds};
    previous = prefixes_[k];
  }
  hit_ = all_hit;
}

Reference backend_reference(Cache& cache, const BackendScene& b, const RenderSettings& settings, std::uint64_t seed,
                            int block_spp, bool use_cache) {
  if (settings.spp < 2)
    throw InputError(fmt::format("{}: a reference of {} spp: a back-end's reference needs at least 2 (two blocks give its "
                                 "variance)",
                                 b.file, settings.spp));
  // At least two blocks: their spread is the reference's variance.
  block_spp = std::max(1, std::min(block_spp, settings.spp / 2));
  RenderSettings whole = settings;
  whole.seed = seed;
  const CacheKey key = b.key("renderer-reference", whole, {{"block_spp", std::to_string(block_spp)}});
  if (!use_cache) cache.remove(key);
  if (auto entry = cache.lookup(key)) {
    Reference ref;
    ref.path = entry->file("reference.exr");
    AovFrame f = read_frame(ref.path, {layer::kColor}, std::vector<std::string>{layer::kColor, layer::kVariance});
    ref.color = f.layer(layer::kColor);
    if (f.has(layer::kVariance)) ref.variance = f.layer(layer::kVariance);
    ref.meta = f.meta;
    ref.convergence = parse_convergence_csv(read_text_file(entry->file("convergence.csv")), entry->file("convergence.csv"));
    ref.cache_hit = true;
    return ref;
  }
  // The blocks, each its own cache entry: the checkpoints of an interrupted render.
  const int blocks = (settings.spp + block_spp - 1) / block_spp;
  std::vector<Image> means;
  std::vector<int> spps;
  std::vector<CacheKey> block_keys;
  Reference ref;
  double seconds = 0;
  Image sum;
  int done = 0;
  for (int k = 0; k < blocks; ++k) {
    RenderSettings s = whole;
    s.spp = std::min(block_spp, settings.spp - k * block_spp);
    const std::uint32_t bs = backend_seed("reference", seed, k);
    bool hit = false;
    AovFrame f = cached_render(cache, b, s, bs, {layer::kColor}, use_cache, &hit);
    if (hit) ++ref.blocks_resumed;
    else ++ref.blocks_rendered;
    block_keys.push_back(render_key(b, s, bs, {layer::kColor}));
    seconds += f.meta.render_seconds;
    means.push_back(f.layer(layer::kColor));
    spps.push_back(s.spp);
    done += s.spp;
    spdlog::info("{}: reference block {}/{} ({} spp){}", b.file, k + 1, blocks, s.spp, hit ? " from the cache" : "");
  }
  // The spp-weighted mean of the blocks, and the variance of that mean from their spread: with
  // n blocks of equal weight, sum (m_b - m)^2 / (n (n - 1)), unbiased with n - 1 degrees of freedom.
  const Image& first = means.front();
  ref.color = Image(first.width(), first.height(), 3);
  for (std::size_t k = 0; k < means.size(); ++k)
    for (std::size_t i = 0; i < first.size(); ++i) ref.color.data()[i] += means[k].data()[i] * float(spps[k]) / float(done);
  const std::size_t n = means.size();
  if (n >= 2) {
    ref.variance = Image(first.width(), first.height(), 3);
    for (std::size_t k = 0; k < n; ++k) {
      const double w = double(spps[k]) / done;
      for (std::size_t i = 0; i < first.size(); ++i) {
        const double d = double(means[k].data()[i]) - ref.color.data()[i];
        ref.variance.data()[i] += float(w * w * d * d * double(n) / double(n - 1));
      }
    }
    double var = 0, mean2 = 0, rel = 0;
    for (std::size_t i = 0; i < first.size(); ++i) {
      const double m = ref.color.data()[i], v = ref.variance.data()[i];
      var += v, mean2 += m * m, rel += v / (m * m + 0.01);
    }
    ref.convergence.push_back({done, seconds, mean2 > 0 ? std::sqrt(var / mean2) : 0.0, rel / double(first.size())});
  }
  FrameMeta& m = ref.meta;
  m.scene = b.file;
  m.spp = done;
  m.seed = seed;
  m.tracer_version = b.backend->manifest().name + ": " + b.backend->version();
  m.build_version = build_version_and_revision();
  m.render_seconds = seconds;
  m.extra["reference"] = std::string("1");
  m.extra["cache_key"] = key.digest();
  m.extra["max_depth"] = std::to_string(settings.max_depth);
  m.extra["block_spp"] = std::to_string(block_spp);
  ref.render_seconds = seconds;
  CacheEntry entry = cache.store(key, [&](const std::string& dir) {
    write_reference(ref, dir + "/reference.exr", dir + "/convergence.csv");
  });
  ref.path = entry.file("reference.exr");
  // The finished reference is safe in the cache: its blocks have served their purpose.
  for (const auto& k : block_keys) cache.remove(k);
  return ref;
}

}  // namespace dnb::experiment
