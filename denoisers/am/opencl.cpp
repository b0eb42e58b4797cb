#include "denoisers/am/opencl.h"
#include "core/env.h"

#include "core/errors.h"
#include "denoisers/am/capture.h"

#ifdef DNB_WITH_OPENCL
#define CL_HPP_ENABLE_EXCEPTIONS
#include <CL/opencl.hpp>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <deque>
#include <cstdio>
#include <cstdlib>
#include <map>
#include <memory>
#include <mutex>
#include <string>

#include <tbb/parallel_for.h>

#include "denoisers/am/opencl_source.h"
#include "denoisers/am/grid.h"
#include "denoisers/am/opencl_device.h"
#endif

namespace dnb {

#ifndef DNB_WITH_OPENCL

bool am_opencl_available(std::string* why) {
  if (why) *why = "this build has no OpenCL (configure with -DDNB_WITH_OPENCL=ON)";
  return false;
}
std::string am_opencl_device_name() { return {}; }
Image am_filter_opencl(ConstImageView, ConstImageView, const AmSettings&, const std::vector<AmQuery>&, std::vector<float>*) {
  throw WorkError("device=opencl: this build has no OpenCL (configure with -DDNB_WITH_OPENCL=ON)");
}

#else

namespace {

// The most manifolds of one tree level that the group kernels (splat_group, slice_split_group)
// handle in one pass over the full-resolution images. The CPU path groups 8 (am/run.h); here a
// group's sums live in each work-item's private memory (about 10 KB at 8 guide dimensions for
// 4), which a CPU device keeps in its cache and a GPU would spill beyond a few.
constexpr int kMaxGroup = 4;

// One context, queue and program cache per process: PoCL compiles a program in about 0.8 s.
struct ClState {
  cl::Context context;
  cl::Device device;
  cl::CommandQueue queue;
  std::map<std::pair<int, int>, cl::Program> programs;
  std::mutex mutex;
  std::string error;
  bool ok = false;
  bool gpu = false;  // the device is a GPU: the recursive filters one column per work-item (rf_cols1, transposes)
  bool fp64 = false;  // the device has doubles: split_dirs computes in double, as the CPU path
  // DENOISEBENCH_OPENCL_PROFILE=1: every kernel, write and read of a run timed by the device (queue
  // profiling), summed per name and printed to stderr after the run (bench/device/am_device.cpp).
  const bool profile = [] {
    const char* p = env::get("OPENCL_PROFILE");
    return p && *p && std::string(p) != "0";
  }();

  ClState() {
    try {
      std::vector<cl::Platform> platforms;
      cl::Platform::get(&platforms);
      if (platforms.empty()) throw std::runtime_error("no OpenCL platform");
      std::size_t pick = 0;
      if (const char* p = env::get("OPENCL_PLATFORM")) pick = std::size_t(std::atoi(p));
      if (pick >= platforms.size()) throw std::runtime_error("DENOISEBENCH_OPENCL_PLATFORM out of range");
      std::vector<cl::Device> devices;
      platforms[pick].getDevices(CL_DEVICE_TYPE_ALL, &devices);
      if (devices.empty()) throw std::runtime_error("no OpenCL device on the platform");
      device = devices[0];
      gpu = (device.getInfo<CL_DEVICE_TYPE>() & CL_DEVICE_TYPE_GPU) != 0;
      fp64 = device.getInfo<CL_DEVICE_EXTENSIONS>().find("cl_khr_fp64") != std::string::npos;
      context = cl::Context(device);
      queue = cl::CommandQueue(context, device, profile ? cl_command_queue_properties(CL_QUEUE_PROFILING_ENABLE) : 0);
      ok = true;
    } catch (const std::exception& e) {
      error = e.what();
    }
  }

  // Device buffers kept between runs, by size: a run at 1024x768 takes about 300 MB of them, and
  // fresh allocations cost it their page faults and zeroing by the kernel (a fifth of proposed's
  // time on PoCL). At most kPoolBytes are kept; a buffer beyond that is released.
  static constexpr std::size_t kPoolBytes = std::size_t(1) << 30;
  std::multimap<std::size_t, cl::Buffer> pool;
  std::size_t pooled_bytes = 0;
  std::mutex pool_mutex;

