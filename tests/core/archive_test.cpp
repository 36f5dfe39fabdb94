#include <spacewarp/core/archive.h>

#include <cstring>
#include <limits>
#include <memory>
#include <string>
#include <vector>

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <spacewarp/core/coordinates.h>
#include <spacewarp/core/errors.h>
#include <spacewarp/core/handle_distances.h>
#include <spacewarp/core/warp.h>

#include "test_util.h"

namespace spacewarp {
namespace {

using ::testing::HasSubstr;

enum class Colour { red, green, blue };

// One of every primitive, with values that show byte order, sign and special doubles.
void writeEverything(ArchiveWriter& out) {
  out.tag("everything");
  out.u8(0xab);
  out.u32(0x01020304u);
  out.u64(0x0102030405060708ull);
  out.i32(-5);
  out.f64(-0.0);
  out.f64(std::numeric_limits<double>::quiet_NaN());
  out.f64(std::numeric_limits<double>::infinity());
  out.f64(std::numeric_limits<double>::denorm_min());
  out.boolean(true);
  out.boolean(false);
  out.string(std::string("a\0b", 3));
  out.vec3({1.5, -2.25, 1e300});
  Mat3 m3;
  for (int c = 0; c < 3; ++c)
    for (int r = 0; r < 3; ++r) m3[c][r] = 3 * c + r + 0.5;
  out.mat3(m3);
  Mat4 m4;
  for (int c = 0; c < 4; ++c)
    for (int r = 0; r < 4; ++r) m4[c][r] = 4 * c + r - 0.25;
  out.mat4(m4);
  const std::vector<double> ds{0.1, 0.2, -0.3};
  out.doubles(ds);
  const std::vector<Vec3> vs{{1, 2, 3}, {4, 5, 6}};
  out.vec3s(vs);
  const std::vector<std::uint32_t> u32s{7, 0xffffffffu};
  out.u32s(u32s);
  const std::vector<std::uint64_t> u64s{9, 0xffffffffffffffffull};
  out.u64s(u64s);
  out.enumeration(Colour::blue);
}

// Reads what writeEverything() wrote (after its tag), checking each value bit for bit.
void readEverything(ArchiveReader& in) {
  EXPECT_EQ(in.u8(), 0xab);
  EXPECT_EQ(in.u32(), 0x01020304u);
  EXPECT_EQ(in.u64(), 0x0102030405060708ull);
  EXPECT_EQ(in.i32(), -5);
  const double negativeZero = in.f64();
  EXPECT_EQ(negativeZero, 0.0);
  EXPECT_TRUE(std::signbit(negativeZero));
  const double nan = in.f64();
  const double quiet = std::numeric_limits<double>::quiet_NaN();
  EXPECT_EQ(std::memcmp(&nan, &quiet, sizeof(double)), 0);
  EXPECT_EQ(in.f64(), std::numeric_limits<double>::infinity());
  EXPECT_EQ(in.f64(), std::numeric_limits<double>::denorm_min());
  EXPECT_TRUE(in.boolean());
  EXPECT_FALSE(in.boolean());
  EXPECT_EQ(in.string(), std::string("a\0b", 3));
  EXPECT_TRUE(test::bitEqual(in.vec3(), Vec3(1.5, -2.25, 1e300)));
  const Mat3 m3 = in.mat3();
  for (int c = 0; c < 3; ++c)
    for (int r = 0; r < 3; ++r) EXPECT_EQ(m3[c][r], 3 * c + r + 0.5);
  const Mat4 m4 = in.mat4();
  for (int c = 0; c < 4; ++c)
    for (int r = 0; r < 4; ++r) EXPECT_EQ(m4[c][r], 4 * c + r - 0.25);
  EXPECT_EQ(in.doubles(), (std::vector<double>{0.1, 0.2, -0.3}));
  const std::vector<Vec3> vs = in.vec3s();
  ASSERT_EQ(vs.size(), 2u);
  EXPECT_TRUE(test::bitEqual(vs[1], Vec3(4, 5, 6)));
  EXPECT_EQ(in.u32s(), (std::vector<std::uint32_t>{7, 0xffffffffu}));
  EXPECT_EQ(in.u64s(), (std::vector<std::uint64_t>{9, 0xffffffffffffffffull}));
  EXPECT_EQ(in.enumeration<Colour>(3), Colour::blue);
}

const ArchiveLoaders& noLoaders() {
  static const ArchiveLoaders loaders;
  return loaders;
}

TEST(Archive, EveryPrimitiveRoundTrips) {
  ArchiveWriter out;
  writeEverything(out);
  ArchiveReader in(out.bytes(), noLoaders());
  EXPECT_EQ(in.string(), "everything");
  readEverything(in);
  EXPECT_TRUE(in.atEnd());
}

TEST(Archive, IsLittleEndianAndPacked) {
  ArchiveWriter out;
  out.u32(0x01020304u);
  out.boolean(true);
  out.f64(1.0);  // 0x3ff0000000000000
  EXPECT_EQ(out.bytes(), std::string("\x04\x03\x02\x01\x01\0\0\0\0\0\0\xf0\x3f", 13));
}

TEST(Archive, TruncationAtEveryByteIsRefusedWithInvalidInput) {
  ArchiveWriter out;
  writeEverything(out);
  const std::string& bytes = out.bytes();
  for (std::size_t n = 0; n < bytes.size(); ++n) {
    ArchiveReader in(std::string_view(bytes).substr(0, n), noLoaders());
    const std::string message = test::messageOf<InvalidInput>([&] {
      in.string();
      readEverything(in);
    });
    EXPECT_THAT(message, HasSubstr("warp archive: truncated")) << "at " << n << " bytes";
  }
}

TEST(Archive, CountsLargerThanTheBytesLeftAreRefusedBeforeAllocating) {
  // A count of 2^61 doubles would be 16 EiB: refused from the count, not by bad_alloc.
  for (const std::uint64_t count : {std::uint64_t{1} << 61, std::uint64_t{3}, ~std::uint64_t{0}}) {
    ArchiveWriter out;
    out.u64(count);
    out.f64(1.0);
    out.f64(2.0);  // 16 bytes left: room for 2 doubles, not 3
    ArchiveReader doubles(out.bytes(), noLoaders());
    EXPECT_THAT(test::messageOf<InvalidInput>([&] { doubles.doubles(); }),
                HasSubstr(std::to_string(count) + " doubles"));
    ArchiveReader points(out.bytes(), noLoaders());
    EXPECT_THAT(test::messageOf<InvalidInput>([&] { points.vec3s(); }),
                HasSubstr("but 16 bytes left"));
    ArchiveReader text(out.bytes(), noLoaders());
    if (count > 16) {
      EXPECT_THAT(test::messageOf<InvalidInput>([&] { text.string(); }), HasSubstr("truncated"));
    }
  }
}

TEST(Archive, BadBooleansAndEnumeratorsAreRefusedNamingTheByte) {
  ArchiveWriter out;
  out.u8(0);
  out.u8(2);
  out.u32(3);
  ArchiveReader in(out.bytes(), noLoaders());
  EXPECT_FALSE(in.boolean());
  EXPECT_THAT(test::messageOf<InvalidInput>([&] { in.boolean(); }),
              HasSubstr("a boolean is 2, not 0 or 1 (byte 1)"));
  in.u8();
  EXPECT_THAT(test::messageOf<InvalidInput>([&] { in.enumeration<Colour>(3); }),
              HasSubstr("enumerator 3 out of range (there are 3) (byte 6)"));
}

// A warp of this test only, to check nesting and dispatch.
class ShiftWarp final : public Warp {
 public:
  explicit ShiftWarp(std::shared_ptr<const Warp> inner, Vec3 shift)
      : inner_(std::move(inner)), shift_(shift) {}
  Vec3 apply(const Vec3& x) const override { return (inner_ ? inner_->apply(x) : x) + shift_; }
  const std::shared_ptr<const Warp>& inner() const { return inner_; }
  void save(ArchiveWriter& out) const override {
    out.tag("shift");
    out.vec3(shift_);
    out.boolean(inner_ != nullptr);
    if (inner_) out.warp(*inner_);
  }
  static std::shared_ptr<const Warp> load(ArchiveReader& in) {
    const Vec3 shift = in.vec3();
    std::shared_ptr<const Warp> inner = in.boolean() ? in.warp() : nullptr;
    return std::make_shared<ShiftWarp>(std::move(inner), shift);
  }

