// End-to-end tests of `spacewarp compare`: the images and reports exist and parse, the
// report's figures are the property kit's, a method that fails is reported while the others
// still run, the side-by-side image is labelled, and bad input leaves nothing behind.

#include <algorithm>
#include <array>
#include <cstdint>
#include <filesystem>

#include <gtest/gtest.h>
#include <stb_image.h>
#include <nlohmann/json.hpp>

#include <spacewarp/coords/cage.h>
#include <spacewarp/coords/green.h>
#include <spacewarp/coords/mean_value.h>
#include <spacewarp/coords/properties.h>
#include <spacewarp/core/io/mesh_io.h>
#include "apps/cli_test_util.h"
#include "coords/coords_test_shapes.h"

namespace spacewarp {
namespace {

namespace fs = std::filesystem;
using nlohmann::json;
using test::CliResult;

// Width and height from a PNG's IHDR chunk; {0, 0} if the file is not a PNG.
std::pair<std::uint32_t, std::uint32_t> pngSize(const fs::path& path) {
  const std::string bytes = test::slurp(path);
  if (bytes.size() < 24 || bytes.compare(0, 8, "\x89PNG\r\n\x1a\n") != 0 ||
      bytes.compare(12, 4, "IHDR") != 0)
    return {0, 0};
  auto be32 = [&](std::size_t at) {
    std::uint32_t v = 0;
    for (int k = 0; k < 4; ++k) v = v << 8 | static_cast<unsigned char>(bytes[at + k]);
    return v;
  };
  return {be32(16), be32(20)};
}

// A decoded RGB image (stb_image), empty if the file is not one.
struct Picture {
  int width = 0, height = 0;
  std::vector<std::uint8_t> rgb;