  cl::Buffer take(std::size_t bytes) {
    {
      std::lock_guard<std::mutex> lock(pool_mutex);
      auto it = pool.find(bytes);
      if (it != pool.end()) {
        cl::Buffer b = it->second;
        pool.erase(it);
        pooled_bytes -= bytes;
        return b;
      }
    }
    return cl::Buffer(context, CL_MEM_READ_WRITE, bytes);
  }
  // Safe while commands that use `b` are still queued: the queue is in order, so whoever takes it
  // next enqueues after them.
  void give(std::size_t bytes, const cl::Buffer& b) {
    std::lock_guard<std::mutex> lock(pool_mutex);
    if (pooled_bytes + bytes > kPoolBytes) return;
    pool.emplace(bytes, b);
    pooled_bytes += bytes;
  }

  cl::Program program(int dims, int chans) {
    std::lock_guard<std::mutex> lock(mutex);
    auto it = programs.find({dims, chans});
    if (it != programs.end()) return it->second;
    cl::Program p(context, std::string(kAdaptiveManifoldClSource) + "\n" + kProposedClSource);
    const std::string options = "-cl-std=CL1.2 -DDIMS=" + std::to_string(dims) + " -DCHANS=" + std::to_string(chans) +
                                " -DMAXG=" + std::to_string(kMaxGroup);
    try {
      p.build({device}, options.c_str());
    } catch (const cl::BuildError& e) {
      std::string log;
      for (auto& [dev, l] : e.getBuildLog()) log += l;
      throw WorkError("OpenCL build of denoisers/am/adaptive_manifold.cl failed: " + log);
    }
    programs.emplace(std::pair{dims, chans}, p);
    return p;
  }
};

ClState& state() {
  static ClState s;
  return s;
}

class ClRun : private am_detail::AmRunShape {
 public:
  // Host images: uploaded and made planar on the device.
  ClRun(ConstImageView src, ConstImageView guide, const AmSettings& s, const std::vector<AmQuery>& queries)
      : AmRunShape(src, guide, s, queries), st_(state()), nq_(queries.size()) {
    prog_ = st_.program(D_, C_);
    // The images go up interleaved, as they are, and become planes on the device (to_planar):
    // the host's planar copy took as long as the upload itself on the H200 machine.
    guide_ = planar_on_device(guide, D_, "write guide");
    src_ = planar_on_device(src, C_, "write source");
    host_mark("upload");
    prepare();
    if (nq_ > 0) {
      std::vector<int> xy(2 * nq_);
      std::vector<float> qg(nq_ * D_);
      tbb::parallel_for(std::size_t(0), nq_, [&](std::size_t q) {
        xy[2 * q] = queries_[q].x, xy[2 * q + 1] = queries_[q].y;
        for (int c = 0; c < D_; ++c) qg[q * D_ + c] = queries_[q].guide[c];
      });
      // Runs of consecutive queries at one pixel (query_group upsamples once per run).
      std::vector<int> runs{0};
      for (std::size_t q = 1; q < nq_; ++q)
        if (queries_[q].x != queries_[q - 1].x || queries_[q].y != queries_[q - 1].y) runs.push_back(int(q));
      runs.push_back(int(nq_));
      set_runs(std::move(runs));
      qxy_ = upload(xy);
      qguide_ = upload(qg);
      // Each query's source value for the outlier adjustment (its own, or the pixel's when it
      // gives none: read on the device) and whether it is adjusted, for finish_queries.
      std::vector<float> qs(nq_ * C_, 0.0f);
      std::vector<int> qflags(nq_);
      tbb::parallel_for(std::size_t(0), nq_, [&](std::size_t q) {
        const AmQuery& a = queries_[q];
        if (a.src) std::copy(a.src, a.src + C_, qs.begin() + std::ptrdiff_t(q * C_));
        qflags[q] = (a.adjust_outliers ? 1 : 0) | (a.src ? 2 : 0);
      });
      qsrc_ = upload(qs);
      qflags_ = upload(qflags);
    }
    host_mark("tables and queries");
  }

