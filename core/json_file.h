// JSON files with errors that name them, and typed access with errors that name the key: the
// one reader behind results.json, the nightly's summaries, gates and benchmark files.
#pragma once

#include <string>

#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include "core/errors.h"

namespace dnb::json_file {

// Reads and parses `path`; InputError naming it when it is missing, unreadable or not JSON.
nlohmann::json read(const std::string& path);
// Writes `j` (indented by `indent`) to `path` atomically, with a final line break.
void write(const std::string& path, const nlohmann::json& j, int indent = 2);

// j[key] as T; InputError "WHERE: missing key 'KEY'" or "... has the wrong type (...)".
template <class T>
T get(const nlohmann::json& j, const std::string& key, const std::string& where) {
  if (!j.is_object() || !j.contains(key)) throw InputError(fmt::format("{}: missing key '{}'", where, key));
  try {
    return j.at(key).get<T>();
  } catch (const nlohmann::json::exception&) {
    throw InputError(fmt::format("{}: key '{}' has the wrong type ({})", where, key, j.at(key).type_name()));
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
