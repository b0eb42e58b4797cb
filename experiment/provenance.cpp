#include "experiment/provenance.h"

#include <unistd.h>

#include <fstream>
#include <iterator>
#include <thread>

#include "core/hash.h"
#include "core/version.h"
#include "tracer/render.h"  // kTracerVersion

namespace dnb::experiment {

nlohmann::json machine_info() {
  nlohmann::json m;
  char host[256] = {};
  gethostname(host, sizeof host - 1);
  m["hostname"] = host;
  m["hardware_threads"] = std::thread::hardware_concurrency();
  std::ifstream cpu("/proc/cpuinfo");
  for (std::string line; std::getline(cpu, line);)
    if (line.rfind("model name", 0) == 0) {
      m["cpu"] = line.substr(line.find(':') + 2);
      break;
    }
  return m;
}

const std::string& build_id() {
  static const std::string id = [] {
    std::ifstream in("/proc/self/exe", std::ios::binary);
    std::string bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    return bytes.empty() ? std::string("unknown") : sha256_hex(bytes);
  }();
  return id;
}

nlohmann::json build_info() {
  return {{"version", DNB_VERSION}, {"git_revision", DNB_GIT_REVISION}, {"build_type", DNB_BUILD_TYPE},
          {"compiler", DNB_COMPILER}, {"tracer_version", kTracerVersion}, {"build_id", build_id()}};
}

}  // namespace dnb::experiment
