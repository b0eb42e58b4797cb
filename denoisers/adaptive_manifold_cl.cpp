#include "denoisers/adaptive_manifold_cl.h"

#include "core/errors.h"

#ifdef DNB_WITH_OPENCL
#define CL_HPP_ENABLE_EXCEPTIONS
#include <CL/opencl.hpp>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <map>
#include <mutex>

#include "denoisers/adaptive_manifold_cl_source.h"
#include "denoisers/am_grid.h"
#endif

namespace dnb {

#ifndef DNB_WITH_OPENCL

bool am_opencl_available(std::string* why) {
  if (why) *why = "this build has no OpenCL (configure with -DDNB_WITH_OPENCL=ON)";
  return false;
}
Image am_filter_opencl(ConstImageView, ConstImageView, const AmSettings&, const std::vector<AmQuery>&, std::vector<float>*) {
  throw WorkError("device=opencl: this build has no OpenCL (configure with -DDNB_WITH_OPENCL=ON)");
}

#else

namespace {

// One context, queue and program cache per process: PoCL compiles a program in about 0.8 s.
struct ClState {
  cl::Context context;
  cl::Device device;
  cl::CommandQueue queue;
  std::map<std::pair<int, int>, cl::Program> programs;
  std::mutex mutex;
  std::string error;
  bool ok = false;

  ClState() {
    try {
      std::vector<cl::Platform> platforms;
      cl::Platform::get(&platforms);
      if (platforms.empty()) throw std::runtime_error("no OpenCL platform");
      std::size_t pick = 0;
      if (const char* p = std::getenv("DNB_OPENCL_PLATFORM")) pick = std::size_t(std::atoi(p));
      if (pick >= platforms.size()) throw std::runtime_error("DNB_OPENCL_PLATFORM out of range");
      std::vector<cl::Device> devices;
      platforms[pick].getDevices(CL_DEVICE_TYPE_ALL, &devices);
      if (devices.empty()) throw std::runtime_error("no OpenCL device on the platform");
      device = devices[0];
      context = cl::Context(device);
      queue = cl::CommandQueue(context, device);
      ok = true;
    } catch (const std::exception& e) {
      error = e.what();
    }
  }

