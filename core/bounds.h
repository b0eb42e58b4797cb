// The bounds on every number a user types: command-line options (apps/args.h turns a Bound into
// a CLI11 check) and config or scene keys (ConfigTable::get with a Bound, core/config.h). One
// table, so `render --threads`, `reference --threads` and a config's `threads` accept the same
// values, and every bound says why it holds.
//
//   int spp = t.get("spp", 256, bounds::kSpp);   // InputError "file:line: key 'spp': ..." otherwise
#pragma once

#include <cstdint>
#include <limits>
#include <string>

#include "core/image.h"

namespace dnb {

// Inclusive integer range and the reason for it (shown in the error message).
struct Bound {
  std::int64_t min, max;
  const char* why;
};

// Inclusive range of real numbers; non-finite values are always refused.
struct RealBound {
  double min, max;
  const char* why;
  bool min_exclusive = false;  // (min, max] instead of [min, max]
};

namespace bounds {
inline constexpr Bound kSide{1, Image::kMaxSide, "image planes are addressed with 32-bit indices"};
inline constexpr std::int64_t kMaxPixels = Image::kMaxPixels;  // width * height, same reason
inline constexpr Bound kSpp{1, 1 << 24, "2^24 samples per pixel is far beyond a converged reference"};
inline constexpr Bound kBlockSpp{1, 1 << 24, "a block is at most a whole reference of 2^24 samples"};
inline constexpr Bound kThreads{0, 1024,
                                "0 means all cores; more worker threads than cores only cost a stack and "
                                "scratch buffers each"};
inline constexpr Bound kSeed{0, std::numeric_limits<std::int64_t>::max(), "seeds are non-negative integers"};
inline constexpr Bound kMaxDepth{1, 1024, "path length in segments; longer paths carry no measurable light"};
inline constexpr Bound kRepeats{1, 1000, "timing repeats of one method on one frame"};
// A sphere of N segments has N^2 triangles: 1024 segments make 1M triangles, some 300 MB of
// mesh and BVH and a second to build (2048 took 1.2 GB and 5 s).
inline constexpr Bound kSegments{3, 1024, "a sphere of N segments has N^2 triangles (memory)"};
inline constexpr Bound kArchSegments{2, 1024, "the same bound as a sphere's"};
inline constexpr Bound kObjectCopies{1, 10000, "copies of one object (`repeat`)"};
// Triangles of one mesh: its 3 vertex indices per triangle are 32-bit.
inline constexpr std::int64_t kMaxTriangles = std::int64_t(1) << 28;
// An image texture is held as float RGB: 2^26 texels (8192 x 8192) take 768 MB.
inline constexpr std::int64_t kMaxTexels = std::int64_t(1) << 26;
inline constexpr Bound kTextureOctaves{1, 24, "noise octaves beyond 24 are below float precision"};
// Scene coordinates and sizes: beyond this, float positions have less than a millimetre.
inline constexpr RealBound kLength{0, 1e6, "scene lengths beyond 1e6 lose float precision", true};
inline constexpr RealBound kCoordinate{-1e6, 1e6, "scene coordinates beyond 1e6 lose float precision"};
// Radiance: finite, non-negative, and far below float's 3.4e38 so that sums over a pixel stay finite.
inline constexpr RealBound kRadiance{0, 1e30, "emission is non-negative radiance; above 1e30 sums overflow float"};
inline constexpr RealBound kReflectance{0, 1, "albedo and tint are reflectances in [0, 1]"};
}  // namespace bounds

// "expected MIN..MAX (WHY), got VALUE", for messages that prefix the file, key or option.
std::string bound_violation(const Bound& b, const std::string& got);
std::string bound_violation(const RealBound& b, const std::string& got);
bool within(std::int64_t v, const Bound& b);
bool within(double v, const RealBound& b);
// Throws InputError "WHERE: expected ..." when v is outside b.
void check_bound(std::int64_t v, const Bound& b, const std::string& where);
void check_bound(double v, const RealBound& b, const std::string& where);

}  // namespace dnb
