// The block driver of references: fixed-order reduction, checkpoints, MPI passes, progress and
// the convergence log. Nothing here renders (reference_image.cpp calls the tracer), so the
// driver is tested with synthetic sums.
#include "tracer/reference.h"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <memory>
#include <sstream>

#include <fmt/format.h>
#include <nlohmann/json.hpp>
#include <spdlog/spdlog.h>

#include "core/atomic_file.h"
#include "core/errors.h"
#include "core/exr_io.h"
#include "core/hash.h"
#include "core/progress.h"
#include "core/timer.h"
#include "distributed/mpi_context.h"

namespace dnb {
namespace fs = std::filesystem;

namespace {

// 2: pair_sq (squared differences of sample pairs) replaced sum_sq (squared samples).
// 3: group_sum (the sample groups' sums, render.h) and group_samples replaced pair_sq.
constexpr const char* kCheckpointMagic = "DNBCKPT3";
// MPI tag of block transfers; messages between two ranks are never reordered by MPI, so one tag
// suffices.
constexpr int kBlockTag = 4101;

ColorSums zero_sums(int width, int height) {
  ColorSums s;
  s.width = width;
  s.height = height;
  s.sum.assign(std::size_t(width) * height * 3, 0.0);
  s.group_sum.assign(s.sum.size() * kSampleGroups, 0.0);
  return s;
}

// Lines of an identity text that differ between two identities, for a clear refusal message.
std::string identity_difference(const std::string& a, const std::string& b) {
  auto lines = [](const std::string& s) {
    std::vector<std::string> out;
    std::istringstream in(s);
    for (std::string l; std::getline(in, l);) out.push_back(l);
    return out;
  };
  auto la = lines(a), lb = lines(b);
  std::vector<std::string> diffs;
  for (auto& l : la)
    if (std::find(lb.begin(), lb.end(), l) == lb.end()) diffs.push_back("checkpoint has " + l);
  for (auto& l : lb)
    if (std::find(la.begin(), la.end(), l) == la.end()) diffs.push_back("this run has " + l);
  return fmt::format("{}", fmt::join(diffs, "; "));
}

nlohmann::json rows_to_json(const std::vector<ConvergenceRow>& rows) {
  auto a = nlohmann::json::array();
  // Doubles as JSON numbers: nlohmann writes them round-trip exact; NaN (fewer than 2 samples)
  // becomes null.
  auto num = [](double v) { return std::isfinite(v) ? nlohmann::json(v) : nlohmann::json(nullptr); };
  for (auto& r : rows) a.push_back({r.spp, num(r.seconds), num(r.rel_error), num(r.est_relmse)});
  return a;
}

std::vector<ConvergenceRow> rows_from_json(const nlohmann::json& a) {
  auto num = [](const nlohmann::json& v) { return v.is_null() ? NAN : v.get<double>(); };
  std::vector<ConvergenceRow> rows;
  for (auto& r : a) rows.push_back({r.at(0).get<std::int64_t>(), num(r.at(1)), num(r.at(2)), num(r.at(3))});
  return rows;
}

}  // namespace

void add_block(ColorSums& total, const ColorSums& block) {
  if (total.width != block.width || total.height != block.height || total.sum.size() != block.sum.size() ||
      total.group_sum.size() != block.group_sum.size())
    throw WorkError(fmt::format("block sums of {}x{} cannot be added to a total of {}x{}", block.width,
                                block.height, total.width, total.height));
  // The tracer's element-wise add: applied in block order, it makes references bit-identical.
  total.add(block);
}

ConvergenceRow convergence_of(const ColorSums& s) {
  ConvergenceRow row;
  row.spp = s.samples;
  const double n = double(s.samples);
  int groups = 0;
  for (std::int64_t g : s.group_samples) groups += g > 0;
  if (groups < 2 || s.sum.empty()) {
    row.rel_error = row.est_relmse = NAN;
    return row;
  }
  double sum_var = 0, sum_mean2 = 0, relmse = 0;
  for (std::size_t i = 0; i < s.sum.size(); ++i) {
    const double mean = s.sum[i] / n;
    const double var = s.variance_of_mean(i);  // from the sample groups (render.h)
    sum_var += var;
    sum_mean2 += mean * mean;
    relmse += var / (mean * mean + 0.01);
  }
  row.rel_error = sum_mean2 > 0 ? std::sqrt(sum_var / sum_mean2) : NAN;
  row.est_relmse = relmse / double(s.sum.size());
  return row;
}

std::string convergence_csv(const std::vector<ConvergenceRow>& rows) {
  std::string csv = "spp,seconds,rel_error,est_relmse\n";
  for (auto& r : rows) csv += fmt::format("{},{:.3f},{:.6g},{:.6g}\n", r.spp, r.seconds, r.rel_error, r.est_relmse);
  return csv;
}

std::vector<ConvergenceRow> parse_convergence_csv(const std::string& text, const std::string& path) {
  std::istringstream in(text);
  std::string line;
  if (!std::getline(in, line) || line != "spp,seconds,rel_error,est_relmse")
    throw InputError(fmt::format("'{}': expected the header 'spp,seconds,rel_error,est_relmse'", path));
  std::vector<ConvergenceRow> rows;
  for (int n = 2; std::getline(in, line); ++n) {
    ConvergenceRow r;
    char* end = nullptr;
    const char* p = line.c_str();
    r.spp = std::strtoll(p, &end, 10);
    double* fields[] = {&r.seconds, &r.rel_error, &r.est_relmse};
    bool ok = end != p;
    for (double* f : fields) {
      if (!ok || *end != ',') {
        ok = false;
        break;
      }
      p = end + 1;
      *f = std::strtod(p, &end);  // reads "nan" too
      ok = end != p;
    }
    if (!ok || *end != '\0') throw InputError(fmt::format("'{}' line {}: expected spp,seconds,rel_error,est_relmse", path, n));
    rows.push_back(r);
  }
  return rows;
}

// ---------------------------------------------------------------------------------------------
// Checkpoint files

void write_checkpoint(const std::string& path, const Checkpoint& ck) {
  const ColorSums& s = ck.sums;
  const std::size_t bytes = s.sum.size() * sizeof(double), group_bytes = s.group_sum.size() * sizeof(double);
  nlohmann::json h;
  h["identity"] = ck.identity;
  h["blocks_done"] = ck.blocks_done;
  h["width"] = s.width;
  h["height"] = s.height;
  h["samples"] = s.samples;
  h["group_samples"] = s.group_samples;
  h["dropped"] = s.dropped;
  h["seconds"] = ck.seconds;
  h["convergence"] = rows_to_json(ck.convergence);
  h["values"] = s.sum.size();
  // Raw doubles in this machine's byte order: a checkpoint resumes on the machine (kind) that
  // wrote it.
  h["double_bytes"] = sizeof(double);
  h["sum_sha256"] = sha256_hex(s.sum.data(), bytes);
  h["group_sum_sha256"] = sha256_hex(s.group_sum.data(), group_bytes);
  const std::string header = h.dump();

  const std::string head = fmt::format("{}\n{} {}\n{}", kCheckpointMagic, header.size(), sha256_hex(header), header);
  // Written in place, piece by piece: a copy of the payload in memory would be the largest
  // buffer of a reference render (24 doubles a pixel for the groups' sums).
  AtomicOutput out(path);
  out.write_at(head.data(), head.size(), 0);  // every write checked
  out.write_at(s.sum.data(), bytes, head.size());
  out.write_at(s.group_sum.data(), group_bytes, head.size() + bytes);
  out.finish_writes();  // fsynced
  out.commit();         // then renamed over the previous checkpoint
}

std::optional<Checkpoint> read_checkpoint(const std::string& path, std::string* damage) {
  std::error_code ec;
  if (!fs::exists(path, ec)) return std::nullopt;
  auto fail = [&](const std::string& why) -> std::optional<Checkpoint> {
    if (damage) *damage = why;
    return std::nullopt;
  };
  std::string data;
  try {
    data = read_text_file(path);
  } catch (const std::exception& e) {
    return fail(e.what());
  }
  std::size_t p = data.find('\n');
  if (p == std::string::npos || data.substr(0, p) != kCheckpointMagic) return fail("not a denoisebench checkpoint");
  std::size_t q = data.find('\n', p + 1);
  if (q == std::string::npos) return fail("truncated in its header");
  std::istringstream line(data.substr(p + 1, q - p - 1));
  std::size_t header_size = 0;
  std::string header_sha;
  if (!(line >> header_size >> header_sha)) return fail("malformed header line");
  if (data.size() < q + 1 + header_size) return fail("truncated in its header");
  const std::string header = data.substr(q + 1, header_size);
  if (sha256_hex(header) != header_sha) return fail("header checksum mismatch");
  try {
    auto h = nlohmann::json::parse(header);
    Checkpoint ck;
    ck.identity = h.at("identity").get<std::string>();
    ck.blocks_done = h.at("blocks_done").get<int>();
    ck.seconds = h.at("seconds").get<double>();
    ck.convergence = rows_from_json(h.at("convergence"));
    ColorSums& s = ck.sums;
    s.width = h.at("width").get<int>();
    s.height = h.at("height").get<int>();
    s.samples = h.at("samples").get<std::int64_t>();
    const auto gs = h.at("group_samples").get<std::vector<std::int64_t>>();
    if (gs.size() != std::size_t(kSampleGroups))
      return fail(fmt::format("{} sample groups, this build has {}", gs.size(), kSampleGroups));
    std::copy(gs.begin(), gs.end(), s.group_samples);
    s.dropped = h.at("dropped").get<std::int64_t>();
    const std::size_t values = h.at("values").get<std::size_t>();
    if (h.at("double_bytes").get<std::size_t>() != sizeof(double) || values != std::size_t(s.width) * s.height * 3)
      return fail("payload layout does not match this machine or its size");
    const std::size_t bytes = values * sizeof(double), group_bytes = bytes * kSampleGroups;
    const std::size_t payload = q + 1 + header_size;
    if (data.size() != payload + bytes + group_bytes)
      return fail(fmt::format("{} bytes, expected {} (truncated?)", data.size(), payload + bytes + group_bytes));
    s.sum.resize(values);
    s.group_sum.resize(values * kSampleGroups);
    std::memcpy(s.sum.data(), data.data() + payload, bytes);
    std::memcpy(s.group_sum.data(), data.data() + payload + bytes, group_bytes);
    if (sha256_hex(s.sum.data(), bytes) != h.at("sum_sha256").get<std::string>() ||
        sha256_hex(s.group_sum.data(), group_bytes) != h.at("group_sum_sha256").get<std::string>())
      return fail("payload checksum mismatch (corrupted)");
    return ck;
  } catch (const std::exception& e) {
    return fail(fmt::format("malformed header ({})", e.what()));
  }
}

// ---------------------------------------------------------------------------------------------
// The driver

namespace {

// Sample indices [begin, end) of block b.
std::pair<int, int> block_range(const BlockJob& job, int b) {
  return {b * job.block_spp, std::min(job.spp, (b + 1) * job.block_spp)};
}

// Where rank 0 starts: nothing done, or the state of a valid checkpoint of this job.
struct ResumeState {
  ColorSums total;
  int done = 0;                // blocks already in total
  double seconds_before = 0;   // render time of earlier sessions
  std::vector<ConvergenceRow> convergence;
  std::string refusal;         // not empty: the checkpoint belongs to another job (InputError)
};

ResumeState resume_from_checkpoint(const BlockJob& job, int nblocks) {
  ResumeState st;
  st.total = zero_sums(job.width, job.height);
  if (job.checkpoint_path.empty()) return st;
  std::string damage;
  auto ck = read_checkpoint(job.checkpoint_path, &damage);
  if (!ck && !damage.empty())
    spdlog::warn("checkpoint '{}' is damaged ({}); ignoring it and starting the render over", job.checkpoint_path,
                 damage);
  if (ck && ck->identity != job.identity) {
    st.refusal = fmt::format(
        "checkpoint '{}' belongs to a different reference ({}); resume with the same arguments, or use "
        "another checkpoint folder, or delete the file",
        job.checkpoint_path, identity_difference(ck->identity, job.identity));
  } else if (ck && (ck->blocks_done < 0 || ck->blocks_done > nblocks || ck->sums.width != job.width ||
                    ck->sums.height != job.height ||
                    ck->sums.samples != (ck->blocks_done == 0 ? 0 : block_range(job, ck->blocks_done - 1).second))) {
    spdlog::warn("checkpoint '{}' is inconsistent (blocks and samples disagree); starting the render over",
                 job.checkpoint_path);
  } else if (ck) {
    st.total = std::move(ck->sums);
    st.done = ck->blocks_done;
    st.seconds_before = ck->seconds;
    st.convergence = std::move(ck->convergence);
    spdlog::info("{}: resuming from checkpoint '{}': {} of {} spp done", job.what, job.checkpoint_path,
                 st.total.samples, job.spp);
  }
  return st;
}

// A block's sums from a rank to rank 0: samples, dropped and the groups' sample counts as
// doubles (exact below 2^53), then sum and group_sum.
void send_block(const ColorSums& s) {
  double head[2 + kSampleGroups] = {double(s.samples), double(s.dropped)};
  for (int g = 0; g < kSampleGroups; ++g) head[2 + g] = double(s.group_samples[g]);
  mpi::send_doubles(0, kBlockTag, head, 2 + kSampleGroups);
  mpi::send_doubles(0, kBlockTag, s.sum.data(), s.sum.size());
  mpi::send_doubles(0, kBlockTag, s.group_sum.data(), s.group_sum.size());
}

void receive_block(int from, ColorSums& s) {
  double head[2 + kSampleGroups];
  mpi::recv_doubles(from, kBlockTag, head, 2 + kSampleGroups);
  s.samples = std::int64_t(head[0]);
  s.dropped = std::int64_t(head[1]);
  for (int g = 0; g < kSampleGroups; ++g) s.group_samples[g] = std::int64_t(head[2 + g]);
  mpi::recv_doubles(from, kBlockTag, s.sum.data(), s.sum.size());
  mpi::recv_doubles(from, kBlockTag, s.group_sum.data(), s.group_sum.size());
}

}  // namespace

BlockResult accumulate_blocks(const BlockJob& job, const BlockRenderer& render) {
  if (job.width <= 0 || job.height <= 0 || job.spp <= 0 || job.block_spp <= 0)
    throw InputError(fmt::format("reference: size {}x{}, spp {} and block spp {} must be positive", job.width,
                                 job.height, job.spp, job.block_spp));
  const int nblocks = (job.spp + job.block_spp - 1) / job.block_spp;
  const int ranks = mpi::size(), me = mpi::rank();
  const bool root = mpi::is_root();
  const std::int64_t pixels = std::int64_t(job.width) * job.height;

  BlockResult result;
  ColorSums total;
  int done = 0;
  double seconds_before = 0;
  std::string refusal;
  if (root) {
    ResumeState st = resume_from_checkpoint(job, nblocks);
    total = std::move(st.total);
    done = st.done;
    seconds_before = st.seconds_before;
    result.convergence = std::move(st.convergence);
    refusal = std::move(st.refusal);
  }
  // Every rank learns the outcome, so that a refusal ends all of them instead of hanging some.
  refusal = mpi::broadcast_string(refusal);
  if (!refusal.empty()) throw InputError(refusal);
  done = int(mpi::broadcast_int(done));
  result.blocks_resumed = done;

  std::unique_ptr<Progress> progress;
  if (root && job.progress && done < nblocks) {
    const std::int64_t left = std::int64_t(job.spp - block_range(job, done).first) * pixels;
    progress = std::make_unique<Progress>(
        fmt::format("{} ({} rank{})", job.what, ranks, ranks > 1 ? "s" : ""), left, "samples");
  }
  auto on_progress = [&](std::int64_t n) {
    if (progress) progress->add(n);
  };
  auto check_block = [&](const ColorSums& s, int b) {
    auto [begin, end] = block_range(job, b);
    if (s.width != job.width || s.height != job.height || s.samples != end - begin ||
        s.sum.size() != std::size_t(pixels) * 3 || s.group_sum.size() != s.sum.size() * kSampleGroups)
      throw WorkError(fmt::format("block {} (samples {}..{}) came back as {}x{} with {} samples", b, begin, end,
                                  s.width, s.height, s.samples));
  };

  Stopwatch clock;
  while (done < nblocks) {
    // A pass: block done + r for rank r.
    const int pass_end = std::min(done + ranks, nblocks);
    const int my_block = done + me;
    ColorSums mine;
    if (my_block < pass_end) {
      auto [begin, end] = block_range(job, my_block);
      mine = render(begin, end, on_progress);
      check_block(mine, my_block);
      ++result.blocks_rendered;
    }
    if (root) {
      add_block(total, mine);
      ColorSums other = zero_sums(job.width, job.height);
      for (int b = done + 1; b < pass_end; ++b) {
        receive_block(b - done, other);
        check_block(other, b);
        add_block(total, other);
        if (progress) progress->add(other.samples * pixels);
      }
      ConvergenceRow row = convergence_of(total);
      row.seconds = seconds_before + clock.seconds();
      result.convergence.push_back(row);
      done = pass_end;
      if (!job.checkpoint_path.empty()) {
        Stopwatch write_clock;
        write_checkpoint(job.checkpoint_path, {job.identity, done, total, result.convergence, row.seconds});
        result.checkpoint_seconds += write_clock.seconds();
        ++result.checkpoints_written;
      }
      spdlog::debug("{}: {} spp, relative error {:.4g}", job.what, row.spp, row.rel_error);
    } else {
      if (my_block < pass_end) send_block(mine);
      done = pass_end;
    }
  }
  if (progress) progress->finish();
  // Blocks rendered by the whole job, for the caller's log and tests.
  if (mpi::size() > 1) {
    auto counts = mpi::gather_strings(std::to_string(result.blocks_rendered));
    if (root) {
      result.blocks_rendered = 0;
      for (auto& c : counts) result.blocks_rendered += std::stoi(c);
    }
  }
  result.seconds = seconds_before + clock.seconds();
  if (root) result.sums = std::move(total);
  return result;
}

// ---------------------------------------------------------------------------------------------
// Output

void write_reference(const Reference& ref, const std::string& exr_path, const std::string& csv_path) {
  if (ref.color.empty()) throw WorkError("write_reference: empty reference");
  AovFrame frame(ref.color.width(), ref.color.height());
  frame.meta = ref.meta;
  frame.set(layer::kColor, ref.color);
  frame.set(layer::kVariance, ref.variance);
  // The log is written (and checked) before the image, and committed after it: a full disk
  // fails the call before either file appears.
  std::optional<AtomicOutput> csv;
  if (!csv_path.empty()) {
    csv.emplace(csv_path);
    csv->write(convergence_csv(ref.convergence));
  }
  write_frame(frame, exr_path);
  if (csv) csv->commit();
}

}  // namespace dnb
