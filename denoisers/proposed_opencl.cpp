#include "denoisers/proposed_opencl.h"

#include <random>
#include <string>

#include "core/env.h"
#include "core/errors.h"

namespace dnb {
AovFrame with_rounding_noise(const AovFrame& frame, int levels, float eps, std::uint64_t seed) {
  AovFrame g = frame;
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<float> u(-1.0f, 1.0f);
  for (int k = 0; k <= levels; ++k)
    for (const char* base : {layer::kDirect, layer::kIndirect}) {
      const std::string name = layer::at_level(k, base);
      if (!g.has(name)) continue;
      Image& im = g.layer(name);
      for (std::size_t i = 0; i < im.size(); ++i) im.data()[i] *= 1.0f + eps * u(rng);
    }
  return g;
}
}  // namespace dnb

#ifndef DNB_WITH_OPENCL

namespace dnb {
Image proposed_opencl(const AovFrame&, const ProposedDevicePlan&, MethodStats&) {
  throw WorkError("device=opencl: this build has no OpenCL (configure with -DDNB_WITH_OPENCL=ON)");
}
}  // namespace dnb

#else

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <deque>
#include <map>
#include <memory>
#include <string>
#include <vector>

#include <opencv2/core.hpp>

#include "denoisers/am/opencl_device.h"
#include "denoisers/illumination.h"

namespace dnb {
namespace {

using am_cl::Pooled;

class Pipeline {
 public:
  Pipeline(const AovFrame& f, const ProposedDevicePlan& p, MethodStats& stats)
      : f_(f), p_(p), stats_(stats), q_(am_cl::queue()), W_(f.width()), H_(f.height()), N_(std::size_t(W_) * H_),
        dims_(std::clamp(p.nlm.dims, 1, (2 * p.nlm.radius + 1) * (2 * p.nlm.radius + 1))), D_(dims_ + 4),
        fp64_(am_cl::device_has_fp64()), prog_(am_cl::program(D_, 3)) {}

  // A pipeline that threw may leave writes from kept_ queued: they finish before it goes.
  ~Pipeline() {
    try {
      q_.finish();
    } catch (...) {
    }
  }
  Pipeline(const Pipeline&) = delete;
  Pipeline& operator=(const Pipeline&) = delete;

  Image run() {
    const int K = p_.levels;
    std::vector<Level> lv(std::size_t(K) + 1);
    {
      ScopedPhase ph(stats_, "device_upload");
      for (int k = 0; k <= K; ++k) upload_level(k, lv[std::size_t(k)]);
      if (p_.edges) upload_edges();
    }
    cut_ = zeros(sizeof(cl_int));
    {
      ScopedPhase ph(stats_, "device_filter");
      // Every layer's NLM statistics first, then one wait for their covariances, then the rest:
      // the host's eigen-decompositions cost the device one idle gap per frame, not one per layer.
      std::deque<LayerJob> jobs;
      plan_level0(lv[0], jobs);
      for (int k = 1; k <= K; ++k) plan_reflection_level(k, lv[std::size_t(k)], jobs);
      for (LayerJob& j : jobs) nlm_statistics(j);
      q_.finish();
      for (LayerJob& j : jobs) filter(j);
      for (int k = 0; k < K; ++k)
        if (p_.smooth_tints) smooth_tint_of(k, lv);
    }
    ScopedPhase ph(stats_, "device_compose");
    Pooled below;
    for (int k = K; k >= 0; --k) below = compose_level(k, lv, below);
    guard(below);
    Pooled il(sizeof(float) * N_ * 3);
    run1(kernel("pp_interleave"), N_, int(N_), 3, *below, *il);
    Image out(W_, H_, 3);
    cl_int cut = 0;
    q_.enqueueReadBuffer(*cut_, CL_FALSE, 0, sizeof(cl_int), &cut);
    q_.enqueueReadBuffer(*il, CL_TRUE, 0, sizeof(float) * N_ * 3, out.data());
    stats_.counters["firefly_pixels"] = double(cut);
    stats_.counters["guide_channels"] = D_;
    if (am_cl::profiling()) print_profile();
    return out;
  }

