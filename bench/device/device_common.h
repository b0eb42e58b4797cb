// What the two device drivers share (bench/device/am_device.cpp, the adaptive-manifold core;
// bench/device/proposed_device.cpp, proposed's whole filter): their command line, medians and the
// JSON they write. Header-only: the drivers are built from sources, without the harness's libraries.
#pragma once

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <string>
#include <vector>

namespace dnb::device_tool {

// [--repeat N] [--json OUT] [--perturb EPS] FILE...; ok is false (after a usage line on stderr)
// for anything else, for N < 1 or for no file; help for -h or --help.
struct Args {
  int repeat = 10;
  double perturb = 0;
  std::string json;
  std::vector<std::string> files;
  bool ok = true, help = false;
};
inline Args parse_args(int argc, char** argv, double default_perturb, const char* usage) {
  Args a;
  a.perturb = default_perturb;
  for (int i = 1; i < argc; ++i) {
    const std::string s = argv[i];
    if (s == "--repeat" && i + 1 < argc) {
      a.repeat = std::atoi(argv[++i]);
    } else if (s == "--perturb" && i + 1 < argc) {
      a.perturb = std::atof(argv[++i]);
    } else if (s == "--json" && i + 1 < argc) {
      a.json = argv[++i];
    } else if (s == "-h" || s == "--help") {
      a.help = true;
    } else if (s.rfind("--", 0) == 0) {
      a.ok = false;
    } else {
      a.files.push_back(s);
    }
  }
  a.ok = a.ok && !a.help && !a.files.empty() && a.repeat >= 1;
  if (!a.ok) std::fprintf(stderr, "usage: %s %s\n", argv[0], usage);
  return a;
}

inline double median(std::vector<double> v) {
  std::sort(v.begin(), v.end());
  const std::size_t n = v.size();
  return n % 2 ? v[n / 2] : 0.5 * (v[n / 2 - 1] + v[n / 2]);
}

// A JSON string literal of s (quotes, backslashes and control characters escaped).
inline std::string json_string(const std::string& s) {
  std::string r = "\"";
  for (const unsigned char ch : s) {
    if (ch == '"' || ch == '\\') {
      r += '\\';
      r += char(ch);
    } else if (ch < 0x20) {
      char b[8];
      std::snprintf(b, sizeof b, "\\u%04x", ch);
      r += b;
    } else {
      r += char(ch);
    }
  }
  return r + "\"";
}

// A JSON number, or null for NaN and infinities (which JSON cannot hold).
inline std::string json_number(double v) {
  if (!std::isfinite(v)) return "null";
  char b[32];
  std::snprintf(b, sizeof b, "%.9g", v);
  return b;
}

}  // namespace dnb::device_tool
