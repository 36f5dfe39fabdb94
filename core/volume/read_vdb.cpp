#include <spacewarp/core/volume/read_vdb.h>

#include <exception>
#include <new>
#include <string>
#include <system_error>

#include <openvdb/io/File.h>

#include <spacewarp/core/errors.h>

namespace spacewarp {

VdbFile readVdbFile(const std::filesystem::path& path, bool headerOnly) {
  openvdb::initialize();
  std::error_code ec;
  if (!std::filesystem::exists(path, ec)) throw IoError(path.string() + ": no such file");
  if (std::filesystem::is_directory(path, ec)) throw IoError(path.string() + ": is a directory");
  VdbFile content;
  try {
    openvdb::io::File file(path.string());
    file.open(/*delayLoad=*/headerOnly);
    if (!headerOnly) {
      content.grids = *file.getGrids();
      content.metadata = file.getMetadata();
    }
    file.close();
  } catch (const openvdb::Exception& e) {
    throw IoError(path.string() + ": not a readable OpenVDB file (" + e.what() + ")");
  } catch (const std::ios_base::failure& e) {
    throw IoError(path.string() + ": cannot be read (" + e.what() + ")");
  } catch (const std::bad_alloc&) {
    // The grids do not fit in the memory available, or a corrupt size field asks for more
    // memory than there is: the two cannot be told apart here.
    throw IoError(path.string() +
                  ": out of memory while reading it (or a size in it is corrupt and too large)");
  } catch (const std::exception& e) {
    // OpenVDB's readers also let through the standard library's and its codecs' exceptions.
    throw IoError(path.string() + ": not a readable OpenVDB file (" + e.what() + ")");
  }
  if (!content.metadata) content.metadata = std::make_shared<openvdb::MetaMap>();
  for (const openvdb::GridBase::Ptr& grid : content.grids)
    if (!grid) throw IoError(path.string() + ": not a readable OpenVDB file (a grid is missing)");
  return content;
}

}  // namespace spacewarp
