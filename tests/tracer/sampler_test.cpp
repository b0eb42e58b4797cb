// rt::Sampler's sequence mode (tracer/math.h): the Sobol' points against Boost's generator, the
// nets that every power-of-two prefix of a group forms in every pair of dimensions (what makes
// the samples nested in the spp), the independent mode left as it was; and the progressive
// render that the nesting allows.
#include <gtest/gtest.h>

#include <boost/random/sobol.hpp>
#include <cstdint>
#include <set>
#include <utility>
#include <vector>

#include "core/errors.h"
#include "thread_count.h"
#include "tracer/math.h"
#include "tracer/render.h"
#include "tracer/scene_loader.h"

namespace dnb::rt {
namespace {

// Boost's Sobol' engine (Joe and Kuo's direction numbers) in two dimensions: its n-th point is
// point gray(n + 1) of the sequence in index order (Boost skips the point at 0 and steps in Gray
// code order), as 32-bit fractions.
TEST(Sampler, SobolsFirstTwoDimensionsAreBoosts) {
  boost::random::sobol_engine<std::uint32_t, 32> boost_sobol(2);
  for (std::uint32_t n = 0; n < 4096; ++n) {
    const std::uint32_t i = (n + 1) ^ ((n + 1) >> 1);
    const std::uint32_t x = boost_sobol(), y = boost_sobol();
    ASSERT_EQ(sobol_dim0(i), x) << "point " << i;
    ASSERT_EQ(sobol_dim1(i), y) << "point " << i;
    ASSERT_EQ(sobol_dim1_reversed(i), reverse_bits(y)) << "point " << i;
  }
}

TEST(Sampler, NestedUniformScrambleIsAPermutationThatKeepsLeadingDigits) {
  // Owen scrambling maps x's top k bits through a permutation that depends only on them: points
  // in one dyadic interval [a / 2^k, (a + 1) / 2^k) land together in one such interval.
  const std::uint32_t seed = 0x1234567u;
  for (int k = 1; k <= 6; ++k) {
    const int shift = 32 - k;
    std::set<std::uint32_t> images;
    for (std::uint32_t a = 0; a < (1u << k); ++a) {
      const std::uint32_t lo = a << shift;
      const std::uint32_t top = nested_uniform_scramble(lo, seed) >> shift;
      for (std::uint32_t r : {1u, 7u, (1u << shift) - 1})  // other points of the same interval
        ASSERT_EQ(nested_uniform_scramble(lo | r, seed) >> shift, top) << "k " << k << " a " << a;
      images.insert(top);
    }
    EXPECT_EQ(images.size(), std::size_t(1) << k) << "not a permutation of the intervals at k " << k;
  }
}

// For sample groups g of one pixel: are its first 2^m points a (0, m, 2)-net in the pair of
// dimensions (d, d + 1), i.e. does every elementary box of area 2^-m hold exactly one point?
bool prefix_is_net(std::uint64_t seed, std::uint64_t pixel, int g, int m, int vertex) {
  std::vector<std::pair<float, float>> pts;
  for (int i = 0; i < (1 << m); ++i) {
    Sampler s = Sampler::pixel_sample(seed, pixel, std::uint64_t(i) * Sampler::kGroups + std::uint64_t(g));
    if (vertex == 0) {
      const float u = s.next(), v = s.next();
      pts.emplace_back(u, v);
    } else {
      s.start_vertex(vertex);
      pts.emplace_back(s.at(dims::kBsdfU), s.at(dims::kBsdfV));
    }
  }
  for (int kx = 0; kx <= m; ++kx) {
    const int ky = m - kx;
    std::set<std::pair<int, int>> boxes;
    for (auto [u, v] : pts) boxes.emplace(int(u * float(1 << kx)), int(v * float(1 << ky)));
    if (boxes.size() != pts.size()) return false;
  }
  return true;
}

TEST(Sampler, EveryPowerOfTwoPrefixOfAGroupIsANetInEachPairOfDimensions) {
  for (int m = 1; m <= 8; ++m)
    for (int g : {0, 5})
      for (int vertex : {0, 1, int(dims::kSequenceVertices)}) EXPECT_TRUE(prefix_is_net(42, 1234 + std::uint64_t(m), g, m, vertex))
          << "m " << m << " group " << g << " vertex " << vertex;
}

TEST(Sampler, GroupsAndPixelsHaveTheirOwnScrambles) {
  auto first = [](std::uint64_t pixel, int s) {
    Sampler a = Sampler::pixel_sample(7, pixel, std::uint64_t(s));
    return a.next();
  };
  EXPECT_NE(first(0, 0), first(0, 1));  // group 0 and group 1: independent scrambles
  EXPECT_NE(first(0, 0), first(1, 0));  // pixel 0 and pixel 1
  // The same (seed, pixel, sample) is the same point, whatever was asked before.
  Sampler a = Sampler::pixel_sample(7, 3, 21), b = Sampler::pixel_sample(7, 3, 21);
  a.start_vertex(2);
  const float bsdf = a.at(dims::kBsdfU);
  b.next();
  b.next();
  b.start_vertex(1);
  b.at(dims::kLightU);
  b.start_vertex(2);
  EXPECT_EQ(b.at(dims::kBsdfU), bsdf);
}

// Every number a path can read (the sequence dimensions from the table, the hashed ones past
// them) equals pixel_sample's, for runs that start and end inside a group's rows, at small and
// large point indices (a 16M-spp reference reaches index 2^21), and over several tables' worth.
TEST(Sampler, SampleTableGivesPixelSamplesNumbers) {
  SampleTable table;
  const std::pair<std::uint64_t, std::uint64_t> runs[] = {
      {0, 256}, {0, 1}, {3, 200}, {4000, 4256}, {16380, 16390}, {(1u << 24) - 77, 1u << 24}, {255, 1027}};
  for (const auto& [begin, end] : runs)
    for (std::uint64_t pixel : {std::uint64_t(0), std::uint64_t(98765)}) {
      std::uint64_t visited = 0;
      for_pixel_samples(table, 11, pixel, begin, end, [&](std::uint64_t s, Sampler t) {
        ASSERT_EQ(s, begin + visited) << "samples out of order";
        ++visited;
        Sampler p = Sampler::pixel_sample(11, pixel, s);
        EXPECT_EQ(t.next(), p.next()) << "film x, sample " << s;
        EXPECT_EQ(t.next(), p.next()) << "film y, sample " << s;
        for (int v = 1; v <= int(dims::kSequenceVertices) + 1; ++v) {
          t.start_vertex(v);
          p.start_vertex(v);
          for (int slot = 0; slot < dims::kVertexDims; ++slot)
            ASSERT_EQ(t.at(slot), p.at(slot)) << "sample " << s << " vertex " << v << " slot " << slot;
        }
      });
      EXPECT_EQ(visited, end - begin);
    }
}

TEST(Sampler, IndependentModeReadsItsNumbersInCallOrder) {
  // The irradiance cache's records use it: at() and start_vertex() do not change its numbers.
  Sampler a(5, 6, 7), b(5, 6, 7);
  b.start_vertex(3);
  EXPECT_EQ(a.next(), b.at(dims::kBsdfV));
  EXPECT_EQ(a.next(), b.at(dims::kLightChoice));
  EXPECT_EQ(a.dimension(), b.dimension());
}


}  // namespace
}  // namespace dnb::rt