  cl::Program program(int dims, int chans) {
    std::lock_guard<std::mutex> lock(mutex);
    auto it = programs.find({dims, chans});
    if (it != programs.end()) return it->second;
    cl::Program p(context, kAdaptiveManifoldClSource);
    const std::string options = "-cl-std=CL1.2 -DDIMS=" + std::to_string(dims) + " -DCHANS=" + std::to_string(chans);
    try {
      p.build({device}, options.c_str());
    } catch (const cl::BuildError& e) {
      std::string log;
      for (auto& [dev, l] : e.getBuildLog()) log += l;
      throw WorkError("OpenCL build of denoisers/adaptive_manifold.cl failed: " + log);
    }
    programs.emplace(std::pair{dims, chans}, p);
    return p;
  }
};

ClState& state() {
  static ClState s;
  return s;
}

template <typename T>
cl::Buffer buffer(cl::Context& ctx, const std::vector<T>& v) {
  return cl::Buffer(ctx, CL_MEM_READ_WRITE | CL_MEM_COPY_HOST_PTR, sizeof(T) * std::max<std::size_t>(v.size(), 1),
                    const_cast<T*>(v.data()));
}

class ClRun : private am_detail::AmRunShape {
 public:
  ClRun(ConstImageView src, ConstImageView guide, const AmSettings& s, const std::vector<AmQuery>& queries)
      : AmRunShape(src, guide, s, queries), st_(state()) {
    prog_ = st_.program(D_, C_);
    auto& ctx = st_.context;
    const std::size_t N = std::size_t(W_) * H_;
    std::vector<float> g(N * D_), f(N * C_);
    for (int y = 0; y < H_; ++y)
      for (int x = 0; x < W_; ++x) {
        const std::size_t i = std::size_t(y) * W_ + x;
        for (int c = 0; c < D_; ++c) g[c * N + i] = guide.pixel(x, y)[c];
        for (int c = 0; c < C_; ++c) f[c * N + i] = src.pixel(x, y)[c];
      }
    guide_ = buffer(ctx, g);
    src_ = buffer(ctx, f);
    acc_ = buffer(ctx, std::vector<float>(N * (C_ + 1), 0.0f));
    w_ = buffer(ctx, std::vector<float>(N, 0.0f));
    min_d2_ = buffer(ctx, std::vector<float>(s.adjust_outliers ? N : 1, INFINITY));
    label_ = buffer(ctx, std::vector<cl_ushort>(N, 1));
    // The CPU path's bilinear tables.
    std::vector<int> x0, x1, y0, y1;
    std::vector<float> fx, fy;
    am_detail::bilinear_table(W_, sw_, df_, x0, x1, fx);
    am_detail::bilinear_table(H_, sh_, df_, y0, y1, fy);
    tx0_ = buffer(ctx, x0), tx1_ = buffer(ctx, x1), tfx_ = buffer(ctx, fx);
    ty0_ = buffer(ctx, y0), ty1_ = buffer(ctx, y1), tfy_ = buffer(ctx, fy);
    // The splat kernel's work-items cover 8 full-resolution columns each (adaptive_manifold.cl).
    nwx_ = (W_ + 7) / 8;
    colsum_ = cl::Buffer(ctx, CL_MEM_READ_WRITE, sizeof(float) * std::size_t(std::max(C_ + 1, 2 * (D_ + 1))) * sh_ * W_);
    cov_ = cl::Buffer(ctx, CL_MEM_READ_WRITE, sizeof(float) * std::size_t(nwx_) * sh_ * D_ * D_);
    cov_rows_ = cl::Buffer(ctx, CL_MEM_READ_WRITE, sizeof(float) * std::size_t(sh_) * D_ * D_);
    const int hstride = std::max(sw_ - 1, 1);
    ah_ = cl::Buffer(ctx, CL_MEM_READ_WRITE, sizeof(float) * std::size_t(sh_) * hstride);
    av_ = cl::Buffer(ctx, CL_MEM_READ_WRITE, sizeof(float) * std::size_t(std::max(sh_ - 1, 1)) * sw_);
    if (!queries_.empty()) {
      std::vector<int> xy(2 * queries_.size());
      std::vector<float> qg(queries_.size() * D_);
      for (std::size_t q = 0; q < queries_.size(); ++q) {
        if (queries_[q].x < 0 || queries_[q].x >= W_ || queries_[q].y < 0 || queries_[q].y >= H_)
          throw WorkError("am_filter_opencl: a slice query lies outside the image");
        xy[2 * q] = queries_[q].x, xy[2 * q + 1] = queries_[q].y;
        for (int c = 0; c < D_; ++c) qg[q * D_ + c] = queries_[q].guide[c];
      }
      qxy_ = buffer(ctx, xy);
      qguide_ = buffer(ctx, qg);
      qacc_ = buffer(ctx, std::vector<float>(queries_.size() * (C_ + 1), 0.0f));
      qmin_ = buffer(ctx, std::vector<float>(queries_.size(), INFINITY));
    }
  }

  Image run(std::vector<float>* query_out) {
    auto& ctx = st_.context;
    auto& q = st_.queue;
    const std::size_t N = std::size_t(W_) * H_;
    // The first manifold: the guide low-passed at full resolution.
    cl::Buffer eta_full(ctx, CL_MEM_READ_WRITE, sizeof(float) * N * D_);
    q.enqueueCopyBuffer(guide_, eta_full, 0, 0, sizeof(float) * N * D_);
    low_pass(eta_full, W_, H_, D_, s_.sigma_s);
    node(1, 1, eta_full, true);

    cl::Buffer out(ctx, CL_MEM_WRITE_ONLY, sizeof(float) * N * C_);
    cl::Kernel k(prog_, "finish");
    set(k, W_, H_, acc_, src_, min_d2_, int(s_.adjust_outliers), float(-0.5 * s_.outlier_scale / (s_.sigma_r * s_.sigma_r)), out);
    launch(k, W_, H_);
    Image img(W_, H_, C_);
    q.enqueueReadBuffer(out, CL_TRUE, 0, sizeof(float) * N * C_, img.data());
    if (query_out && !queries_.empty()) {
      std::vector<float> acc(queries_.size() * (C_ + 1)), mn(queries_.size());
      q.enqueueReadBuffer(qacc_, CL_TRUE, 0, sizeof(float) * acc.size(), acc.data());
      q.enqueueReadBuffer(qmin_, CL_TRUE, 0, sizeof(float) * mn.size(), mn.data());
      const float alpha_k = float(-0.5 * s_.outlier_scale / (s_.sigma_r * s_.sigma_r));
      query_out->assign(queries_.size() * C_, 0.0f);
      for (std::size_t i = 0; i < queries_.size(); ++i) {
        const float den = acc[i * (C_ + 1) + C_];
        const float alpha = queries_[i].adjust_outliers ? std::exp(alpha_k * mn[i]) : 1.0f;
        for (int c = 0; c < C_; ++c) {
          const float f = queries_[i].src ? queries_[i].src[c] : src_value(queries_[i].x, queries_[i].y, c);
          const float g = den > kAmMinWeight ? acc[i * (C_ + 1) + c] / den : f;
          (*query_out)[i * C_ + c] = f + alpha * (g - f);
        }
      }
    } else if (query_out) {
      query_out->clear();
    }
    return img;
  }

