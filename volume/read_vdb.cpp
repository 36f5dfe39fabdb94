#include <spacewarp/volume/read_vdb.h>

#include <cerrno>
#include <cstdint>
#include <cstring>
#include <exception>
#include <fstream>
#include <ios>
#include <map>
#include <memory>
#include <new>
#include <string>
#include <string_view>
#include <system_error>
#include <vector>

#include <openvdb/io/Archive.h>
#include <openvdb/io/GridDescriptor.h>
#include <openvdb/io/io.h>

#include <spacewarp/core/errors.h>

namespace spacewarp {
namespace {

/// The fewest bytes a grid descriptor takes: three strings (a 4-byte length each: unique name,
/// type, instance parent) and three 8-byte stream positions.
constexpr std::uint64_t kMinDescriptorBytes = 3 * 4 + 3 * 8;

/// `text` as one printable line of at most 200 characters, for messages.
std::string shortened(std::string_view text) {
  constexpr std::size_t kMax = 200;
  std::string line = printable(text.substr(0, kMax));
  if (text.size() > kMax) line += "...";
  return line;
}

/// Reads a VDB file as io::File does (header, file metadata, grid descriptors, then every grid
/// at its recorded position), but from a stream that throws at the first read past the end of
/// the file, and with every recorded position checked against the file's size.
///
/// io::File reads with unchecked istream::read calls: a truncated file leaves the values it
/// could not read as they were (mostly zero) and the grid reads on with a failed stream, so a
/// file cut inside a grid loads as a grid with an empty or partial tree and no error. Here the
/// stream has failbit in its exception mask, so the first read that the file cannot satisfy
/// ends the reading, and the grid descriptors' end positions (the last one is the size of the
/// whole file) are checked before any grid is read, so a cut file is refused even when only
/// its header is read.
class VdbReader : public openvdb::io::Archive {
 public:
  VdbReader(std::string name, std::uint64_t size) : name_(std::move(name)), size_(size) {}

  VdbFile read(std::istream& in, bool headerOnly) {
    VdbFile content;
    try {
      in.exceptions(std::ios::failbit | std::ios::badbit);
      readContent(in, headerOnly, content);
    } catch (const IoError&) {
      throw;
    } catch (...) {
      // The stream says whether the file ended too soon; this is checked before the
      // exception's type because libstdc++ may throw an ios_base::failure of the other ABI,
      // which no handler here could name.
      const bool ended = in.rdstate() & std::ios::eofbit;
      if (ended) {
        fail("it ends inside " + stage_ + " (the file has " + std::to_string(size_) + " bytes)");
      }
      try {
        throw;
      } catch (const std::bad_alloc&) {
        fail(stage_ + ": a size in it is too large");
      } catch (const openvdb::Exception& e) {
        fail(stage_ + ": " + shortened(e.what()));
      } catch (const std::exception& e) {
        fail(stage_ + ": " + (in.bad() ? std::string("read error") : shortened(e.what())));
      }
    }
    return content;
  }

 private:
  [[noreturn]] void fail(const std::string& why) const {
    throw IoError(name_ + ": truncated or corrupt OpenVDB file: " + why);
  }

  void readContent(std::istream& in, bool headerOnly, VdbFile& content) {
    stage_ = "the file header";
    std::int64_t magic = 0;
    in.read(reinterpret_cast<char*>(&magic), sizeof magic);
    if (magic != openvdb::OPENVDB_MAGIC) throw IoError(name_ + ": not an OpenVDB file");
    in.seekg(0);
    readHeader(in);

    // Tag the stream with the file format, library version and compression, as io::File does.
    streamMetadata_ = std::make_shared<openvdb::io::StreamMetadata>();
    streamMetadata_->setSeekable(true);
    openvdb::io::setStreamMetadataPtr(in, streamMetadata_, /*transfer=*/false);
    setFormatVersion(in);
    setLibraryVersion(in);
    setDataCompression(in);

    stage_ = "the file metadata";
    content.metadata = std::make_shared<openvdb::MetaMap>();
    content.metadata->readMeta(in);

    stage_ = "the grid count";
    const std::int32_t count = readGridCount(in);
    const std::uint64_t position = static_cast<std::uint64_t>(in.tellg());
    if (count < 0 || static_cast<std::uint64_t>(count) >
                         (size_ - std::min(size_, position)) / kMinDescriptorBytes) {
      fail("the grid count " + std::to_string(count) + " does not fit in the file");
    }
    if (inputHasGridOffsets())
      readSeekable(in, count, headerOnly, content);
    else
      readSequential(in, count, content);
  }