namespace dnb {
namespace {

// The nested samples in a render (tracer/render.h): the colour of the first N samples of one
// progressive render is, bit for bit, render_frame's colour layer at spp N, whatever the
// threads; what the experiment's plain curve and `render --spp N` rely on.
TEST(ProgressiveRender, EachPrefixIsTheRenderOfItsSpp) {
  auto scene = load_scene("cornell-box");
  RenderSettings s;
  s.width = 24;
  s.height = 18;
  s.seed = 11;
  s.spp = 40;
  s.threads = 2;
  const std::vector<int> prefixes = {1, 3, 16, 40};
  std::vector<Image> images;
  std::vector<double> seconds;
  // Two threads really run (tests/thread_count.h), against one below.
  ASSERT_GT(test::run_on_threads(2, [&] {
              render_color_prefixes(*scene, s, prefixes, [&](std::size_t k, Image image, double t) {
                EXPECT_EQ(k, images.size());
                images.push_back(std::move(image));
                seconds.push_back(t);
              });
            }),
            1);
  ASSERT_EQ(images.size(), prefixes.size());
  for (std::size_t k = 0; k < prefixes.size(); ++k) {
    RenderSettings one = s;
    one.spp = prefixes[k];
    one.threads = 1;
    const AovFrame f = render_frame(*scene, one);
    EXPECT_TRUE(images[k] == f.layer(layer::kColor)) << "prefix " << prefixes[k];
    if (k > 0) {
      EXPECT_GE(seconds[k], seconds[k - 1]);
      EXPECT_FALSE(images[k] == images[k - 1]);
    }
  }
  EXPECT_THROW(render_color_prefixes(*scene, s, {4, 2}, [](std::size_t, Image, double) {}), InputError);
  EXPECT_THROW(render_color_prefixes(*scene, s, {41}, [](std::size_t, Image, double) {}), InputError);
}

}  // namespace
}  // namespace dnb
