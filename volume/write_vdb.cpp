#include <spacewarp/volume/write_vdb.h>

#include <ostream>

#include <openvdb/io/Archive.h>

#include <spacewarp/core/errors.h>
#include <spacewarp/core/io/atomic_file.h>

namespace spacewarp {
namespace {

// OpenVDB's own file writer (io::File) opens the file itself and checks no write; this writes
// the same seekable format to the stream of the one atomic-write path instead.
class VdbArchive : public openvdb::io::Archive {
 public:
  void writeTo(std::ostream& out, const openvdb::GridCPtrVec& grids,
               const openvdb::MetaMap& metadata) const {
    write(out, grids, /*seekable=*/true, metadata);
  }
};

}  // namespace

void writeVdbFile(const std::filesystem::path& path, const openvdb::GridCPtrVec& grids,
                  const openvdb::MetaMap& metadata) {
  openvdb::initialize();
  try {
    writeFileAtomically(path,
                        [&](std::ostream& out) { VdbArchive().writeTo(out, grids, metadata); });
  } catch (const openvdb::Exception& e) {
    throw IoError(path.string() + ": cannot be written (" + e.what() + ")");
  }
}

}  // namespace spacewarp
