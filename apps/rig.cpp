#include "apps/rig.h"

#include <cmath>
#include <fstream>
#include <functional>
#include <limits>
#include <map>
#include <set>

#include "apps/cage_methods.h"
#include "core/bend.h"
#include "core/combinators.h"
#include "core/errors.h"
#include "core/taper.h"
#include "core/twist.h"

namespace spacewarp::cli {

namespace {

using nlohmann::json;

// Reads the keys of one rig object with clear, located errors, and remembers which keys were
// read so that unknown (usually misspelt) keys can be reported.
class RigReader {
 public:
  RigReader(const json& object, std::filesystem::path baseDir, std::string where)
      : object_(object), baseDir_(std::move(baseDir)), where_(std::move(where)) {
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

  const std::filesystem::path& baseDir() const { return baseDir_; }
  const std::string& where() const { return where_; }

  /// Rejects keys that no reader asked for.
  void finish() const {
    for (const auto& [key, value] : object_.items()) {
      if (!seen_.count(key)) fail(key, "is not a key of this method");
    }
  }

  [[noreturn]] void fail(const std::string& key, const std::string& what) const {
    throw InvalidInput(where_ + ": " + (key.empty() ? "" : "'" + key + "' ") + what);
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
  std::set<std::string> seen_{"method"};
};

using Factory = std::function<std::shared_ptr<const Warp>(RigReader&)>;

// One entry per rig method: adding a method is one line here plus its keys in README.md.
const std::map<std::string, Factory>& factories() {
  static const std::map<std::string, Factory> table = {
      {"twist",
       [](RigReader& r) {
         TwistParams p;
         p.origin = r.vec3("origin");
         p.axis = r.vec3("axis");
         p.rate = r.number("rate");
         std::tie(p.lo, p.hi) = r.limits("limits");
         return std::make_shared<TwistWarp>(p);
       }},
      {"bend",
       [](RigReader& r) {
         BendParams p;
         p.origin = r.vec3("origin");
         p.axis = r.vec3("axis");
         p.direction = r.vec3("direction");
         p.rate = r.number("rate");
         std::tie(p.lo, p.hi) = r.limits("limits");
         return std::make_shared<BendWarp>(p);
       }},
      {"taper",
       [](RigReader& r) {
         TaperParams p;
         p.origin = r.vec3("origin");
         p.axis = r.vec3("axis");
         p.rate = r.number("rate");
         std::tie(p.lo, p.hi) = r.limits("limits");
         return std::make_shared<TaperWarp>(p);
       }},
      {"affine", [](RigReader& r) { return std::make_shared<AffineWarp>(r.matrix4("matrix")); }},
      {"mvc", [](RigReader& r) { return cageWarp("mvc", r.path("cage"), r.path("pose")); }},
      {"green", [](RigReader& r) { return cageWarp("green", r.path("cage"), r.path("pose")); }},
      {"compose",
       [](RigReader& r) {
         std::shared_ptr<const Warp> result;
         const json& warps = r.array("warps");
         for (std::size_t i = 0; i < warps.size(); ++i) {
           auto next = warpFromRig(warps[i], r.baseDir(),
                                   r.where() + ": warps[" + std::to_string(i) + "]");
           result = result ? std::make_shared<ComposedWarp>(result, next) : next;
         }
         return result;
       }},
  };
  return table;
}

}  // namespace

std::shared_ptr<const Warp> warpFromRig(const json& rig, const std::filesystem::path& baseDir,
                                        const std::string& where) {
  RigReader reader(rig, baseDir, where);
  const std::string method = reader.string("method");
  const auto it = factories().find(method);
  if (it == factories().end()) {
    std::string known;
    for (const std::string& m : rigMethods()) known += (known.empty() ? "" : ", ") + m;
    reader.fail("method", "'" + method + "' is not one of: " + known);
  }
  std::shared_ptr<const Warp> warp;
  try {
    warp = it->second(reader);
  } catch (const InvalidInput& e) {
    // Messages from the warps' own validation: say which rig they came from.
    const std::string what = e.what();
    if (what.rfind(where, 0) == 0) throw;
    throw InvalidInput(where + ": " + what);
  }
  reader.finish();
  return warp;
}

std::shared_ptr<const Warp> loadRig(const std::filesystem::path& path) {
  std::ifstream in(path);
  if (!in) throw IoError(path.string() + ": cannot open the rig file");
  json rig;
  try {
    rig = json::parse(in);
  } catch (const json::parse_error& e) {
    throw IoError(path.string() + ": not valid JSON: " + e.what());
  }
  return warpFromRig(rig, path.parent_path(), path.string());
}

std::vector<std::string> rigMethods() {
  std::vector<std::string> names;
  for (const auto& [name, factory] : factories()) names.push_back(name);
  return names;
}

}  // namespace spacewarp::cli
