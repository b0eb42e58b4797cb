// CSV as RFC 4180 writes it: fields holding a comma, a quote or a line break are quoted, quotes
// inside doubled. One implementation for every CSV the harness writes or reads back
// (results.csv, the report's tables, the nightly history).
#pragma once

#include <string>
#include <vector>

namespace dnb::csv {

// `s` as one CSV field (quoted only when it must be).
std::string field(const std::string& s);
// One CSV line (no line break) from its fields.
std::string line(const std::vector<std::string>& fields);
// The fields of one line (without its line break); the inverse of line().
std::vector<std::string> split(const std::string& line);

}  // namespace dnb::csv
