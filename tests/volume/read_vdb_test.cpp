// Tests of volume/read_vdb.h: intact files read back as OpenVDB wrote them, in file order;
// truncated files (every cut of small files, random cuts of larger ones, each written with and
// without grid offsets, with grids of every kind) are refused with an IoError naming the file,
// never read as a file with an empty or partial grid.

#include <algorithm>
#include <bit>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <random>
#include <sstream>
#include <string>
#include <vector>

#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <openvdb/io/Archive.h>
#include <openvdb/io/Compression.h>
#include <openvdb/io/Stream.h>
#include <openvdb/openvdb.h>
#include <openvdb/points/PointConversion.h>
#include <openvdb/points/PointCount.h>
#include <openvdb/tools/PointIndexGrid.h>

#include <spacewarp/core/errors.h>
#include <spacewarp/volume/detail/openvdb_chunks.h>
#include <spacewarp/volume/read_vdb.h>
#include "io/io_test_util.h"
#include "volume/volume_test_util.h"

#if defined(SPACEWARP_SANITIZED) && __has_include(<sanitizer/lsan_interface.h>)
#include <sanitizer/lsan_interface.h>
#define SPACEWARP_LSAN 1
#endif

namespace spacewarp {
namespace {

namespace fs = std::filesystem;
using ::testing::HasSubstr;

/// How a file is laid out: with grid offsets (what io::File writes, read at the recorded
/// positions) or as a stream (what io::Stream writes, read in one pass).
enum class Layout { Seekable, Stream };

const char* layoutName(Layout layout) { return layout == Layout::Seekable ? "seekable" : "stream"; }

/// Writes the seekable layout to any seekable stream (io::File only writes to a path).
class MemoryArchive : public openvdb::io::Archive {
 public:
  using Archive::setCompression;