  /// A file with grid offsets (what io::File writes): the descriptors first, each followed by
  /// its grid, then the grids at their recorded positions.
  void readSeekable(std::istream& in, std::int32_t count, bool headerOnly, VdbFile& content) {
    std::vector<openvdb::io::GridDescriptor> descriptors;
    for (std::int32_t i = 0; i < count; ++i) {
      stage_ = "grid descriptor " + std::to_string(i + 1) + " of " + std::to_string(count);
      openvdb::io::GridDescriptor gd;
      gd.read(in);
      const std::int64_t descriptorEnd = in.tellg();
      stage_ = gridName(gd);
      const std::int64_t gridPos = gd.getGridPos(), blockPos = gd.getBlockPos(),
                         endPos = gd.getEndPos();
      if (endPos < 0 || static_cast<std::uint64_t>(endPos) > size_) {
        fail(stage_ + " ends at byte " + std::to_string(endPos) + ", past the end of the file (" +
             std::to_string(size_) + " bytes)");
      }
      if (gridPos < descriptorEnd || gridPos > endPos ||
          (!gd.isInstance() && (blockPos < gridPos || blockPos > endPos))) {
        fail(stage_ + ": its recorded positions (" + std::to_string(gridPos) + ", " +
             std::to_string(blockPos) + ", " + std::to_string(endPos) +
             ") are out of order or out of the file");
      }
      descriptors.push_back(gd);
      gd.seekToEnd(in);
    }
    if (headerOnly) return;

    NamedGridMap named;
    for (const openvdb::io::GridDescriptor& gd : descriptors) {
      stage_ = gridName(gd);
      openvdb::GridBase::Ptr grid = createGrid(gd);
      gd.seekToGrid(in);
      readGrid(grid, gd, in);
      if (static_cast<std::int64_t>(in.tellg()) > gd.getEndPos())
        fail(stage_ + ": its data runs past its recorded end (byte " +
             std::to_string(gd.getEndPos()) + ")");
      content.grids.push_back(grid);
      named[gd.uniqueName()] = grid;
    }
    stage_ = "the grid instances";
    for (const openvdb::io::GridDescriptor& gd : descriptors) connectInstance(gd, named);
  }

  /// A file written as a stream (no grid offsets): every descriptor followed by its grid.
  void readSequential(std::istream& in, std::int32_t count, VdbFile& content) {
    std::vector<openvdb::io::GridDescriptor> descriptors;
    NamedGridMap named;
    for (std::int32_t i = 0; i < count; ++i) {
      stage_ = "grid descriptor " + std::to_string(i + 1) + " of " + std::to_string(count);
      openvdb::io::GridDescriptor gd;
      gd.read(in);
      stage_ = gridName(gd);
      openvdb::GridBase::Ptr grid = createGrid(gd);
      readGrid(grid, gd, in);
      descriptors.push_back(gd);
      content.grids.push_back(grid);
      named[gd.uniqueName()] = grid;
    }
    stage_ = "the grid instances";
    for (const openvdb::io::GridDescriptor& gd : descriptors) connectInstance(gd, named);
  }

  static std::string gridName(const openvdb::io::GridDescriptor& gd) {
    return "grid '" + shortened(openvdb::io::GridDescriptor::nameAsString(gd.uniqueName())) + "'";
  }

  openvdb::GridBase::Ptr createGrid(const openvdb::io::GridDescriptor& gd) const {
    if (!openvdb::GridBase::isRegistered(gd.gridType()))
      fail(stage_ + ": unknown grid type '" + shortened(gd.gridType()) + "'");
    openvdb::GridBase::Ptr grid = openvdb::GridBase::createGrid(gd.gridType());
    if (!grid) fail(stage_ + ": unknown grid type '" + shortened(gd.gridType()) + "'");
    grid->setSaveFloatAsHalf(gd.saveFloatAsHalf());
    return grid;
  }

  std::string name_;
  std::uint64_t size_;
  std::string stage_;  ///< What is being read, for messages ("grid 'density'").
  openvdb::io::StreamMetadata::Ptr streamMetadata_;  ///< The stream points at it while reading.
};

}  // namespace

VdbFile readVdbFile(const std::filesystem::path& path, bool headerOnly) {
  openvdb::initialize();
  const std::string name = path.string();
  std::error_code ec;
  const std::filesystem::file_status status = std::filesystem::status(path, ec);
  if (!std::filesystem::exists(status)) throw IoError(name + ": no such file");
  if (std::filesystem::is_directory(status)) throw IoError(name + ": is a directory");
  if (!std::filesystem::is_regular_file(status))
    throw IoError(name + ": not a regular file (an OpenVDB file is read at recorded offsets)");
  const std::uintmax_t size = std::filesystem::file_size(path, ec);
  if (ec) throw IoError(name + ": cannot be read (" + ec.message() + ")");
  errno = 0;
  std::ifstream in(path, std::ios::binary);
  if (!in) {
    const int code = errno;
    throw IoError(name + ": cannot be read" +
                  (code != 0 ? " (" + std::string(std::strerror(code)) + ")" : std::string()));
  }
  VdbFile content = VdbReader(name, size).read(in, headerOnly);
  if (!content.metadata) content.metadata = std::make_shared<openvdb::MetaMap>();
  for (const openvdb::GridBase::Ptr& grid : content.grids)
    if (!grid) throw IoError(name + ": truncated or corrupt OpenVDB file: a grid is missing");
  return content;
}

}  // namespace spacewarp
