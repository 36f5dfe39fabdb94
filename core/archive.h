#pragma once
// The warp archive: a compact binary form of any Warp, Coordinates or HandleDistances, so that a
// solved warp (RBF weights, a harmonic field, a fitted lattice) can be stored or sent to another
// process and used there without solving again. Little-endian and packed; every read is bounds
// checked, so a truncated or hostile archive is refused with InvalidInput, never a crash.
//
// Each class writes itself in its save() (a tag, then its fields, nested objects through
// warp()/coordinates()/distances()), and reads itself back in a static load(ArchiveReader&).
// The table from tags to load functions lives in rig/warp_archive.cpp, the one place that sees
// every module; rig/warp_archive.h has the whole-archive functions (header, version).

#include <cstddef>
#include <cstdint>
#include <functional>
#include <map>
#include <memory>
#include <span>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include <spacewarp/core/math.h>

namespace spacewarp {

class Warp;
class Coordinates;
class HandleDistances;
class ArchiveReader;

/// What loads a nested object once its tag has been read (filled by rig/warp_archive.cpp).
struct ArchiveLoaders {
  std::map<std::string, std::function<std::shared_ptr<const Warp>(ArchiveReader&)>, std::less<>>
      warps;
  std::map<std::string, std::function<std::shared_ptr<const Coordinates>(ArchiveReader&)>,
           std::less<>>
      coordinates;
  std::map<std::string, std::function<std::shared_ptr<const HandleDistances>(ArchiveReader&)>,
           std::less<>>
      distances;
};

/// The tag of a back-reference to a nested object written earlier in the same archive (no class
/// has it): followed by the object's number (u64), counted from 0 in the order objects start.
inline constexpr std::string_view kBackReference = "#";

/// Writes an archive: little-endian, packed. Sequences are their count (u64), then the data.
class ArchiveWriter {
 public:
  /// The first thing every save() writes: the tag its loader is registered under ("twist").
  void tag(std::string_view typeTag);

  void u8(std::uint8_t value);
  void u32(std::uint32_t value);
  void u64(std::uint64_t value);
  void i32(std::int32_t value);
  void f64(double value);  ///< The exact bits (NaN payloads and signed zeros included).
  void boolean(bool value);
  void string(std::string_view text);
  void vec3(const Vec3& v);
  void mat3(const Mat3& m);  ///< Column by column.
  void mat4(const Mat4& m);  ///< Column by column.
  void doubles(std::span<const double> values);
  void vec3s(std::span<const Vec3> values);
  void u32s(std::span<const std::uint32_t> values);
  void u64s(std::span<const std::uint64_t> values);

  /// An enumerator, as u32.
  template <class E>
  void enumeration(E e) {
    u32(static_cast<std::uint32_t>(e));
  }

  /// Nested objects: call x.save(*this), or, for an object already written in this archive (the
  /// same address, e.g. one Coordinates shared by several warps), write the back-reference tag
  /// kBackReference and the object's number, so that it is stored once and loads as one shared
  /// object. Nesting deeper than ArchiveReader::maxDepth is
  /// refused here with the reader's message, so nothing is saved that would not load.
  void warp(const Warp& w);
  void coordinates(const Coordinates& c);
  void distances(const HandleDistances& d);

  /// What has been written.
  const std::string& bytes() const { return bytes_; }

 private:
  template <class T>
  void nested(const T& object, int kind);

  std::string bytes_;
  int depth_ = 0;
  // The nested objects written so far, by kind and address, numbered in the order they started:
  // a second occurrence is written as a back-reference to that number.
  std::map<std::pair<int, const void*>, std::uint64_t> written_;
};

/// Reads an archive written by ArchiveWriter. Every read checks the bytes left; a failed check
/// throws InvalidInput("warp archive: <what> (byte N)").
class ArchiveReader {
 public:
  /// Reads `bytes` (not copied: it must outlive the reader), loading nested objects through
  /// `loaders` (kept by reference).
  ArchiveReader(std::string_view bytes, const ArchiveLoaders& loaders);

  std::uint8_t u8();
  std::uint32_t u32();
  std::uint64_t u64();
  std::int32_t i32();
  double f64();
  bool boolean();  ///< Refuses any byte but 0 and 1.
  std::string string();
  Vec3 vec3();
  Mat3 mat3();
  Mat4 mat4();
  /// Sequences: the count is checked against the bytes left before anything is allocated.
  std::vector<double> doubles();
  std::vector<Vec3> vec3s();
  std::vector<std::uint32_t> u32s();
  std::vector<std::uint64_t> u64s();

  /// An enumerator written by ArchiveWriter::enumeration; refuses values >= valueCount.
  template <class E>
  E enumeration(std::uint32_t valueCount) {
    const std::uint32_t value = u32();
    if (value >= valueCount) failEnumeration(value, valueCount);
    return static_cast<E>(value);
  }

  /// Nested objects: read the tag and dispatch through the loaders; an unknown tag is refused
  /// naming it, and so is nesting deeper than maxDepth.
  std::shared_ptr<const Warp> warp();
  std::shared_ptr<const Coordinates> coordinates();
  std::shared_ptr<const HandleDistances> distances();

  /// Throws InvalidInput("warp archive: " + what + " (byte N)"), N the current position.
  [[noreturn]] void fail(const std::string& what) const;

  /// The message of an InvalidInput thrown while the object tagged `typeTag`, starting at byte
  /// `start`, was loading (a constructor's check): "warp archive: <tag> at byte <start>: " +
  /// `what`, or `what` itself if it already starts with "warp archive:" (one prefix only, however
  /// deep the objects nest).
  static std::string inContext(std::string_view typeTag, std::size_t start,
                               const std::string& what);

  /// Whether every byte has been read.
  bool atEnd() const { return position_ == bytes_.size(); }

  /// The current position, in bytes from the start.
  std::size_t position() const { return position_; }

  /// The bytes not read yet: what a count must fit in before anything is allocated for it.
  std::size_t bytesLeft() const { return bytes_.size() - position_; }

  /// Moves back to `position` (at most the current one), so that fail() names the start of
  /// the field at fault.
  void seek(std::size_t position);

  /// How deep objects may nest (a composition of compositions ...): a hostile archive cannot
  /// exhaust the stack.
  static constexpr int maxDepth = 64;

 private:
  const char* take(std::size_t n, const char* what);
  std::size_t count(std::size_t elementSize, const char* what);
  [[noreturn]] void failEnumeration(std::uint32_t value, std::uint32_t valueCount) const;
  template <class T, class Table>
  std::shared_ptr<const T> nested(const Table& table, const char* kind);
  template <class T>
  std::shared_ptr<const T> backReference(std::size_t start, const char* kind);
  template <class T, class ReadOne>
  std::vector<T> array(const char* what, ReadOne readOne);

  std::string_view bytes_;
  const ArchiveLoaders& loaders_;
  std::size_t position_ = 0;
  int depth_ = 0;
  // Every nested object read so far, in the order they started (null while one is loading), and
  // its kind, for back-references.
  std::vector<std::pair<const char*, std::shared_ptr<const void>>> objects_;
};

}  // namespace spacewarp
