#include <spacewarp/core/deform_stream.h>

#include <algorithm>
#include <bit>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <limits>
#include <random>
#include <string>
#include <vector>

#include <gtest/gtest.h>
#include <sys/stat.h>

#include <spacewarp/core/deform.h>
#include <spacewarp/core/errors.h>
#include <spacewarp/core/io/mesh_io.h>
#include <spacewarp/core/io/ply_stream.h>
#include <spacewarp/core/twist.h>
#include "io/io_test_util.h"
#include "test_util.h"

namespace spacewarp {
namespace {

// What the test PLY files hold.
struct Spec {
  std::size_t vertices = 100;
  bool doublePositions = false;
  bool normals = false;
  bool extras = false;  // uchar colours, a float property, and a dropped "edge" list element
  bool faces = false;   // triangles, quads and pentagons with a face attribute
  bool bigEndian = false;
  std::uint32_t seed = 1;
};

// A binary PLY file's bytes, written value by value with explicit types (so that float
// positions, big-endian files and other elements are covered, which writePly does not write).
class PlyBytes {
 public:
  explicit PlyBytes(bool bigEndian)
      : swap_(bigEndian != (std::endian::native == std::endian::big)) {}

  template <class T>
  void put(T value) {
    unsigned char bytes[sizeof(T)];
    std::memcpy(bytes, &value, sizeof(T));
    if (swap_) std::reverse(bytes, bytes + sizeof(T));
    data.append(reinterpret_cast<const char*>(bytes), sizeof(T));
  }

  std::string data;