 private:
  // A level's layers on the device, planar, full frame; its filtered layers and its box.
  struct Level {
    Pooled d, i, t, r, e, n, z, tint;  // tint: the raw refl<k>.tint (k >= 1)
    Pooled fd, fi;                     // filtered D and I (full frame, 0 outside the box)
    Pooled zn;                         // depth over the median of the box (the box's size)
    Pooled zb, nb;                     // level k >= 1: its depth and normal cropped to the box
    Pooled smoothed;                   // the smoothed tint of level k + 1 (full frame), or empty
    PixelBox box;
    float median = 1.0f;
  };

  // ---- kernels and buffers
  cl::Kernel& kernel(const char* name) {
    auto it = kernels_.find(name);
    if (it == kernels_.end()) it = kernels_.emplace(name, cl::Kernel(prog_, name)).first;
    return it->second;
  }
  template <typename... A>
  void run1(cl::Kernel& k, std::size_t n, A&&... args) {
    set(k, std::forward<A>(args)...);
    const std::size_t l = 64;
    q_.enqueueNDRangeKernel(k, cl::NullRange, cl::NDRange((std::max<std::size_t>(n, 1) + l - 1) / l * l), cl::NDRange(l),
                            nullptr, event(k));
  }
  template <typename... A>
  void run2(cl::Kernel& k, int w, int h, int depth, A&&... args) {
    set(k, std::forward<A>(args)...);
    const std::size_t l = 32;
    q_.enqueueNDRangeKernel(k, cl::NullRange, cl::NDRange((std::size_t(w) + l - 1) / l * l, std::size_t(h), std::size_t(depth)),
                            cl::NDRange(l, 1, 1), nullptr, event(k));
  }
  // DENOISEBENCH_OPENCL_PROFILE: each kernel of the pipeline timed by the device (the core's calls
  // print their own), summed per name and printed after the frame.
  cl::Event* event(cl::Kernel& k) {
    if (!am_cl::profiling()) return nullptr;
    events_.emplace_back(k.getInfo<CL_KERNEL_FUNCTION_NAME>(), cl::Event());
    return &events_.back().second;
  }
  void print_profile() {
    q_.finish();
    std::map<std::string, std::pair<double, int>> by;
    double total = 0;
    for (auto& [name, e] : events_) {
      const double ms = double(e.getProfilingInfo<CL_PROFILING_COMMAND_END>() - e.getProfilingInfo<CL_PROFILING_COMMAND_START>()) * 1e-6;
      by[name].first += ms, ++by[name].second, total += ms;
    }
    std::string line = "opencl profile, proposed's pipeline besides the core: " + std::to_string(total) + " ms of device time:";
    for (auto& [name, t] : by) line += " " + name + " " + std::to_string(t.first) + " ms/" + std::to_string(t.second) + ";";
    std::fprintf(stderr, "%s\n", line.c_str());
  }
  template <typename... A>
  static void set(cl::Kernel& k, A&&... args) {
    cl_uint i = 0;
    (k.setArg(i++, std::forward<A>(args)), ...);
  }
  Pooled zeros(std::size_t bytes) {
    Pooled b(bytes);
    q_.enqueueFillBuffer(*b, 0.0f, 0, b.bytes());
    return b;
  }
  // Host data for a write that does not block: kept until the pipeline ends.
  template <typename T>
  Pooled upload(std::vector<T> v) {
    Pooled b(sizeof(T) * std::max<std::size_t>(v.size(), 1));
    if (!v.empty()) {
      auto kept = std::make_shared<std::vector<T>>(std::move(v));
      q_.enqueueWriteBuffer(*b, CL_FALSE, 0, sizeof(T) * kept->size(), kept->data());
      kept_.push_back(std::move(kept));
    }
    return b;
  }
  // An interleaved layer of the frame as planes (written as it is, made planar by to_planar).
  Pooled planar(const Image& im) {
    const std::size_t n = im.size();
    Pooled il(sizeof(float) * n), out(sizeof(float) * n);
    q_.enqueueWriteBuffer(*il, CL_FALSE, 0, sizeof(float) * n, im.data());  // the frame outlives the pipeline's finish
    cl::Kernel& k = kernel("to_planar");
    run1(k, im.pixel_count(), int(im.pixel_count()), im.channels(), *il, *out);
    return out;
  }
  // Box b of planar `full` (ch planes of the frame), and its paste back into a frame of zeros.
  Pooled crop(const Pooled& full, int ch, const PixelBox& b) {
    Pooled out(sizeof(float) * std::size_t(b.w) * b.h * ch);
    q_.enqueueCopyBufferRect(*full, *out, {sizeof(float) * std::size_t(b.x), std::size_t(b.y), 0}, {0, 0, 0},
                             {sizeof(float) * std::size_t(b.w), std::size_t(b.h), std::size_t(ch)}, sizeof(float) * W_,
                             sizeof(float) * N_, sizeof(float) * b.w, sizeof(float) * std::size_t(b.w) * b.h);
    return out;
  }
  Pooled paste(const Pooled& part, int ch, const PixelBox& b) {
    Pooled out = zeros(sizeof(float) * N_ * ch);
    q_.enqueueCopyBufferRect(*part, *out, {0, 0, 0}, {sizeof(float) * std::size_t(b.x), std::size_t(b.y), 0},
                             {sizeof(float) * std::size_t(b.w), std::size_t(b.h), std::size_t(ch)}, sizeof(float) * b.w,
                             sizeof(float) * std::size_t(b.w) * b.h, sizeof(float) * W_, sizeof(float) * N_);
    return out;
  }

