// TOML configuration through toml++, with strict keys: every key is read where its default is
// written (`int spp = t.get("spp", 256);`), and finish() turns any key that was never read
// into an InputError naming the file, the line, the key and the valid keys.
#pragma once

#include <array>
#include <cstdint>
#include <memory>
#include <optional>
#include <set>
#include <string>
#include <vector>

#include <toml++/toml.h>

#include "core/bounds.h"

namespace dnb {

class ConfigTable;

// A parsed TOML document (owns the table). Parse errors are InputErrors with file:line:column.
class ConfigFile {
 public:
  static ConfigFile load(const std::string& path);
  static ConfigFile parse(const std::string& text, const std::string& source_name);
  ConfigTable root() const;
  const std::string& path() const { return path_; }

 private:
  std::string path_;
  std::shared_ptr<toml::table> table_;
};

class ConfigTable {
 public:
  ConfigTable(const toml::table* table, std::string file, std::string prefix);

  const std::string& file() const { return file_; }
  // Dotted path of this table inside the file ("" for the root).
  const std::string& prefix() const { return prefix_; }
  bool contains(const std::string& key) const { return table_->contains(key); }
  // The TOML type of a present key (none when absent), for keys that accept several forms.
  toml::node_type type_of(const std::string& key) const {
    const toml::node* n = table_->get(key);
    return n ? n->type() : toml::node_type::none;
  }

  // Typed reads with a default; a present key of the wrong type is an InputError, and so is an
  // integer that does not fit the type read (no silent wrap-around).
  bool get(const std::string& key, bool def) { return get_impl<bool>(key, def, "a boolean"); }
  int get(const std::string& key, int def);
  std::int64_t get(const std::string& key, std::int64_t def) { return get_int(key, def); }
  double get(const std::string& key, double def);
  // Bounded reads (core/bounds.h): a value outside the bound is an InputError naming file, line,
  // key, the bound and its reason. Real-number reads refuse NaN and infinities.
  int get(const std::string& key, int def, const Bound& b);
  std::int64_t get(const std::string& key, std::int64_t def, const Bound& b);
  double get(const std::string& key, double def, const RealBound& b);
  std::array<double, 3> get(const std::string& key, std::array<double, 3> def, const RealBound& b);
  // A list of integers (whole numbers written as reals, `1e3`, are accepted), each within b.
  std::vector<int> get(const std::string& key, const std::vector<int>& def, const Bound& b);
  std::string get(const std::string& key, const char* def) { return get(key, std::string(def)); }
  std::string get(const std::string& key, const std::string& def) {
    return get_impl<std::string>(key, def, "a string");
  }
  std::array<double, 3> get(const std::string& key, std::array<double, 3> def);
  std::vector<double> get(const std::string& key, const std::vector<double>& def);
  std::vector<std::string> get(const std::string& key, const std::vector<std::string>& def);

  // Required keys: absent is an InputError naming the key.
  std::string require_string(const std::string& key);
  double require_double(const std::string& key);
  std::array<double, 3> require_vec3(const std::string& key);
  std::array<double, 3> require_vec3(const std::string& key, const RealBound& b);
  double require_double(const std::string& key, const RealBound& b);

  // Sub-tables and arrays of tables ([[geometry]]). Reading them marks the key as read.
  std::optional<ConfigTable> table(const std::string& key);
  std::vector<ConfigTable> tables(const std::string& key);
  // Every key of this table, for tables whose keys are free-form names (method parameters).
  std::vector<std::string> keys() const;
  // The raw value of a key as text (for free-form parameter tables); marks it read.
  std::string raw(const std::string& key);

  // Throws InputError for the first key of this table that was never read.
  void finish() const;
  // "file:line: key 'a.b'" for messages about a key.
  std::string where(const std::string& key) const;

 private:
  std::int64_t get_int(const std::string& key, std::int64_t def);
  template <typename T>
  T get_impl(const std::string& key, const T& def, const char* expected) {
    const toml::node* n = mark(key);
    if (!n) return def;
    auto v = n->value_exact<T>();
    if (!v) type_error(key, expected);
    return *v;
  }
  const toml::node* mark(const std::string& key);
  [[noreturn]] void type_error(const std::string& key, const char* expected) const;

  const toml::table* table_;
  std::string file_;
  std::string prefix_;
  std::shared_ptr<std::set<std::string>> read_;
};

}  // namespace dnb
