// `denoisebench metrics` as a scorer: many images in one call, CSV rows appended, thresholds as a
// CI gate, error maps, --layer, and 8-bit PNG inputs decoded from sRGB.
#include <cmath>
#include <fstream>

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <OpenImageIO/imageio.h>
#include <nlohmann/json.hpp>

#include "core/exr_io.h"
#include "core/csv.h"
#include "test_util.h"

namespace dnb {
namespace {
using ::testing::HasSubstr;

Image gradient(int w, int h, float scale) {
  Image im(w, h, 3);
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x)
      for (int c = 0; c < 3; ++c) im.at(x, y, c) = scale * float(x + 2 * y + c + 1) / float(w + 2 * h + 3);
  return im;
}

std::vector<std::string> lines_of(const std::string& path) {
  std::ifstream f(path);
  std::vector<std::string> out;
  for (std::string l; std::getline(f, l);) out.push_back(l);
  return out;
}

TEST(MetricsScorer, SeveralImagesOneCsvRowEachAppendedOnASecondCall) {
  test::TempDir dir;
  write_rgb(gradient(16, 12, 1.0f), dir.file("ref.exr"));
  write_rgb(gradient(16, 12, 0.9f), dir.file("a.exr"));
  write_rgb(gradient(16, 12, 0.5f), dir.file("b.exr"));
  const std::string cmd = "metrics " + dir.file("a.exr") + " " + dir.file("b.exr") + " --ref " + dir.file("ref.exr") +
                          " --metric mse --metric flip --csv " + dir.file("s.csv");
  auto r = test::run_denoisebench(cmd);
  ASSERT_EQ(r.exit_code, 0) << r.output;
  auto rows = lines_of(dir.file("s.csv"));
  ASSERT_EQ(rows.size(), 3u);
  EXPECT_EQ(rows[0], "image,reference,mse,flip");
  const auto a = csv::split(rows[1]), b = csv::split(rows[2]);
  EXPECT_EQ(a[0], dir.file("a.exr"));
  EXPECT_EQ(b[0], dir.file("b.exr"));
  EXPECT_LT(std::stod(a[2]), std::stod(b[2]));  // 10% darker scores better than 50% darker
  EXPECT_LT(std::stod(a[3]), std::stod(b[3]));
  // The numbers are those of the one-image form, image by image.
  auto one = test::run_denoisebench_stdout("metrics --json " + dir.file("b.exr") + " " + dir.file("ref.exr"));
  ASSERT_EQ(one.exit_code, 0) << one.errors;
  EXPECT_DOUBLE_EQ(nlohmann::json::parse(one.output)["mse"].get<double>(), std::stod(b[2]));
  // A second call appends, with no second header.
  ASSERT_EQ(test::run_denoisebench(cmd).exit_code, 0);
  rows = lines_of(dir.file("s.csv"));
  ASSERT_EQ(rows.size(), 5u);
  EXPECT_EQ(rows[3], rows[1]);
  // Other columns into the same file would put numbers under the wrong names: refused, file kept.
  auto other = test::run_denoisebench("metrics " + dir.file("a.exr") + " --ref " + dir.file("ref.exr") +
                                      " --metric ssim --csv " + dir.file("s.csv"));
  EXPECT_EQ(other.exit_code, 2) << other.output;
  EXPECT_THAT(other.output, HasSubstr("image,reference,mse,flip"));
  EXPECT_EQ(lines_of(dir.file("s.csv")).size(), 5u);
}

TEST(MetricsScorer, FailAboveAndBelowGateTheExitStatus) {
  test::TempDir dir;
  write_rgb(gradient(16, 12, 1.0f), dir.file("ref.exr"));
  write_rgb(gradient(16, 12, 0.8f), dir.file("a.exr"));
  auto j = test::run_denoisebench_stdout("metrics --json " + dir.file("a.exr") + " " + dir.file("ref.exr"));
  ASSERT_EQ(j.exit_code, 0) << j.errors;
  const double mse = nlohmann::json::parse(j.output)["mse"].get<double>();
  ASSERT_GT(mse, 1.0);
  const std::string base = "metrics " + dir.file("a.exr") + " --ref " + dir.file("ref.exr");
  auto below = test::run_denoisebench(base + " --fail-above mse=" + std::to_string(mse * 1.01));
  EXPECT_EQ(below.exit_code, 0) << below.output;
  auto above = test::run_denoisebench(base + " --fail-above mse=" + std::to_string(mse * 0.99));
  EXPECT_EQ(above.exit_code, 1) << above.output;
  EXPECT_THAT(above.output, HasSubstr("a.exr"));
  EXPECT_THAT(above.output, HasSubstr("mse"));
  EXPECT_THAT(above.output, HasSubstr("is above"));
  auto ssim = test::run_denoisebench(base + " --fail-below ssim=0.999999");
  EXPECT_EQ(ssim.exit_code, 1) << ssim.output;
  EXPECT_THAT(ssim.output, HasSubstr("is below"));
  // A threshold on a metric that is not scored, or a malformed one, is bad usage.
  EXPECT_EQ(test::run_denoisebench(base + " --metric flip --fail-above mse=3").exit_code, 2);
  EXPECT_EQ(test::run_denoisebench(base + " --fail-above mse").exit_code, 2);
  EXPECT_EQ(test::run_denoisebench(base + " --fail-above msee=3").exit_code, 2);
}

void write_png8(const std::string& path, int w, int h, unsigned char value) {
  OIIO::ImageSpec spec(w, h, 3, OIIO::TypeDesc::UINT8);
  std::vector<unsigned char> px(std::size_t(w) * h * 3, value);
  auto out = OIIO::ImageOutput::create(path);
  ASSERT_TRUE(out && out->open(path, spec) && out->write_image(OIIO::TypeDesc::UINT8, px.data()) && out->close());
}

TEST(MetricsScorer, An8BitPngIsDecodedFromSrgbAndScoredOnThe8BitMetricsOnly) {
  test::TempDir dir;
  write_png8(dir.file("grey.png"), 16, 12, 128);
  // 128 in sRGB is linear ((128/255 + 0.055) / 1.055)^2.4 = 0.2158605.
  const float linear = float(std::pow((128.0 / 255.0 + 0.055) / 1.055, 2.4));
  write_rgb(Image(16, 12, 3, linear), dir.file("grey.exr"));
  write_rgb(gradient(16, 12, 0.5f), dir.file("ref.exr"));
  auto png = test::run_denoisebench_stdout("metrics --json " + dir.file("grey.png") + " " + dir.file("ref.exr"));
  auto exr = test::run_denoisebench_stdout("metrics --json " + dir.file("grey.exr") + " " + dir.file("ref.exr"));
  ASSERT_EQ(png.exit_code, 0) << png.errors;
  ASSERT_EQ(exr.exit_code, 0) << exr.errors;
  const auto p = nlohmann::json::parse(png.output), e = nlohmann::json::parse(exr.output);
  // The 8-bit metrics see the same integers; FLIP reads linear values, which differ by float
  // rounding (OIIO hands 128/255 over as a float before it is decoded): 1e-6 relative.
  for (const char* m : {"mse", "psnr", "ssim"}) EXPECT_DOUBLE_EQ(p[m].get<double>(), e[m].get<double>()) << m;
  EXPECT_NEAR(p["flip"].get<double>(), e["flip"].get<double>(), 1e-6 * e["flip"].get<double>());
  EXPECT_THAT(png.errors, HasSubstr("decoded to linear"));
  // The linear metrics are left out for the 8-bit file, and said so; asked for, they are refused
  // unless the user takes them knowingly.
  EXPECT_FALSE(p.contains("mse_hdr"));
  EXPECT_TRUE(e.contains("mse_hdr"));
  EXPECT_THAT(png.errors, HasSubstr("8-bit metrics only"));
  auto asked = test::run_denoisebench("metrics " + dir.file("grey.png") + " " + dir.file("ref.exr") + " --metric mse_hdr");
  EXPECT_EQ(asked.exit_code, 2) << asked.output;
  EXPECT_THAT(asked.output, HasSubstr("--linear-metrics-on-8bit"));
  auto knowing = test::run_denoisebench_stdout("metrics --json " + dir.file("grey.png") + " " + dir.file("ref.exr") +
                                               " --metric mse_hdr --linear-metrics-on-8bit");
  ASSERT_EQ(knowing.exit_code, 0) << knowing.errors;
  EXPECT_NEAR(nlohmann::json::parse(knowing.output)["mse_hdr"].get<double>(), e["mse_hdr"].get<double>(),
              1e-6 * e["mse_hdr"].get<double>());  // the same float rounding
}

TEST(MetricsScorer, ErrorMapsAsExrAndFalseColourPngAndLayerPicksAPrefix) {
  test::TempDir dir;
  write_rgb(gradient(16, 12, 1.0f), dir.file("ref.exr"));
  // A multi-layer file: the image to score lives under "denoised.", beside an unrelated R,G,B.
  const Image d = gradient(16, 12, 0.7f);
  test::Channels ch;
  for (int c = 0; c < 3; ++c) {
    std::vector<float> plane(16 * 12), zero(16 * 12, 0.0f);
    for (std::size_t i = 0; i < plane.size(); ++i) plane[i] = d.data()[3 * i + std::size_t(c)];
    ch.emplace_back(std::string("denoised.") + "RGB"[c], plane);
    ch.emplace_back(std::string(1, "RGB"[c]), zero);
  }
  test::write_exr(dir.file("multi.exr"), 16, 12, ch);
  write_rgb(d, dir.file("plain.exr"));
  auto r = test::run_denoisebench_stdout("metrics --json " + dir.file("multi.exr") + " --ref " + dir.file("ref.exr") +
                                         " --layer denoised --metric flip --metric mse --error-maps " + dir.file("maps"));
  ASSERT_EQ(r.exit_code, 0) << r.errors;
  auto plain = test::run_denoisebench_stdout("metrics --json " + dir.file("plain.exr") + " " + dir.file("ref.exr"));
  EXPECT_DOUBLE_EQ(nlohmann::json::parse(r.output)["mse"].get<double>(), nlohmann::json::parse(plain.output)["mse"].get<double>());
  for (const char* f : {"multi.flip.exr", "multi.flip.png", "multi.mse.exr", "multi.mse.png"})
    EXPECT_TRUE(std::filesystem::is_regular_file(dir.file("maps/") + f)) << f;
  // The EXR map is the per-pixel FLIP: its mean is the score.
  const Image map = read_rgb(dir.file("maps/multi.flip.exr"));
  double sum = 0;
  for (std::size_t i = 0; i < map.pixel_count(); ++i) sum += map.data()[3 * i];
  EXPECT_NEAR(sum / double(map.pixel_count()), nlohmann::json::parse(r.output)["flip"].get<double>(), 1e-6);
  // The PNG holds the image and the colour bar under it.
  auto in = OIIO::ImageInput::open(dir.file("maps/multi.flip.png"));
  ASSERT_TRUE(in);
  EXPECT_GT(in->spec().height, 12);
  // A prefix the file lacks names the layers it has.
  auto bad = test::run_denoisebench("metrics " + dir.file("multi.exr") + " " + dir.file("ref.exr") + " --layer denoized");
  EXPECT_EQ(bad.exit_code, 2);
  EXPECT_THAT(bad.output, HasSubstr("denoised"));
}

TEST(MetricsScorer, FlipsPooledStatisticsAndHdrFlipsExposureRange) {
  test::TempDir dir;
  write_rgb(gradient(16, 12, 4.0f), dir.file("ref.exr"));  // HDR: values up to 4
  write_rgb(gradient(16, 12, 3.0f), dir.file("a.exr"));
  auto r = test::run_denoisebench_stdout("metrics --json " + dir.file("a.exr") + " --ref " + dir.file("ref.exr") +
                                         " --metric flip --metric hdrflip");
  ASSERT_EQ(r.exit_code, 0) << r.errors;
  const auto j = nlohmann::json::parse(r.output);
  for (const char* m : {"flip", "hdrflip"}) {
    const auto& p = j[std::string(m) + "_pooled"];
    // The pooled mean is the score, to the float rounding of the map it is pooled from.
    EXPECT_NEAR(p["mean"].get<double>(), j[m].get<double>(), 1e-6 * j[m].get<double>()) << m;
    EXPECT_LE(p["min"].get<double>(), p["weighted_first_quartile"].get<double>()) << m;
    EXPECT_LE(p["weighted_first_quartile"].get<double>(), p["weighted_median"].get<double>()) << m;
    EXPECT_LE(p["weighted_median"].get<double>(), p["weighted_third_quartile"].get<double>()) << m;
    EXPECT_LE(p["weighted_third_quartile"].get<double>(), p["max"].get<double>()) << m;
  }
  EXPECT_GE(j["hdrflip_exposures"]["count"].get<int>(), 2);
  EXPECT_LT(j["hdrflip_exposures"]["start"].get<double>(), j["hdrflip_exposures"]["stop"].get<double>());
}

}  // namespace
}  // namespace dnb