  // Planes already on the device, and queries too (am_cl::am_filter_planar).
  ClRun(const cl::Buffer& src, const cl::Buffer& guide, int W, int H, int C, int D, std::uint64_t seed,
        const AmSettings& s, const am_cl::DeviceQueries* dq)
      : AmRunShape(W, H, C, D, seed, s, no_queries()), st_(state()), nq_(dq ? dq->count : 0) {
    prog_ = st_.program(D_, C_);
    src_ = src;
    guide_ = guide;
    prepare();
    if (nq_ > 0) {
      set_runs(dq->runs);
      qxy_ = dq->xy, qguide_ = dq->guide, qsrc_ = dq->src;
      qflags_ = filled(nq_, cl_int(3));  // adjusted, towards the query's own value
    }
  }

  ~ClRun() {
    // Every write of upload() done before its host data goes (a run that threw may leave some queued).
    try {
      st_.queue.finish();
    } catch (...) {
    }
    for (auto& [bytes, b] : owned_) st_.give(bytes, b);
  }
  ClRun(const ClRun&) = delete;
  ClRun& operator=(const ClRun&) = delete;

  Image run(std::vector<float>* query_out) {
    auto& q = st_.queue;
    const std::size_t N = std::size_t(W_) * H_;
    tree();
    cl::Buffer out = take(sizeof(float) * N * C_);
    finish(out, false);
    Image img(W_, H_, C_);
    q.enqueueReadBuffer(out, CL_TRUE, 0, sizeof(float) * N * C_, img.data(), nullptr, event("read output"));
    host_mark("finish and read-back");
    if (query_out && nq_ > 0) {
      cl::Buffer answers = take(sizeof(float) * nq_ * C_);
      finish_queries(answers);
      query_out->resize(nq_ * C_);
      q.enqueueReadBuffer(answers, CL_TRUE, 0, sizeof(float) * nq_ * C_, query_out->data(), nullptr, event("read queries"));
    } else if (query_out) {
      query_out->clear();
    }
    host_mark("queries' read-back and results");
    if (st_.profile) print_profile();
    return img;
  }

  // The output (C planes) and the queries' answers into the caller's buffers; nothing read back.
  void run_device(const cl::Buffer& out, const cl::Buffer* answers) {
    tree();
    finish(out, true);
    if (answers && nq_ > 0) finish_queries(*answers);
    if (st_.profile) print_profile();
  }

 private:
  static const std::vector<AmQuery>& no_queries() {
    static const std::vector<AmQuery> none;
    return none;
  }
  template <typename T>
  cl::Buffer filled(std::size_t count, T value) {  // filled on the device, no host copy
    const std::size_t bytes = sizeof(T) * std::max<std::size_t>(count, 1);
    cl::Buffer b = take(bytes);
    st_.queue.enqueueFillBuffer(b, value, 0, bytes);
    return b;
  }
  void set_runs(std::vector<int> runs) {
    nruns_ = int(runs.size()) - 1;
    runs_ = upload(std::move(runs));
  }

  // What both constructors share: the sums, labels, tables, scratch and the split vectors' starts.
  void prepare() {
    const std::size_t N = std::size_t(W_) * H_;
    acc_ = filled(N * (C_ + 1), 0.0f);
    w_ = take(sizeof(float) * N * kMaxGroup);  // each manifold's weights, by splat_group
    min_d2_ = filled(s_.adjust_outliers ? N : 1, float(INFINITY));
    label_ = filled(N, cl_ushort(1));
    // The CPU path's bilinear tables.
    std::vector<int> x0, x1, y0, y1;
    std::vector<float> fx, fy;
    am_detail::bilinear_table(W_, sw_, df_, x0, x1, fx);
    am_detail::bilinear_table(H_, sh_, df_, y0, y1, fy);
    tx0_ = upload(x0), tx1_ = upload(x1), tfx_ = upload(fx);
    ty0_ = upload(y0), ty1_ = upload(y1), tfy_ = upload(fy);
    // The splat kernel's work-items cover 8 full-resolution columns each (adaptive_manifold.cl).
    nwx_ = (W_ + 7) / 8;
    // Column sums only where a block is wider than a work-item's 8 columns (block_store).
    colsum_ = take(sizeof(float) * (8 % df_ == 0 ? 1 : std::size_t(kMaxGroup) * std::max(C_ + 1, 2 * (D_ + 1)) * sh_ * W_));
    const std::size_t tri = std::size_t(D_) * (D_ + 1) / 2;  // the covariances' upper triangles
    cov_ = take(sizeof(float) * std::size_t(kMaxGroup) * nwx_ * sh_ * tri);
    cov_rows_ = take(sizeof(float) * std::size_t(kMaxGroup) * sh_ * tri);
    vetas_ = take(sizeof(float) * std::size_t(kMaxGroup) * sw_ * sh_);
    // The power iteration's start vectors of every node that splits (ids 1 .. 2^(height - 1) - 1),
    // by id, in the type split_dirs computes in.
    const int ids = 1 << std::max(height_ - 1, 1);
    std::vector<double> start(std::size_t(ids) * D_, 0.0);
    for (int id = 1; id < ids; ++id) {
      const std::vector<double> v = am_detail::split_start(D_, seed_, id);
      std::copy(v.begin(), v.end(), start.begin() + std::ptrdiff_t(id) * D_);
    }
    starts_ = st_.fp64 ? upload(std::move(start)) : upload(std::vector<float>(start.begin(), start.end()));
    const int hstride = std::max(sw_ - 1, 1);
    ah_ = take(sizeof(float) * std::size_t(sh_) * hstride);
    av_ = take(sizeof(float) * std::size_t(std::max(sh_ - 1, 1)) * sw_);
    if (nq_ > 0) {
      qacc_ = filled(nq_ * (C_ + 1), 0.0f);
      qmin_ = filled(nq_, float(INFINITY));
    }
  }

