#include "apps/rig.h"

#include <fstream>
#include <map>

#include "apps/cage_methods.h"
#include "apps/ffd_rig.h"
#include "apps/graph_rig.h"
#include "apps/mls_rig.h"
#include "apps/rbf_rig.h"
#include "core/bend.h"
#include "core/combinators.h"
#include "core/errors.h"
#include "core/taper.h"
#include "core/twist.h"

namespace spacewarp::cli {

namespace {

using nlohmann::json;

using nlohmann::json;

Rig warpOnly(std::shared_ptr<const Warp> warp) { return {std::move(warp), nullptr}; }

// One entry per rig method: adding a method is one line here plus its keys in README.md.
const std::map<std::string, RigFactory>& factories() {
  static const std::map<std::string, RigFactory> table = {
      {"twist",
       [](RigReader& r) {
         TwistParams p;
         p.origin = r.vec3("origin");
         p.axis = r.vec3("axis");
         p.rate = r.number("rate");
         std::tie(p.lo, p.hi) = r.limits("limits");
         return warpOnly(std::make_shared<TwistWarp>(p));
       }},
      {"bend",
       [](RigReader& r) {
         BendParams p;
         p.origin = r.vec3("origin");
         p.axis = r.vec3("axis");
         p.direction = r.vec3("direction");
         p.rate = r.number("rate");
         std::tie(p.lo, p.hi) = r.limits("limits");
         return warpOnly(std::make_shared<BendWarp>(p));
       }},
      {"taper",
       [](RigReader& r) {
         TaperParams p;
         p.origin = r.vec3("origin");
         p.axis = r.vec3("axis");
         p.rate = r.number("rate");
         std::tie(p.lo, p.hi) = r.limits("limits");
         return warpOnly(std::make_shared<TaperWarp>(p));
       }},
      {"affine",
       [](RigReader& r) { return warpOnly(std::make_shared<AffineWarp>(r.matrix4("matrix"))); }},
      {"mvc", [](RigReader& r) { return cageRig("mvc", r.path("cage"), r.path("pose")); }},
      {"green", [](RigReader& r) { return cageRig("green", r.path("cage"), r.path("pose")); }},
      {"harmonic", harmonicRig},
      {"ffd", ffdRig},
      {"graph", graphRig},
      {"mls", mlsRig},
      {"rbf", rbfRig},
      {"compose",
       [](RigReader& r) {
         std::shared_ptr<const Warp> result;
         const json& warps = r.array("warps");
         for (std::size_t i = 0; i < warps.size(); ++i) {
           auto next =
               rigFromJson(warps[i], r.baseDir(), r.where() + ": warps[" + std::to_string(i) + "]")
                   .warp;
           result = result ? std::make_shared<ComposedWarp>(result, next) : next;
         }
         return warpOnly(result);
       }},
  };
  return table;
}

}  // namespace

Rig rigFromJson(const json& rig, const std::filesystem::path& baseDir, const std::string& where) {
  RigReader reader(rig, baseDir, where);
  const std::string method = reader.string("method");
  const auto it = factories().find(method);
  if (it == factories().end()) {
    std::string known;
    for (const std::string& m : rigMethods()) known += (known.empty() ? "" : ", ") + m;
    reader.fail("method", "'" + method + "' is not one of: " + known);
  }
  Rig result;
  try {
    result = it->second(reader);
  } catch (const InvalidInput& e) {
    // Messages from the warps' own validation: say which rig they came from.
    const std::string what = e.what();
    if (what.rfind(where, 0) == 0) throw;
    throw InvalidInput(where + ": " + what);
  }
  reader.finish();
  return result;
}

json readRigFile(const std::filesystem::path& path) {
  std::ifstream in(path);
  if (!in) throw IoError(path.string() + ": cannot open the rig file");
  try {
    return json::parse(in);
  } catch (const json::parse_error& e) {
    throw IoError(path.string() + ": not valid JSON: " + e.what());
  }
}

Rig loadRig(const std::filesystem::path& path) {
  return rigFromJson(readRigFile(path), path.parent_path(), path.string());
}

std::vector<std::string> rigMethods() {
  std::vector<std::string> names;
  for (const auto& [name, factory] : factories()) names.push_back(name);
  return names;
}

}  // namespace spacewarp::cli