 private:
  bool swap_;
};

std::string makePly(const Spec& spec) {
  std::mt19937 rng(spec.seed);
  std::uniform_real_distribution<double> coordinate(-2.0, 2.0);
  std::uniform_int_distribution<int> byte(0, 255);
  const char* type = spec.doublePositions ? "double" : "float";
  std::string header = std::string("ply\nformat ") +
                       (spec.bigEndian ? "binary_big_endian" : "binary_little_endian") +
                       " 1.0\ncomment test input\nelement vertex " + std::to_string(spec.vertices) +
                       "\n";
  if (spec.extras) header += "property uchar red\n";
  for (const char* axis : {"x", "y", "z"})
    header += std::string("property ") + type + " " + axis + "\n";
  if (spec.normals) header += "property float nx\nproperty float ny\nproperty float nz\n";
  if (spec.extras) header += "property uchar green\nproperty float confidence\n";
  std::vector<std::vector<std::int32_t>> polygons;
  if (spec.faces) {
    std::uniform_int_distribution<std::int32_t> vertex(
        0, static_cast<std::int32_t>(spec.vertices - 1));
    for (std::size_t f = 0; f < spec.vertices / 2; ++f) {
      polygons.emplace_back(3 + f % 3);
      for (std::int32_t& v : polygons.back()) v = vertex(rng);
    }
    header += "element face " + std::to_string(polygons.size()) +
              "\nproperty list uchar int vertex_indices\nproperty ushort material\n";
  }
  if (spec.extras) header += "element edge 2\nproperty list uchar int vertex_pair\n";
  header += "end_header\n";

  PlyBytes bytes(spec.bigEndian);
  for (std::size_t v = 0; v < spec.vertices; ++v) {
    if (spec.extras) bytes.put(static_cast<std::uint8_t>(byte(rng)));
    for (int c = 0; c < 3; ++c) {
      if (spec.doublePositions)
        bytes.put(coordinate(rng));
      else
        bytes.put(static_cast<float>(coordinate(rng)));
    }
    if (spec.normals) {
      const Vec3 n = test::randomUnit(rng);
      for (int c = 0; c < 3; ++c) bytes.put(static_cast<float>(n[c]));
    }
    if (spec.extras) {
      bytes.put(static_cast<std::uint8_t>(byte(rng)));
      bytes.put(static_cast<float>(coordinate(rng)));
    }
  }
  for (std::size_t f = 0; f < polygons.size(); ++f) {
    bytes.put(static_cast<std::uint8_t>(polygons[f].size()));
    for (std::int32_t v : polygons[f]) bytes.put(v);
    bytes.put(static_cast<std::uint16_t>(f % 7));
  }
  if (spec.extras) {
    for (int e = 0; e < 2; ++e) {
      bytes.put(std::uint8_t{2});
      bytes.put(std::int32_t{0});
      bytes.put(std::int32_t{1});
    }
  }
  return header + bytes.data;
}

TwistWarp twist() {
  TwistOptions options;
  options.axis = Vec3(0.2, 0.1, 1.0);
  options.rate = 0.7;
  return TwistWarp(options);
}

// The whole-file path of `spacewarp deform`: read, deform, write.
std::string inMemory(const Warp& warp, const std::filesystem::path& input,
                     const std::filesystem::path& output, bool ascii = false) {
  PolygonSoup soup = readSoup(input);
  deform(warp, soup);
  WriteOptions options;
  if (ascii) options.plyEncoding = PlyEncoding::Ascii;
  writeSoup(soup, output, options);
  return test::readFile(output);
}

class StreamDeform : public ::testing::TestWithParam<Spec> {};

TEST_P(StreamDeform, OutputIsByteIdenticalToTheWholeFilePathForEveryChunkSize) {
  const Spec spec = GetParam();
  const test::TempDir dir;
  const auto input = dir.path() / "in.ply";
  test::writeFile(input, makePly(spec));
  const TwistWarp warp = twist();
  for (bool ascii : {false, true}) {
    const std::string expected = inMemory(warp, input, dir.path() / "memory.ply", ascii);
    ASSERT_GT(expected.size(), 100u);
    for (std::size_t chunk : {std::size_t{1}, std::size_t{7}, std::size_t{1000}, spec.vertices}) {
      StreamDeformOptions options;
      options.chunkPoints = chunk;
      options.ascii = ascii;
      const auto output = dir.path() / "streamed.ply";
      const StreamDeformReport report = deformFileStreaming(warp, input, output, options);
      EXPECT_EQ(test::readFile(output), expected) << "chunk " << chunk << " ascii " << ascii;
      EXPECT_EQ(report.points, spec.vertices);
      EXPECT_EQ(report.chunks, (spec.vertices + chunk - 1) / chunk);
      EXPECT_EQ(report.faces, spec.faces ? spec.vertices / 2 : 0);
      EXPECT_EQ(report.notKept.empty(), !spec.extras);
    }
  }
}

TEST_P(StreamDeform, RowRangePartsAssembleIntoTheWholeOutput) {
  const Spec spec = GetParam();
  const test::TempDir dir;
  const auto input = dir.path() / "in.ply";
  test::writeFile(input, makePly(spec));
  const TwistWarp warp = twist();
  const std::string expected = inMemory(warp, input, dir.path() / "memory.ply");
  const PlyLayout layout = plyLayout(input);
  const std::uint64_t n = layout.vertexCount;
  // Uneven ranges, an empty one among them.
  const std::vector<std::uint64_t> cuts = {0, 1, 1, n / 3, n};
  std::vector<std::filesystem::path> parts;
  for (std::size_t k = 0; k + 1 < cuts.size(); ++k) {
    parts.push_back(dir.path() / ("part" + std::to_string(k)));
    StreamDeformOptions options;
    options.chunkPoints = 5;
    deformPlyRows(warp, input, cuts[k], cuts[k + 1] - cuts[k], parts.back(), options);
    EXPECT_EQ(std::filesystem::file_size(parts.back()),
              (cuts[k + 1] - cuts[k]) * plyOutputRowBytes(layout));
  }
  assemblePly(input, parts, dir.path() / "assembled.ply");
  EXPECT_EQ(test::readFile(dir.path() / "assembled.ply"), expected);
}

INSTANTIATE_TEST_SUITE_P(
    Files, StreamDeform,
    ::testing::Values(Spec{}, Spec{.doublePositions = true, .seed = 2},
                      Spec{.vertices = 64, .normals = true, .seed = 3},
                      Spec{.vertices = 90, .normals = true, .extras = true, .seed = 4},
                      Spec{.vertices = 50, .faces = true, .seed = 5},
                      Spec{.vertices = 77,
                           .doublePositions = true,
                           .normals = true,
                           .extras = true,
                           .faces = true,
                           .bigEndian = true,
                           .seed = 6},
                      Spec{.vertices = 40, .extras = true, .bigEndian = true, .seed = 7}));

TEST(PlyLayout, DescribesTheVertexRowsAndElementRanges) {
  const test::TempDir dir;
  const auto input = dir.path() / "in.ply";
  const Spec spec{.vertices = 20, .normals = true, .extras = true, .faces = true};
  const std::string bytes = makePly(spec);
  test::writeFile(input, bytes);
  const PlyLayout layout = plyLayout(input);
  EXPECT_EQ(layout.vertexCount, 20u);
  EXPECT_EQ(layout.vertexRowBytes, 1 + 12 + 12 + 1 + 4u);
  EXPECT_EQ(layout.vertexOffset, bytes.find("end_header\n") + 11);
  ASSERT_EQ(layout.vertexProperties.size(), 9u);
  EXPECT_EQ(layout.vertexProperties[1].name, "x");
  EXPECT_EQ(layout.vertexProperties[1].offset, 1u);
  EXPECT_EQ(layout.vertexProperties[8].type, ScalarType::Float32);
  ASSERT_EQ(layout.elements.size(), 3u);
  // The elements tile the data section up to the end of the file.
  EXPECT_EQ(layout.elements[0].offset, layout.vertexOffset);
  for (std::size_t e = 0; e + 1 < layout.elements.size(); ++e)
    EXPECT_EQ(layout.elements[e].offset + layout.elements[e].bytes, layout.elements[e + 1].offset);
  EXPECT_EQ(layout.elements.back().offset + layout.elements.back().bytes, bytes.size());
  EXPECT_EQ(layout.faceCount, 10u);
  EXPECT_EQ(layout.largestPolygon, 5u);
  EXPECT_EQ(plyOutputRowBytes(layout), 48 + 1 + 1 + 4u);
}

TEST(PlyLayout, RefusesAsciiAndVertexListsButIsStreamableSaysSoFirst) {
  const test::TempDir dir;
  const auto ascii = dir.path() / "a.ply";
  test::writeFile(ascii,
                  "ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty float "
                  "y\nproperty float z\nend_header\n1 2 3\n");
  EXPECT_FALSE(isStreamablePly(ascii));
  EXPECT_THROW(plyLayout(ascii), IoError);
  const auto lists = dir.path() / "l.ply";
  test::writeFile(lists,
                  "ply\nformat binary_little_endian 1.0\nelement vertex 0\nproperty float x\n"
                  "property float y\nproperty float z\nproperty list uchar int ids\nend_header\n");
  EXPECT_FALSE(isStreamablePly(lists));
  EXPECT_NE(test::messageOf<IoError>([&] { plyLayout(lists); }).find("list"), std::string::npos);
  EXPECT_FALSE(isStreamablePly(dir.path() / "x.obj"));
}

// Every refusal names the file and the element at fault, leaves no output, and matches the
// whole-file reader's message.
class StreamRefusals : public ::testing::Test {
 protected:
  void expectRefused(const std::string& bytes, const std::string& fragment, bool ioError = true) {
    test::writeFile(input_, bytes);
    const auto output = dir_.path() / "out.ply";
    StreamDeformOptions options;
    options.chunkPoints = 3;
    const auto run = [&] { deformFileStreaming(twist(), input_, output, options); };
    const std::string message =
        ioError ? test::messageOf<IoError>(run) : test::messageOf<InvalidInput>(run);
    EXPECT_NE(message.find(input_.string()), std::string::npos) << message;
    EXPECT_NE(message.find(fragment), std::string::npos) << message;
    EXPECT_EQ(test::listDirectory(dir_.path()), std::set<std::string>{"in.ply"});
    if (ioError) {
      const std::string whole = test::messageOf<IoError>([&] { readSoup(input_); });
      EXPECT_EQ(message, whole);
    }
  }

