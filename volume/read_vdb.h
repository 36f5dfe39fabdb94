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

/// Reads every grid of the VDB file at `path` (with `headerOnly`, only checks that it is one:
/// the file is opened with delayed loading and no grid is read). Calls openvdb::initialize().
/// Throws IoError naming the file if it is missing, a directory, or not a readable OpenVDB file:
/// whatever OpenVDB throws on malformed bytes (its own exceptions, stream failures, allocations
/// that corrupt sizes make impossible) becomes that IoError.
VdbFile readVdbFile(const std::filesystem::path& path, bool headerOnly = false);

}  // namespace spacewarp
