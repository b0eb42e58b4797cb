#include "apps/args.h"

#include <charconv>

#include <fmt/format.h>

#include "core/errors.h"

namespace dnb::app {

std::pair<int, int> parse_size(const std::string& value, const std::string& option) {
  const auto bad = [&](const std::string& why) {
    return InputError(fmt::format("{} '{}': expected WIDTHxHEIGHT, e.g. 1024x768 ({})", option, value, why));
  };
  const auto x = value.find_first_of("xX");
  if (x == std::string::npos) throw bad("no 'x'");
  long long w = 0, h = 0;
  const char* begin = value.data();
  const char* end = begin + value.size();
  auto [pw, ew] = std::from_chars(begin, begin + x, w);
  auto [ph, eh] = std::from_chars(begin + x + 1, end, h);
  if (ew != std::errc() || pw != begin + x || eh != std::errc() || ph != end || x == 0)
    throw bad(ew == std::errc::result_out_of_range || eh == std::errc::result_out_of_range ? "a side is out of range"
                                                                                           : "not two whole numbers");
  if (!within(w, bounds::kSide) || !within(h, bounds::kSide))
    throw bad(fmt::format("each side must be {}..{}: {}", bounds::kSide.min, bounds::kSide.max, bounds::kSide.why));
  if (w * h > bounds::kMaxPixels) throw bad(fmt::format("at most {} pixels in all", bounds::kMaxPixels));
  return {int(w), int(h)};
}

CLI::Validator in_bounds(const Bound& b) {
  return CLI::Validator(
      [b](std::string& text) -> std::string {
        long long v = 0;
        const char* begin = text.data();
        const char* end = begin + text.size();
        auto [p, ec] = std::from_chars(begin, end, v);
        if (ec != std::errc() || p != end || text.empty() || !within(v, b))
          return bound_violation(b, "'" + text + "'");
        return {};
      },
      fmt::format("INT in [{} - {}]", b.min, b.max));
}

CLI::Option* add_threads_option(CLI::App& cmd, int& threads, const std::string& help) {
  return cmd.add_option("--threads", threads, help)->check(in_bounds(bounds::kThreads));
}

}  // namespace dnb::app
