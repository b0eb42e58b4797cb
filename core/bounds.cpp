#include "core/bounds.h"

#include <cmath>

#include <fmt/format.h>

#include "core/errors.h"

namespace dnb {

std::string bound_violation(const Bound& b, const std::string& got) {
  if (b.max == std::numeric_limits<std::int64_t>::max())
    return fmt::format("expected an integer >= {} ({}), got {}", b.min, b.why, got);
  return fmt::format("expected an integer in {}..{} ({}), got {}", b.min, b.max, b.why, got);
}

std::string bound_violation(const RealBound& b, const std::string& got) {
  return fmt::format("expected a finite number in {}{}, {}] ({}), got {}", b.min_exclusive ? "(" : "[", b.min, b.max,
                     b.why, got);
}

bool within(std::int64_t v, const Bound& b) { return v >= b.min && v <= b.max; }

bool within(double v, const RealBound& b) {
  return std::isfinite(v) && (b.min_exclusive ? v > b.min : v >= b.min) && v <= b.max;
}

void check_bound(std::int64_t v, const Bound& b, const std::string& where) {
  if (!within(v, b)) throw InputError(fmt::format("{}: {}", where, bound_violation(b, std::to_string(v))));
}

void check_bound(double v, const RealBound& b, const std::string& where) {
  if (!within(v, b)) throw InputError(fmt::format("{}: {}", where, bound_violation(b, fmt::format("{}", v))));
}

}  // namespace dnb
