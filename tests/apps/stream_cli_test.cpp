// `spacewarp deform --chunk-points`: a streamed deform of a binary PLY writes the same bytes
// as the whole-file path, says it streamed, refuses what the whole-file path refuses with the
// same exit code and leaves no output behind. (Write failures and signals during a streamed
// run: io_safety_cli_test.cpp.)

#include <algorithm>
#include <cstring>
#include <filesystem>
#include <limits>
#include <string>

#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <sys/stat.h>

#include <spacewarp/core/io/mesh_io.h>
#include <spacewarp/core/io/ply.h>
#include <spacewarp/core/io/ply_stream.h>
#include "apps/cli_test_util.h"

namespace spacewarp {
namespace {

using ::testing::HasSubstr;

class StreamCliTest : public test::CliFixture {
 protected:
  StreamCliTest() : CliFixture("spacewarp_stream_cli_") {}

  void SetUp() override {
    CliFixture::SetUp();
    write("twist.json",
          R"({"method": "twist", "origin": [0, 0, 0], "axis": [0, 0, 1], "rate": 0.5})");
  }

  std::string p(const std::string& name) const { return (dir_ / name).string(); }

  // A big-endian PLY with normals, colours and polygons (writePly writes every encoding).
  void writeSoupInput(std::size_t n) {
    PolygonSoup soup = writeCloud(Vec3(-1), Vec3(1), n, 9);
    for (std::size_t i = 0; i < n; ++i) soup.normals.push_back(glm::normalize(soup.positions[i]));
    VertexAttribute red{"red", ScalarType::UInt8, {}};
    for (std::size_t i = 0; i < n; ++i) red.values.push_back(static_cast<double>(i % 256));
    soup.attributes.push_back(red);
    for (std::uint32_t f = 0; f + 4 < n; f += 3) {
      if (f % 2)
        soup.addPolygon(std::vector<std::uint32_t>{f, f + 1, f + 2});
      else
        soup.addPolygon(std::vector<std::uint32_t>{f, f + 1, f + 2, f + 3, f + 4});
    }
    std::ofstream out(dir_ / "soup.ply", std::ios::binary);
    writePly(soup, out, PlyEncoding::BinaryBigEndian);
  }
};

TEST_F(StreamCliTest, StreamedOutputIsByteIdenticalAndTheSummarySaysSo) {
  writeSoupInput(500);
  for (const std::string ascii : {"", "--ascii "}) {
    const test::CliResult whole = run("deform " + ascii + "--chunk-points 0 --rig " +
                                      p("twist.json") + " " + p("soup.ply") + " -o " + p("a.ply"));
    ASSERT_EQ(whole.exitCode, 0) << whole.err;
    EXPECT_THAT(whole.out, ::testing::Not(HasSubstr("streamed")));
    for (const std::string chunk : {"1", "7", "1000"}) {
      const test::CliResult streamed =
          run("deform " + ascii + "--chunk-points " + chunk + " --rig " + p("twist.json") + " " +
              p("soup.ply") + " -o " + p("b.ply"));
      ASSERT_EQ(streamed.exitCode, 0) << streamed.err;
      const std::string chunks = chunk == "1"   ? "500 chunks"
                                 : chunk == "7" ? "72 chunks"
                                                : "1 chunk";
      EXPECT_THAT(streamed.out, HasSubstr("streamed in " + chunks)) << streamed.out;
      EXPECT_EQ(test::slurp(dir_ / "b.ply"), test::slurp(dir_ / "a.ply")) << ascii << chunk;
    }
  }
}

TEST_F(StreamCliTest, AsciiAndPipeInputsAreReadWholeWithAWarning) {
  writeCloud(Vec3(-1), Vec3(1), 50, 3);
  ASSERT_EQ(run("deform --ascii --chunk-points 0 --rig " + p("twist.json") + " " + p("cloud.ply") +
                " -o " + p("ascii.ply"))
                .exitCode,
            0);
  const test::CliResult ascii = run("deform --chunk-points 10 --rig " + p("twist.json") + " " +
                                    p("ascii.ply") + " -o " + p("out.ply"));
  ASSERT_EQ(ascii.exitCode, 0) << ascii.err;
  EXPECT_THAT(ascii.out, ::testing::Not(HasSubstr("streamed")));
  EXPECT_THAT(ascii.err, HasSubstr(p("ascii.ply") + ": read whole, --chunk-points ignored"));
  // A pipe would be read twice by a streamed run: it is read whole, with the same output.
  ASSERT_EQ(run("deform --chunk-points 0 --rig " + p("twist.json") + " " + p("cloud.ply") + " -o " +
                p("whole.ply"))
                .exitCode,
            0);
  ASSERT_EQ(mkfifo(p("pipe.ply").c_str(), 0600), 0);
  for (const std::string chunk : {"", "--chunk-points 7 "}) {
    // The writer gives up after a while if the command never opens the pipe.
    const test::CliResult piped =
        run("deform " + chunk + "--rig " + p("twist.json") + " " + p("pipe.ply") + " -o " +
                p("piped.ply"),
            "(timeout 60 cat " + p("cloud.ply") + " > " + p("pipe.ply") + " &); ");
    ASSERT_EQ(piped.exitCode, 0) << piped.err;
    EXPECT_EQ(test::slurp(dir_ / "piped.ply"), test::slurp(dir_ / "whole.ply"));
    EXPECT_EQ(piped.err.find("--chunk-points ignored") != std::string::npos, !chunk.empty())
        << piped.err;
  }
}

TEST_F(StreamCliTest, ChunkPointsIsAUsageErrorForNonPlyInputOrOutputAndNonNumbers) {
  writeSoup(PolygonSoup(writeCloud(Vec3(-1), Vec3(1), 10, 3)), dir_ / "cloud.obj");
  const test::CliResult r = run("deform --chunk-points 10 --rig " + p("twist.json") + " " +
                                p("cloud.obj") + " -o " + p("out.ply"));
  EXPECT_EQ(r.exitCode, 2);
  EXPECT_THAT(r.err, HasSubstr("--chunk-points applies to .ply input only"));
  const test::CliResult obj = run("deform --chunk-points 10 --rig " + p("twist.json") + " " +
                                  p("cloud.ply") + " -o " + p("out.obj"));
  EXPECT_EQ(obj.exitCode, 2);
  EXPECT_THAT(obj.err, HasSubstr("--chunk-points applies to .ply output only"));
  EXPECT_FALSE(std::filesystem::exists(dir_ / "out.ply"));
  EXPECT_FALSE(std::filesystem::exists(dir_ / "out.obj"));
  for (const std::string bad : {"-1", "abc", "''", "18446744073709551616", "1e3", "10x"}) {
    const test::CliResult u = run("deform --chunk-points " + bad + " --rig " + p("twist.json") +
                                  " " + p("cloud.ply") + " -o " + p("out.ply"));
    EXPECT_EQ(u.exitCode, 2) << bad;
    EXPECT_THAT(u.err, HasSubstr("is not a non-negative integer below 2^64")) << bad;
    EXPECT_LT(u.err.size(), 300u) << u.err;
    EXPECT_FALSE(std::filesystem::exists(dir_ / "out.ply"));
  }
  // The largest count is a chunk of every row.
  const test::CliResult most = run("deform --chunk-points 18446744073709551615 --rig " +
                                   p("twist.json") + " " + p("cloud.ply") + " -o " + p("out.ply"));
  EXPECT_EQ(most.exitCode, 0) << most.err;
  EXPECT_THAT(most.out, HasSubstr("streamed in 1 chunk"));
}

#ifdef SPACEWARP_HAVE_HARMONIC
TEST_F(StreamCliTest, AWarpDomainErrorNamesTheFileAndTheVertexInIt) {
  // A harmonic cage around the origin; vertex 290 of 301 moved far outside it.
  write("cage.obj",
        "v -2 -2 -2\nv 2 -2 -2\nv 2 2 -2\nv -2 2 -2\nv -2 -2 2\nv 2 -2 2\nv 2 2 2\nv -2 2 "
        "2\nf 1 4 3\nf 1 3 2\nf 5 6 7\nf 5 7 8\nf 1 2 6\nf 1 6 5\nf 2 3 7\nf 2 7 6\nf 3 4 "
        "8\nf 3 8 7\nf 4 1 5\nf 4 5 8\n");
  PolygonSoup cloud = writeCloud(Vec3(-1), Vec3(1), 301, 5);
  cloud.positions[290] = Vec3(10.0);
  writeSoup(cloud, dir_ / "oob.ply");
  const std::string args = "--method harmonic --cage " + p("cage.obj") + " --pose " +
                           p("cage.obj") + " --outside raise " + p("oob.ply") + " -o " +
                           p("out.ply");
  const test::CliResult whole = run("deform --chunk-points 0 " + args);
  ASSERT_EQ(whole.exitCode, 3) << whole.err;
  EXPECT_THAT(whole.err, HasSubstr(p("oob.ply") + ": HarmonicWarp: 1 of 301 points are outside "
                                                  "the cage (the first is point 290)"));
  // The failing chunk is the last: the same message.
  EXPECT_EQ(run("deform --chunk-points 200 " + args).err, whole.err);
  // An earlier chunk: the file's index and total, the chunk's count as "at least".
  const test::CliResult chunked = run("deform --chunk-points 100 " + args);
  EXPECT_EQ(chunked.exitCode, 3);
  EXPECT_THAT(chunked.err, HasSubstr(p("oob.ply") + ": HarmonicWarp: at least 1 of 301 points are "
                                                    "outside the cage (the first is point 290)"));
  EXPECT_FALSE(std::filesystem::exists(dir_ / "out.ply"));
}
#endif

TEST_F(StreamCliTest, NonFiniteVertexInALateChunkIsExit3NamingItWithNoOutput) {
  writeCloud(Vec3(-1), Vec3(1), 100, 4);
  std::string bytes = test::slurp(dir_ / "cloud.ply");
  const PlyLayout layout = plyLayout(dir_ / "cloud.ply");
  const auto z = std::find_if(layout.vertexProperties.begin(), layout.vertexProperties.end(),
                              [](const PlyPropertyLayout& p) { return p.name == "z"; });
  ASSERT_EQ(z->type, ScalarType::Float64);
  const double nan = std::numeric_limits<double>::quiet_NaN();
  std::memcpy(bytes.data() + layout.vertexOffset + 97 * layout.vertexRowBytes + z->offset, &nan,
              sizeof nan);
  write("cloud.ply", bytes);
  const test::CliResult r = run("deform --chunk-points 10 --rig " + p("twist.json") + " " +
                                p("cloud.ply") + " -o " + p("out.ply"));
  EXPECT_EQ(r.exitCode, 3);
  EXPECT_THAT(r.err, HasSubstr(p("cloud.ply") + ": vertex 97: non-finite coordinate"));
  EXPECT_FALSE(std::filesystem::exists(dir_ / "out.ply"));
  for (const auto& entry : std::filesystem::directory_iterator(dir_))
    EXPECT_FALSE(entry.path().filename().string().ends_with(".tmp")) << entry.path();
}

TEST_F(StreamCliTest, TruncatedFileAndBadFaceIndexAreExit3) {
  writeSoupInput(60);
  std::string bytes = test::slurp(dir_ / "soup.ply");
  write("short.ply", bytes.substr(0, bytes.size() - 3));
  const test::CliResult truncated = run("deform --chunk-points 10 --rig " + p("twist.json") + " " +
                                        p("short.ply") + " -o " + p("out.ply"));
  EXPECT_EQ(truncated.exitCode, 3);
  EXPECT_THAT(truncated.err, HasSubstr(p("short.ply") + ": face"));
  EXPECT_THAT(truncated.err, HasSubstr("unexpected end of file"));
  // The last index of the last face (big-endian int) set to 60, one past the last vertex.
  const char bad[4] = {0, 0, 0, 60};
  bytes.replace(bytes.size() - 4, 4, bad, 4);
  write("bad.ply", bytes);
  const test::CliResult index = run("deform --chunk-points 10 --rig " + p("twist.json") + " " +
                                    p("bad.ply") + " -o " + p("out.ply"));
  EXPECT_EQ(index.exitCode, 3);
  EXPECT_THAT(index.err, HasSubstr("vertex index 60 is out of range (60 vertices)"));
  EXPECT_FALSE(std::filesystem::exists(dir_ / "out.ply"));
}

}  // namespace
}  // namespace spacewarp
