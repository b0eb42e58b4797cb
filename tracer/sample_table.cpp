// rt::SampleTable::prepare (tracer/math.h): the sequence dimensions of a run of a pixel's
// samples, the same integer operations as Sampler::dimension_value, arranged so that the
// compiler vectorises them: one loop per pair of dimensions over the run's samples, eight
// consecutive samples (one of each group) to a vector, each lane with its group's scrambles.
#include <algorithm>

#include "tracer/math.h"

namespace dnb::rt {

void SampleTable::prepare(std::uint64_t seed, std::uint64_t pixel, std::uint64_t begin, std::uint64_t end) {
  constexpr int G = Sampler::kGroups;
  static_assert(G == 8, "a vector of eight lanes holds one sample of each group");
  begin_ = begin;
  const std::uint64_t pixel_key = Sampler::pixel_key(seed, pixel);
  for (int g = 0; g < G; ++g) group_key_[g] = Sampler::group_key(pixel_key, g);
  const int n = int(std::min<std::uint64_t>(end - begin, kMaxSamples) + G - 1) / G * G;  // whole vectors
  // Lane l of a vector holds sample begin + 8 v + l: group (begin + l) mod 8, point index
  // (begin + l) / 8 + v.
  alignas(32) std::uint32_t first[G];
  for (int l = 0; l < G; ++l) first[l] = std::uint32_t((begin + std::uint64_t(l)) / G);
  // sobol_dim1_reversed(j) without its data-dependent loop: j < 2^bits when the point index is
  // (the shuffle keeps every aligned block of 2^k indices in itself), so `bits` direction numbers
  // suffice.
  const std::uint32_t last = std::uint32_t((begin + std::uint64_t(n) - 1) / G);
  int bits = 0;
  while (bits < 32 && (last >> bits) != 0) ++bits;
  alignas(32) std::uint64_t lane_key[G];
  for (int l = 0; l < G; ++l) lane_key[l] = group_key_[(begin + std::uint64_t(l)) % G];
  for (int pair = 0; pair < dims::kSequenceDims / 2; ++pair) {
    if (Sampler::is_hashed(std::uint32_t(2 * pair))) continue;  // the roulette pairs: never read from here
    // The lanes' scrambles for this pair (a loop of 64-bit hashes the compiler vectorises too).
    alignas(32) std::uint32_t s1[G], s2[G], s3[G], shift0[G];
    for (int l = 0; l < G; ++l) {
      const Sampler::PairScrambles p = Sampler::pair_scrambles(lane_key[l], std::uint32_t(pair));
      s1[l] = p.s1;
      s2[l] = p.s2;
      s3[l] = p.s3;
      shift0[l] = laine_karras_permutation(0, p.s1);
    }
    float* xs = &values_[std::size_t(2 * pair) * kMaxSamples];
    float* ys = &values_[std::size_t(2 * pair + 1) * kMaxSamples];
    for (int v = 0; v < n; v += G) {
      const std::uint32_t vi = std::uint32_t(v / G);
      alignas(32) std::uint32_t j[G], d1[G];
      for (int l = 0; l < G; ++l) {
        j[l] = reverse_bits(laine_karras_permutation(reverse_bits(first[l] + vi), s1[l]) ^ shift0[l]);
        d1[l] = 0;
      }
      std::uint32_t w = 1;
      for (int b = 0; b < bits; ++b, w ^= w << 1)
        for (int l = 0; l < G; ++l) d1[l] ^= (0u - ((j[l] >> b) & 1u)) & w;
      for (int l = 0; l < G; ++l) {
        xs[v + l] = u32_to_unit(reverse_bits(laine_karras_permutation(j[l], s2[l])));
        ys[v + l] = u32_to_unit(reverse_bits(laine_karras_permutation(d1[l], s3[l])));
      }
    }
  }
}

}  // namespace dnb::rt
