#include "core/file_names.h"

#include <fmt/format.h>

#include "core/errors.h"
#include "core/hash.h"

namespace dnb::file_names {

namespace {

bool allowed(char c) {
  return (c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') || (c >= '0' && c <= '9') || c == '_' || c == '-' ||
         c == '+' || c == '.';
}

}  // namespace

bool is_file_name(const std::string& s) {
  if (s.empty() || s.size() > kMaxLength || s.front() == '.' || s.front() == '-') return false;
  for (char c : s)
    if (!allowed(c)) return false;
  return true;
}

std::string checked(const std::string& s, const std::string& where) {
  if (!is_file_name(s))
    throw InputError(fmt::format("{}: name {:?} becomes a file or folder name: expected {}", where, s, kRule));
  return s;
}

std::string mapped(const std::string& s) {
  if (is_file_name(s)) return s;
  std::string o = s.empty() ? "_" : s;
  for (char& c : o)
    if (!allowed(c)) c = '_';
  if (o.front() == '.' || o.front() == '-') o.front() = '_';
  if (o.size() > kMaxLength) o = o.substr(0, kMaxLength - 17) + "-" + sha256_hex(s).substr(0, 16);
  return o;
}

}  // namespace dnb::file_names
