// libFuzzer target for the VDB input path of `spacewarp deform`: the bytes are written to a
// file, read by readVdbFile() and every grid goes through the dispatch (isWarpableGrid,
// warpGrid) with a mild twist. Malformed files must be rejected with IoError, grids that cannot
// be warped with InvalidInput; any other exception, a crash, a sanitizer report or a hang is
// a finding. OpenVDB itself is not instrumented: the aim is our code path, not OpenVDB's.
//
// A corrupt size field makes OpenVDB ask for petabytes (io::unzipFromStream's buffer). The
// system allocator refuses such a request with std::bad_alloc, which readVdbFile() turns into
// IoError; ASan's allocator aborts instead, so this target replaces the global operator new
// with one that refuses, as the system does, any request above kAllocationCap (every
// unaligned form, so that each pairs with its delete). ASan still checks every access to what
// it hands out (malloc is intercepted).
#include <unistd.h>

#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <new>
#include <string>

#include <spacewarp/core/errors.h>
#include <spacewarp/core/twist.h>
#include <spacewarp/volume/read_vdb.h>
#include <spacewarp/volume/warp_grid.h>

namespace {

[[noreturn]] void finding(const char* what, const char* detail) {
  std::fprintf(stderr, "fuzz finding: %s: %s\n", what, detail);
  std::abort();
}

// Grids larger than this are read but not warped: warping is linear in the active voxels (an
// active root tile holds 4096³), so a few bytes could otherwise ask for hours of honest work.
constexpr openvdb::Index64 kMaxWarpedVoxels = 1 << 14;

// Above every honest single allocation for a file of at most -max_len (32 kB) bytes: OpenVDB's
// largest fixed-size blocks (an internal node's child table) are well under 1 MB, so only a
// corrupt size field asks for more. Lower than that, a corrupt metadata size of several hundred
// MB costs seconds of ASan's checked copying per input, which the fuzzer reports as a timeout.
constexpr std::size_t kAllocationCap = std::size_t{64} << 20;

}  // namespace

void* operator new(std::size_t size) {
  if (size > kAllocationCap) throw std::bad_alloc();
  if (void* memory = std::malloc(size == 0 ? 1 : size)) return memory;
  throw std::bad_alloc();
}
void* operator new[](std::size_t size) { return ::operator new(size); }
void* operator new(std::size_t size, const std::nothrow_t&) noexcept {
  if (size > kAllocationCap) return nullptr;
  return std::malloc(size == 0 ? 1 : size);
}
void* operator new[](std::size_t size, const std::nothrow_t& tag) noexcept {
  return ::operator new(size, tag);
}
void operator delete(void* memory) noexcept { std::free(memory); }
void operator delete[](void* memory) noexcept { std::free(memory); }
void operator delete(void* memory, std::size_t) noexcept { std::free(memory); }
void operator delete[](void* memory, std::size_t) noexcept { std::free(memory); }
void operator delete(void* memory, const std::nothrow_t&) noexcept { std::free(memory); }
void operator delete[](void* memory, const std::nothrow_t&) noexcept { std::free(memory); }

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  using namespace spacewarp;
  static const std::filesystem::path path =
      std::filesystem::temp_directory_path() / ("fuzz_vdb_" + std::to_string(::getpid()) + ".vdb");
  {
    std::ofstream out(path, std::ios::binary | std::ios::trunc);
    out.write(reinterpret_cast<const char*>(data), static_cast<std::streamsize>(size));
  }
  VdbFile file;
  try {
    file = readVdbFile(path);
  } catch (const IoError&) {
    return 0;
  } catch (const std::exception& e) {
    finding("readVdbFile threw something other than IoError", e.what());
  }
  static const TwistWarp twist(
      TwistOptions{.origin = Vec3(0.0), .axis = Vec3(0, 0, 1), .rate = 0.3});
  WarpVolumeOptions options;
  options.inverse.maxIterations = 8;
  for (const openvdb::GridBase::Ptr& grid : file.grids) {
    if (!isWarpableGrid(*grid) || grid->activeVoxelCount() > kMaxWarpedVoxels) continue;
    try {
      const WarpedGrid<openvdb::GridBase> warped = warpGrid(twist, *grid, options);
      if (!warped.grid) finding("warpGrid returned no grid", grid->getName().c_str());
    } catch (const InvalidInput&) {
    } catch (const std::exception& e) {
      finding("warpGrid threw something other than InvalidInput", e.what());
    }
  }
  return 0;
}