 private:
  template <typename... A>
  static void set(cl::Kernel& k, A&&... args) {
    cl_uint i = 0;
    (k.setArg(i++, std::forward<A>(args)), ...);
  }

  // Enqueues `k` over gx x gy work-items in work-groups of kGroup x 1, the global size rounded up
  // (every kernel returns early past its image). Without a local size PoCL's CPU driver may
  // choose work-groups of one item, which it cannot vectorise across.
  void launch(cl::Kernel& k, std::size_t gx, std::size_t gy = 1) {
    const std::size_t lx = std::min<std::size_t>(kGroup, gx);
    st_.queue.enqueueNDRangeKernel(k, cl::NullRange, cl::NDRange((gx + lx - 1) / lx * lx, gy), cl::NDRange(lx, 1));
  }
  static constexpr std::size_t kGroup = 32;

  float src_value(int x, int y, int c) {
    float v = 0;
    const std::size_t N = std::size_t(W_) * H_;
    st_.queue.enqueueReadBuffer(src_, CL_TRUE, sizeof(float) * (c * N + std::size_t(y) * W_ + x), sizeof(float), &v);
    return v;
  }

  // The recursive filter with a constant feedback (their h_filter) on `n` planes of w x h.
  void low_pass(cl::Buffer& p, int w, int h, int n, double sigma) {
    const float a = float(std::exp(-std::sqrt(2.0) / sigma));
    recursive(p, w, h, n, a);
  }
  void recursive(cl::Buffer& p, int w, int h, int n, float constant) {
    cl::Kernel rows(prog_, "rf_rows"), cols(prog_, "rf_cols");
    set(rows, w, h, p, ah_, std::max(w - 1, 1), constant);
    set(cols, w, h, p, av_, constant);
    launch(rows, (std::size_t(h) + 7) / 8, n);  // 8 rows per work-item
    launch(cols, (std::size_t(w) + 7) / 8, n);  // 8 columns per work-item
  }

