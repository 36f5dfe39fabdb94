// libFuzzer target for readPly (see fuzz_common.h for what counts as a finding). The round
// trip uses one of the three encodings, chosen by the input size.
#include <cstddef>
#include <cstdint>

#include <spacewarp/core/io/ply.h>
#include "tests/fuzz/fuzz_common.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  using namespace spacewarp;
  const PlyEncoding encodings[] = {PlyEncoding::Ascii, PlyEncoding::BinaryLittleEndian,
                                   PlyEncoding::BinaryBigEndian};
  const PlyEncoding encoding = encodings[size % 3];
  fuzz::check(
      data, size, [](std::istream& in) { return readPly(in, "fuzz.ply"); },
      [encoding](const PolygonSoup& soup, std::ostream& out) { writePly(soup, out, encoding); },
      /*withAttributes=*/true);
  return 0;
}