  explicit Picture(const fs::path& path) {
    int channels = 0;
    std::uint8_t* data = stbi_load(path.c_str(), &width, &height, &channels, 3);
    if (data) rgb.assign(data, data + std::size_t(width) * height * 3);
    stbi_image_free(data);
  }
  std::array<int, 3> at(int x, int y) const {
    const std::size_t k = (std::size_t(y) * width + x) * 3;
    return {rgb[k], rgb[k + 1], rgb[k + 2]};
  }
  // Pixels of the rectangle [x0, x1) × [y0, y1) for which `test` holds.
  template <class Test>
  int count(int x0, int y0, int x1, int y1, Test test) const {
    int n = 0;
    for (int y = y0; y < y1; ++y)
      for (int x = x0; x < x1; ++x) n += test(at(x, y));
    return n;
  }
  // The rectangle's pixels, row by row, to compare two regions.
  std::vector<std::uint8_t> crop(int x0, int y0, int x1, int y1) const {
    std::vector<std::uint8_t> out;
    for (int y = y0; y < y1; ++y)
      out.insert(out.end(), rgb.begin() + (std::size_t(y) * width + x0) * 3,
                 rgb.begin() + (std::size_t(y) * width + x1) * 3);
    return out;
  }
};

bool isDark(const std::array<int, 3>& c) { return c[0] < 64 && c[1] < 64 && c[2] < 64; }
bool isFailedGrey(const std::array<int, 3>& c) { return c == std::array<int, 3>{128, 128, 128}; }

class CompareTest : public test::CliFixture {
 protected:
  CompareTest() : CliFixture("spacewarp_compare_") {}
  void SetUp() override {
    CliFixture::SetUp();
    writeSoup(test::lPrism(), dir_ / "cage.obj");  // concave: mean-value weights go negative
  }
  CliResult compare(const std::string& args) {
    return run("compare --cage " + (dir_ / "cage.obj").string() + " " + args + " -o " +
               (dir_ / "out").string());
  }
};

TEST_F(CompareTest, WritesOneImagePerMethodSideBySideAndBothReports) {
  const CliResult r = compare("--methods mvc,green,ffd --slice z=0.5 --control 3 --resolution 64");
  ASSERT_EQ(r.exitCode, 0) << r.err;
  const fs::path out = dir_ / "out";
  const json report = json::parse(test::slurp(out / "report.json"));
  for (const char* key : {"cage", "control", "slice", "resolution", "colourScale", "samples",
                          "methods", "images", "insidePixels"})
    EXPECT_TRUE(report.contains(key)) << key;
  const auto width = report["resolution"][0].get<std::uint32_t>();
  const auto height = report["resolution"][1].get<std::uint32_t>();
  // The L's cross-section is 2 x 2 and frames the image: square, 64 pixels a side.
  EXPECT_EQ(width, 64u);
  EXPECT_EQ(height, 64u);
  ASSERT_EQ(report["methods"].size(), 3u);
  for (const json& m : report["methods"]) {
    const auto name = m["name"].get<std::string>();
    EXPECT_EQ(pngSize(out / (name + ".png")), std::make_pair(width, height)) << name;
    for (const char* key : {"setupSeconds", "bindSeconds", "properties", "slice", "controlIndex"})
      EXPECT_TRUE(m.contains(key)) << name << " " << key;
  }
  const auto [stripWidth, stripHeight] = pngSize(out / "compare.png");
  EXPECT_EQ(stripWidth, 3 * width + 2 * 8);  // 8-pixel gaps
  EXPECT_GT(stripHeight, height);            // the colour bar underneath
  EXPECT_NE(pngSize(out / "colour_bar.png").first, 0u);
  const std::string md = test::slurp(out / "report.md");
  EXPECT_NE(md.find("| mvc |"), std::string::npos);
  EXPECT_NE(md.find("compare.png"), std::string::npos);
  EXPECT_TRUE(r.err.empty()) << "no progress display when stderr is not a terminal: " << r.err;
}

TEST_F(CompareTest, ReportFiguresAreThePropertyKits) {
  ASSERT_EQ(compare("--methods mvc,green --slice z=0.5 --samples 300 --resolution 32").exitCode, 0);
  const json report = json::parse(test::slurp(dir_ / "out" / "report.json"));
  auto cage = std::make_shared<const Cage>(Cage::fromFile(dir_ / "cage.obj"));
  const std::vector<Vec3> samples =
      interiorSamples(*cage, report["samples"]["count"].get<std::size_t>(),
                      report["samples"]["seed"].get<std::uint64_t>());
  const PropertyReport mvc = measureProperties(MeanValueCoordinates(cage), *cage, samples);
  const PropertyReport green = measureProperties(GreenCoordinates(cage), *cage, samples);
  for (const json& m : report["methods"]) {
    const PropertyReport& expected = m["name"] == "mvc" ? mvc : green;
    const json& p = m["properties"];
    EXPECT_EQ(p["sampleCount"].get<std::size_t>(), expected.sampleCount);
    EXPECT_DOUBLE_EQ(p["partitionOfUnity"].get<double>(), expected.partitionOfUnity);
    EXPECT_DOUBLE_EQ(p["linearReproduction"].get<double>(), expected.linearReproduction);
    EXPECT_DOUBLE_EQ(p["minWeight"].get<double>(), expected.minWeight);
    EXPECT_DOUBLE_EQ(p["negativeFraction"].get<double>(), expected.negativeFraction);
    EXPECT_DOUBLE_EQ(p["lagrange"].get<double>(), expected.lagrange);
    EXPECT_DOUBLE_EQ(p["faceInterpolation"].get<double>(), expected.faceInterpolation);
  }
  // The concave L: mean-value coordinates go negative somewhere inside.
  EXPECT_LT(mvc.minWeight, 0.0);
}

TEST_F(CompareTest, SliceValuesAreTheCoordinateFunctionAndShareOneScale) {
  ASSERT_EQ(compare("--methods mvc,rbf --point 0.5,0.5,0.5 --normal 0,0,2 --control 7 "
                    "--resolution 48")
                .exitCode,
            0);
  const json report = json::parse(test::slurp(dir_ / "out" / "report.json"));
  double lo = 0.0, hi = 0.0;
  for (const json& m : report["methods"]) {
    EXPECT_EQ(m["controlIndex"], 7);
    EXPECT_LE(m["slice"]["max"].get<double>(), 1.0 + 1e-9);
    lo = std::min(lo, m["slice"]["min"].get<double>());
    hi = std::max(hi, m["slice"]["max"].get<double>());
  }
  EXPECT_EQ(report["colourScale"]["min"].get<double>(), lo);
  EXPECT_EQ(report["colourScale"]["max"].get<double>(), hi);
  EXPECT_EQ(report["slice"]["normal"], json::array({0.0, 0.0, 1.0}));
}

TEST_F(CompareTest, BadInputExitsWithAMessageAndWritesNothing) {
  struct Case {
    std::string args;
    int exitCode;
    std::string message;
  };
  const std::vector<Case> cases = {
      {"--slice z=0.5 --control 99", 3, "control 99"},
      {"--slice z=7", 3, "does not cut the cage"},
      {"--slice w=1", 2, "AXIS x, y or z"},
      {"--slice z=abc", 2, "must be a finite number, not 'abc'"},
      {"--slice z=nan", 2, "must be a finite number, not 'nan'"},
      {"--methods mvc,nope --slice z=0.5", 2, ""},
      {"--methods mvc,green,mvc --slice z=0.5", 2, "'mvc' is listed twice"},
      {"--methods mvc,,green --slice z=0.5", 2, "unknown method ''"},
      {"--control -1 --slice z=0.5", 2, "--control"},
      {"--control 1", 2, ""},  // no plane
#ifdef SPACEWARP_HAVE_HARMONIC
      // Harmonic's options without harmonic among the methods (accepted silently once).
      {"--methods mvc --precision 1 --slice z=0.5", 2,
       "--precision applies to --method harmonic only, not to --methods mvc"},
#endif
  };
  for (const Case& c : cases) {
    const CliResult r = compare(c.args);
    EXPECT_EQ(r.exitCode, c.exitCode) << c.args << ": " << r.err;
    EXPECT_NE(r.err.find(c.message), std::string::npos) << c.args << ": " << r.err;
    EXPECT_FALSE(fs::exists(dir_ / "out")) << c.args;
  }
  const CliResult missing = run("compare --cage " + (dir_ / "missing.obj").string() +
                                " --slice z=0 -o " + (dir_ / "out").string());
  EXPECT_EQ(missing.exitCode, 3);
  EXPECT_NE(missing.err.find("missing.obj"), std::string::npos) << missing.err;
  EXPECT_EQ(std::count(missing.err.begin(), missing.err.end(), '\n'), 1) << missing.err;
  EXPECT_FALSE(fs::exists(dir_ / "out"));
}

TEST_F(CompareTest, PanelsHaveTitlesAndTheColourBarHasNumbers) {
  ASSERT_EQ(compare("--methods mvc,green,ffd --slice z=0.5 --control 10 --resolution 64").exitCode,
            0);
  const json report = json::parse(test::slurp(dir_ / "out" / "report.json"));
  const Picture strip(dir_ / "out" / "compare.png");
  ASSERT_GT(strip.width, 0);
  const json& layout = report["images"]["layout"];
  const int titleHeight = layout["titleHeight"].get<int>();
  const int panelWidth = layout["panelSize"][0].get<int>();
  ASSERT_GT(titleHeight, 0);

  // Every title band has ink, and no two are alike: each names its own method.
  std::vector<std::vector<std::uint8_t>> titles;
  for (const json& panel : layout["panels"]) {
    const int left = panel["left"].get<int>();
    EXPECT_EQ(panel["top"].get<int>(), titleHeight);
    EXPECT_GT(strip.count(left, 0, left + panelWidth, titleHeight, isDark), 10) << panel["name"];
    titles.push_back(strip.crop(left, 0, left + panelWidth, titleHeight));
  }
  ASSERT_EQ(titles.size(), 3u);
  EXPECT_NE(titles[0], titles[1]);
  EXPECT_NE(titles[1], titles[2]);
  EXPECT_NE(titles[0], titles[2]);

  // The colour bar's numbers: min (< 0 for mean-value coordinates on the L) and max beside the
  // bar, 0 and other round values under their tick marks; ascending in the report.
  const double lo = report["colourScale"]["min"].get<double>();
  const double hi = report["colourScale"]["max"].get<double>();
  ASSERT_LT(lo, 0.0);
  const auto ticks = report["colourScale"]["labelledTicks"].get<std::vector<double>>();
  ASSERT_GE(ticks.size(), 4u);  // min, 0, a round value, max
  EXPECT_EQ(ticks.front(), lo);
  EXPECT_EQ(ticks.back(), hi);
  EXPECT_NE(std::find(ticks.begin(), ticks.end(), 0.0), ticks.end());
  EXPECT_TRUE(std::is_sorted(ticks.begin(), ticks.end()));
  const json& bar = layout["bar"];
  const int barLeft = bar["left"].get<int>(), barTop = bar["top"].get<int>();
  const int barRight = barLeft + bar["width"].get<int>();
  const int barBottom = barTop + bar["height"].get<int>(), labelTop = bar["labelTop"].get<int>();
  ASSERT_GT(barLeft, 0);
  ASSERT_LT(barRight, strip.width);
  ASSERT_LT(labelTop, strip.height);
  EXPECT_GT(strip.count(0, barTop, barLeft, barBottom, isDark), 5) << "min beside the bar";
  EXPECT_GT(strip.count(barRight, barTop, strip.width, barBottom, isDark), 5) << "max";
  for (std::size_t k = 1; k + 1 < ticks.size(); ++k) {
    const int x = barLeft + static_cast<int>((ticks[k] - lo) / (hi - lo) * (barRight - barLeft));
    EXPECT_GT(strip.count(std::max(0, x - 12), labelTop, std::min(strip.width, x + 12),
                          strip.height, isDark),
              5)
        << "number under the tick at " << ticks[k];
  }
  // Nothing is written between the panels and the bar.
  EXPECT_EQ(
      strip.count(0, titleHeight + layout["panelSize"][1].get<int>(), strip.width, barTop, isDark),
      0);
  const Picture standalone(dir_ / "out" / "colour_bar.png");
  ASSERT_GT(standalone.height, 24);
  EXPECT_GT(standalone.count(0, 24, standalone.width, standalone.height, isDark), 20)
      << "colour_bar.png has numbers under the bar";
}

// Set-up of harmonic coordinates that fails: a --harmonic-cache file that is not one. Skips
// in a build without TetGen (no harmonic method).
class CompareFailureTest : public CompareTest {
 protected:
  void SetUp() override {
    CompareTest::SetUp();
    const CliResult help = run("compare --help");
    if (help.out.find("harmonic") == std::string::npos) GTEST_SKIP() << "built without TetGen";
    write("bad.swh", "not a cache");
  }
  std::string badHarmonic() const { return " --harmonic-cache " + (dir_ / "bad.swh").string(); }
};

TEST_F(CompareFailureTest, AFailedMethodIsReportedAndDrawnAsFailedAndTheOthersStillRun) {
  const CliResult r =
      compare("--methods mvc,harmonic,green --slice z=0.5 --resolution 64" + badHarmonic());
  ASSERT_EQ(r.exitCode, 0) << r.err;
  EXPECT_NE(r.err.find("warning: compare: harmonic failed"), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("bad.swh"), std::string::npos) << r.err;
  const fs::path out = dir_ / "out";
  const json report = json::parse(test::slurp(out / "report.json"));
  EXPECT_EQ(report["failedMethods"], json::array({"harmonic"}));
  ASSERT_EQ(report["methods"].size(), 3u);
  const json& failed = report["methods"][1];
  EXPECT_EQ(failed["name"], "harmonic");
  EXPECT_EQ(failed["status"], "failed");
  EXPECT_EQ(failed["errorType"], "IoError");
  EXPECT_NE(failed["error"].get<std::string>().find("bad.swh"), std::string::npos);
  double lo = 0.0, hi = 0.0;
  for (int k : {0, 2}) {
    const json& m = report["methods"][k];
    EXPECT_EQ(m["status"], "ok") << m["name"];
    EXPECT_LT(m["properties"]["partitionOfUnity"].get<double>(), 1e-9) << m["name"];
    lo = std::min(lo, m["slice"]["min"].get<double>());
    hi = std::max(hi, m["slice"]["max"].get<double>());
  }
  // The scale is the methods that succeeded.
  EXPECT_EQ(report["colourScale"]["min"].get<double>(), lo);
  EXPECT_EQ(report["colourScale"]["max"].get<double>(), hi);

  const std::string md = test::slurp(out / "report.md");
  EXPECT_NE(md.find("| harmonic | failed |"), std::string::npos) << md;
  EXPECT_NE(md.find("not a harmonic coordinate file"), std::string::npos) << md;

  // Its panel (and harmonic.png) is grey and says so; the others are heat maps.
  const Picture alone(out / "harmonic.png");
  ASSERT_EQ(alone.width, 64);
  EXPECT_GT(alone.count(0, 0, 64, alone.height, isFailedGrey), 64 * alone.height / 2);
  EXPECT_GT(alone.count(0, 0, 64, alone.height,
                        [](const auto& c) {
                          return c == std::array<int, 3>{255, 255, 255};
                        }),
            20)
      << "the word 'failed'";
  const Picture strip(out / "compare.png");
  const json& layout = report["images"]["layout"];
  const int top = layout["titleHeight"].get<int>(), height = layout["panelSize"][1].get<int>();
  for (const json& panel : layout["panels"]) {
    const int left = panel["left"].get<int>();
    const int grey = strip.count(left, top, left + 64, top + height, isFailedGrey);
    if (panel["name"] == "harmonic")
      EXPECT_GT(grey, 64 * height / 2);
    else
      EXPECT_EQ(grey, 0) << panel["name"];
    EXPECT_GT(strip.count(left, 0, left + 64, top, isDark), 10) << "title of " << panel["name"];
  }
}

// A cage made of two overlapping boxes: mean-value and Green coordinates are defined, TetGen
// refuses it (a numerical method's own limit, not bad input to the comparison).
TEST_F(CompareFailureTest, AMethodThatRejectsTheCageFailsAloneWithTheReason) {
  PolygonSoup cage = makeBoxSurface(Vec3(0.0), Vec3(2.0), glm::ivec3(1));
  const PolygonSoup second = makeBoxSurface(Vec3(1.0), Vec3(3.0), glm::ivec3(1));
  const auto offset = static_cast<std::uint32_t>(cage.positions.size());
  cage.positions.insert(cage.positions.end(), second.positions.begin(), second.positions.end());
  for (std::size_t f = 0; f < second.polygonCount(); ++f) {
    std::vector<std::uint32_t> face;
    for (std::uint32_t v : second.polygon(f)) face.push_back(v + offset);
    cage.addPolygon(face);
  }
  cage.normals.clear();  // a cage needs none
  writeSoup(cage, dir_ / "cage.obj");
  const CliResult r =
      compare("-q --methods mvc,harmonic,green --tets 500 --slice z=1.5 --resolution 32");
  ASSERT_EQ(r.exitCode, 0) << r.err;
  EXPECT_NE(r.err.find("harmonic failed"), std::string::npos) << "even with -q: " << r.err;
  const json report = json::parse(test::slurp(dir_ / "out" / "report.json"));
  EXPECT_EQ(report["failedMethods"], json::array({"harmonic"}));
  for (const json& m : report["methods"]) {
    if (m["name"] != "harmonic") {
      EXPECT_EQ(m["status"], "ok") << m["name"];
      continue;
    }
    EXPECT_EQ(m["errorType"], "InvalidInput");
    EXPECT_NE(m["error"].get<std::string>().find("intersects itself"), std::string::npos)
        << m["error"];
  }
}

TEST_F(CompareFailureTest, EveryMethodFailingExitsWith4AndStillWritesTheReasons) {
  const CliResult r = compare("--methods harmonic --slice z=0.5 --resolution 32" + badHarmonic());
  EXPECT_EQ(r.exitCode, 4) << r.err;
  EXPECT_NE(r.err.find("every method failed"), std::string::npos) << r.err;
  const json report = json::parse(test::slurp(dir_ / "out" / "report.json"));
  EXPECT_EQ(report["methods"][0]["status"], "failed");
  EXPECT_TRUE(fs::exists(dir_ / "out" / "compare.png"));
}

}  // namespace
}  // namespace spacewarp