  // ---- the frame's layers, once
  void upload_level(int k, Level& l) {
    l.d = planar(f_.layer(layer::at_level(k, layer::kDirect)));
    l.i = planar(f_.layer(layer::at_level(k, layer::kIndirect)));
    l.t = planar(f_.layer(layer::at_level(k, layer::kAlbedo)));
    l.r = planar(f_.layer(layer::at_level(k, layer::kReflection)));
    l.e = planar(f_.layer(layer::at_level(k, layer::kEmission)));
    l.n = planar(f_.layer(layer::at_level(k, layer::kNormal)));
    l.z = planar(f_.layer(layer::at_level(k, layer::kDepth)));
    if (k > 0) l.tint = planar(f_.layer(layer::at_level(k, layer::kTint)));
  }
  // Level 0's edge sub-pixels: each query's pixel and the sub-pixel's values, in query order.
  void upload_edges() {
    const EdgeSubpixels& g = *f_.edges;
    constexpr int S = EdgeSubpixels::kPerPixel;
    nq_ = g.size() * S;
    std::vector<int> xy(2 * nq_), runs(g.size() + 1), pixels(g.pixels.begin(), g.pixels.end());
    std::vector<float> d(3 * nq_), i(3 * nq_), a(3 * nq_), n(3 * nq_), z(nq_);
    for (std::size_t e = 0; e < g.size(); ++e) {
      runs[e] = int(e * S);
      for (int s = 0; s < S; ++s) {
        const std::size_t q = e * S + std::size_t(s);
        const EdgeSample& x = g.of(e)[s];
        xy[2 * q] = g.pixels[e] % W_, xy[2 * q + 1] = g.pixels[e] / W_;
        for (int c = 0; c < 3; ++c) d[3 * q + c] = x.direct[c], i[3 * q + c] = x.indirect[c], a[3 * q + c] = x.albedo[c],
                                    n[3 * q + c] = x.normal[c];
        z[q] = x.depth;
      }
    }
    runs[g.size()] = int(nq_);
    runs_ = std::move(runs);
    qxy_ = upload(std::move(xy));
    edge_pixels_ = upload(std::move(pixels));
    sub_direct_ = upload(std::move(d));
    sub_indirect_ = upload(std::move(i));
    sub_albedo_ = upload(std::move(a));
    sub_normal_ = upload(std::move(n));
    sub_depth_ = upload(std::move(z));
  }

