// End-to-end tests of the "mls" rig method of the spacewarp executable: deform agrees with the
// library in every mode, and bad rigs exit with the documented codes and messages.

#include <filesystem>
#include <sstream>
#include <string>
#include <vector>

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <spacewarp/core/io/mesh_io.h>
#include <spacewarp/core/primitives.h>
#include <spacewarp/nonlinear/mls.h>
#include "apps/cli_test_util.h"

namespace fs = std::filesystem;
using namespace spacewarp;
using ::testing::HasSubstr;

namespace {

using ::spacewarp::test::BadRigTest;

// A fresh folder per test (see cli_test_util.h).
class MlsCliTest : public test::CliFixture {
 protected:
  MlsCliTest() : test::CliFixture("spacewarp_mls_cli_") {}
};

using test::jsonPoints;

TEST_F(MlsCliTest, DeformMatchesTheLibraryWarpInEveryMode) {
  const std::vector<Vec3> handles = makeRandomPoints(Vec3(-1.0), Vec3(1.0), 12, 5).positions;
  const std::vector<Vec3> offsets = makeRandomPoints(Vec3(-0.3), Vec3(0.3), 12, 6).positions;
  std::vector<Vec3> targets;
  for (std::size_t i = 0; i < handles.size(); ++i) targets.push_back(handles[i] + offsets[i]);
  PolygonSoup cloud;
  static_cast<PointSet&>(cloud) = makeRandomPoints(Vec3(-1.5), Vec3(1.5), 300, 9);
  writeSoup(cloud, dir_ / "cloud.ply");
  for (const char* mode : {"", "affine", "similarity", "rigid"}) {
    const std::string modeKey = *mode ? std::string(R"("mode": ")") + mode + R"(", )" : "";
    write("mls.json", R"({"method": "mls", )" + modeKey + R"("alpha": 1.5, "handles": )" +
                          jsonPoints(handles) + R"(, "targets": )" + jsonPoints(targets) + "}");
    MlsOptions options;
    if (*mode) options.mode = mlsModeFromName(mode);
    options.alpha = 1.5;
    const MlsWarp warp(handles, targets, options);
    const test::CliResult r =
        run("deform --rig " + (dir_ / "mls.json").string() + " " + (dir_ / "cloud.ply").string() +
            " -o " + (dir_ / "out.ply").string());
    ASSERT_EQ(r.exitCode, 0) << mode << ": " << r.err;
    const PolygonSoup out = readSoup(dir_ / "out.ply");
    ASSERT_EQ(out.size(), cloud.size());
    for (std::size_t i = 0; i < cloud.size(); ++i)
      ASSERT_LE(glm::length(out.positions[i] - warp.apply(cloud.positions[i])), 1e-12)
          << mode << " point " << i;
  }
}

const std::string kTet = "[[0,0,0],[1,0,0],[0,1,0],[0,0,1],[1,1,1]]";
const std::string kPlane = "[[0,0,0],[1,0,0],[0,1,0],[1,1,0],[2,1,0]]";
const std::string kLine = "[[0,0,0],[1,1,1],[2,2,2],[3,3,3],[4,4,4]]";

INSTANTIATE_TEST_SUITE_P(
    MlsRigs, BadRigTest,
    ::testing::Values(
        test::BadRig{"UnknownMode",
                     R"({"method": "mls", "mode": "conformal", "handles": )" + kTet +
                         R"(, "targets": )" + kTet + "}",
                     3, "'mode' MLS mode 'conformal' is not one of: affine, similarity, rigid"},
        test::BadRig{"MissingTargets", R"({"method": "mls", "handles": )" + kTet + "}", 3,
                     "'targets' is missing"},
        test::BadRig{"SizeMismatch",
                     R"({"method": "mls", "handles": )" + kTet + R"(, "targets": [[0,0,0]]})", 3,
                     "as many points as 'handles'"},
        test::BadRig{"NegativeAlpha",
                     R"({"method": "mls", "alpha": -1, "handles": )" + kTet + R"(, "targets": )" +
                         kTet + "}",
                     3, "'alpha' must be > 0"},
        test::BadRig{
            "UnknownKey",
            R"({"method": "mls", "alpa": 1, "handles": )" + kTet + R"(, "targets": )" + kTet + "}",
            3, "'alpa' is not a key of this method"},
        test::BadRig{"CoplanarAffine",
                     R"({"method": "mls", "mode": "affine", "handles": )" + kPlane +
                         R"(, "targets": )" + kPlane + "}",
                     3, "the handles are coplanar"},
        test::BadRig{"CollinearRigid",
                     R"({"method": "mls", "handles": )" + kLine + R"(, "targets": )" + kTet + "}",
                     3, "the handles are collinear"},
        test::BadRig{"Coincident",
                     R"({"method": "mls", "handles": [[0,0,0],[1,0,0],[0,1,0],[0,0,1],[0,0,0]],
                      "targets": )" +
                         kTet + "}",
                     3, "handles 0 and 4 coincide"}),
    ::spacewarp::test::badRigName);

}  // namespace
