// What kind of method a method is (denoisers/method.h), apart from the method interface so that
// the results schema (experiment/results.h) can record it without the interface.
#pragma once

#include <string>

namespace dnb {

// Filter: turns the AOV frame into an image. Renderer: renders the scene itself (the irradiance
// cache); it may or may not read a frame.
enum class MethodKind { Filter, Renderer };
const char* to_string(MethodKind k);  // "filter", "renderer"
MethodKind method_kind_from_string(const std::string& s, const std::string& where);  // InputError otherwise

}  // namespace dnb
