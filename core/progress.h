// A progress line for long operations (renders, experiment runs): done/total, rate and time
// left, printed through spdlog at most once per `interval` seconds. Thread-safe add().
#pragma once

#include <atomic>
#include <chrono>
#include <cstdint>
#include <mutex>
#include <string>

namespace dnb {

class Progress {
 public:
  Progress(std::string what, std::int64_t total, std::string unit, double interval_seconds = 2.0);
  void add(std::int64_t n);
  // Prints the closing line (total time and rate); called by the destructor if not before.
  void finish();
  ~Progress();
  double elapsed_seconds() const;

 private:
  void print(std::int64_t done, bool final_line);
  std::string what_, unit_;
  std::int64_t total_;
  double interval_;
  std::atomic<std::int64_t> done_{0};
  std::chrono::steady_clock::time_point start_;
  // When the last line was printed, in steady_clock ticks: read by every add() without the lock
  // (the quick test whether a line is due), written under it; atomic, since a plain time_point
  // read there raced with the write (ThreadSanitizer, ReferenceCli's checkpoint test).
  std::atomic<std::chrono::steady_clock::rep> last_print_;
  std::mutex mutex_;
  bool finished_ = false;
};

// "1m 05s", "3.2s", "2h 10m".
std::string format_duration(double seconds);

}  // namespace dnb
