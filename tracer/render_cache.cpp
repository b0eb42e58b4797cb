#include "tracer/render_cache.h"

#include <fcntl.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cstdlib>
#include <filesystem>

#include <fmt/format.h>
#include <nlohmann/json.hpp>
#include <spdlog/spdlog.h>

#include "core/env.h"
#include "core/atomic_file.h"
#include "core/errors.h"
#include "core/exr_io.h"
#include "core/hash.h"

namespace dnb {
namespace fs = std::filesystem;

namespace {

constexpr const char* kManifest = "MANIFEST.json";
constexpr const char* kFormat = "denoisebench-cache-1";
std::atomic<int> g_staging_counter{0};

// fsync a file or folder so that a crash after the rename cannot expose lost data.
void sync_path(const fs::path& p, bool directory) {
  int fd = ::open(p.c_str(), directory ? (O_RDONLY | O_DIRECTORY) : O_RDONLY);
  if (fd < 0) return;
  ::fsync(fd);
  ::close(fd);
}

std::string unique_sibling(const fs::path& dir, const std::string& prefix, const std::string& digest) {
  return (dir / fmt::format(".{}-{}-{}-{}", prefix, digest.substr(0, 16), ::getpid(), g_staging_counter++)).string();
}

// Staging and trash folders left by a process killed while storing: removed once a day old (a
// younger one may belong to a store in progress in another process).
void remove_stale_staging(const fs::path& kind_dir) {
  std::error_code ec;
  const auto now = fs::file_time_type::clock::now();
  for (auto it = fs::directory_iterator(kind_dir, ec); !ec && it != fs::directory_iterator(); it.increment(ec)) {
    const std::string name = it->path().filename().string();
    if (name.rfind(".staging-", 0) != 0 && name.rfind(".trash-", 0) != 0) continue;
    std::error_code e;
    auto t = fs::last_write_time(it->path(), e);
    if (!e && now - t > std::chrono::hours(24)) fs::remove_all(it->path(), e);
  }
}

}  // namespace

// ---------------------------------------------------------------------------------------------
// CacheKey

CacheKey::CacheKey(std::string kind) : kind_(std::move(kind)) {
  if (kind_.empty() || kind_.find_first_of("/\\\n.") != std::string::npos)
    throw WorkError(fmt::format("cache kind '{}' must be a plain non-empty name", kind_));
}

CacheKey& CacheKey::add(const std::string& name, const std::string& value) {
  if (name.empty() || name.find_first_of("=\n") != std::string::npos || value.find('\n') != std::string::npos)
    throw WorkError(fmt::format("cache key part '{}' must be a name without '=' or newlines", name));
  for (auto& [n, v] : parts_)
    if (n == name) throw WorkError(fmt::format("cache key part '{}' added twice", name));
  parts_.emplace_back(name, value);
  return *this;
}

CacheKey& CacheKey::add(const std::string& name, std::int64_t value) { return add(name, std::to_string(value)); }
CacheKey& CacheKey::add(const std::string& name, std::uint64_t value) { return add(name, std::to_string(value)); }
CacheKey& CacheKey::add(const std::string& name, double value) { return add(name, fmt::format("{:.17g}", value)); }

std::string CacheKey::canonical() const {
  std::string s = kind_ + "\n";
  for (auto& [n, v] : parts_) s += n + "=" + v + "\n";
  return s;
}

std::string CacheKey::digest() const { return sha256_hex(canonical()); }

// ---------------------------------------------------------------------------------------------
// Cache

std::string Cache::default_dir() {
  if (const char* d = env::get("CACHE"); d && *d) return d;
  if (const char* x = std::getenv("XDG_CACHE_HOME"); x && *x) return (fs::path(x) / "denoisebench").string();
  if (const char* h = std::getenv("HOME"); h && *h) return (fs::path(h) / ".cache" / "denoisebench").string();
  return (fs::path(".cache") / "denoisebench").string();
}

Cache::Cache(std::string dir) : dir_(std::move(dir)) {
  if (dir_.empty()) throw InputError("the cache folder must not be empty");
}

std::string Cache::entry_dir(const CacheKey& key) const {
  return (fs::path(dir_) / key.kind() / key.digest()).string();
}

std::optional<std::string> verify_cache_entry(const std::string& entry_dir, const CacheKey& key,
                                              std::vector<std::string>* files_out) {
  fs::path dir(entry_dir);
  fs::path manifest_path = dir / kManifest;
  std::error_code ec;
  if (!fs::is_regular_file(manifest_path, ec)) return std::string("its manifest is missing");
  nlohmann::json m;
  try {
    m = nlohmann::json::parse(read_text_file(manifest_path.string()));
  } catch (const std::exception& e) {
    return fmt::format("its manifest is unreadable ({})", e.what());
  }
  try {
    if (m.at("format").get<std::string>() != kFormat) return std::string("its manifest has an unknown format");
    if (m.at("kind").get<std::string>() != key.kind() || m.at("digest").get<std::string>() != key.digest())
      return std::string("its manifest belongs to another key");
    std::vector<std::pair<std::string, std::string>> parts;
    for (auto& p : m.at("parts")) parts.emplace_back(p.at(0).get<std::string>(), p.at(1).get<std::string>());
    if (parts != key.parts()) return std::string("its manifest records other key parts");

    std::vector<std::string> listed;
    for (auto& f : m.at("files")) listed.push_back(f.at("name").get<std::string>());
    std::sort(listed.begin(), listed.end());
    std::vector<std::string> present;
    for (auto& e : fs::directory_iterator(dir))
      if (e.path().filename() != kManifest) present.push_back(e.path().filename().string());
    std::sort(present.begin(), present.end());
    if (present != listed)
      return fmt::format("its files ({}) differ from the manifest's ({})", fmt::join(present, ", "),
                         fmt::join(listed, ", "));

    for (auto& f : m.at("files")) {
      std::string name = f.at("name").get<std::string>();
      fs::path p = dir / name;
      auto size = fs::file_size(p, ec);
      if (ec) return fmt::format("'{}' cannot be read: {}", name, ec.message());
      if (size != f.at("size").get<std::uintmax_t>())
        return fmt::format("'{}' has {} bytes, the manifest says {} (truncated?)", name, size,
                           f.at("size").get<std::uintmax_t>());
      if (sha256_file(p.string()) != f.at("sha256").get<std::string>())
        return fmt::format("'{}' does not match its SHA-256 checksum (corrupted)", name);
    }
    if (files_out) *files_out = listed;
  } catch (const std::exception& e) {
    return fmt::format("its manifest is malformed ({})", e.what());
  }
  return std::nullopt;
}

std::optional<CacheEntry> Cache::lookup(const CacheKey& key) {
  std::string dir = entry_dir(key);
  std::error_code ec;
  if (!fs::exists(dir, ec)) {
    ++stats_.misses;
    spdlog::debug("cache miss: {} {}", key.kind(), key.digest());
    return std::nullopt;
  }
  CacheEntry entry{dir, {}};
  if (auto damage = verify_cache_entry(dir, key, &entry.files)) {
    ++stats_.misses;
    ++stats_.corrupt;
    spdlog::warn("cache entry '{}' is damaged: {}; removing it and rebuilding", dir, *damage);
    fs::remove_all(dir, ec);
    return std::nullopt;
  }
  ++stats_.hits;
  spdlog::debug("cache hit: {} {}", key.kind(), key.digest());
  return entry;
}

CacheEntry Cache::store(const CacheKey& key, const std::function<void(const std::string&)>& write) {
  fs::path kind_dir = fs::path(dir_) / key.kind();
  std::error_code ec;
  fs::create_directories(kind_dir, ec);
  if (ec) throw WorkError(fmt::format("cannot create cache folder '{}': {}", kind_dir.string(), ec.message()));
  remove_stale_staging(kind_dir);
  std::string digest = key.digest();
  fs::path staging = unique_sibling(kind_dir, "staging", digest);
  fs::create_directory(staging, ec);
  if (ec) throw WorkError(fmt::format("cannot create '{}': {}", staging.string(), ec.message()));
  // Removes the staging folder if anything below throws.
  struct Cleanup {
    fs::path p;
    bool armed = true;
    ~Cleanup() {
      std::error_code e;
      if (armed) fs::remove_all(p, e);
    }
  } cleanup{staging};

  write(staging.string());

  nlohmann::json m;
  m["format"] = kFormat;
  m["kind"] = key.kind();
  m["digest"] = digest;
  m["parts"] = nlohmann::json::array();
  for (auto& [n, v] : key.parts()) m["parts"].push_back({n, v});
  m["files"] = nlohmann::json::array();
  CacheEntry entry{entry_dir(key), {}};
  std::vector<fs::path> paths;
  for (auto& e : fs::directory_iterator(staging)) paths.push_back(e.path());
  std::sort(paths.begin(), paths.end());
  for (auto& p : paths) {
    if (!fs::is_regular_file(p) || p.filename() == kManifest)
      throw WorkError(fmt::format("cache entry writer left '{}', which is not a plain product file", p.string()));
    sync_path(p, false);
    m["files"].push_back({{"name", p.filename().string()},
                          {"size", fs::file_size(p)},
                          {"sha256", sha256_file(p.string())}});
    entry.files.push_back(p.filename().string());
  }
  write_text_atomic((staging / kManifest).string(), m.dump(2) + "\n");
  sync_path(staging, true);

  // Replace an older entry of the key: move it aside first (rename over a non-empty folder is
  // not allowed), then move the new one into place.
  fs::path final_dir(entry.dir);
  if (fs::exists(final_dir, ec)) {
    fs::path trash = unique_sibling(kind_dir, "trash", digest);
    fs::rename(final_dir, trash, ec);
    fs::remove_all(trash, ec);
  }
  fs::rename(staging, final_dir, ec);
  if (ec) {
    // Another process stored the same key at the same moment: use its entry if intact.
    if (!verify_cache_entry(final_dir.string(), key)) return entry;
    throw WorkError(fmt::format("cannot move cache entry into '{}': {}", final_dir.string(), ec.message()));
  }
  cleanup.armed = false;
  sync_path(kind_dir, true);
  ++stats_.stores;
  spdlog::debug("cache store: {} {}", key.kind(), digest);
  return entry;
}

void Cache::remove(const CacheKey& key) {
  std::error_code ec;
  fs::remove_all(entry_dir(key), ec);
}

AovFrame cached_frame(Cache& cache, const CacheKey& key, const std::function<AovFrame()>& render, bool* hit) {
  if (auto entry = cache.lookup(key)) {
    if (hit) *hit = true;
    return read_frame(entry->file("frame.exr"));
  }
  if (hit) *hit = false;
  AovFrame frame = render();
  cache.store(key, [&](const std::string& dir) { write_frame(frame, dir + "/frame.exr"); });
  return frame;
}

}  // namespace dnb