  // Builds and slices the tree (the image's sums in acc_, the queries' in qacc_ and qmin_).
  void tree() {
    auto& q = st_.queue;
    const std::size_t N = std::size_t(W_) * H_;
    // The first manifold: the guide low-passed at full resolution.
    cl::Buffer eta_full = take(sizeof(float) * N * D_);
    q.enqueueCopyBuffer(guide_, eta_full, 0, 0, sizeof(float) * N * D_);
    low_pass(eta_full, 0, W_, H_, D_, s_.sigma_s);
    // The tree level by level (as the CPU path's am/tree.cpp), each level's manifolds in groups
    // of up to kMaxGroup: a level's manifolds are D planes each of one buffer, in id order.
    Level level{eta_full, 1, 1, true};
    for (int depth = 1; level.count > 0; ++depth) {
      const bool split = depth < height_;
      Level next{cl::Buffer(), split ? 2 * level.count : 0, 2 * level.first_id, false};
      if (split) next.etas = take(sizeof(float) * std::size_t(sw_) * sh_ * D_ * next.count);
      for (int k0 = 0; k0 < level.count; k0 += kMaxGroup)
        group(level, k0, std::min(kMaxGroup, level.count - k0), split, next);
      level = next;
    }
    host_mark("tree (enqueue)");
  }
  float alpha_k() const { return float(-0.5 * s_.outlier_scale / (s_.sigma_r * s_.sigma_r)); }
  // The normalised output into `out`: C planes, or interleaved.
  void finish(const cl::Buffer& out, bool planar) {
    cl::Kernel& k = kernel("finish");
    set(k, W_, H_, acc_, src_, min_d2_, int(s_.adjust_outliers), alpha_k(), int(planar), out);
    launch(k, W_, H_);
  }
  void finish_queries(const cl::Buffer& answers) {
    cl::Kernel& fq = kernel("finish_queries");
    set(fq, int(nq_), W_, H_, qxy_, qacc_, qmin_, qsrc_, qflags_, src_, alpha_k(), answers);
    launch(fq, nq_);
  }

  // A buffer from the pool for the rest of the run, and one for a scope.
  cl::Buffer take(std::size_t bytes) {
    cl::Buffer b = st_.take(bytes);
    owned_.emplace_back(bytes, b);
    return b;
  }
  // A pooled buffer holding v, not a buffer made with CL_MEM_COPY_HOST_PTR: that was a device
  // allocation each time, about 20 per run. The write does not block (a blocking one waits for
  // every kernel queued before it): v is kept until the run ends.
  template <typename T>
  cl::Buffer upload(std::vector<T> v) {
    const std::size_t bytes = sizeof(T) * std::max<std::size_t>(v.size(), 1);
    cl::Buffer b = take(bytes);
    if (!v.empty()) {
      auto kept = std::make_shared<std::vector<T>>(std::move(v));
      st_.queue.enqueueWriteBuffer(b, CL_FALSE, 0, bytes, kept->data(), nullptr, event("write tables"));
      uploaded_.push_back(std::move(kept));
    }
    return b;
  }
  struct Temp {
    Temp(ClState& s, std::size_t n) : st(s), bytes(n), b(s.take(n)) {}
    ~Temp() { st.give(bytes, b); }
    Temp(const Temp&) = delete;
    Temp& operator=(const Temp&) = delete;
    ClState& st;
    std::size_t bytes;
    cl::Buffer b;
  };

