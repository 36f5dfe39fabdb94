#pragma once
// RigReader: reads the keys of one rig object (JSON) with located errors. Every rig method's
// factory uses it, so all rigs report problems the same way.

#include <cmath>
#include <filesystem>
#include <functional>
#include <limits>
#include <set>
#include <string>
#include <utility>
#include <vector>

#include <nlohmann/json.hpp>

#include <spacewarp/core/errors.h>
#include <spacewarp/core/math.h>
#include <spacewarp/rig/rig.h>

namespace spacewarp::detail {

// Reads the keys of one rig object with clear, located errors, and remembers which keys were
// read so that unknown (usually misspelt) keys can be reported.
class RigReader {
 public:
  using json = nlohmann::json;

  /// `depth` counts the rigs this one is nested in (compose's "warps").
  RigReader(const json& object, std::filesystem::path baseDir, std::string where, int depth = 0)
      : object_(object), baseDir_(std::move(baseDir)), where_(std::move(where)), depth_(depth) {
    if (!object_.is_object()) fail("", "a rig must be a JSON object");
  }

  bool has(const std::string& key) const { return object_.contains(key); }

  double number(const std::string& key) {
    const json& v = get(key);
    if (!v.is_number()) fail(key, "must be a number");
    const double d = v.get<double>();
    if (!std::isfinite(d)) fail(key, "must be finite");
    return d;
  }

  double number(const std::string& key, double fallback) {
    return has(key) ? number(key) : (seen_.insert(key), fallback);
  }

  /// A path, resolved against the rig's folder when relative.
  std::filesystem::path path(const std::string& key) {
    const std::filesystem::path p = string(key);
    return p.is_absolute() ? p : baseDir_ / p;
  }

  std::string string(const std::string& key) {
    const json& v = get(key);
    if (!v.is_string()) fail(key, "must be a string");
    return v.get<std::string>();
  }

  Vec3 vec3(const std::string& key) {
    const std::vector<double> v = numbers(get(key), key, 3);
    return {v[0], v[1], v[2]};
  }

  /// An array of [x, y, z] points (world units), at least `minimum` of them.
  std::vector<Vec3> points(const std::string& key, std::size_t minimum = 1) {
    const json& v = get(key);
    if (!v.is_array() || v.size() < minimum)
      fail(key, "must be an array of at least " + std::to_string(minimum) + " [x, y, z] points");
    std::vector<Vec3> out;
    out.reserve(v.size());
    for (std::size_t i = 0; i < v.size(); ++i) {
      const std::vector<double> p = numbers(v[i], key + "[" + std::to_string(i) + "]", 3);
      out.emplace_back(p[0], p[1], p[2]);
    }
    return out;
  }

  /// [lo, hi] limits along an axis; absent means unlimited.
  std::pair<double, double> limits(const std::string& key) {
    if (!has(key)) {
      seen_.insert(key);
      return {-std::numeric_limits<double>::infinity(), std::numeric_limits<double>::infinity()};
    }
    const std::vector<double> v = numbers(get(key), key, 2);
    if (!(v[0] <= v[1])) fail(key, "must be [lo, hi] with lo <= hi");
    return {v[0], v[1]};
  }

  /// A row-major 4 x 4 matrix, returned as GLM (column-major).
  Mat4 matrix4(const std::string& key) {
    const json& rows = get(key);
    if (!rows.is_array() || rows.size() != 4) fail(key, "must be an array of 4 rows");
    Mat4 m;
    for (int r = 0; r < 4; ++r) {
      const std::vector<double> row = numbers(rows[r], key + "[" + std::to_string(r) + "]", 4);
      for (int c = 0; c < 4; ++c) m[c][r] = row[c];
    }
    return m;
  }

  const json& array(const std::string& key) {
    const json& v = get(key);
    if (!v.is_array() || v.empty()) fail(key, "must be a non-empty array");
    return v;
  }

  /// A JSON object (e.g. a nested group of keys, read with a RigReader of its own).
  const json& object(const std::string& key) {
    const json& v = get(key);
    if (!v.is_object()) fail(key, "must be a JSON object");
    return v;
  }

  const std::filesystem::path& baseDir() const { return baseDir_; }
  const std::string& where() const { return where_; }
  int depth() const { return depth_; }

  /// Rejects keys that no reader asked for.
  void finish() const {
    for (const auto& [key, value] : object_.items()) {
      if (!seen_.count(key)) fail(key, "is not a key of this method");
    }
  }

  [[noreturn]] void fail(const std::string& key, const std::string& what) const {
    // Keys and values come from the user: escaped, so a "\u0000" cannot cut the message short.
    throw InvalidInput(printable(where_ + ": " + (key.empty() ? "" : "'" + key + "' ") + what));
  }

 private:
  const json& get(const std::string& key) {
    seen_.insert(key);
    if (!object_.contains(key)) fail(key, "is missing");
    return object_.at(key);
  }

  std::vector<double> numbers(const json& v, const std::string& key, std::size_t n) const {
    if (!v.is_array() || v.size() != n)
      fail(key, "must be an array of " + std::to_string(n) + " numbers");
    std::vector<double> out;
    for (const json& e : v) {
      if (!e.is_number() || !std::isfinite(e.get<double>()))
        fail(key, "must contain finite numbers only");
      out.push_back(e.get<double>());
    }
    return out;
  }

  const json& object_;
  std::filesystem::path baseDir_;
  std::string where_;
  int depth_ = 0;
  std::set<std::string> seen_{"method"};
};

/// Builds one rig method from its reader. A method's keys are read through the reader, which
/// reports unknown keys once the factory returns.
using RigFactory = std::function<Rig(RigReader&)>;

}  // namespace spacewarp::detail
