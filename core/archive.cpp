#include <spacewarp/core/archive.h>

#include <cxxabi.h>

#include <bit>
#include <cstdlib>
#include <cstring>
#include <stdexcept>
#include <typeinfo>

#include <spacewarp/core/coordinates.h>
#include <spacewarp/core/errors.h>
#include <spacewarp/core/handle_distances.h>
#include <spacewarp/core/warp.h>

namespace spacewarp {

namespace {

// The C++ name of the dynamic type of `object`, for the message of what cannot be saved.
template <class T>
std::string typeName(const T& object) {
  const char* mangled = typeid(object).name();
  int status = 0;
  char* demangled = abi::__cxa_demangle(mangled, nullptr, nullptr, &status);
  std::string name = status == 0 && demangled ? demangled : mangled;
  std::free(demangled);
  return name;
}

template <class T>
[[noreturn]] void cannotSave(const char* kind, const T& object) {
  throw InvalidInput(std::string("warp archive: this ") + kind + " (" + typeName(object) +
                     ") cannot be saved");
}

std::string nestedTooDeep() {
  return "objects nested deeper than " + std::to_string(ArchiveReader::maxDepth);
}

}  // namespace

// The defaults of the three interfaces: a class that does not override save() is refused.
void Warp::save(ArchiveWriter&) const { cannotSave("Warp", *this); }
void Coordinates::save(ArchiveWriter&) const { cannotSave("Coordinates", *this); }
void HandleDistances::save(ArchiveWriter&) const { cannotSave("HandleDistances", *this); }

// ---------------------------------------------------------------------------------------------
// Writer. Integers byte by byte (least significant first), so the format does not depend on
// the machine's byte order.

void ArchiveWriter::tag(std::string_view typeTag) { string(typeTag); }

void ArchiveWriter::u8(std::uint8_t value) { bytes_.push_back(static_cast<char>(value)); }

void ArchiveWriter::u32(std::uint32_t value) {
  for (int i = 0; i < 4; ++i) u8(static_cast<std::uint8_t>(value >> (8 * i)));
}

void ArchiveWriter::u64(std::uint64_t value) {
  for (int i = 0; i < 8; ++i) u8(static_cast<std::uint8_t>(value >> (8 * i)));
}

void ArchiveWriter::i32(std::int32_t value) { u32(static_cast<std::uint32_t>(value)); }

void ArchiveWriter::f64(double value) { u64(std::bit_cast<std::uint64_t>(value)); }

void ArchiveWriter::boolean(bool value) { u8(value ? 1 : 0); }

void ArchiveWriter::string(std::string_view text) {
  u64(text.size());
  bytes_.append(text);
}

void ArchiveWriter::vec3(const Vec3& v) {
  for (int i = 0; i < 3; ++i) f64(v[i]);
}

void ArchiveWriter::mat3(const Mat3& m) {
  for (int c = 0; c < 3; ++c) vec3(m[c]);
}

void ArchiveWriter::mat4(const Mat4& m) {
  for (int c = 0; c < 4; ++c)
    for (int r = 0; r < 4; ++r) f64(m[c][r]);
}

// Arrays in bulk: on a little-endian host the memory is the format already (the byte-by-byte
// writes above stay for big-endian hosts), which makes a 10 MB archive several times faster.
void ArchiveWriter::doubles(std::span<const double> values) {
  u64(values.size());
  if constexpr (std::endian::native == std::endian::little)
    bytes_.append(reinterpret_cast<const char*>(values.data()), values.size_bytes());
  else
    for (double v : values) f64(v);
}

void ArchiveWriter::vec3s(std::span<const Vec3> values) {
  u64(values.size());
  static_assert(sizeof(Vec3) == 3 * sizeof(double));
  if constexpr (std::endian::native == std::endian::little)
    bytes_.append(reinterpret_cast<const char*>(values.data()), values.size_bytes());
  else
    for (const Vec3& v : values) vec3(v);
}

void ArchiveWriter::u32s(std::span<const std::uint32_t> values) {
  u64(values.size());
  if constexpr (std::endian::native == std::endian::little)
    bytes_.append(reinterpret_cast<const char*>(values.data()), values.size_bytes());
  else
    for (std::uint32_t v : values) u32(v);
}

void ArchiveWriter::u64s(std::span<const std::uint64_t> values) {
  u64(values.size());
  if constexpr (std::endian::native == std::endian::little)
    bytes_.append(reinterpret_cast<const char*>(values.data()), values.size_bytes());
  else
    for (std::uint64_t v : values) u64(v);
}

template <class T>
void ArchiveWriter::nested(const T& object, int kind) {
  const auto [seen, first] =
      written_.try_emplace({kind, static_cast<const void*>(&object)}, written_.size());
  if (!first) {
    tag(kBackReference);
    u64(seen->second);
    return;
  }
  if (depth_ >= ArchiveReader::maxDepth)
    throw InvalidInput("warp archive: " + nestedTooDeep() + " (byte " +
                       std::to_string(bytes_.size()) + "): this archive would not load");
  ++depth_;
  object.save(*this);
  --depth_;
}

void ArchiveWriter::warp(const Warp& w) { nested(w, 0); }
void ArchiveWriter::coordinates(const Coordinates& c) { nested(c, 1); }
void ArchiveWriter::distances(const HandleDistances& d) { nested(d, 2); }

// ---------------------------------------------------------------------------------------------
// Reader.

ArchiveReader::ArchiveReader(std::string_view bytes, const ArchiveLoaders& loaders)
    : bytes_(bytes), loaders_(loaders) {}

void ArchiveReader::fail(const std::string& what) const {
  throw InvalidInput("warp archive: " + what + " (byte " + std::to_string(position_) + ")");
}

std::string ArchiveReader::inContext(std::string_view typeTag, std::size_t start,
                                     const std::string& what) {
  static constexpr std::string_view prefix = "warp archive:";
  if (what.starts_with(prefix)) return what;  // the reader's own, or an inner object's
  return std::string(prefix) + " " + printable(typeTag) + " at byte " + std::to_string(start) +
         ": " + what;
}

void ArchiveReader::seek(std::size_t position) {
  if (position > position_) throw std::logic_error("ArchiveReader::seek: past the position read");
  position_ = position;
}

void ArchiveReader::failEnumeration(std::uint32_t value, std::uint32_t valueCount) const {
  fail("enumerator " + std::to_string(value) + " out of range (there are " +
       std::to_string(valueCount) + ")");
}

const char* ArchiveReader::take(std::size_t n, const char* what) {
  if (bytes_.size() - position_ < n)
    fail(std::string("truncated: ") + what + " needs " + std::to_string(n) + " bytes, " +
         std::to_string(bytes_.size() - position_) + " left");
  const char* p = bytes_.data() + position_;
  position_ += n;
  return p;
}

std::size_t ArchiveReader::count(std::size_t elementSize, const char* what) {
  const std::uint64_t n = u64();
  const std::size_t left = bytes_.size() - position_;
  if (n > left / elementSize)
    fail(std::string("truncated: ") + std::to_string(n) + " " + what + " of " +
         std::to_string(elementSize) + " bytes each, but " + std::to_string(left) + " bytes left");
  return static_cast<std::size_t>(n);
}

std::uint8_t ArchiveReader::u8() { return static_cast<std::uint8_t>(*take(1, "a byte")); }

std::uint32_t ArchiveReader::u32() {
  const char* p = take(4, "an integer");
  std::uint32_t value = 0;
  for (int i = 0; i < 4; ++i)
    value |= static_cast<std::uint32_t>(static_cast<std::uint8_t>(p[i])) << (8 * i);
  return value;
}

std::uint64_t ArchiveReader::u64() {
  const char* p = take(8, "an integer");
  std::uint64_t value = 0;
  for (int i = 0; i < 8; ++i)
    value |= static_cast<std::uint64_t>(static_cast<std::uint8_t>(p[i])) << (8 * i);
  return value;
}

std::int32_t ArchiveReader::i32() { return static_cast<std::int32_t>(u32()); }

double ArchiveReader::f64() { return std::bit_cast<double>(u64()); }

bool ArchiveReader::boolean() {
  const std::uint8_t b = u8();
  if (b > 1) {
    --position_;  // name the byte at fault
    fail("a boolean is " + std::to_string(b) + ", not 0 or 1");
  }
  return b == 1;
}

std::string ArchiveReader::string() {
  const std::size_t n = count(1, "characters");
  return std::string(take(n, "a string"), n);
}

Vec3 ArchiveReader::vec3() {
  Vec3 v;
  for (int i = 0; i < 3; ++i) v[i] = f64();
  return v;
}

Mat3 ArchiveReader::mat3() {
  Mat3 m;
  for (int c = 0; c < 3; ++c) m[c] = vec3();
  return m;
}

Mat4 ArchiveReader::mat4() {
  Mat4 m;
  for (int c = 0; c < 4; ++c)
    for (int r = 0; r < 4; ++r) m[c][r] = f64();
  return m;
}

// Arrays in bulk on a little-endian host, as the writer (the count was checked by count()).
template <class T, class ReadOne>
std::vector<T> ArchiveReader::array(const char* what, ReadOne readOne) {
  std::vector<T> values(count(sizeof(T), what));
  if constexpr (std::endian::native == std::endian::little) {
    const char* bytes = take(values.size() * sizeof(T), what);
    if (!values.empty()) std::memcpy(values.data(), bytes, values.size() * sizeof(T));
  } else {
    for (T& v : values) v = readOne();
  }
  return values;
}

std::vector<double> ArchiveReader::doubles() {
  return array<double>("doubles", [this] { return f64(); });
}

std::vector<Vec3> ArchiveReader::vec3s() {
  static_assert(sizeof(Vec3) == 3 * sizeof(double));
  return array<Vec3>("points", [this] { return vec3(); });
}

std::vector<std::uint32_t> ArchiveReader::u32s() {
  return array<std::uint32_t>("integers", [this] { return u32(); });
}

std::vector<std::uint64_t> ArchiveReader::u64s() {
  return array<std::uint64_t>("integers", [this] { return u64(); });
}

template <class T, class Table>
std::shared_ptr<const T> ArchiveReader::nested(const Table& table, const char* kind) {
  const std::size_t start = position_;
  const std::string typeTag = string();
  if (typeTag == kBackReference) return backReference<T>(start, kind);
  const auto loader = table.find(typeTag);
  if (loader == table.end()) {
    position_ = start;
    // Another kind's archive is named as such, with the function that loads it.
    std::string other;
    if (loaders_.warps.contains(typeTag))
      other = "a warp (loadWarp, spacewarp.warp_from_bytes)";
    else if (loaders_.coordinates.contains(typeTag))
      other = "coordinates (loadCoordinates, spacewarp.coordinates_from_bytes)";
    else if (loaders_.distances.contains(typeTag))
      other = "handle distances (loadDistances, spacewarp.distances_from_bytes)";
    else if (typeTag == "cage")
      other = "a cage (loadCage, spacewarp.cage_from_bytes)";
    if (!other.empty())
      fail(std::string("'") + typeTag + "' is " + other + ", not " +
           (std::string_view(kind) == "warp" ? "a warp" : kind));
    fail(std::string("unknown ") + kind + " type '" + printable(typeTag) + "'");
  }
  if (depth_ >= maxDepth) {
    position_ = start;
    fail(nestedTooDeep());
  }
  ++depth_;
  const std::size_t number = objects_.size();
  objects_.emplace_back(kind, nullptr);
  std::shared_ptr<const T> object;
  try {
    object = loader->second(*this);
  } catch (const InvalidInput& e) {
    // A constructor's check ("BendWarp: a limit is NaN") does not know it ran on an archive.
    throw InvalidInput(inContext(typeTag, start, e.what()));
  }
  --depth_;
  if (!object) fail(std::string("the ") + kind + " '" + typeTag + "' loaded as nothing");
  objects_[number].second = object;
  return object;
}

template <class T>
std::shared_ptr<const T> ArchiveReader::backReference(std::size_t start, const char* kind) {
  const std::uint64_t number = u64();
  // An object refers only to objects that started before it and have finished loading (the
  // writer never refers to one of its ancestors): anything else is hostile.
  if (number >= objects_.size() || !objects_[number].second ||
      std::string_view(objects_[number].first) != kind) {
    position_ = start;
    fail(std::string("a reference to ") + kind + " number " + std::to_string(number) +
         ", which is not a " + kind + " loaded before it (" + std::to_string(objects_.size()) +
         " objects so far)");
  }
  return std::static_pointer_cast<const T>(objects_[number].second);
}

std::shared_ptr<const Warp> ArchiveReader::warp() { return nested<Warp>(loaders_.warps, "warp"); }

std::shared_ptr<const Coordinates> ArchiveReader::coordinates() {
  return nested<Coordinates>(loaders_.coordinates, "coordinates");
}

std::shared_ptr<const HandleDistances> ArchiveReader::distances() {
  return nested<HandleDistances>(loaders_.distances, "distances");
}

}  // namespace spacewarp