  void writeTo(std::ostream& out, const openvdb::GridPtrVec& grids,
               const openvdb::MetaMap& meta) const {
    write(out, grids, /*seekable=*/true, meta);
  }
};

/// The bytes of a VDB file holding `grids` and the file metadata "scene".
std::string vdbBytes(const openvdb::GridPtrVec& grids, Layout layout,
                     std::uint32_t compression = openvdb::io::COMPRESS_ACTIVE_MASK |
                                                 openvdb::io::COMPRESS_BLOSC) {
  openvdb::MetaMap meta;
  meta.insertMeta("scene", openvdb::StringMetadata("read_vdb test"));
  std::stringstream out(std::ios::in | std::ios::out | std::ios::binary);
  if (layout == Layout::Seekable) {
    MemoryArchive archive;
    archive.setCompression(compression);
    archive.writeTo(out, grids, meta);
  } else {
    openvdb::io::Stream(static_cast<std::ostream&>(out)).write(grids, meta);
  }
  return out.str();
}

/// A uniform velocity field in a cube of n³ voxels.
openvdb::Vec3SGrid::Ptr makeVelocity(int n, double voxelSize) {
  auto grid = openvdb::Vec3SGrid::create(openvdb::Vec3s(0.0f));
  grid->setName("velocity");
  grid->setTransform(openvdb::math::Transform::createLinearTransform(voxelSize));
  for (int i = 0; i < n; ++i)
    for (int j = 0; j < n; ++j)
      for (int k = 0; k < n; ++k)
        grid->tree().setValue(openvdb::Coord(i, j, k), openvdb::Vec3s(float(i), 1.0f, -2.0f));
  return grid;
}

/// `count` points on a helix around (2, 2, z), with an integer attribute "id".
openvdb::points::PointDataGrid::Ptr makePoints(int count, double voxelSize) {
  std::vector<openvdb::Vec3R> positions;
  for (int i = 0; i < count; ++i)
    positions.emplace_back(2.0 + std::cos(0.1 * i), 2.0 + std::sin(0.1 * i), 0.01 * i);
  return test::makePointGrid(positions, voxelSize);
}

/// Grids of every kind the reader meets, the point data grid last: a level set "sphere", a grid
/// "sphere copy" that shares its tree (written as an instance), a fog volume "density", a vector
/// grid "velocity" and a point data grid "points"; the larger `scale`, the larger each grid.
openvdb::GridPtrVec makeGrids(double scale) {
  openvdb::initialize();
  // Every grid in the positive octant: one root child each, which keeps small files small.
  auto sphere = test::makeSphere(0.5 * scale, Vec3(1.0 + 0.6 * scale), 0.1);
  openvdb::GridBase::Ptr copy = sphere->copyGrid();
  copy->setName("sphere copy");
  auto fog = test::makeGaussianFog(Vec3(2.0), 0.1 * scale, 0.1);
  return {sphere, copy, fog, makeVelocity(static_cast<int>(3 * scale), 0.1),
          makePoints(static_cast<int>(40 * scale), 0.25)};
}

/// While it lives, LeakSanitizer ignores what is allocated: OpenVDB's RootNode::readTopology
/// leaks the child node it was reading when the read throws (it stores the node only once read),
/// which a cut file makes it do. Not a leak of ours; tests/fuzz/run.sh ignores it too.
class OpenVdbLeaksIgnored {
 public:
#ifdef SPACEWARP_LSAN
  OpenVdbLeaksIgnored() { __lsan_disable(); }
  ~OpenVdbLeaksIgnored() { __lsan_enable(); }
#else
  OpenVdbLeaksIgnored() {}  // user-provided, so that an unused instance is no warning
#endif
  OpenVdbLeaksIgnored(const OpenVdbLeaksIgnored&) = delete;
  OpenVdbLeaksIgnored& operator=(const OpenVdbLeaksIgnored&) = delete;
};

/// The message of the IoError that reading `path` throws ("" if it throws none).
std::string readError(const fs::path& path, bool headerOnly) {
  const OpenVdbLeaksIgnored ignored;
  return test::messageOf<IoError>([&] { readVdbFile(path, headerOnly); });
}

/// Replaces the file at `path` with `bytes`. (Removed first: on ext4, truncating a file that has
/// data on open flushes it to disk, some milliseconds each time.)
void replaceFile(const fs::path& path, const std::string& bytes) {
  fs::remove(path);
  test::writeFile(path, bytes);
}

/// Writes the first `length` bytes of `bytes` to `path` and checks that reading it, whole and
/// header only, throws an IoError naming the file as truncated or corrupt. Returns false (and
/// records the failure) otherwise.
bool expectRefused(const fs::path& path, const std::string& bytes, std::size_t length) {
  replaceFile(path, bytes.substr(0, length));
  const std::string expected = path.string() + ": truncated or corrupt OpenVDB file";
  for (const bool headerOnly : {false, true}) {
    const std::string message = readError(path, headerOnly);
    if (message.rfind(expected, 0) != 0 || message.find('\n') != std::string::npos) {
      ADD_FAILURE() << "the first " << length << " of " << bytes.size() << " bytes"
                    << (headerOnly ? " (header only)" : "") << ": '" << message << "'";
      return false;
    }
  }
  return true;
}

TEST(ReadVdb, IntactFilesReadBackEveryGridInFileOrder) {
  const openvdb::GridPtrVec grids = makeGrids(1.0);
  test::TempDir dir;
  for (const Layout layout : {Layout::Seekable, Layout::Stream}) {
    SCOPED_TRACE(layoutName(layout));
    const fs::path path = dir.path() / "in.vdb";
    test::writeFile(path, vdbBytes(grids, layout));

    const VdbFile header = readVdbFile(path, /*headerOnly=*/true);
    ASSERT_TRUE(header.metadata);
    EXPECT_EQ(header.metadata->metaValue<std::string>("scene"), "read_vdb test");

    const VdbFile file = readVdbFile(path);
    ASSERT_EQ(file.grids.size(), grids.size());
    EXPECT_EQ(file.metadata->metaValue<std::string>("scene"), "read_vdb test");
    for (std::size_t g = 0; g < grids.size(); ++g) {
      EXPECT_EQ(file.grids[g]->getName(), grids[g]->getName());
      EXPECT_EQ(file.grids[g]->type(), grids[g]->type());
      EXPECT_EQ(file.grids[g]->activeVoxelCount(), grids[g]->activeVoxelCount());
    }
    EXPECT_TRUE(test::bitIdentical(*openvdb::gridPtrCast<openvdb::FloatGrid>(file.grids[0]),
                                   *openvdb::gridPtrCast<openvdb::FloatGrid>(grids[0])));
    EXPECT_EQ(file.grids[1]->baseTreePtr(), file.grids[0]->baseTreePtr())
        << "the instance shares its parent's tree";
    EXPECT_TRUE(test::bitIdentical(*openvdb::gridPtrCast<openvdb::FloatGrid>(file.grids[2]),
                                   *openvdb::gridPtrCast<openvdb::FloatGrid>(grids[2])));
    EXPECT_TRUE(test::bitIdentical(*openvdb::gridPtrCast<openvdb::Vec3SGrid>(file.grids[3]),
                                   *openvdb::gridPtrCast<openvdb::Vec3SGrid>(grids[3])));
    const auto points = openvdb::gridPtrCast<openvdb::points::PointDataGrid>(file.grids[4]);
    ASSERT_TRUE(points);
    EXPECT_EQ(openvdb::points::pointCount(points->tree()), 40u);
  }
}

/// The offsets at which each grid but the first starts in the file of `grids` (the file of the
/// first k grids ends where grid k starts).
std::vector<std::size_t> gridStarts(const openvdb::GridPtrVec& grids, Layout layout) {
  std::vector<std::size_t> starts;
  for (std::size_t k = 1; k < grids.size(); ++k)
    starts.push_back(
        vdbBytes(openvdb::GridPtrVec(grids.begin(), grids.begin() + k), layout).size());
  return starts;
}

/// Whether `length` is within `margin` bytes of one of `offsets`.
bool near(std::size_t length, const std::vector<std::size_t>& offsets, std::size_t margin) {
  return std::any_of(offsets.begin(), offsets.end(), [&](std::size_t offset) {
    return length + margin >= offset && length <= offset + margin;
  });
}

TEST(ReadVdb, EveryTruncationNearEachPartOfAFileIsRefused) {
  const openvdb::GridPtrVec grids = makeGrids(0.5);
  test::TempDir dir;
  // With grid offsets, every cut fails the check of the recorded positions before any grid is
  // read: every cut in the first and last 2 kB (header, file metadata, the first grid's
  // descriptor, the last grid's end) and within 256 bytes of each grid's start, every 7th
  // between.
  const std::string seekable = vdbBytes(grids, Layout::Seekable);
  std::vector<std::size_t> starts = gridStarts(grids, Layout::Seekable);
  int failures = 0, cuts = 0;
  for (std::size_t length = 0; length < seekable.size() && failures < 10; ++length) {
    if (length < 2048 || length + 2048 >= seekable.size() || near(length, starts, 256) ||
        length % 7 == 0) {
      failures += !expectRefused(dir.path() / "cut.vdb", seekable, length);
      ++cuts;
    }
  }
  EXPECT_GT(cuts, 8000);

  // Written as a stream, the grids are read until the bytes run out. OpenVDB leaks the node
  // whose topology such a read leaves half done (some 300 kB each time), so fewer cuts: every
  // byte of the first 512 (the header and the first grid's start), within 48 bytes of each
  // grid's start, of the last 128, and every 499th between.
  const std::string stream = vdbBytes(grids, Layout::Stream);
  starts = gridStarts(grids, Layout::Stream);
  failures = 0;
  cuts = 0;
  for (std::size_t length = 0; length < stream.size() && failures < 10; ++length) {
    if (length < 512 || near(length, starts, 48) || length + 128 >= stream.size() ||
        length % 499 == 0) {
      failures += !expectRefused(dir.path() / "cut.vdb", stream, length);
      ++cuts;
    }
  }
  EXPECT_GT(cuts, 1000);
}

TEST(ReadVdb, RandomTruncationsOfLargerFilesAreRefused) {
  const openvdb::GridPtrVec grids = makeGrids(4.0);
  test::TempDir dir;
  std::mt19937_64 rng(2024);
  for (const Layout layout : {Layout::Seekable, Layout::Stream}) {
    SCOPED_TRACE(layoutName(layout));
    const std::string bytes = vdbBytes(grids, layout);
    ASSERT_GT(bytes.size(), 200000u);
    std::uniform_int_distribution<std::size_t> cut(0, bytes.size() - 1);
    int failures = 0;
    for (int i = 0; i < 200 && failures < 10; ++i)
      failures += !expectRefused(dir.path() / "cut.vdb", bytes, cut(rng));
  }
  // Each grid alone in a file, cut in its last bytes.
  for (const openvdb::GridBase::Ptr& grid : grids) {
    SCOPED_TRACE(grid->getName());
    for (const Layout layout : {Layout::Seekable, Layout::Stream}) {
      const std::string bytes = vdbBytes({grid}, layout);
      for (std::size_t back = 1; back <= std::min<std::size_t>(32, bytes.size()); ++back)
        expectRefused(dir.path() / "cut.vdb", bytes, bytes.size() - back);
    }
  }
}

/// The offset of the only copy of the 8 bytes of `value` in `bytes` (npos if none or several).
std::size_t findInt64(const std::string& bytes, std::int64_t value) {
  char pattern[8];
  std::memcpy(pattern, &value, sizeof pattern);
  const std::string needle(pattern, sizeof pattern);
  const std::size_t first = bytes.find(needle);
  return first == bytes.rfind(needle) ? first : std::string::npos;
}

TEST(ReadVdb, ACutThatTheRecordedPositionsHideIsStillRefused) {
  // The last grid's recorded end is the file size. Cut the file inside that grid and make its
  // recorded positions fit the cut: the check of the positions passes, and only the read that
  // runs out of bytes can tell that the grid is incomplete.
  test::TempDir dir;
  const openvdb::GridPtrVec all = makeGrids(0.5);
  for (const openvdb::GridPtrVec& grids :
       {all, openvdb::GridPtrVec{all[0]}, openvdb::GridPtrVec{all[3]}}) {
    SCOPED_TRACE(grids.back()->getName());
    const std::string bytes = vdbBytes(grids, Layout::Seekable);
    const std::size_t endAt = findInt64(bytes, static_cast<std::int64_t>(bytes.size()));
    ASSERT_NE(endAt, std::string::npos);
    std::int64_t gridPos = 0, blockPos = 0;
    std::memcpy(&gridPos, bytes.data() + endAt - 16, 8);
    std::memcpy(&blockPos, bytes.data() + endAt - 8, 8);
    ASSERT_EQ(static_cast<std::size_t>(gridPos), endAt + 8) << "the grid follows its positions";
    ASSERT_LT(gridPos, blockPos);
    // Every byte of the grid's first and last bytes, a stride between (see the test above).
    const auto size = static_cast<std::int64_t>(bytes.size());
    int failures = 0;
    for (std::int64_t length = gridPos; length < size && failures < 10;
         length += (length < gridPos + 128 || length + 128 >= size) ? 1 : 211) {
      std::string cut = bytes.substr(0, static_cast<std::size_t>(length));
      const std::int64_t block = std::min(blockPos, length);
      std::memcpy(cut.data() + endAt - 8, &block, 8);
      std::memcpy(cut.data() + endAt, &length, 8);
      const fs::path path = dir.path() / "cut.vdb";
      replaceFile(path, cut);
      const std::string message = readError(path, /*headerOnly=*/false);
      const std::string expected =
          path.string() + ": truncated or corrupt OpenVDB file: it ends inside grid '";
      if (message.rfind(expected, 0) != 0) {
        ADD_FAILURE() << "cut at " << length << " of " << bytes.size() << ": '" << message << "'";
        ++failures;
      }
      // The header alone is consistent: only reading the grid finds the cut.
      EXPECT_NO_THROW(readVdbFile(path, /*headerOnly=*/true));
    }
  }
}

TEST(ReadVdb, OtherFilesAreRefusedNamingThem) {
  test::TempDir dir;
  const fs::path text = dir.path() / "text.vdb";
  test::writeFile(text, "this is not a volume\n");
  EXPECT_EQ(readError(text, false), text.string() + ": not an OpenVDB file");
  EXPECT_EQ(readError(dir.path() / "missing.vdb", false),
            (dir.path() / "missing.vdb").string() + ": no such file");
  EXPECT_EQ(readError(dir.path(), true), dir.path().string() + ": is a directory");
  EXPECT_THAT(readError("/dev/zero", true), HasSubstr("/dev/zero: not a regular file"));
}

// OpenVDB 10 reads a chunk stored uncompressed into the caller's buffer before checking its
// size (a heap overflow found by fuzz_vdb); volume/detail/openvdb_chunks.cpp checks it first.
using ChunkReader = void (*)(std::istream&, char*, std::size_t);
const ChunkReader kChunkReaders[] = {&openvdb::io::unzipFromStream, &openvdb::io::bloscFromStream};

/// A chunk as OpenVDB stores it uncompressed: the size -n, then n bytes.
std::string storedUncompressed(const std::string& bytes) {
  const std::int64_t size = -static_cast<std::int64_t>(bytes.size());
  return std::string(reinterpret_cast<const char*>(&size), 8) + bytes;
}

TEST(OpenVdbChunks, TheCheckedReadersAreTheOnesThisProgramCalls) {
  EXPECT_TRUE(detail::openVdbChunksChecked());
}

TEST(OpenVdbChunks, AnUncompressedChunkLargerThanTheBufferIsRefusedBeforeAnyByteIsWritten) {
  for (const ChunkReader read : kChunkReaders) {
    for (const std::size_t claimed : {std::size_t(17), std::size_t(4096), std::size_t(15)}) {
      std::istringstream in(storedUncompressed(std::string(claimed, 'x')));
      // The reader is told the buffer holds 16 bytes; the 16 after them must stay untouched.
      std::string buffer(32, '.');
      EXPECT_THROW(read(in, buffer.data(), 16), openvdb::IoError) << claimed;
      EXPECT_EQ(buffer, std::string(32, '.')) << claimed;
    }
    // The most negative size has no positive counterpart.
    const std::int64_t lowest = INT64_MIN;
    std::istringstream in(std::string(reinterpret_cast<const char*>(&lowest), 8));
    std::string buffer(16, '.');
    EXPECT_THROW(read(in, buffer.data(), 16), openvdb::IoError);
  }
}

TEST(OpenVdbChunks, IntactChunksReadAsOpenVdbWroteThem) {
  std::string data(3000, '\0');
  std::mt19937 random(5);
  for (char& c : data) c = static_cast<char>(random() % 7);  // compressible
  for (const bool compressed : {false, true}) {
    for (int which = 0; which < 2; ++which) {
      std::stringstream chunk(std::ios::in | std::ios::out | std::ios::binary);
      if (!compressed)
        chunk << storedUncompressed(data);
      else if (which == 0)
        openvdb::io::zipToStream(chunk, data.data(), data.size());
      else
        openvdb::io::bloscToStream(chunk, data.data(), 1, data.size());
      chunk << "after";
      std::string back(data.size(), '.');
      kChunkReaders[which](chunk, back.data(), back.size());
      EXPECT_EQ(back, data) << compressed << which;
      std::string rest;
      chunk >> rest;
      EXPECT_EQ(rest, "after") << "the reader stopped at the chunk's end";
    }
  }
}

TEST(OpenVdbChunks, AFileWhoseChunkClaimsMoreThanItsLeafIsRefused) {
  // Random bits do not compress: zip stores every leaf's 512 floats uncompressed (size
  // -2048). OpenVDB's own reading of a float grid happens inside libopenvdb, so this also
  // checks that the library's calls reach the checked readers.
  auto grid = openvdb::FloatGrid::create(0.0f);
  grid->setName("noise");
  std::mt19937 random(9);
  for (int i = 0; i < 8; ++i)
    for (int j = 0; j < 8; ++j)
      for (int k = 0; k < 8; ++k)
        grid->tree().setValue(openvdb::Coord(i, j, k),
                              std::bit_cast<float>(static_cast<std::uint32_t>(random())));
  std::string bytes = vdbBytes({grid}, Layout::Seekable, openvdb::io::COMPRESS_ZIP);
  const std::int64_t leaf = -2048, twice = -4096;
  const std::size_t at = bytes.rfind(std::string(reinterpret_cast<const char*>(&leaf), 8));
  ASSERT_NE(at, std::string::npos) << "no leaf stored uncompressed";
  test::TempDir dir;
  const fs::path path = dir.path() / "noise.vdb";
  replaceFile(path, bytes);
  EXPECT_EQ(readError(path, false), "");
  std::memcpy(bytes.data() + at, &twice, 8);
  replaceFile(path, bytes);
  EXPECT_EQ(readError(path, false),
            path.string() +
                ": truncated or corrupt OpenVDB file: grid 'noise': IoError: a chunk stored "
                "uncompressed claims 4096 bytes where 2048 are expected");
}

}  // namespace
}  // namespace spacewarp