  void node(int id, int level, cl::Buffer eta, bool eta_full) {
    auto& ctx = st_.context;
    auto& q = st_.queue;
    const bool split = level < height_;
    const std::size_t n = std::size_t(sw_) * sh_;
    cl::Buffer splat(ctx, CL_MEM_READ_WRITE, sizeof(float) * n * (C_ + 1));
    {
      cl::Kernel k(prog_, "splat");
      set(k, W_, H_, sw_, sh_, df_, guide_, src_, eta, int(eta_full), tx0_, tx1_, tfx_, ty0_, ty1_, tfy_, inv_sr2_, w_,
          min_d2_, int(s_.adjust_outliers), colsum_, int(split), id, label_, cov_);
      launch(k, std::size_t(nwx_), sh_);
      cl::Kernel b(prog_, "splat_blocks");
      set(b, W_, H_, sw_, sh_, df_, colsum_, splat);
      launch(b, sw_, sh_);
    }
    std::vector<float> v(D_, 0.0f);
    if (split) {
      cl::Kernel k(prog_, "cov_rows");
      set(k, nwx_, sh_, cov_, cov_rows_);
      launch(k, sh_);
      std::vector<float> rows(std::size_t(sh_) * D_ * D_);
      q.enqueueReadBuffer(cov_rows_, CL_TRUE, 0, sizeof(float) * rows.size(), rows.data());
      std::vector<double> cov(D_ * D_, 0.0);
      for (int sy = 0; sy < sh_; ++sy)
        for (int k2 = 0; k2 < D_ * D_; ++k2) cov[k2] += rows[std::size_t(sy) * D_ * D_ + k2];
      for (int i = 0; i < D_; ++i)
        for (int j = 0; j < i; ++j) cov[i * D_ + j] = cov[j * D_ + i];
      v = am_detail::split_direction(cov, D_, seed_, id, s_.pca_iterations);
    }
    cl::Buffer small = eta;
    if (eta_full) {
      small = cl::Buffer(ctx, CL_MEM_READ_WRITE, sizeof(float) * n * D_);
      cl::Kernel k(prog_, "downsample");
      set(k, W_, H_, sw_, sh_, df_, eta, small);
      launch(k, sw_, sh_);
    }
    // Blur along the manifold.
    {
      const double ss = s_.sigma_s / df_, sr = s_.sigma_r / std::sqrt(2.0);
      cl::Kernel k(prog_, "dt_weights");
      set(k, sw_, sh_, std::max(sw_ - 1, 1), small, float((ss / sr) * (ss / sr)), float(-std::sqrt(2.0) / ss), ah_, av_);
      launch(k, (std::size_t(sw_) + 7) / 8, sh_);  // 8 reduced columns per work-item
      recursive(splat, sw_, sh_, C_ + 1, 0.0f);
    }
    if (!queries_.empty()) {
      cl::Kernel k(prog_, "query");
      set(k, int(queries_.size()), W_, H_, sw_, sh_, qxy_, qguide_, eta, int(eta_full), splat, tx0_, tx1_, tfx_, ty0_,
          ty1_, tfy_, inv_sr2_, qacc_, qmin_);
      launch(k, queries_.size());
    }
    {
      cl::Kernel k(prog_, "slice");
      set(k, W_, H_, sw_, sh_, splat, tx0_, tx1_, tfx_, ty0_, ty1_, tfy_, w_, acc_);
      launch(k, std::size_t(nwx_), H_);  // 8 columns per work-item
    }
    if (!split) return;
    cl::Buffer vb = buffer(ctx, v);
    cl::Buffer kids[2] = {cl::Buffer(ctx, CL_MEM_READ_WRITE, sizeof(float) * n * (D_ + 1)),
                          cl::Buffer(ctx, CL_MEM_READ_WRITE, sizeof(float) * n * (D_ + 1))};
    {
      cl::Kernel k(prog_, "split");
      set(k, W_, H_, sw_, sh_, df_, guide_, eta, int(eta_full), tx0_, tx1_, tfx_, ty0_, ty1_, tfy_, vb, w_, label_, id,
          colsum_);
      launch(k, std::size_t(nwx_), sh_);
      cl::Kernel b(prog_, "split_blocks");
      set(b, W_, H_, sw_, sh_, df_, colsum_, kids[0], kids[1]);
      launch(b, sw_, sh_);
    }
    for (int c = 0; c < 2; ++c) {
      low_pass(kids[c], sw_, sh_, D_ + 1, s_.sigma_s / df_);
      cl::Buffer child(ctx, CL_MEM_READ_WRITE, sizeof(float) * n * D_);
      cl::Kernel k(prog_, "divide_eta");
      set(k, int(n), kids[c], small, child);
      launch(k, n);
      node(2 * id + c, level + 1, child, false);
    }
  }

  ClState& st_;
  cl::Program prog_;
  cl::Buffer guide_, src_, acc_, w_, min_d2_, label_, tx0_, tx1_, tfx_, ty0_, ty1_, tfy_, cov_, cov_rows_, ah_, av_;
  cl::Buffer colsum_;  // the splat's and the split's column sums (C + 1, or 2 (D + 1), planes of sh x W)
  int nwx_ = 1;        // the splat's work-items per row
  cl::Buffer qxy_, qguide_, qacc_, qmin_;
};

}  // namespace

bool am_opencl_available(std::string* why) {
  ClState& s = state();
  if (!s.ok && why) *why = "no usable OpenCL device: " + s.error;
  return s.ok;
}

Image am_filter_opencl(ConstImageView src, ConstImageView guide, const AmSettings& settings,
                       const std::vector<AmQuery>& queries, std::vector<float>* query_out) {
  std::string why;
  if (!am_opencl_available(&why)) throw WorkError("device=opencl: " + why);
  if (guide.width != src.width || guide.height != src.height) throw WorkError("am_filter_opencl: guide and source differ in size");
  if (src.empty()) return Image(src.width, src.height, src.channels);
  try {
    ClRun run(src, guide, settings, queries);
    return run.run(query_out);
  } catch (const cl::Error& e) {
    throw WorkError(std::string("OpenCL error in the adaptive-manifold core: ") + e.what() + " (" + std::to_string(e.err()) + ")");
  }
}

#endif

}  // namespace dnb