  // ---- filter_layer: fireflies, NLM space, guide, edge queries, the adaptive-manifold core, in
  // two stages (nlm_statistics up to the patch covariance, read back; filter the rest), so that
  // every layer's covariance is read in one wait.
  struct LayerJob {
    // What is filtered: `src` (3 planes of w x h) of a level, guided by its NLM vectors, `normal`
    // and `zn` (normalised depth); `host` is the same layer on the host (the NLM sample's seed).
    // With `sub` (level 0), also the edge sub-pixels' queries with those values.
    const Pooled* src = nullptr;
    Pooled owned_src;  // a crop or a sum made for the job
    ConstImageView host;
    int w = 0, h = 0;
    const Pooled *normal = nullptr, *zn = nullptr;
    float sigma_nlm = 0;
    AmSettings am;
    const Pooled* sub = nullptr;
    float depth_scale = 1.0f;
    // Where the result goes: *image (a frame's planes: pasted at `box` when it is not the whole
    // frame) and *answers (the queries'), when sub is set.
    Pooled* image = nullptr;
    Pooled* answers = nullptr;
    PixelBox box;
    // The first stage's buffers and host copies.
    Pooled kept_buf, bound, m, y, cov, mean;
    const Pooled* kept = nullptr;
    std::uint64_t seed = 0;
    std::vector<double> cov_host, mean_host;
    std::vector<float> cov_f, mean_f;
  };

  // Fireflies, the NLM scale and compressed luminance, the sample's weighted patches and their
  // covariance, whose read-back is enqueued (not waited for).
  void nlm_statistics(LayerJob& j) {
    const int w = j.w, h = j.h;
    const std::size_t n = std::size_t(w) * h;
    const int R = p_.nlm.radius, side = 2 * R + 1, P = side * side;
    const int reflect = (w > R && h > R) ? 1 : 0;
    const std::size_t real = fp64_ ? sizeof(double) : sizeof(float);
    j.kept = j.src;
    if (p_.firefly_ratio > 0) {
      j.kept_buf = Pooled(sizeof(float) * n * 3);
      j.bound = Pooled(sizeof(float) * n);
      run2(kernel("pp_fireflies"), w, h, 1, w, h, p_.firefly_ratio, **j.src, *j.kept_buf, *j.bound, *cut_);
      j.kept = &j.kept_buf;
    }
    Pooled rows(real * std::size_t(h));
    j.m = Pooled(sizeof(float)), j.y = Pooled(sizeof(float) * n);
    run1(kernel("pp_sum_rows"), std::size_t(h), w, h, 3, 0, **j.kept, *rows);
    run1(kernel("pp_sum_finish"), 1, h, int(n), 0, *rows, *j.m);
    run1(kernel("pp_compress"), n, int(n), **j.kept, *j.m, *j.y);
    // The NLM sample's seed: a hash of the layer before its firefly cut (the host's copy), or with
    // DENOISEBENCH_OPENCL_CPU_SEEDS of the cut layer read back, as the CPU path hashes it.
    j.seed = nlm_sample_seed(cpu_seeds_ ? host_copy(**j.kept, w, h, 3).cview() : j.host);
    std::vector<int> picks = nlm_sample_pixels(j.seed, w, h, p_.nlm.samples);
    const int count = int(picks.size());
    Pooled pk = upload(std::move(picks)), wt = upload(nlm_patch_weights(p_.nlm));
    Pooled patches(real * std::size_t(count) * P);
    j.mean = Pooled(real * P), j.cov = Pooled(real * P * P);
    run2(kernel("pp_patches"), count, P, 1, count, w, h, R, reflect, *pk, *j.y, *wt, *patches);
    run1(kernel("pp_patch_mean"), std::size_t(P), count, P, *patches, *j.mean);
    run2(kernel("pp_patch_cov"), P, P, 1, count, P, *patches, *j.mean, *j.cov);
    if (fp64_) {
      j.mean_host.resize(std::size_t(P)), j.cov_host.resize(std::size_t(P) * P);
      q_.enqueueReadBuffer(*j.mean, CL_FALSE, 0, real * P, j.mean_host.data());
      q_.enqueueReadBuffer(*j.cov, CL_FALSE, 0, real * P * P, j.cov_host.data());
    } else {
      j.mean_f.resize(std::size_t(P)), j.cov_f.resize(std::size_t(P) * P);
      q_.enqueueReadBuffer(*j.mean, CL_FALSE, 0, real * P, j.mean_f.data());
      q_.enqueueReadBuffer(*j.cov, CL_FALSE, 0, real * P * P, j.cov_f.data());
    }
  }