  test::TempDir dir_;
  std::filesystem::path input_ = dir_.path() / "in.ply";
};

TEST_F(StreamRefusals, NonFiniteCoordinateInALateChunk) {
  std::string bytes = makePly(Spec{.vertices = 30});
  const float nan = std::numeric_limits<float>::quiet_NaN();
  std::memcpy(bytes.data() + bytes.size() - 12 * 4 + 4, &nan, sizeof nan);  // vertex 26, y
  expectRefused(bytes, "vertex 26: non-finite coordinate");
}

TEST_F(StreamRefusals, NonFiniteNormal) {
  std::string bytes = makePly(Spec{.vertices = 10, .normals = true});
  const float inf = std::numeric_limits<float>::infinity();
  std::memcpy(bytes.data() + bytes.size() - 24 + 12 + 8, &inf, sizeof inf);  // vertex 9, nz
  expectRefused(bytes, "vertex 9: non-finite normal");
}

TEST_F(StreamRefusals, TruncatedVertices) {
  std::string bytes = makePly(Spec{.vertices = 30});
  bytes.resize(bytes.size() - 20);
  expectRefused(bytes, "vertex 28: unexpected end of file");
}

TEST_F(StreamRefusals, TruncatedFaces) {
  std::string bytes = makePly(Spec{.vertices = 30, .faces = true});
  bytes.resize(bytes.size() - 5);
  expectRefused(bytes, "face 14: unexpected end of file");
}

TEST_F(StreamRefusals, FaceIndexOutOfRange) {
  std::string bytes = makePly(Spec{.vertices = 30, .faces = true});
  // The last face is a pentagon (f = 14): count, 5 indices, material. Its third index:
  const std::int32_t bad = 30;
  std::memcpy(bytes.data() + bytes.size() - 2 - 4 * 3, &bad, sizeof bad);
  expectRefused(bytes, "face 14: vertex index 30 is out of range (30 vertices)");
}

TEST_F(StreamRefusals, NoVertices) { expectRefused(makePly(Spec{.vertices = 0}), "no vertices"); }

// Sends points with x > limit to NaN.
class PartialWarp final : public Warp {
 public:
  explicit PartialWarp(double limit) : limit_(limit) {}
  Vec3 apply(const Vec3& x) const override {
    return x.x > limit_ ? Vec3(std::numeric_limits<double>::quiet_NaN()) : x;
  }