  // The program's kernels, made once per run: PoCL looks a kernel's symbols up again for every
  // kernel object (about 3% of a run when each launch made its own). Arguments are captured at
  // enqueue time, so one object serves every launch.
  cl::Kernel& kernel(const char* name) {
    auto it = kernels_.find(name);
    if (it == kernels_.end()) it = kernels_.emplace(name, cl::Kernel(prog_, name)).first;
    return it->second;
  }

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
    enqueue(k, cl::NDRange((gx + lx - 1) / lx * lx, gy), cl::NDRange(lx, 1));
  }
  // Every kernel launch goes through here (timed under the kernel's name with DENOISEBENCH_OPENCL_PROFILE).
  void enqueue(cl::Kernel& k, const cl::NDRange& global, const cl::NDRange& local) {
    st_.queue.enqueueNDRangeKernel(k, cl::NullRange, global, local, nullptr,
                                   st_.profile ? event(k.getInfo<CL_KERNEL_FUNCTION_NAME>()) : nullptr);
  }

  // With DENOISEBENCH_OPENCL_PROFILE: an event to time the next command by, else null.
  cl::Event* event(const std::string& name) {
    if (!st_.profile) return nullptr;
    events_.emplace_back(name, cl::Event());
    return &events_.back().second;
  }
  // A pooled buffer holding the `ch` planes of view v: its rows written as they are (from the
  // caller's memory when they are contiguous, else through one host copy), then to_planar.
  cl::Buffer planar_on_device(ConstImageView v, int ch, const char* what) {
    const std::size_t N = std::size_t(W_) * H_, row = std::size_t(W_) * ch;
    Temp il(st_, sizeof(float) * N * ch);
    const float* data = v.data;
    if (v.row_stride != row) {
      auto rows = std::make_shared<std::vector<float>>(N * ch);
      tbb::parallel_for(0, H_, [&](int y) { std::copy(v.row(y), v.row(y) + row, rows->data() + y * row); });
      data = rows->data();
      uploaded_.push_back(std::move(rows));
    }
    st_.queue.enqueueWriteBuffer(il.b, CL_FALSE, 0, sizeof(float) * N * ch, data, nullptr, event(what));
    cl::Buffer planes = take(sizeof(float) * N * ch);
    cl::Kernel& k = kernel("to_planar");
    set(k, int(N), ch, il.b, planes);
    launch(k, N);
    return planes;
  }

  // With DENOISEBENCH_OPENCL_PROFILE: the host's time since the previous mark, under `what`.
  void host_mark(const char* what) {
    if (!st_.profile) return;
    const auto now = std::chrono::steady_clock::now();
    host_.emplace_back(what, std::chrono::duration<double, std::milli>(now - last_mark_).count());
    last_mark_ = now;
  }
  // The device's time per command name over the run, largest first, the run's wall time, and the
  // host's steps (host_mark) in order.
  void print_profile() {
    st_.queue.finish();
    std::map<std::string, std::pair<double, int>> by_name;
    double total = 0;
    for (auto& [name, e] : events_) {
      const double ms = double(e.getProfilingInfo<CL_PROFILING_COMMAND_END>() - e.getProfilingInfo<CL_PROFILING_COMMAND_START>()) * 1e-6;
      by_name[name].first += ms;
      ++by_name[name].second;
      total += ms;
    }
    std::vector<std::pair<double, std::string>> order;
    for (auto& [name, t] : by_name)
      order.emplace_back(t.first, fmt_entry(name, t.first, t.second));
    std::sort(order.rbegin(), order.rend());
    std::string line = "opencl profile: " + std::to_string(W_) + "x" + std::to_string(H_) + ", " +
                       std::to_string(events_.size()) + " commands, device time " + std::to_string(total) + " ms, wall " +
                       std::to_string(std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - started_).count()) +
                       " ms:";
    for (auto& [t, entry] : order) line += " " + entry;
    line += " host:";
    for (auto& [what, ms] : host_) line += " " + fmt_entry(what, ms, 1);
    std::fprintf(stderr, "%s\n", line.c_str());
    events_.clear();
  }
  static std::string fmt_entry(const std::string& name, double ms, int n) {
    char b[160];
    std::snprintf(b, sizeof b, "%s %.2f ms/%d;", name.c_str(), ms, n);
    return b;
  }
  static constexpr std::size_t kGroup = 32;