  // After the covariances are read: the basis (host), the NLM vectors, the guide, the edge
  // queries and the adaptive-manifold core, into the job's targets.
  void filter(LayerJob& j) {
    const int w = j.w, h = j.h;
    const std::size_t n = std::size_t(w) * h;
    const int R = p_.nlm.radius, side = 2 * R + 1, P = side * side;
    const int reflect = (w > R && h > R) ? 1 : 0;
    cv::Mat covar(P, P, CV_64F), mu(1, P, CV_64F);
    for (int k = 0; k < P * P; ++k) covar.ptr<double>()[k] = fp64_ ? j.cov_host[std::size_t(k)] : j.cov_f[std::size_t(k)];
    for (int k = 0; k < P; ++k) mu.ptr<double>()[k] = fp64_ ? j.mean_host[std::size_t(k)] : j.mean_f[std::size_t(k)];
    const NlmBasis basis = nlm_basis_from_covariance(covar, mu, nlm_patch_weights(p_.nlm), dims_);
    std::vector<float> offsets(basis.offsets.begin(), basis.offsets.end());
    Pooled kern = upload(basis.kernels), offs = upload(std::move(offsets)), center = upload(basis.center);
    Pooled nlm(sizeof(float) * n * dims_);
    Pooled padded(sizeof(float) * (std::size_t(w + 2 * R) * (h + 2 * R) + 8));
    run2(kernel("pp_pad"), w + 2 * R, h + 2 * R, 1, w, h, R, reflect, *j.y, *padded);
    run2(kernel("pp_project8"), (w + 7) / 8, h, 1, w, h, R, *padded, *kern, *offs, *nlm);
    // The guide: each group times sigma_r / its sigma (make_guide).
    const float sr = float(j.am.sigma_r);
    Pooled guide(sizeof(float) * n * D_);
    run1(kernel("pp_guide"), n, int(n), dims_, *nlm, sr / j.sigma_nlm, **j.normal, sr / p_.sigma_normal, **j.zn,
         sr / p_.sigma_depth, *guide);
    // The edge sub-pixels' queries.
    am_cl::DeviceQueries dq;
    Pooled qguide, qsrc;
    if (j.sub) {
      qguide = Pooled(sizeof(float) * nq_ * D_);
      qsrc = Pooled(sizeof(float) * nq_ * 3);
      run1(kernel("pp_edge_guides"), nq_, int(nq_), w, h, dims_, *qxy_, **j.sub, p_.firefly_ratio > 0 ? 1 : 0,
           p_.firefly_ratio > 0 ? *j.bound : **j.src, **j.kept, *j.m, *nlm, *center, sr / j.sigma_nlm, *sub_normal_,
           sr / p_.sigma_normal, *sub_depth_, j.depth_scale, sr / p_.sigma_depth, *qguide, *qsrc);
      dq.count = nq_;
      dq.xy = *qxy_, dq.guide = *qguide, dq.src = *qsrc;
      dq.runs = runs_;
      *j.answers = Pooled(sizeof(float) * nq_ * 3);
    }
    // The split vectors' seed: the NLM sample's, mixed; with DENOISEBENCH_OPENCL_CPU_SEEDS the CPU
    // path's (a hash of the guide, read back).
    const std::uint64_t am_seed = cpu_seeds_ ? am_detail::guide_seed(host_copy(*guide, w, h, D_).cview())
                                             : j.seed ^ 0x5851F42D4C957F2Dull;
    Pooled out(sizeof(float) * n * 3);
    am_cl::am_filter_planar(**j.kept, *guide, w, h, 3, D_, am_seed, j.am, j.sub ? &dq : nullptr, *out,
                            j.sub ? &**j.answers : nullptr);
    const bool whole = j.box.x == 0 && j.box.y == 0 && j.box.w == W_ && j.box.h == H_;
    *j.image = whole ? std::move(out) : paste(out, 3, j.box);
  }

  // Planes read back into an interleaved host image (DENOISEBENCH_OPENCL_CPU_SEEDS only).
  Image host_copy(const cl::Buffer& planes, int w, int h, int ch) {
    const std::size_t n = std::size_t(w) * h;
    std::vector<float> p(n * ch);
    q_.enqueueReadBuffer(planes, CL_TRUE, 0, sizeof(float) * p.size(), p.data());
    Image im(w, h, ch);
    for (std::size_t i = 0; i < n; ++i)
      for (int c = 0; c < ch; ++c) im.data()[i * ch + c] = p[std::size_t(c) * n + i];
    return im;
  }

