// libFuzzer target for warp archives (rig/warp_archive.h): the bytes are loaded as a warp
// (loadWarp) and as coordinates (loadCoordinates). Only InvalidInput may come out (a load
// function's constructor may also find a SolverError); any other exception, a crash, a
// sanitizer report or a timeout is a finding. What loads must save again, and that archive must
// load and save to the same bytes; a loaded warp is applied to a few points. Memory is capped
// as in fuzz_rig, so that an archive asking for a huge lattice is refused by the estimate.
#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <string>
#include <string_view>
#include <vector>

#include <spacewarp/core/detail/memory_budget.h>
#include <spacewarp/core/errors.h>
#include <spacewarp/rig/warp_archive.h>

namespace {

[[noreturn]] void finding(const char* what) {
  std::fprintf(stderr, "fuzz finding: %s\n", what);
  std::abort();
}

// Saving what was loaded gives an archive that loads and saves to the same bytes.
template <class T, class Save, class Load>
void expectStableRoundTrip(const T& object, Save save, Load load) {
  std::string once;
  try {
    once = save(object);
  } catch (const spacewarp::InvalidInput&) {
    finding("a loaded object cannot be saved");
  }
  if (save(*load(once)) != once) finding("a saved archive changed on a second round trip");
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  using namespace spacewarp;
  static const bool capped = (detail::setMemoryCap(std::size_t{64} << 20), true);
  (void)capped;
  const std::string_view bytes(reinterpret_cast<const char*>(data), size);
  try {
    const auto warp = loadWarp(bytes);
    expectStableRoundTrip(*warp, saveWarp, loadWarp);
    std::vector<Vec3> points{{0.0, 0.0, 0.0}, {0.5, -0.25, 0.125}, {3.0, 2.0, -1.0}};
    try {
      warp->applyBatch(points, points);
      (void)warp->jacobian(Vec3(0.25));
    } catch (const InvalidInput&) {  // points outside a cage
    }
  } catch (const InvalidInput&) {
  } catch (const SolverError&) {
  }
  try {
    const auto coordinates = loadCoordinates(bytes);
    expectStableRoundTrip(*coordinates, saveCoordinates, loadCoordinates);
    std::vector<double> row(coordinates->columnCount());
    try {
      coordinates->weights(Vec3(0.25), row);
    } catch (const InvalidInput&) {
    }
  } catch (const InvalidInput&) {
  } catch (const SolverError&) {
  }
  return 0;
}
