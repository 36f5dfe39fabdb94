#pragma once
// Writing OpenVDB files atomically: the output path of `spacewarp deform` on volumes and of
// spacewarp.warp_volume in Python.

#include <filesystem>

#include <openvdb/openvdb.h>

namespace spacewarp {

/// Writes `grids` and the file-level `metadata` to the VDB file at `path` in OpenVDB's seekable
/// format (with grid offsets, for delayed loading), atomically through writeFileAtomically(): on
/// any failure no partial or temporary file is left and an existing file is untouched. Throws
/// IoError naming the file.
void writeVdbFile(const std::filesystem::path& path, const openvdb::GridCPtrVec& grids,
                  const openvdb::MetaMap& metadata);

}  // namespace spacewarp
