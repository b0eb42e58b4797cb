// JSON files with errors that name them, and typed access with errors that name the key: the
// one reader behind results.json, the nightly's summaries, gates and benchmark files.
#pragma once

#include <cmath>
#include <cstdint>
#include <limits>
#include <optional>
#include <string>
#include <type_traits>
#include <utility>
#include <vector>

#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include "core/errors.h"

namespace dnb::json_file {

// Reads and parses `path`; InputError naming it when it is missing, unreadable or not JSON.
nlohmann::json read(const std::string& path);
// Writes `j` (indented by `indent`) to `path` atomically, with a final line break.
void write(const std::string& path, const nlohmann::json& j, int indent = 2);

namespace detail {
// A JSON number as the integer type T, or nothing when it is not a whole number T can hold.
// nlohmann's get<int>() converts 1e300 or 3e9 with a plain cast: undefined behaviour for a
// float out of range (found by fuzz/results_fuzz.cpp), a silent wrap for a wide integer.
template <class T>
std::optional<T> whole_number(const nlohmann::json& v) {
  if (v.is_number_unsigned()) {
    const auto u = v.get<std::uint64_t>();
    if (std::in_range<T>(u)) return T(u);
  } else if (v.is_number_integer()) {
    const auto i = v.get<std::int64_t>();
    if (std::in_range<T>(i)) return T(i);
  } else if (v.is_number_float()) {
    const double d = v.get<double>();  // whole and within int64 (2^63 itself is not)
    if (std::isfinite(d) && d == std::trunc(d) && d >= -0x1p63 && d < 0x1p63 && std::in_range<T>(std::int64_t(d)))
      return T(std::int64_t(d));
  }
  return std::nullopt;
}
template <class T>
T whole_number_or_throw(const nlohmann::json& v, const std::string& key, const std::string& where) {
  if (auto n = whole_number<T>(v)) return *n;
  throw InputError(fmt::format("{}: key '{}' must be a whole number in [{}, {}], got {}", where, key,
                               std::numeric_limits<T>::min(), std::numeric_limits<T>::max(), v.dump()));
}
template <class T>
inline constexpr bool is_integer = std::is_integral_v<T> && !std::is_same_v<T, bool>;
template <class T>
struct integer_vector : std::false_type {};
template <class U>
struct integer_vector<std::vector<U>> : std::bool_constant<is_integer<U>> {};
}  // namespace detail

// j[key] as T; InputError "WHERE: missing key 'KEY'" or "... has the wrong type (...)". An
// integer T (or a vector of them) takes only whole numbers in its range.
template <class T>
T get(const nlohmann::json& j, const std::string& key, const std::string& where) {
  if (!j.is_object() || !j.contains(key)) throw InputError(fmt::format("{}: missing key '{}'", where, key));
  const nlohmann::json& v = j.at(key);
  if constexpr (detail::is_integer<T>) {
    if (v.is_number()) return detail::whole_number_or_throw<T>(v, key, where);
  } else if constexpr (detail::integer_vector<T>::value) {
    if (v.is_array()) {
      T out;
      for (const auto& e : v) {
        if (!e.is_number()) throw InputError(fmt::format("{}: key '{}' holds a {}, expected numbers", where, key, e.type_name()));
        out.push_back(detail::whole_number_or_throw<typename T::value_type>(e, key, where));
      }
      return out;
    }
  }
  try {
    return v.get<T>();
  } catch (const nlohmann::json::exception&) {
    throw InputError(fmt::format("{}: key '{}' has the wrong type ({})", where, key, v.type_name()));
  }
}
// j[key] as T, or `fallback` when the key is absent; a present key of the wrong type is an error.
template <class T>
T get_or(const nlohmann::json& j, const std::string& key, T fallback, const std::string& where) {
  return j.is_object() && j.contains(key) ? get<T>(j, key, where) : fallback;
}
// A number; null reads as NaN (the harness writes a non-finite value as null).
double number(const nlohmann::json& j, const std::string& key, const std::string& where);
// number(), or `fallback` when the key is absent.
double number_or(const nlohmann::json& j, const std::string& key, double fallback, const std::string& where);
// A finite number as JSON, a non-finite one as null (JSON has no NaN or Inf).
nlohmann::json number_or_null(double v);

}  // namespace dnb::json_file