  // The recursive filter with a constant feedback (their h_filter) on planes p0 .. p0 + n - 1 of w x h.
  void low_pass(cl::Buffer& p, int p0, int w, int h, int n, double sigma) {
    const float a = float(std::exp(-std::sqrt(2.0) / sigma));
    recursive(p, p0, w, h, n, a);
  }
  void recursive(cl::Buffer& p, int p0, int w, int h, int n, float constant) {
    cl::Kernel& cols = kernel(lanes_ == 1 ? "rf_cols1" : "rf_cols");
    if (lanes_ == 1) {
      // A GPU: the rows as columns of the transposed planes (transpose_planes in the kernels).
      Temp t(st_, sizeof(float) * std::size_t(w) * h * n);
      transpose(p, p0, w, h, n, t.b, 0);
      cl::Buffer coef = av_;  // unread with a constant feedback
      std::unique_ptr<Temp> coef_t;
      if (constant == 0 && w > 1) {  // ah (h rows of w - 1) transposed: row x - 1 holds every row's a[x - 1]
        coef_t = std::make_unique<Temp>(st_, sizeof(float) * std::size_t(w - 1) * h);
        transpose(ah_, 0, w - 1, h, 1, coef_t->b, 0);
        coef = coef_t->b;
      }
      set(cols, h, w, t.b, 0, coef, constant);
      launch(cols, std::size_t(h), n);
      transpose(t.b, 0, h, w, n, p, p0);
      set(cols, w, h, p, p0, av_, constant);
      launch(cols, std::size_t(w), n);
      return;
    }
    cl::Kernel& rows = kernel("rf_rows");
    set(rows, w, h, p, p0, ah_, std::max(w - 1, 1), constant);
    set(cols, w, h, p, p0, av_, constant);
    launch(rows, (std::size_t(h) + 7) / 8, n);  // 8 rows per work-item
    launch(cols, (std::size_t(w) + 7) / 8, n);  // 8 columns per work-item
  }
  // Planes s0 .. s0 + n - 1 of src (w x h) transposed into planes d0 .. of dst (h x w).
  void transpose(cl::Buffer& src, int s0, int w, int h, int n, cl::Buffer& dst, int d0) {
    cl::Kernel& k = kernel("transpose_planes");
    set(k, w, h, src, s0, dst, d0);
    constexpr std::size_t T = 16;  // the kernel's tile
    enqueue(k, cl::NDRange((std::size_t(w) + T - 1) / T * T, (std::size_t(h) + T - 1) / T * T, n), cl::NDRange(T, T, 1));
  }
  // Rows or columns per work-item of the recursive filters: 8 (float8, for a CPU device's vector
  // lanes) or 1 (a GPU's); DENOISEBENCH_OPENCL_LANES=1 or 8 overrides the device's type, read per run.
  static int lanes_for(bool gpu) {
    const char* e = env::get("OPENCL_LANES");
    if (e && std::string(e) == "1") return 1;
    if (e && std::string(e) == "8") return 8;
    return gpu ? 1 : 8;
  }

  // One level of the tree: `count` manifolds with ids first_id .. first_id + count - 1, D planes
  // each in `etas` (on the reduced grid; the root's alone at full resolution).
  struct Level {
    cl::Buffer etas;
    int count = 0, first_id = 1;
    bool full = false;
  };

