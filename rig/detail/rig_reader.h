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
#include <spacewarp/core/progress.h>
#include <spacewarp/rig/rig.h>

namespace spacewarp::detail {

/// Where a rig is, for messages: its file (as messages name it) and, for a rig inside compose
/// rigs, its index in each enclosing "warps" array, outermost first.
struct RigPlace {
  std::string file;
  std::vector<std::size_t> warps;
  /// Given to the solves a rig runs (graph, lattice fit, RBF fit); nested rigs share it.
  ProgressCallback progress = {};

  /// The place nested as warps[index] of this one.
  RigPlace nested(std::size_t index) const {
    RigPlace inner = *this;
    inner.warps.push_back(index);
    return inner;
  }

  /// "rig.json", "rig.json: warps[1].warps[0]"; deeper than 4 levels only the first two and
  /// the last, so that the line stays short: "rig.json: warps[0].warps[0]...warps[2] (64
  /// levels)".
  std::string str() const {
    if (warps.empty()) return file;
    // Appended piece by piece (GCC 12 warns falsely, -Wrestrict, about "." + a string).
    std::string path = file;
    const auto step = [&](std::size_t level) {
      path += "warps[";
      path += std::to_string(warps[level]);
      path += ']';
    };
    path += ": ";
    if (warps.size() <= 4) {
      for (std::size_t level = 0; level < warps.size(); ++level) {
        if (level > 0) path += '.';
        step(level);
      }
    } else {
      step(0);
      path += '.';
      step(1);
      path += "...";
      step(warps.size() - 1);
      path += " (";
      path += std::to_string(warps.size());
      path += " levels)";
    }
    return path;
  }
};

// Reads the keys of one rig object with clear, located errors, and remembers which keys were
// read so that unknown (usually misspelt) keys can be reported.
/// The n finite numbers of the JSON array v; otherwise fail(what is wrong), which throws.
template <class Fail>
std::vector<double> finiteNumbers(const nlohmann::json& v, std::size_t n, const Fail& fail) {
  if (!v.is_array() || v.size() != n) fail("must be an array of " + std::to_string(n) + " numbers");
  std::vector<double> out;
  for (const nlohmann::json& e : v) {
    if (!e.is_number() || !std::isfinite(e.get<double>())) fail("must contain finite numbers only");
    out.push_back(e.get<double>());
  }
  return out;
}

class RigReader {
 public:
  using json = nlohmann::json;

  /// `depth` counts the rigs this one is nested in (compose's "warps").
  RigReader(const json& object, std::filesystem::path baseDir, std::string where, int depth = 0)
      : object_(object), baseDir_(std::move(baseDir)), where_(std::move(where)), depth_(depth) {
    if (!object_.is_object()) fail("", "a rig must be a JSON object");
  }

  /// A rig at `place`; with `checkOnly`, factories stop before their expensive solves
  /// (checking()).
  RigReader(const json& object, std::filesystem::path baseDir, RigPlace place, bool checkOnly)
      : RigReader(object, std::move(baseDir), place.str(), static_cast<int>(place.warps.size())) {
    place_ = std::move(place);
    checking_ = checkOnly;
  }

  /// Declares every key the object may have (besides "method"), and rejects any other at once,
  /// before a missing or mistyped key is reported: an unknown key is usually the misspelling
  /// that makes a required one missing. The message: "'rat' is not a key of <subject> (the
  /// keys of <name>: origin, axis, rate, limits)".
  void allowOnly(const std::vector<std::string>& keys, const std::string& subject,
                 const std::string& name) {
    allowed_ = std::set<std::string>(keys.begin(), keys.end());
    allowed_.insert("method");
    for (const auto& [key, value] : object_.items()) {
      if (allowed_.count(key)) continue;
      std::string list;
      for (const std::string& k : keys) list += (list.empty() ? "" : ", ") + k;
      fail(key, "is not a key of " + subject + " (the keys of " + name + ": " + list + ")");
    }
  }

  /// Whether only the rig is being checked (checkRig, `spacewarp info`): factories then return
  /// once every key is read and validated, before solving (an empty Rig).
  bool checking() const { return checking_; }

  /// Where this rig is (for nested compose rigs).
  const RigPlace& place() const { return place_; }

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

  /// Rejects keys that no reader asked for: unknown ones, or (with allowOnly) known ones that
  /// the other keys given make unused.
  void finish() const {
    for (const auto& [key, value] : object_.items()) {
      if (seen_.count(key)) continue;
      if (allowed_.empty()) fail(key, "is not a key of this method");
      fail(key, "has no effect with the other keys given: remove it");
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
    return finiteNumbers(v, n, [&](const std::string& what) { fail(key, what); });
  }

  const json& object_;
  std::filesystem::path baseDir_;
  std::string where_;
  int depth_ = 0;
  RigPlace place_;
  bool checking_ = false;
  std::set<std::string> seen_{"method"};
  std::set<std::string> allowed_;  // empty: any key until finish()
};

/// Builds one rig method from its reader. A method's keys are read through the reader, which
/// reports unknown keys once the factory returns.
using RigFactory = std::function<Rig(RigReader&)>;

}  // namespace spacewarp::detail
