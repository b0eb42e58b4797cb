#include "core/config.h"

#include <cmath>
#include <filesystem>
#include <limits>

#include <fmt/format.h>

#include "core/errors.h"

namespace dnb {

ConfigFile ConfigFile::load(const std::string& path) {
  std::error_code ec;  // a name the system refuses (too long) is no such file, not an exception
  if (!std::filesystem::exists(path, ec)) throw InputError(fmt::format("'{}': no such file", path));
  if (!std::filesystem::is_regular_file(path, ec))
    throw InputError(fmt::format("'{}': not a regular file (a folder, a device or a pipe): expected a TOML file", path));
  ConfigFile f;
  f.path_ = path;
  try {
    f.table_ = std::make_shared<toml::table>(toml::parse_file(path));
  } catch (const toml::parse_error& e) {
    throw InputError(fmt::format("{}:{}:{}: TOML syntax error: {}", path, e.source().begin.line,
                                 e.source().begin.column, e.description()));
  }
  return f;
}

ConfigFile ConfigFile::parse(const std::string& text, const std::string& source_name) {
  ConfigFile f;
  f.path_ = source_name;
  try {
    f.table_ = std::make_shared<toml::table>(toml::parse(text, source_name));
  } catch (const toml::parse_error& e) {
    throw InputError(fmt::format("{}:{}:{}: TOML syntax error: {}", source_name, e.source().begin.line,
                                 e.source().begin.column, e.description()));
  }
  return f;
}

ConfigTable ConfigFile::root() const { return ConfigTable(table_.get(), path_, ""); }

ConfigTable::ConfigTable(const toml::table* table, std::string file, std::string prefix)
    : table_(table), file_(std::move(file)), prefix_(std::move(prefix)),
      read_(std::make_shared<std::set<std::string>>()) {}

std::string ConfigTable::where(const std::string& key) const {
  const toml::node* n = table_->get(key);
  auto line = n ? n->source().begin.line : table_->source().begin.line;
  std::string full = prefix_.empty() ? key : prefix_ + "." + key;
  return fmt::format("{}:{}: key '{}'", file_, line, full);
}

const toml::node* ConfigTable::mark(const std::string& key) {
  read_->insert(key);
  return table_->get(key);
}

void ConfigTable::type_error(const std::string& key, const char* expected) const {
  throw InputError(fmt::format("{}: expected {}", where(key), expected));
}

std::int64_t ConfigTable::get_int(const std::string& key, std::int64_t def) {
  const toml::node* n = mark(key);
  if (!n) return def;
  auto v = n->value_exact<std::int64_t>();
  if (!v) type_error(key, "an integer");
  return *v;
}

int ConfigTable::get(const std::string& key, int def) {
  return int(get(key, std::int64_t(def),
                 Bound{std::numeric_limits<int>::min(), std::numeric_limits<int>::max(), "a 32-bit integer"}));
}

std::int64_t ConfigTable::get(const std::string& key, std::int64_t def, const Bound& b) {
  const std::int64_t v = get_int(key, def);
  if (table_->contains(key)) check_bound(v, b, where(key));
  return v;
}

int ConfigTable::get(const std::string& key, int def, const Bound& b) {
  return int(get(key, std::int64_t(def), b));  // b lies inside int's range
}

double ConfigTable::get(const std::string& key, double def, const RealBound& b) {
  const double v = get(key, def);
  if (table_->contains(key)) check_bound(v, b, where(key));
  return v;
}

std::array<double, 3> ConfigTable::get(const std::string& key, std::array<double, 3> def, const RealBound& b) {
  const auto v = get(key, def);
  if (table_->contains(key))
    for (double x : v)
      if (!within(x, b))
        throw InputError(
            fmt::format("{}: {}", where(key), bound_violation(b, fmt::format("[{}, {}, {}]", v[0], v[1], v[2]))));
  return v;
}

std::vector<int> ConfigTable::get(const std::string& key, const std::vector<int>& def, const Bound& b) {
  const toml::node* n = mark(key);
  if (!n) return def;
  const toml::array* a = n->as_array();
  if (!a) type_error(key, "an array of integers");
  std::vector<int> out;
  for (const auto& e : *a) {
    std::int64_t v = 0;
    if (auto i = e.value_exact<std::int64_t>()) {
      v = *i;
    } else if (auto d = e.value_exact<double>()) {
      // Compared as a double first: converting 1e30 to an integer is undefined.
      if (!(*d == std::floor(*d)) || *d < double(b.min) || *d > double(b.max))
        throw InputError(fmt::format("{}: {}", where(key), bound_violation(b, fmt::format("{}", *d))));
      v = std::int64_t(*d);
    } else {
      type_error(key, "an array of integers");
    }
    check_bound(v, b, where(key));
    out.push_back(int(v));
  }
  return out;
}

double ConfigTable::get(const std::string& key, double def) {
  const toml::node* n = mark(key);
  if (!n) return def;
  // Integers are accepted where a real number is expected ("sigma = 2").
  if (auto v = n->value_exact<double>()) return *v;
  if (auto v = n->value_exact<std::int64_t>()) return double(*v);
  type_error(key, "a number");
}

std::vector<double> ConfigTable::get(const std::string& key, const std::vector<double>& def) {
  const toml::node* n = mark(key);
  if (!n) return def;
  const toml::array* a = n->as_array();
  if (!a) type_error(key, "an array of numbers");
  std::vector<double> out;
  for (const auto& e : *a) {
    if (auto v = e.value_exact<double>()) out.push_back(*v);
    else if (auto vi = e.value_exact<std::int64_t>()) out.push_back(double(*vi));
    else type_error(key, "an array of numbers");
  }
  return out;
}

std::array<double, 3> ConfigTable::get(const std::string& key, std::array<double, 3> def) {
  if (!table_->contains(key)) {
    read_->insert(key);
    return def;
  }
  auto v = get(key, std::vector<double>{});
  if (v.size() != 3) type_error(key, "an array of 3 numbers");
  return {v[0], v[1], v[2]};
}

std::vector<std::string> ConfigTable::get(const std::string& key, const std::vector<std::string>& def) {
  const toml::node* n = mark(key);
  if (!n) return def;
  const toml::array* a = n->as_array();
  if (!a) type_error(key, "an array of strings");
  std::vector<std::string> out;
  for (const auto& e : *a) {
    auto v = e.value_exact<std::string>();
    if (!v) type_error(key, "an array of strings");
    out.push_back(*v);
  }
  return out;
}

std::string ConfigTable::require_string(const std::string& key) {
  if (!table_->contains(key))
    throw InputError(fmt::format("{}: required key '{}' is missing (expected a string)", file_,
                                 prefix_.empty() ? key : prefix_ + "." + key));
  return get(key, std::string());
}

double ConfigTable::require_double(const std::string& key) {
  if (!table_->contains(key))
    throw InputError(fmt::format("{}: required key '{}' is missing (expected a number)", file_,
                                 prefix_.empty() ? key : prefix_ + "." + key));
  return get(key, 0.0);
}

std::array<double, 3> ConfigTable::require_vec3(const std::string& key) {
  if (!table_->contains(key))
    throw InputError(fmt::format("{}: required key '{}' is missing (expected an array of 3 numbers)", file_,
                                 prefix_.empty() ? key : prefix_ + "." + key));
  return get(key, std::array<double, 3>{0, 0, 0});
}

double ConfigTable::require_double(const std::string& key, const RealBound& b) {
  const double v = require_double(key);
  check_bound(v, b, where(key));
  return v;
}

std::array<double, 3> ConfigTable::require_vec3(const std::string& key, const RealBound& b) {
  require_vec3(key);  // the missing-key message
  return get(key, std::array<double, 3>{0, 0, 0}, b);
}

std::optional<ConfigTable> ConfigTable::table(const std::string& key) {
  const toml::node* n = mark(key);
  if (!n) return std::nullopt;
  const toml::table* t = n->as_table();
  if (!t) type_error(key, "a table");
  return ConfigTable(t, file_, prefix_.empty() ? key : prefix_ + "." + key);
}

std::vector<ConfigTable> ConfigTable::tables(const std::string& key) {
  const toml::node* n = mark(key);
  std::vector<ConfigTable> out;
  if (!n) return out;
  const toml::array* a = n->as_array();
  if (!a) type_error(key, "an array of tables ([[name]])");
  int i = 0;
  for (const auto& e : *a) {
    const toml::table* t = e.as_table();
    if (!t) type_error(key, "an array of tables");
    out.emplace_back(t, file_, fmt::format("{}[{}]", prefix_.empty() ? key : prefix_ + "." + key, i++));
  }
  return out;
}

std::vector<std::string> ConfigTable::keys() const {
  std::vector<std::string> out;
  for (const auto& [k, v] : *table_) out.emplace_back(k.str());
  return out;
}

std::string ConfigTable::raw(const std::string& key) {
  const toml::node* n = mark(key);
  if (!n) throw InputError(fmt::format("{}: key '{}' is missing", file_, key));
  if (auto s = n->value_exact<std::string>()) return *s;
  if (auto b = n->value_exact<bool>()) return *b ? "true" : "false";
  if (auto i = n->value_exact<std::int64_t>()) return std::to_string(*i);
  if (auto d = n->value_exact<double>()) return fmt::format("{}", *d);
  type_error(key, "a string, number or boolean");
}

void ConfigTable::finish() const {
  for (const auto& [k, v] : *table_) {
    std::string key(k.str());
    if (read_->count(key)) continue;
    std::string full = prefix_.empty() ? key : prefix_ + "." + key;
    throw InputError(fmt::format("{}:{}: unknown key '{}' (valid keys{}: {})", file_, v.source().begin.line,
                                 full, prefix_.empty() ? "" : " in '" + prefix_ + "'",
                                 fmt::join(*read_, ", ")));
  }
}

}  // namespace dnb
