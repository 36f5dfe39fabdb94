// Tests of the line reading that the text readers share (core/io/detail/text_format.h): line ends,
// line numbers and byte offsets across the blocks it reads, and bounded reading of binary and
// endless input.

#include <spacewarp/core/io/detail/text_format.h>

#include <cstdint>
#include <istream>
#include <sstream>
#include <streambuf>
#include <string>
#include <string_view>
#include <vector>

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <spacewarp/core/errors.h>
#include "endless_input.h"
#include "test_util.h"

namespace spacewarp {
namespace {

using ::testing::ElementsAre;
using ::testing::HasSubstr;

std::vector<std::string> linesOf(const std::string& text, bool loneCrEndsLine) {
  std::istringstream in(text);
  detail::TextLines lines(in, "input.txt", loneCrEndsLine);
  std::vector<std::string> result;
  std::string_view line;
  while (lines.next(line)) result.emplace_back(line);
  return result;
}

/// The message of the IoError that reading every line of `in` throws ("" if none).
std::string errorReading(std::istream& in, bool loneCrEndsLine) {
  return test::messageOf<IoError>([&] {
    detail::TextLines lines(in, "input.txt", loneCrEndsLine);
    std::string_view line;
    while (lines.next(line)) {
    }
  });
}

TEST(TextLines, LinesEndAtLfAndCrLfAndAtALoneCrWhenAsked) {
  EXPECT_THAT(linesOf("a\nb\r\nc\rd", true), ElementsAre("a", "b", "c", "d"));
  EXPECT_THAT(linesOf("a\nb\r\nc\rd", false), ElementsAre("a", "b\r", "c\rd"));
  EXPECT_THAT(linesOf("a\n\nb\n", true), ElementsAre("a", "", "b"));
  EXPECT_THAT(linesOf("\r\r\n\n", true), ElementsAre("", "", ""));
  EXPECT_THAT(linesOf("", true), ElementsAre());
}

TEST(TextLines, LineNumbersAndNulOffsetsAreExactAcrossBlocks) {
  // 20000 short lines span three blocks of 64 KiB; each prefix length moves the line ends
  // against the block boundaries, so that some "\r\n" is split between two blocks.
  for (const std::string end : {"\n", "\r\n", "\r"}) {
    for (std::size_t prefix = 0; prefix < 12; ++prefix) {
      SCOPED_TRACE("line end of " + std::to_string(end.size()) + " bytes, prefix " +
                   std::to_string(prefix));
      // (Appended piece by piece: GCC 12 warns falsely about "literal" + std::string here.)
      std::string text = "#";
      text.append(prefix, 'c');
      text += end;
      for (int i = 0; i < 20000; ++i) {
        text += "v 1 2 3";
        text += end;
      }
      const std::size_t nulAt = text.size() + 3;
      text += "bad";
      text += '\0';
      text += end;
      const bool loneCr = end == "\r";
      std::istringstream in(text);
      EXPECT_EQ(errorReading(in, loneCr), "input.txt:20002: unexpected NUL byte (byte offset " +
                                              std::to_string(nulAt) + "): not a text file");
      EXPECT_EQ(linesOf(text.substr(0, nulAt), loneCr).size(), 20002u);
    }
  }
}

TEST(TextLines, BinaryInputFailsAtItsFirstBlock) {
  test::EndlessInput zeros("", '\0');
  std::istream in(&zeros);
  EXPECT_EQ(errorReading(in, true),
            "input.txt:1: unexpected NUL byte (byte offset 0): not a text file");
  EXPECT_LE(zeros.served(), test::EndlessInput::kBlockBound);
}

TEST(TextLines, AnEndlessLineFailsAtTheLengthLimit) {
  test::EndlessInput letters("first line\n", 'a');
  std::istream in(&letters);
  EXPECT_THAT(errorReading(in, false), HasSubstr("input.txt:2: line too long (more than "));
  EXPECT_GT(letters.served(), detail::kMaxTextLine);
  EXPECT_LE(letters.served(), detail::kMaxTextLine + test::EndlessInput::kBlockBound);
}

}  // namespace
}  // namespace spacewarp
