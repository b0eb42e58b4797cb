#include "core/progress.h"

#include <cmath>

#include <fmt/format.h>
#include <spdlog/spdlog.h>

namespace dnb {

std::string format_duration(double s) {
  if (!std::isfinite(s) || s < 0) return "?";
  if (s < 60) return fmt::format("{:.1f}s", s);
  if (s < 3600) return fmt::format("{}m {:02}s", int(s) / 60, int(s) % 60);
  return fmt::format("{}h {:02}m", int(s) / 3600, (int(s) % 3600) / 60);
}

Progress::Progress(std::string what, std::int64_t total, std::string unit, double interval_seconds)
    : what_(std::move(what)), unit_(std::move(unit)), total_(total), interval_(interval_seconds),
      start_(std::chrono::steady_clock::now()), last_print_(start_.time_since_epoch().count()) {}

double Progress::elapsed_seconds() const {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - start_).count();
}

void Progress::add(std::int64_t n) {
  using clock = std::chrono::steady_clock;
  std::int64_t done = done_.fetch_add(n) + n;
  const auto now = clock::now();
  const auto since_last = [&] {
    return std::chrono::duration<double>(now - clock::time_point(clock::duration(last_print_.load(std::memory_order_relaxed))))
        .count();
  };
  if (since_last() < interval_) return;
  std::unique_lock lock(mutex_, std::try_to_lock);
  if (!lock.owns_lock() || since_last() < interval_) return;
  last_print_.store(now.time_since_epoch().count(), std::memory_order_relaxed);
  print(done, false);
}

void Progress::print(std::int64_t done, bool final_line) {
  double t = elapsed_seconds();
  double rate = t > 0 ? done / t : 0;
  if (final_line) {
    spdlog::info("{}: done, {} {} in {} ({:.3g} {}/s)", what_, done, unit_, format_duration(t), rate, unit_);
    return;
  }
  double left = rate > 0 ? (total_ - done) / rate : NAN;
  spdlog::info("{}: {:3.0f}% {}/{} {}, {:.3g} {}/s, {} left", what_, total_ > 0 ? 100.0 * done / total_ : 0.0,
               done, total_, unit_, rate, unit_, format_duration(left));
}

void Progress::finish() {
  std::lock_guard lock(mutex_);
  if (finished_) return;
  finished_ = true;
  if (elapsed_seconds() >= interval_) print(done_.load(), true);
}

Progress::~Progress() { finish(); }

}  // namespace dnb
