// A content-keyed on-disk cache of expensive render products (converged references, input
// AOV frames), shared by `denoisebench reference` and `denoisebench run`.
//
// A key is a kind ("reference", "frame", ...) plus named parts, each the value or content hash
// of something that determines the product (scene_content_hash, size, spp, seed,
// kTracerVersion, ...). Its digest (SHA-256 of the canonical text of the parts) names the
// entry: a folder DIR/<kind>/<digest>/ holding the product's files and a MANIFEST.json with
// the key's parts and the size and SHA-256 of every file.
//
// Entries are stored atomically (written into a staging folder, manifest last, renamed into
// place), and every lookup verifies the manifest and every file's size and checksum: a
// corrupted or truncated entry is reported, removed and treated as missing, never used.
//
//   Cache cache(Cache::default_dir());
//   CacheKey key("frame");
//   key.add("scene", scene_content_hash(scene)).add("spp", 16).add("seed", 1);
//   AovFrame f = cached_frame(cache, key, [&] { return render_frame(scene, settings); });
#pragma once

#include <cstdint>
#include <functional>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "core/aov_frame.h"
#include "core/hash.h"  // sha256_hex, sha256_file: declared here before they moved to core/

namespace dnb {

class CacheKey {
 public:
  explicit CacheKey(std::string kind);
  // Parts are kept in the order added; the same parts in the same order give the same digest.
  // A name may appear once (a second add of the same name is a programming error: WorkError).
  CacheKey& add(const std::string& name, const std::string& value);
  CacheKey& add(const std::string& name, const char* value) { return add(name, std::string(value)); }
  CacheKey& add(const std::string& name, std::int64_t value);
  CacheKey& add(const std::string& name, int value) { return add(name, std::int64_t(value)); }
  CacheKey& add(const std::string& name, std::uint64_t value);
  // Doubles are written with 17 significant digits (round-trip exact).
  CacheKey& add(const std::string& name, double value);

  const std::string& kind() const { return kind_; }
  const std::vector<std::pair<std::string, std::string>>& parts() const { return parts_; }
  // "kind\nname=value\n..." : what the digest hashes, and what the manifest records.
  std::string canonical() const;
  std::string digest() const;  // SHA-256 hex of canonical()

 private:
  std::string kind_;
  std::vector<std::pair<std::string, std::string>> parts_;
};

// A verified entry: its folder and file names.
struct CacheEntry {
  std::string dir;
  std::vector<std::string> files;  // names relative to dir, sorted
  std::string file(const std::string& name) const { return dir + "/" + name; }
};

struct CacheStats {
  std::int64_t hits = 0;
  std::int64_t misses = 0;   // includes corrupt entries
  std::int64_t corrupt = 0;  // entries found damaged and removed
  std::int64_t stores = 0;
};

class Cache {
 public:
  // $DENOISEBENCH_CACHE, else $XDG_CACHE_HOME/denoisebench, else ~/.cache/denoisebench, else
  // ./.cache/denoisebench.
  static std::string default_dir();

  explicit Cache(std::string dir);
  const std::string& dir() const { return dir_; }

  // The folder an entry of this key lives in (whether it exists or not).
  std::string entry_dir(const CacheKey& key) const;

  // The verified entry, or nothing when it is absent or damaged (a damaged entry is logged as
  // a warning naming what is wrong, and removed so that it is rebuilt).
  std::optional<CacheEntry> lookup(const CacheKey& key);

  // Stores a new entry: `write` fills the staging folder it is given with the product's files
  // (any names, no sub-folders); then the manifest is written and the folder renamed into
  // place, replacing an older entry of the same key. If `write` throws, nothing is stored.
  CacheEntry store(const CacheKey& key, const std::function<void(const std::string& staging_dir)>& write);

  // Removes an entry if present (e.g. to force a render).
  void remove(const CacheKey& key);

  const CacheStats& stats() const { return stats_; }

 private:
  std::string dir_;
  CacheStats stats_;
};

// Checks an entry folder against its manifest; returns the reason it is damaged, or nothing
// when it is intact. Exposed for tests and for `denoisebench` diagnostics.
std::optional<std::string> verify_cache_entry(const std::string& entry_dir, const CacheKey& key,
                                              std::vector<std::string>* files = nullptr);

// The input-frame cache of the experiment runner: the AOV frame of `key` (frame.exr and, when
// the frame has edge sub-pixels, its deep edge file), read from the cache when present and
// intact, else produced by `render`, stored and returned. `hit` (optional) says which.
AovFrame cached_frame(Cache& cache, const CacheKey& key, const std::function<AovFrame()>& render,
                      bool* hit = nullptr);

}  // namespace dnb