  // Manifolds k0 .. k0 + m - 1 of `level`: splat (one pass over the images for the group), blur
  // each, answer the queries, slice and split (one pass), and the children into next.etas.
  void group(const Level& level, int k0, int m, bool split, Level& next) {
    const std::size_t n = std::size_t(sw_) * sh_;
    const int id0 = level.first_id + k0;
    // Blocks that fit a work-item's 8 columns are summed there (block_store in the kernels).
    const bool direct = 8 % df_ == 0;
    Temp splats_tmp(st_, sizeof(float) * n * (C_ + 1) * m);
    cl::Buffer& splats = splats_tmp.b;
    {
      cl::Kernel& k = kernel("splat_group");
      set(k, W_, H_, sw_, sh_, df_, m, guide_, src_, level.etas, k0, int(level.full), tx0_, tx1_, tfx_, ty0_, ty1_,
          tfy_, inv_sr2_, w_, min_d2_, int(s_.adjust_outliers), colsum_, int(direct), splats, int(split), id0, label_, cov_);
      launch(k, std::size_t(nwx_), sh_);
    }
    if (!direct)
      for (int j = 0; j < m; ++j) {
        cl::Kernel& b = kernel("splat_blocks");
        set(b, W_, H_, sw_, sh_, df_, j, colsum_, j * (C_ + 1), splats);
        launch(b, sw_, sh_);
      }
    // The split directions: the leading eigenvectors of the clusters' covariances, on the device
    // (split_dirs): nothing of the tree waits for the host.
    cl::Buffer vb = take(sizeof(float) * std::size_t(m) * D_);
    if (split) {
      for (int j = 0; j < m; ++j) {
        cl::Kernel& k = kernel("cov_rows");
        set(k, nwx_, sh_, j, cov_, cov_rows_);
        launch(k, sh_);
      }
      cl::Kernel& k = kernel("split_dirs");
      set(k, sh_, m, id0, s_.pca_iterations, cov_rows_, starts_, vb);
      launch(k, std::size_t(m));
    }
    // Each manifold on the reduced grid: planes e0 .. of `small`.
    cl::Buffer small = level.etas;
    int e0 = k0 * D_;
    if (level.full) {
      small = take(sizeof(float) * n * D_);
      cl::Kernel& k = kernel("downsample");
      set(k, W_, H_, sw_, sh_, df_, level.etas, small);
      launch(k, sw_, sh_);
      e0 = 0;
    }
    // Blur along each manifold.
    const double ss = s_.sigma_s / df_, sr = s_.sigma_r / std::sqrt(2.0);
    for (int j = 0; j < m; ++j) {
      cl::Kernel& k = kernel("dt_weights");
      set(k, sw_, sh_, std::max(sw_ - 1, 1), small, e0 + j * D_, float((ss / sr) * (ss / sr)), float(-std::sqrt(2.0) / ss),
          ah_, av_);
      launch(k, (std::size_t(sw_) + 7) / 8, sh_);  // 8 reduced columns per work-item
      recursive(splats, j * (C_ + 1), sw_, sh_, C_ + 1, 0.0f);
    }
    if (nq_ > 0) {
      cl::Kernel& k = kernel("query_group");
      set(k, nruns_, runs_, W_, H_, sw_, sh_, m, qxy_, qguide_, level.etas, k0, int(level.full), splats, tx0_, tx1_, tfx_,
          ty0_, ty1_, tfy_, inv_sr2_, qacc_, qmin_);
      launch(k, std::size_t(nruns_));
    }
    if (split && !level.full) {
      cl::Kernel& k = kernel("veta");
      set(k, int(n), m, small, k0, vb, vetas_);
      launch(k, n);
    }
    // The children's splats: D + 1 planes per child, the left and the right child of each manifold.
    Temp kids_tmp(st_, sizeof(float) * n * 2 * (D_ + 1) * (split ? m : 1));
    cl::Buffer& kids = kids_tmp.b;
    {
      cl::Kernel& k = kernel("slice_split_group");
      set(k, W_, H_, sw_, sh_, df_, m, splats, tx0_, tx1_, tfx_, ty0_, ty1_, tfy_, w_, acc_, int(split), guide_,
          level.etas, int(level.full), vb, vetas_, label_, id0, colsum_, int(direct), kids);
      launch(k, std::size_t(nwx_), sh_);
    }
    if (!split) return;
    if (!direct)
      for (int j = 0; j < m; ++j) {
        cl::Kernel& b = kernel("split_blocks");
        set(b, W_, H_, sw_, sh_, df_, j, colsum_, kids);
        launch(b, sw_, sh_);
      }
    low_pass(kids, 0, sw_, sh_, 2 * (D_ + 1) * m, s_.sigma_s / df_);
    for (int j = 0; j < m; ++j)
      for (int c = 0; c < 2; ++c) {
        cl::Kernel& k = kernel("divide_eta");
        set(k, int(n), kids, (2 * j + c) * (D_ + 1), small, e0 + j * D_, next.etas, (2 * (k0 + j) + c) * D_);
        launch(k, n);
      }
  }