  Pooled normalized(const Pooled& z, int w, int h, float median) {
    const std::size_t n = std::size_t(w) * h;
    Pooled out(sizeof(float) * n);
    run1(kernel("pp_normalize_depth"), n, int(n), *z, median, *out);
    return out;
  }

  // Level 0: the whole frame, its D and I with the edge sub-pixels' queries.
  void plan_level0(Level& l, std::deque<LayerJob>& jobs) {
    l.box = {0, 0, W_, H_};
    const Image& z = f_.layer(layer::kDepth);
    l.median = median_depth(z, l.box);
    l.zn = normalized(l.z, W_, H_, l.median);
    // edge_queries' depth scale: normalised over raw depth at the first pixel with both positive.
    float depth_scale = 1.0f;
    for (std::size_t k = 0; k < z.size(); ++k) {
      const float v = z.data()[k];
      if (std::isfinite(v) && v > 0 && v / l.median > 0) {
        depth_scale = (v / l.median) / v;
        break;
      }
    }
    for (int layer_i = 0; layer_i < 2; ++layer_i) {
      LayerJob& j = jobs.emplace_back();
      j.src = layer_i == 0 ? &l.d : &l.i;
      j.host = f_.layer(layer_i == 0 ? layer::kDirect : layer::kIndirect).cview();
      j.w = W_, j.h = H_, j.normal = &l.n, j.zn = &l.zn;
      j.sigma_nlm = layer_i == 0 ? p_.sigma_direct : p_.sigma_nlm;
      j.am = p_.am;
      j.sub = p_.edges ? (layer_i == 0 ? &sub_direct_ : &sub_indirect_) : nullptr;
      j.depth_scale = depth_scale;
      j.image = layer_i == 0 ? &l.fd : &l.fi;
      j.answers = layer_i == 0 ? &qd_ : &qi_;
      j.box = l.box;
    }
  }

  // Reflection level k: its box (its tint's non-zero pixels grown by 6 sigma_s), filtered there.
  void plan_reflection_level(int k, Level& l, std::deque<LayerJob>& jobs) {
    l.box = nonzero_box(f_.layer(layer::at_level(k, layer::kTint)), int(std::ceil(6.0 * p_.am.sigma_s)));
    stats_.counters["level" + std::to_string(k) + "_filtered_fraction"] = double(l.box.w) * l.box.h / double(N_);
    if (l.box.empty()) {
      l.fd = zeros(sizeof(float) * N_ * 3);
      l.fi = zeros(sizeof(float) * N_ * 3);
      return;
    }
    const PixelBox& b = l.box;
    l.median = median_depth(f_.layer(layer::at_level(k, layer::kDepth)), b);
    l.zb = crop(l.z, 1, b), l.nb = crop(l.n, 3, b);
    l.zn = normalized(l.zb, b.w, b.h, l.median);
    const Image& d = f_.layer(layer::at_level(k, layer::kDirect));
    const Image& i = f_.layer(layer::at_level(k, layer::kIndirect));
    auto job = [&](Pooled src, ConstImageView host, Pooled* image) {
      LayerJob& j = jobs.emplace_back();
      j.owned_src = std::move(src);
      j.src = &j.owned_src;
      j.host = host;
      j.w = b.w, j.h = b.h, j.normal = &l.nb, j.zn = &l.zn;
      j.sigma_nlm = p_.sigma_nlm;
      j.am = p_.reflection_am;
      j.image = image;
      j.box = b;
    };
    if (p_.reflection_sum) {
      const Pooled db = crop(l.d, 3, b), ib = crop(l.i, 3, b);
      Pooled sum(sizeof(float) * std::size_t(b.w) * b.h * 3);
      run1(kernel("pp_add"), std::size_t(b.w) * b.h * 3, int(std::size_t(b.w) * b.h * 3), *db, *ib, *sum);
      // The CPU path hashes the crop of D + I; the host has D and I: their crop of D stands in.
      job(std::move(sum), d.cview().crop(b.x, b.y, b.w, b.h), &l.fd);
      l.fi = zeros(sizeof(float) * N_ * 3);
      return;
    }
    job(crop(l.d, 3, b), d.cview().crop(b.x, b.y, b.w, b.h), &l.fd);
    job(crop(l.i, 3, b), i.cview().crop(b.x, b.y, b.w, b.h), &l.fi);
  }