 private:
  std::shared_ptr<const Warp> inner_;
  Vec3 shift_;
};

ArchiveLoaders shiftLoaders() {
  ArchiveLoaders loaders;
  loaders.warps.emplace("shift", &ShiftWarp::load);
  return loaders;
}

TEST(Archive, NestedObjectsDispatchOnTheirTag) {
  const auto warp = std::make_shared<ShiftWarp>(std::make_shared<ShiftWarp>(nullptr, Vec3(1, 0, 0)),
                                                Vec3(0, 2, 0));
  ArchiveWriter out;
  out.warp(*warp);
  const ArchiveLoaders loaders = shiftLoaders();
  ArchiveReader in(out.bytes(), loaders);
  const std::shared_ptr<const Warp> loaded = in.warp();
  EXPECT_TRUE(in.atEnd());
  EXPECT_TRUE(test::bitEqual(loaded->apply(Vec3(0.5)), Vec3(1.5, 2.5, 0.5)));
}

TEST(Archive, UnknownTagsAreNamed) {
  ArchiveWriter out;
  out.tag("no such warp");
  const ArchiveLoaders loaders = shiftLoaders();
  ArchiveReader warps(out.bytes(), loaders);
  EXPECT_THAT(test::messageOf<InvalidInput>([&] { warps.warp(); }),
              HasSubstr("unknown warp type 'no such warp' (byte 0)"));
  ArchiveReader coordinates(out.bytes(), loaders);
  EXPECT_THAT(test::messageOf<InvalidInput>([&] { coordinates.coordinates(); }),
              HasSubstr("unknown coordinates type 'no such warp'"));
  ArchiveReader distances(out.bytes(), loaders);
  EXPECT_THAT(test::messageOf<InvalidInput>([&] { distances.distances(); }),
              HasSubstr("unknown distances type 'no such warp'"));
}

TEST(Archive, NestingDeeperThanTheLimitIsRefusedNotRecursedInto) {
  std::shared_ptr<const Warp> warp;
  for (int i = 0; i < ArchiveReader::maxDepth + 1; ++i)
    warp = std::make_shared<ShiftWarp>(warp, Vec3(1.0));
  // The writer refuses it with the reader's message: nothing is saved that would not load.
  ArchiveWriter refused;
  EXPECT_THAT(test::messageOf<InvalidInput>([&] { refused.warp(*warp); }),
              HasSubstr("nested deeper than 64"));
  // Written by hand (the outermost save() called directly), the reader refuses it at the start
  // of the object one level too deep.
  ArchiveWriter out;
  warp->save(out);
  const ArchiveLoaders loaders = shiftLoaders();
  ArchiveReader in(out.bytes(), loaders);
  EXPECT_THAT(test::messageOf<InvalidInput>([&] { in.warp(); }),
              HasSubstr("nested deeper than 64"));
  // Exactly the limit saves and loads.
  ArchiveWriter deepest;
  deepest.warp(*std::static_pointer_cast<const ShiftWarp>(warp)->inner());
  ArchiveReader back(deepest.bytes(), loaders);
  EXPECT_NE(back.warp(), nullptr);
  EXPECT_TRUE(back.atEnd());
}

// Interfaces whose implementations do not override save() are refused, naming the type.
class UnsavedDistances final : public HandleDistances {
 public:
  std::span<const Vec3> handles() const override { return {}; }
  void distances(const Vec3&, std::span<double>) const override {}
  void distancesAndGradients(const Vec3&, std::span<double>, std::span<Vec3>) const override {}
};

TEST(Archive, ClassesWithoutSaveAreRefusedNamingTheirType) {
  ArchiveWriter out;
  const ShiftWarp saved(nullptr, Vec3(0.0));
  EXPECT_NO_THROW(out.warp(saved));
  struct Unsaved final : Warp {
    Vec3 apply(const Vec3& x) const override { return x; }
  };
  EXPECT_THAT(test::messageOf<InvalidInput>([&] { out.warp(Unsaved()); }),
              HasSubstr("this Warp (spacewarp::(anonymous namespace)::"));
  EXPECT_THAT(test::messageOf<InvalidInput>([&] { out.distances(UnsavedDistances()); }),
              HasSubstr("UnsavedDistances) cannot be saved"));
}

}  // namespace
}  // namespace spacewarp
