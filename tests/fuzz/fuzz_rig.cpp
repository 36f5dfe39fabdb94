// libFuzzer target for the rig reader: the bytes are parsed as a rig file (parseRigJson) and
// built (rigFromJson), and read as a surface edit's handles file (parseHandlesJson,
// resolveHandles), with paths resolved in an empty folder, so no cage or cache file is
// ever found. Only the typed errors may come out (InvalidInput, which the memory estimate also
// throws, IoError, SolverError); any other exception, a crash, a sanitizer report or a timeout is a
// finding. Memory is capped so that a rig asking for a huge job is refused by the estimate,
// as it would be on a small machine, instead of running into libFuzzer's RSS limit.
#include <unistd.h>

#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <string>
#include <string_view>
#include <vector>

#include <spacewarp/core/detail/memory_budget.h>
#include <spacewarp/core/errors.h>
#include <spacewarp/rig/handles_file.h>
#include <spacewarp/rig/rig.h>
#include <spacewarp/surface/handles.h>

namespace {

std::filesystem::path emptyFolder() {
  const std::filesystem::path dir =
      std::filesystem::temp_directory_path() / ("spacewarp_fuzz_rig_" + std::to_string(::getpid()));
  std::filesystem::create_directories(dir);
  return dir;
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  using namespace spacewarp;
  static const std::filesystem::path dir = emptyFolder();
  static const bool capped = (detail::setMemoryCap(std::size_t{64} << 20), true);
  (void)capped;
  const std::string_view text(reinterpret_cast<const char*>(data), size);
  nlohmann::json document;
  try {
    document = parseRigJson(text, "fuzz.json");
  } catch (const InvalidInput&) {
    return 0;
  } catch (const IoError&) {
    return 0;
  }
  try {
    rigFromJson(document, dir, "fuzz.json");
  } catch (const InvalidInput&) {
  } catch (const IoError&) {
  } catch (const SolverError&) {
  }
  // The same bytes as a handles file of surface editing, on a model of 64 vertices.
  static const std::vector<Vec3> model = [] {
    std::vector<Vec3> points;
    for (int i = 0; i < 64; ++i) points.emplace_back(i % 4, (i / 4) % 4, i / 16);
    return points;
  }();
  try {
    resolveHandles(parseHandlesJson(document, "fuzz.json", model.size()), model);
  } catch (const InvalidInput&) {
  }
  return 0;
}