  ClState& st_;
  cl::Program prog_;
  cl::Buffer guide_, src_, acc_, w_, min_d2_, label_, tx0_, tx1_, tfx_, ty0_, ty1_, tfy_, cov_, cov_rows_, ah_, av_;
  cl::Buffer colsum_;  // a group's column sums: the splat's (C + 1 planes of sh x W per manifold), the split's (2 (D + 1))
  cl::Buffer vetas_;  // a group's v . eta on the reduced grid (one plane per manifold)
  cl::Buffer starts_;  // the split directions' start vectors, D per node id
  std::map<std::string, cl::Kernel> kernels_;
  std::vector<std::shared_ptr<void>> uploaded_;  // host data of upload()'s writes, kept until the run ends
  int lanes_ = lanes_for(st_.gpu);
  std::deque<std::pair<std::string, cl::Event>> events_;  // DENOISEBENCH_OPENCL_PROFILE only (deque: stable addresses)
  std::chrono::steady_clock::time_point started_ = std::chrono::steady_clock::now(), last_mark_ = started_;
  std::vector<std::pair<const char*, double>> host_;  // DENOISEBENCH_OPENCL_PROFILE: host_mark()'s steps
  std::vector<std::pair<std::size_t, cl::Buffer>> owned_;  // given back to the pool by the destructor
  int nwx_ = 1;        // the splat's work-items per row
  cl::Buffer qxy_, qguide_, qacc_, qmin_, runs_, qsrc_, qflags_;
  int nruns_ = 0;
  std::size_t nq_ = 0;  // the queries (host or device)
};

}  // namespace

bool am_opencl_available(std::string* why) {
  ClState& s = state();
  if (!s.ok && why) *why = "no usable OpenCL device: " + s.error;
  return s.ok;
}

std::string am_opencl_device_name() {
  ClState& s = state();
  if (!s.ok) return {};
  const cl::Platform platform(s.device.getInfo<CL_DEVICE_PLATFORM>());
  return platform.getInfo<CL_PLATFORM_NAME>() + " / " + s.device.getInfo<CL_DEVICE_NAME>();
}

Image am_filter_opencl(ConstImageView src, ConstImageView guide, const AmSettings& settings,
                       const std::vector<AmQuery>& queries, std::vector<float>* query_out) {
  std::string why;
  if (!am_opencl_available(&why)) throw WorkError("device=opencl: " + why);
  if (guide.width != src.width || guide.height != src.height) throw WorkError("am_filter_opencl: guide and source differ in size");
  if (src.empty()) return Image(src.width, src.height, src.channels);
  try {
    ClRun run(src, guide, settings, queries);
    am_capture_if_asked(src, guide, settings, queries);
    return run.run(query_out);
  } catch (const cl::Error& e) {
    throw WorkError(std::string("OpenCL error in the adaptive-manifold core: ") + e.what() + " (" + std::to_string(e.err()) + ")");
  }
}

namespace am_cl {

cl::CommandQueue& queue() { return state().queue; }
bool device_has_fp64() { return state().fp64; }
cl::Program program(int dims, int chans) { return state().program(dims, chans); }
bool profiling() { return state().profile; }

Pooled::Pooled(std::size_t bytes) : bytes_(std::max<std::size_t>(bytes, 4)), buf_(state().take(bytes_)) {}
Pooled::~Pooled() {
  if (bytes_ > 0) state().give(bytes_, buf_);
}
Pooled& Pooled::operator=(Pooled&& o) noexcept {
  if (this != &o) {
    if (bytes_ > 0) state().give(bytes_, buf_);
    bytes_ = o.bytes_;
    buf_ = std::move(o.buf_);
    o.bytes_ = 0;
  }
  return *this;
}

void am_filter_planar(const cl::Buffer& src, const cl::Buffer& guide, int width, int height, int C, int D,
                      std::uint64_t seed, const AmSettings& settings, const DeviceQueries* queries, const cl::Buffer& out,
                      const cl::Buffer* answers) {
  ClRun run(src, guide, width, height, C, D, seed, settings, queries);
  run.run_device(out, answers);
}

}  // namespace am_cl

#endif

}  // namespace dnb
