#include "core/json_file.h"

#include <cmath>
#include <filesystem>

#include "core/atomic_file.h"

namespace dnb::json_file {

nlohmann::json read(const std::string& path) {
  if (!std::filesystem::exists(path)) throw InputError(fmt::format("'{}': no such file", path));
  try {
    return nlohmann::json::parse(read_text_file(path));
  } catch (const nlohmann::json::exception& e) {
    throw InputError(fmt::format("'{}': not valid JSON ({})", path, e.what()));
  }
}

void write(const std::string& path, const nlohmann::json& j, int indent) {
  write_text_atomic(path, j.dump(indent) + "\n");
}

double number(const nlohmann::json& j, const std::string& key, const std::string& where) {
  if (!j.is_object() || !j.contains(key)) throw InputError(fmt::format("{}: missing key '{}'", where, key));
  const nlohmann::json& v = j.at(key);
  if (v.is_null()) return NAN;
  if (!v.is_number()) throw InputError(fmt::format("{}: key '{}' is not a number ({})", where, key, v.type_name()));
  return v.get<double>();
}

double number_or(const nlohmann::json& j, const std::string& key, double fallback, const std::string& where) {
  return j.is_object() && j.contains(key) ? number(j, key, where) : fallback;
}

nlohmann::json number_or_null(double v) { return std::isfinite(v) ? nlohmann::json(v) : nlohmann::json(nullptr); }

}  // namespace dnb::json_file
