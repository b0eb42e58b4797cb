#include "experiment/provenance.h"

#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <iterator>
#include <thread>

#include <spdlog/spdlog.h>

#include "core/build_info.h"
#include "core/hash.h"
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

namespace {

// The code-ids file beside the running program, read once; nothing when there is none for it.
const std::optional<CodeIds>& program_code_ids() {
  static const std::optional<CodeIds> ids = [] {
    std::error_code ec;
    const auto exe = std::filesystem::read_symlink("/proc/self/exe", ec);
    if (ec) return std::optional<CodeIds>{};
    return read_code_ids(exe.string() + ".code-ids.json", build_id());
  }();
  return ids;
}

bool is_sha256_hex(const nlohmann::json& v) {
  if (!v.is_string()) return false;
  const auto& s = v.get_ref<const std::string&>();
  return s.size() == 64 && s.find_first_not_of("0123456789abcdef") == std::string::npos;
}

}  // namespace

std::optional<CodeIds> read_code_ids(const std::string& file, const std::string& program_sha256) {
  std::ifstream in(file);
  if (!in) return std::nullopt;
  // A missing or foreign file is normal (a copied program); a malformed one is said, since the
  // build wrote it: either way every cell falls back to the whole program's hash, which is safe.
  const auto doc = nlohmann::json::parse(in, nullptr, /*allow_exceptions=*/false);
  const auto malformed = [&](const char* why) {
    spdlog::warn("{}: {}; finished cells are reused only by this very program", file, why);
    return std::nullopt;
  };
  try {
    if (!doc.is_object() || doc.value("format", "") != "denoisebench-code-ids" || doc.value("version", 0) != 1)
      return malformed("not a denoisebench-code-ids file of version 1");
    if (doc.value("program_sha256", "") != program_sha256) return std::nullopt;  // another build's
    if (!is_sha256_hex(doc.value("shared", nlohmann::json()))) return malformed("'shared' is not a SHA-256");
    CodeIds ids;
    ids.shared = doc["shared"];
    const auto methods = doc.value("methods", nlohmann::json::object());
    if (!methods.is_object()) return malformed("'methods' is not an object");
    for (const auto& [name, id] : methods.items()) {
      if (!is_sha256_hex(id)) return malformed("a method's identity is not a SHA-256");
      ids.methods[name] = id;
    }
    return ids;
  } catch (const nlohmann::json::exception&) {  // a key of the wrong type (value() throws)
    return malformed("a key has the wrong type");
  }
}

std::string method_code_id(const std::string& method) {
  const auto& ids = program_code_ids();
  if (!ids) return build_id();
  const auto it = ids->methods.find(method);
  return it != ids->methods.end() ? it->second : ids->shared;
}

std::string shared_code_id() {
  const auto& ids = program_code_ids();
  return ids ? ids->shared : build_id();
}

nlohmann::json build_info() {
  return {{"version", build_version()},
          {"git_revision", build_revision()},
          {"build_type", build_type()},
          {"compiler", build_compiler()},
          {"tracer_version", kTracerVersion},
          {"build_id", build_id()},
          // How finished cells are matched to code: per method (the build's code-ids file) or by
          // the whole program (without one).
          {"code_identity", program_code_ids() ? "per-method" : "program"}};
}

}  // namespace dnb::experiment