 private:
  double limit_;
};

TEST_F(StreamRefusals, WarpToANonFinitePositionNamesTheVertexInTheFile) {
  test::writeFile(input_, makePly(Spec{.vertices = 200}));
  PolygonSoup soup = readSoup(input_);
  // The largest x of the first 10 points: the first point beyond it is in a later chunk.
  double limit = soup.positions[0].x;
  for (std::size_t i = 1; i < 10; ++i) limit = std::max(limit, soup.positions[i].x);
  std::size_t first = 10;
  while (first < soup.size() && soup.positions[first].x <= limit) ++first;
  ASSERT_LT(first, soup.size());
  StreamDeformOptions options;
  options.chunkPoints = 3;
  const auto output = dir_.path() / "out.ply";
  const std::string message = test::messageOf<InvalidInput>(
      [&] { deformFileStreaming(PartialWarp(limit), input_, output, options); });
  EXPECT_NE(message.find(input_.string() + ": the warp sent vertex " + std::to_string(first) +
                         " to a non-finite position"),
            std::string::npos)
      << message;
  EXPECT_FALSE(std::filesystem::exists(output));
  EXPECT_EQ(test::listDirectory(dir_.path()), std::set<std::string>{"in.ply"});
}

TEST_F(StreamRefusals, CancelLeavesNoOutput) {
  test::writeFile(input_, makePly(Spec{.vertices = 50}));
  StreamDeformOptions options;
  options.chunkPoints = 5;
  int calls = 0;
  options.progress = [&](std::string_view, double) { return ++calls < 3; };
  EXPECT_THROW(deformFileStreaming(twist(), input_, dir_.path() / "out.ply", options), Cancelled);
  EXPECT_EQ(test::listDirectory(dir_.path()), std::set<std::string>{"in.ply"});
}

TEST_F(StreamRefusals, PartSizesMustMatchTheLayout) {
  test::writeFile(input_, makePly(Spec{.vertices = 10}));
  const auto part = dir_.path() / "part";
  deformPlyRows(twist(), input_, 0, 10, part);
  // One row short: the parts do not cover the vertices.
  const auto shortPart = dir_.path() / "short";
  deformPlyRows(twist(), input_, 0, 9, shortPart);
  EXPECT_NE(test::messageOf<InvalidInput>([&] {
              assemblePly(input_, {shortPart}, dir_.path() / "out.ply");
            }).find("hold 9 vertex rows"),
            std::string::npos);
  // A part cut mid-row.
  std::string bytes = test::readFile(part);
  bytes.pop_back();
  test::writeFile(part, bytes);
  EXPECT_NE(test::messageOf<InvalidInput>([&] {
              assemblePly(input_, {part}, dir_.path() / "out.ply");
            }).find(part.string() + ": 239 bytes is not a whole number"),
            std::string::npos);
  EXPECT_FALSE(std::filesystem::exists(dir_.path() / "out.ply"));
  EXPECT_THROW(deformPlyRows(twist(), input_, 5, 6, part), InvalidInput);
}

// Leaves points with x > limit unmapped (as a cage warp does points outside its cage), through
// the batch kernel, so that applyBatch throws the warp's "N of M points" message.
class DomainWarp final : public Warp {
 public:
  explicit DomainWarp(double limit) : limit_(limit) {}
  Vec3 apply(const Vec3& x) const override { return x; }

