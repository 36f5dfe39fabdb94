// libFuzzer target for readObj (see fuzz_common.h for what counts as a finding).
#include <cstddef>
#include <cstdint>

#include <spacewarp/core/io/obj.h>
#include "tests/fuzz/fuzz_common.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  using namespace spacewarp;
  fuzz::check(
      data, size, [](std::istream& in) { return readObj(in, "fuzz.obj"); },
      [](const PolygonSoup& soup, std::ostream& out) { writeObj(soup, out); },
      /*withAttributes=*/false);
  return 0;
}
