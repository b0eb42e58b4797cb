// The list of built-in methods: adding a method is one source file plus one line here.
#include "denoisers/method.h"

namespace dnb {

void register_builtin_methods(MethodRegistry& r) {
  (void)r;
  // One line per method, e.g.: r.add(bilateral_method());
}

}  // namespace dnb