  // Level k's surface tint (layer k + 1's) smoothed on level k's box with its normal and depth.
  void smooth_tint_of(int k, std::vector<Level>& lv) {
    Level& l = lv[std::size_t(k)];
    const Level& next = lv[std::size_t(k) + 1];
    if (l.box.empty()) return;  // level k shows nowhere: neither does k + 1 (its tint is zero)
    const PixelBox& b = l.box;
    const bool whole = b.w == W_ && b.h == H_;
    const std::size_t n = std::size_t(b.w) * b.h;
    Pooled tb = whole ? Pooled() : crop(next.tint, 3, b);
    const Pooled& tint = whole ? next.tint : tb;
    const Pooled& normal = whole ? l.n : l.nb;
    // The edge pixels keep their own tint (proposed.cpp's edge mask), when the frame has them.
    const bool keep = f_.edges && !f_.edges->pixels.empty();
    Pooled mask;
    if (keep) {
      std::vector<cl_uchar> m(n, 0);
      for (int px : f_.edges->pixels) {
        const int x = px % W_ - b.x, y = px / W_ - b.y;
        if (x >= 0 && y >= 0 && x < b.w && y < b.h) m[std::size_t(y) * b.w + std::size_t(x)] = 1;
      }
      mask = upload(std::move(m));
    }
    Pooled first(sizeof(float) * n * 3), centre(sizeof(float) * n), out(sizeof(float) * n * 3);
    const float n2 = p_.tint_normal_distance * p_.tint_normal_distance;
    cl::Kernel& k2 = kernel("pp_tint_pass");
    const cl::Buffer& m_or = keep ? *mask : *tint;
    // Pass 1 from the raw tints' sums (centre and prev unread), pass 2 around pass 1's (next unwritten).
    run2(k2, b.w, b.h, 1, b.w, b.h, p_.tint_radius, p_.tint_band, n2, p_.tint_depth_distance, *tint, *normal, *l.zn,
         keep ? 1 : 0, m_or, 1, *tint, *tint, *first, 1, *centre);
    run2(k2, b.w, b.h, 1, b.w, b.h, p_.tint_radius, p_.tint_band, n2, p_.tint_depth_distance, *tint, *normal, *l.zn,
         keep ? 1 : 0, m_or, 0, *centre, *first, *out, 0, *centre);
    if (whole) {
      l.smoothed = std::move(out);
      return;
    }
    // Outside the box the raw tint (zero there), inside the smoothed one.
    Pooled full(sizeof(float) * N_ * 3);
    q_.enqueueCopyBuffer(*next.tint, *full, 0, 0, sizeof(float) * N_ * 3);
    q_.enqueueCopyBufferRect(*out, *full, {0, 0, 0}, {sizeof(float) * std::size_t(b.x), std::size_t(b.y), 0},
                             {sizeof(float) * std::size_t(b.w), std::size_t(b.h), 3}, sizeof(float) * b.w,
                             sizeof(float) * n, sizeof(float) * W_, sizeof(float) * N_);
    l.smoothed = std::move(full);
  }

  // ---- composition (proposed.cpp's compose_levels) and the detail guard
  Pooled compose_level(int k, const std::vector<Level>& lv, const Pooled& below) {
    const Level& l = lv[std::size_t(k)];
    const bool has_below = k < p_.levels;
    const Level* nx = has_below ? &lv[std::size_t(k) + 1] : nullptr;
    const cl::Buffer& raw = has_below ? *nx->tint : *l.r;
    const cl::Buffer& tint = has_below && !l.smoothed.empty() ? *l.smoothed : raw;
    const cl::Buffer& comp = has_below ? *below : *l.r;
    const cl::Buffer& d1 = has_below ? *nx->d : *l.r;
    const cl::Buffer& i1 = has_below ? *nx->i : *l.r;
    const cl::Buffer& t1 = has_below ? *nx->t : *l.r;
    const cl::Buffer& r1 = has_below ? *nx->r : *l.r;
    const cl::Buffer& e1 = has_below ? *nx->e : *l.r;
    Pooled out(sizeof(float) * N_ * 3);
    run1(kernel("pp_compose"), N_ * 3, int(N_ * 3), *l.fd, *l.fi, *l.t, *l.e, *l.r, has_below ? 1 : 0, tint, raw, comp,
         d1, i1, t1, r1, e1, *out);
    if (k == 0 && p_.edges) {
      const int npx = int(f_.edges->size());
      run1(kernel("pp_compose_edges"), std::size_t(npx), npx, int(N_), EdgeSubpixels::kPerPixel, *edge_pixels_, *qd_,
           *qi_, *sub_albedo_, *l.e, *l.r, has_below ? 1 : 0, tint, raw, comp, d1, i1, t1, r1, e1, *out);
      stats_.counters["edge_pixels"] = double(npx);
    }
    return out;
  }

