// Names that become one component of a path inside an output folder: a config's `name` (its
// results folder), a variant's `name` and a method's name (image stems), a scene's name or label
// (its image and frame folders), a plug-in's `name`. Every such value goes through one of the two
// functions below, so that no value a config, a scene or a plug-in manifest holds can reach a
// path outside the folder it is written into (docs/design.md, "Names that become paths"):
//
//   checked(v, where)  a name the user wrote as a name: refused unless it is a file name already
//                      (InputError "WHERE: name '../x': expected ...", exit 2);
//   mapped(v)          a name derived from something else (a scene given as a file path, a
//                      label defaulted from a frame file's stem): every other character becomes
//                      '_', so the result is always a file name.
//
//   file_names::checked("proposed-paper", "quick.toml:44: key 'name'") == "proposed-paper"
//   file_names::mapped("scenes/my box.toml") == "scenes_my_box.toml"
//   file_names::mapped("..") == "_."
#pragma once

#include <string>

namespace dnb::file_names {

// A file name: 1 to kMaxLength characters from [A-Za-z0-9._+-], not starting with '.' (no "."
// or "..", no hidden files) or '-' (it would read as an option in a shell).
inline constexpr std::size_t kMaxLength = 120;
inline constexpr const char* kRule =
    "1 to 120 letters, digits, '_', '-', '+' or '.', not starting with '.' or '-'";

bool is_file_name(const std::string& s);
// `s` itself when it is a file name; InputError naming `where` and the rule otherwise.
std::string checked(const std::string& s, const std::string& where);
// A file name for any `s`: disallowed characters become '_', a leading '.' or '-' becomes '_',
// the empty string "_"; a name longer than kMaxLength keeps its start and ends in 16 hex digits
// of its SHA-256, so two long names stay apart. Identity on file names.
std::string mapped(const std::string& s);

}  // namespace dnb::file_names
