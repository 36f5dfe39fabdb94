#pragma once
// Reading OpenVDB files whole, with every failure of a malformed file turned into an IoError
// that names the file: the input path of `spacewarp deform` on volumes (and of its fuzzer).

#include <filesystem>

#include <openvdb/openvdb.h>

namespace spacewarp {

/// The grids of a VDB file, fully loaded, and its file-level metadata (never null).
struct VdbFile {
  openvdb::GridPtrVec grids;
  openvdb::MetaMap::Ptr metadata;
};

/// Reads every grid of the VDB file at `path`, in file order (with `headerOnly`, only checks that
/// it is one: its header, metadata and grid descriptors are read, no grid, unless the file was
/// written as a stream, without grid offsets, which is read whole). Calls
/// openvdb::initialize(). Throws IoError naming the file if it is missing, a directory, not a
/// regular file, not an OpenVDB file, or truncated or corrupt ("<path>: truncated or corrupt
/// OpenVDB file: ..."): a file that ends before what it declares (even when only its header is
/// read, since every grid's recorded end must lie within the file), and whatever OpenVDB throws
/// on malformed bytes (its own exceptions, stream failures, allocations that corrupt sizes make
/// impossible). Never returns an empty or partial grid in place of a missing one.
VdbFile readVdbFile(const std::filesystem::path& path, bool headerOnly = false);

}  // namespace spacewarp
