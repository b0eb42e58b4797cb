// Names of an enum's values, in one table per enum: to_string and the strict reading back that
// every file format of the harness uses (an InputError naming where, the key, the valid names).
// One shape for every enum that is written into a file (Role, MethodKind, import transforms...).
#pragma once

#include <cstddef>
#include <string>

#include <fmt/format.h>

#include "core/errors.h"

namespace dnb {

template <class E>
struct EnumName {
  E value;
  const char* name;
};

template <class E, std::size_t N>
const char* enum_name(E value, const EnumName<E> (&names)[N]) {
  for (const auto& n : names)
    if (n.value == value) return n.name;
  return names[0].name;  // unreachable for a complete table
}

// "a, b, c" for messages.
template <class E, std::size_t N>
std::string enum_names_list(const EnumName<E> (&names)[N]) {
  std::string out;
  for (const auto& n : names) out += (out.empty() ? "" : ", ") + std::string(n.name);
  return out;
}

// InputError "<where>: expected one of a, b (got "x")" when `text` names no value; `where`
// names the file, line or record and the key ("f.toml:3: key 'plugin.protocol'").
template <class E, std::size_t N>
E enum_from_name(const std::string& text, const EnumName<E> (&names)[N], const std::string& where) {
  for (const auto& n : names)
    if (text == n.name) return n.value;
  throw InputError(fmt::format("{}: expected one of {} (got \"{}\")", where, enum_names_list(names), text));
}

}  // namespace dnb