  void guard(Pooled& out) {
    stats_.counters["detail_guard_used"] = 0;
    if (p_.detail_guard <= 0 || !f_.has(layer::kVariance) || !f_.has(layer::kColor)) return;
    const Image& x = f_.layer(layer::kColor);
    const Image& v = f_.layer(layer::kVariance);
    if (x.channels() != 3 || v.channels() != 3) return;
    const std::size_t n = N_ * 3;
    const std::size_t real = fp64_ ? sizeof(double) : sizeof(float);
    Pooled xb = planar(x), vb = planar(v);
    Pooled rows(real * std::size_t(H_)), e(sizeof(float)), work(sizeof(float) * n), med(sizeof(float) * n),
        sd(sizeof(float) * n), clamped = zeros(sizeof(cl_int));
    run1(kernel("pp_sum_rows"), std::size_t(H_), W_, H_, 3, 1, *out, *rows);
    run1(kernel("pp_sum_finish"), 1, H_, int(n), 1, *rows, *e);
    run1(kernel("pp_guard_rel"), n, int(n), *out, *vb, *e, *work);
    run2(kernel("pp_median5"), W_, H_, 3, W_, H_, *work, *med);
    run1(kernel("pp_guard_sd"), n, int(n), *out, *vb, *xb, *med, *e, *sd, *work);
    run2(kernel("pp_median5"), W_, H_, 3, W_, H_, *work, *med);
    run1(kernel("pp_guard_clamp"), n, int(n), p_.detail_guard, *xb, *sd, *med, *out, *clamped);
    cl_int c = 0;
    q_.enqueueReadBuffer(*clamped, CL_TRUE, 0, sizeof(cl_int), &c);
    stats_.counters["detail_guard_used"] = 1;
    stats_.counters["detail_guard_clamped_samples"] = double(c);
  }

  const AovFrame& f_;
  const ProposedDevicePlan& p_;
  MethodStats& stats_;
  cl::CommandQueue& q_;
  const int W_, H_;
  const std::size_t N_;
  const int dims_, D_;
  const bool fp64_;
  // DENOISEBENCH_OPENCL_CPU_SEEDS=1: the CPU path's seeds (two read-backs per layer), so that a test
  // can hold the two paths to rounding where no split is decided by it (docs/opencl-gpu.md).
  const bool cpu_seeds_ = [] {
    const char* e = env::get("OPENCL_CPU_SEEDS");
    return e && *e && std::string(e) != "0";
  }();
  cl::Program prog_;
  std::map<std::string, cl::Kernel> kernels_;
  std::vector<std::shared_ptr<void>> kept_;
  std::deque<std::pair<std::string, cl::Event>> events_;  // DENOISEBENCH_OPENCL_PROFILE only (stable addresses)
  Pooled cut_;
  // Level 0's edge sub-pixels (queries in edge-pixel order, kPerPixel each) and their answers.
  std::size_t nq_ = 0;
  std::vector<int> runs_;
  Pooled qxy_, edge_pixels_, sub_direct_, sub_indirect_, sub_albedo_, sub_normal_, sub_depth_, qd_, qi_;
};

}  // namespace

Image proposed_opencl(const AovFrame& frame, const ProposedDevicePlan& plan, MethodStats& stats) {
  try {
    Pipeline p(frame, plan, stats);
    Image out = p.run();
    am_cl::queue().finish();  // every write from the frame's memory done
    return out;
  } catch (const cl::Error& e) {
    try {
      am_cl::queue().finish();
    } catch (...) {
    }
    throw WorkError(std::string("OpenCL error in proposed's device pipeline: ") + e.what() + " (" + std::to_string(e.err()) + ")");
  }
}

}  // namespace dnb
#endif
