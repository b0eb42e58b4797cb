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
  if (w < 1 || h < 1 || w > 65536 || h > 65536) throw bad("each side must be 1..65536");
  if (w * h > (1LL << 28)) throw bad("at most 2^28 pixels in all");
  return {int(w), int(h)};
}

}  // namespace dnb::app