 protected:
  UnmappedPoints applyRange(std::span<const Vec3> in, std::span<Vec3> out, std::size_t begin,
                            std::size_t end) const override {
    UnmappedPoints unmapped;
    for (std::size_t i = begin; i != end; ++i) {
      out[i] = in[i];
      if (in[i].x > limit_) unmapped.add(i);
    }
    return unmapped;
  }

 private:
  double limit_;
};

// The largest x of the first `rows` points: a DomainWarp with it maps those and fails later.
double largestX(const PolygonSoup& soup, std::size_t rows) {
  double limit = soup.positions[0].x;
  for (std::size_t i = 1; i < rows; ++i) limit = std::max(limit, soup.positions[i].x);
  return limit;
}

TEST_F(StreamRefusals, WarpDomainErrorIsTheWholeFileMessageWithIndicesInTheFile) {
  test::writeFile(input_, makePly(Spec{.vertices = 200}));
  PolygonSoup soup = readSoup(input_);
  const auto output = dir_.path() / "out.ply";
  const auto streamed = [&](const Warp& warp, std::size_t chunk) {
    StreamDeformOptions options;
    options.chunkPoints = chunk;
    return test::messageOf<InvalidInput>(
        [&] { deformFileStreaming(warp, input_, output, options); });
  };
  const auto whole = [&](const Warp& warp) {
    return test::messageOf<InvalidInput>(
        [&] { namingFile(input_.string(), [&] { deform(warp, soup); }); });
  };
  // Failures only in the last chunk (rows 150 to 199): the count is the file's, the message
  // the whole-file path's exactly.
  const DomainWarp late(largestX(soup, 150));
  EXPECT_EQ(streamed(late, 150), whole(late));
  EXPECT_EQ(streamed(late, 1000), whole(late));
  // Failures from the first chunk on: the first point is the file's, the count "at least" that
  // of the chunk where it is.
  const double limit = largestX(soup, 10);
  const DomainWarp early(limit);
  std::size_t first = 10;
  while (soup.positions[first].x <= limit) ++first;
  const std::size_t chunk = 3, begin = first / chunk * chunk;
  std::size_t inChunk = 0;
  for (std::size_t i = begin; i < begin + chunk; ++i) inChunk += soup.positions[i].x > limit;
  EXPECT_EQ(streamed(early, chunk), input_.string() + ": at least " + std::to_string(inChunk) +
                                        " of 200 points could not be warped (the first is point " +
                                        std::to_string(first) + ")");
  EXPECT_EQ(test::listDirectory(dir_.path()), std::set<std::string>{"in.ply"});
  // deformPlyRows: the same, with indices of the file.
  const std::string part = test::messageOf<InvalidInput>(
      [&] { deformPlyRows(early, input_, begin, 20, dir_.path() / "part"); });
  EXPECT_NE(part.find(input_.string() + ": at least "), std::string::npos) << part;
  EXPECT_NE(part.find("of 200 points could not be warped (the first is point " +
                      std::to_string(first) + ")"),
            std::string::npos)
      << part;
}

TEST_F(StreamRefusals, APartThatIsTheInputIsRefusedAndTheInputKept) {
  const std::string bytes = makePly(Spec{.vertices = 10, .faces = true});
  test::writeFile(input_, bytes);
  const auto symlink = dir_.path() / "link.ply";
  const auto hardLink = dir_.path() / "hard.ply";
  std::filesystem::create_symlink(input_, symlink);
  std::filesystem::create_hard_link(input_, hardLink);
  for (const auto& part : {input_, symlink, hardLink}) {
    const std::string message =
        test::messageOf<InvalidInput>([&] { deformPlyRows(twist(), input_, 0, 10, part); });
    EXPECT_NE(message.find(part.string()), std::string::npos) << message;
    EXPECT_NE(message.find("is the input " + input_.string()), std::string::npos) << message;
    EXPECT_EQ(test::readFile(input_), bytes);
    EXPECT_THROW(assemblePly(input_, {part}, dir_.path() / "out.ply"), InvalidInput);
  }
  EXPECT_FALSE(std::filesystem::exists(dir_.path() / "out.ply"));
}

TEST_F(StreamRefusals, AnOverflowingRowRangeSaysSo) {
  test::writeFile(input_, makePly(Spec{.vertices = 10}));
  const std::string message = test::messageOf<InvalidInput>([&] {
    deformPlyRows(twist(), input_, 3, std::numeric_limits<std::uint64_t>::max(),
                  dir_.path() / "part");
  });
  EXPECT_NE(message.find("first_row + row_count overflows"), std::string::npos) << message;
}

TEST_F(StreamRefusals, APipeIsNotStreamable) {
  const auto fifo = dir_.path() / "pipe.ply";
  ASSERT_EQ(mkfifo(fifo.c_str(), 0600), 0);
  // Neither call opens the pipe (which would block with no writer).
  EXPECT_FALSE(isStreamablePly(fifo));
  const std::string message = test::messageOf<InvalidInput>([&] { plyLayout(fifo); });
  EXPECT_NE(message.find(fifo.string() + ": cannot stream a pipe"), std::string::npos) << message;
}

TEST(StreamDeformChunks, AChunkPastTheRowsIsOneChunkAndProgressEndsOnce) {
  test::TempDir dir;
  const auto input = dir.path() / "in.ply";
  test::writeFile(input, makePly(Spec{.vertices = 5000, .normals = true}));
  const std::string expected = inMemory(twist(), input, dir.path() / "whole.ply");
  // Sequential (3) and pipelined (4096, and past the rows) chunks.
  for (std::size_t chunk : {std::size_t{3}, std::size_t{4096}, std::size_t{5000},
                            std::numeric_limits<std::size_t>::max()}) {
    StreamDeformOptions options;
    options.chunkPoints = chunk;
    std::vector<double> fractions;
    options.progress = [&](std::string_view stage, double fraction) {
      if (stage == "deform") fractions.push_back(fraction);
      return true;
    };
    const auto output = dir.path() / "out.ply";
    const StreamDeformReport report = deformFileStreaming(twist(), input, output, options);
    EXPECT_EQ(report.chunks,
              (5000 + std::min<std::size_t>(chunk, 5000) - 1) / std::min<std::size_t>(chunk, 5000))
        << chunk;
    EXPECT_EQ(test::readFile(output), expected) << chunk;
    EXPECT_EQ(std::count(fractions.begin(), fractions.end(), 1.0), 1) << chunk;
    EXPECT_TRUE(std::is_sorted(fractions.begin(), fractions.end())) << chunk;
  }
}

TEST(StreamDeformChunks, AChunkOfManyCodecBlocksIsByteIdentical) {
  // Rows are decoded and encoded 16 MiB at a time: 800k rows of 30 input and 54 output bytes
  // are several blocks on both sides within one chunk, and blocks end mid-chunk.
  test::TempDir dir;
  const auto input = dir.path() / "in.ply";
  test::writeFile(input, makePly(Spec{.vertices = 800000, .normals = true, .extras = true}));
  const std::string expected = inMemory(twist(), input, dir.path() / "whole.ply");
  for (std::size_t chunk : {std::size_t{500003}, std::numeric_limits<std::size_t>::max()}) {
    StreamDeformOptions options;
    options.chunkPoints = chunk;
    const auto output = dir.path() / "out.ply";
    deformFileStreaming(twist(), input, output, options);
    EXPECT_TRUE(test::readFile(output) == expected) << chunk;
  }
}

}  // namespace
}  // namespace spacewarp
