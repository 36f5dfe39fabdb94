#pragma once

namespace spacewarp::detail {

/// OpenVDB 10 reads a data chunk that a file stores uncompressed (its size field negative)
/// straight into the caller's buffer and only then compares the size with the buffer's, so a
/// corrupt size field overflows the heap (io::unzipFromStream and io::bloscFromStream; found
/// by fuzz_vdb). openvdb_chunks.cpp defines both functions again: being linked into the
/// program, its definitions take the place of libopenvdb's for every caller, OpenVDB's own
/// calls included (they go through the PLT). They check the size first and then hand the
/// chunk to OpenVDB's own function.
///
/// Returns whether the checked functions are the ones the program calls (false when another
/// copy of OpenVDB was bound first, e.g. by a module loaded earlier into the same process).
/// readVdbFile calls it, which also keeps openvdb_chunks.cpp in every program that reads VDB
/// files through spacewarp.
bool openVdbChunksChecked();

}  // namespace spacewarp::detail
