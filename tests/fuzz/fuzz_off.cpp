// libFuzzer target for readOff (see fuzz_common.h for what counts as a finding).
#include <cstddef>
#include <cstdint>

#include <spacewarp/core/io/off.h>
#include "tests/fuzz/fuzz_common.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  using namespace spacewarp;
  fuzz::check(
      data, size, [](std::istream& in) { return readOff(in, "fuzz.off"); },
      [](const PolygonSoup& soup, std::ostream& out) { writeOff(soup, out); },
      /*withAttributes=*/false);
  return 0;
}
