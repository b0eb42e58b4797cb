#include "core/memory_budget.h"
#include "core/env.h"

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <string>

#include <fmt/format.h>
#include <unistd.h>

#include "core/errors.h"

namespace dnb {
namespace fs = std::filesystem;

double physical_memory_bytes() {
  const long pages = ::sysconf(_SC_PHYS_PAGES), page = ::sysconf(_SC_PAGE_SIZE);
  return pages > 0 && page > 0 ? double(pages) * double(page) : 0.0;
}

double parse_memory_size(const std::string& text, const std::string& what) {
  std::size_t used = 0;
  double value = -1;
  try {
    value = std::stod(text, &used);
  } catch (const std::exception&) {
    used = 0;
  }
  double scale = 1;
  if (used > 0 && used + 1 == text.size()) {
    const std::string units = "KMGT";
    const auto k = units.find(char(std::toupper(static_cast<unsigned char>(text.back()))));
    if (k != std::string::npos) scale = std::ldexp(1.0, 10 * int(k + 1)), ++used;
  }
  if (used == 0 || used != text.size() || !std::isfinite(value) || value <= 0)
    throw InputError(fmt::format("{} '{}': expected a size in bytes above 0, or with K, M, G or T (e.g. 4G)", what, text));
  return value * scale;
}

namespace {

// A cgroup memory limit file's value in bytes, or 0 when it has none ("max", missing, or v1's
// "unlimited", a number near 2^63).
double cgroup_limit(const std::string& file) {
  std::ifstream f(file);
  std::string v;
  if (!(f >> v) || v == "max") return 0;
  char* end = nullptr;
  const double bytes = std::strtod(v.c_str(), &end);
  return (end && *end == 0 && bytes > 0 && bytes < 0x1p62) ? bytes : 0;
}

// Lowers `budget` to `limit` when the limit is known (> 0) and lower; 0 is "unknown" for both.
void lower_to(double& budget, double limit) {
  if (limit > 0 && (budget == 0 || limit < budget)) budget = limit;
}

}  // namespace

double memory_budget_bytes() {
  double budget = physical_memory_bytes();
  lower_to(budget, cgroup_limit("/sys/fs/cgroup/memory/memory.limit_in_bytes"));  // v1, the mount's own cgroup
  lower_to(budget, cgroup_limit("/sys/fs/cgroup/memory.max"));                     // v2, the mount's root
  std::ifstream self("/proc/self/cgroup");
  for (std::string line; std::getline(self, line);) {
    if (!line.starts_with("0::/")) continue;  // v2: limits of the process's cgroup and its parents
    for (std::filesystem::path p = line.substr(3); p.has_relative_path(); p = p.parent_path())
      lower_to(budget, cgroup_limit("/sys/fs/cgroup" + p.string() + "/memory.max"));
  }
  if (const char* limit = env::get("MEMORY_LIMIT"); limit && *limit)
    lower_to(budget, parse_memory_size(limit, "$DENOISEBENCH_MEMORY_LIMIT"));
  return budget;
}

void refuse_decode_beyond(const std::string& path, int width, int height, int channels, double need,
                          double available_bytes) {
  if (available_bytes > 0 && need > available_bytes)
    throw InputError(fmt::format("'{}': decoding {}x{} with {} channels needs about {:.1f} GiB, more than the "
                                 "{:.1f} GiB this process may use (memory, cgroup limit, $DENOISEBENCH_MEMORY_LIMIT)",
                                 path, width, height, channels, need / double(1ull << 30),
                                 available_bytes / double(1ull << 30)));
}

void check_decode_memory(const std::string& path, int width, int height, int channels, double available_bytes) {
  refuse_decode_beyond(path, width, height, channels, 2.0 * double(width) * double(height) * double(channels) * sizeof(float),
                       available_bytes);
}

}  // namespace dnb
