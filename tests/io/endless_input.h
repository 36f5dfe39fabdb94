#pragma once
// An input that does not end (like /dev/zero or a FIFO fed forever), counting the bytes it
// hands out, for tests that a reader stops early on binary or endless input.

#include <algorithm>
#include <cstdint>
#include <streambuf>
#include <string>
#include <utility>

namespace spacewarp::test {

/// `prefix`, then `fill` bytes without end: up to kCap bytes, so that a reader that does not
/// stop early ends (and fails its test) rather than running the machine out of memory.
class EndlessInput : public std::streambuf {
 public:
  /// What the text readers may read past the point where they could tell that the input is
  /// bad: one 64 KiB block of their own, and one chunk of this input.
  static constexpr std::uint64_t kBlockBound = (std::uint64_t{1} << 16) + 4096;
  /// Where the input ends after all: far past any limit of the readers.
  static constexpr std::uint64_t kCap = std::uint64_t{256} << 20;

  EndlessInput(std::string prefix, char fill) : prefix_(std::move(prefix)), chunk_(4096, fill) {}

  /// The bytes handed out so far (an upper bound of what the reader consumed).
  std::uint64_t served() const { return served_; }

 protected:
  int_type underflow() override {
    if (gptr() != nullptr && gptr() < egptr()) return traits_type::to_int_type(*gptr());
    std::string& source = prefixServed_ || prefix_.empty() ? chunk_ : prefix_;
    prefixServed_ = true;
    if (served_ >= kCap) return traits_type::eof();
    const auto size =
        static_cast<std::size_t>(std::min<std::uint64_t>(source.size(), kCap - served_));
    setg(source.data(), source.data(), source.data() + size);
    served_ += size;
    return traits_type::to_int_type(*gptr());
  }

 private:
  std::string prefix_;
  std::string chunk_;
  bool prefixServed_ = false;
  std::uint64_t served_ = 0;
};

}  // namespace spacewarp::test
