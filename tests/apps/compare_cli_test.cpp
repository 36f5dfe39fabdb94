// End-to-end tests of `spacewarp compare`: the images and reports exist and parse, the
// report's figures are the property kit's, and bad input leaves nothing behind.

#include <cstdint>
#include <filesystem>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "apps/cli_test_util.h"
#include "coords/cage.h"
#include "coords/coords_test_shapes.h"
#include "coords/green.h"
#include "coords/mean_value.h"
#include "coords/properties.h"
#include "core/io/mesh_io.h"

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
      {"--slice w=1", 2, ""},
      {"--slice z=abc", 2, ""},
      {"--methods mvc,nope --slice z=0.5", 2, ""},
      {"--control 1", 2, ""},  // no plane
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

}  // namespace
}  // namespace spacewarp
