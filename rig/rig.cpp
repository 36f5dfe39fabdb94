#include <spacewarp/rig/rig.h>

#include <fstream>
#include <map>
#include <set>
#include <sstream>
#include <string>
#include <string_view>
#include <vector>

#include <spacewarp/core/bend.h>
#include <spacewarp/core/combinators.h>
#include <spacewarp/core/errors.h>
#include <spacewarp/core/taper.h>
#include <spacewarp/core/twist.h>
#include <spacewarp/rig/cage_rig.h>
#include <spacewarp/rig/detail/ffd_rig.h>
#include <spacewarp/rig/detail/graph_rig.h>
#include <spacewarp/rig/detail/harmonic_rig.h>
#include <spacewarp/rig/detail/idw_rig.h>
#include <spacewarp/rig/detail/json_file.h>
#include <spacewarp/rig/detail/kelvinlet_rig.h>
#include <spacewarp/rig/detail/mls_rig.h>
#include <spacewarp/rig/detail/rbf_rig.h>
#include <spacewarp/rig/detail/rig_reader.h>
#include <spacewarp/rig/detail/skinning_rig.h>
#include <spacewarp/rig/detail/wires_rig.h>

namespace spacewarp {

namespace {

using detail::RigFactory;
using detail::RigReader;
using nlohmann::json;

Rig buildRig(const json& rig, const std::filesystem::path& baseDir, const detail::RigPlace& place,
             bool checkOnly);

Rig warpOnly(std::shared_ptr<const Warp> warp) { return {std::move(warp), nullptr}; }

// A rig method: the keys it may have (besides "method") and how it is built from them.
struct Method {
  std::vector<std::string> keys;
  RigFactory build;
};

// One entry per rig method: adding a method is one line here plus its keys in README.md.
const std::map<std::string, Method>& factories() {
  static const std::map<std::string, Method> table = {
      {"twist",
       {{"origin", "axis", "rate", "limits"},
        [](RigReader& r) {
          TwistOptions p;
          p.origin = r.vec3("origin");
          p.axis = r.vec3("axis");
          p.rate = r.number("rate");
          std::tie(p.lo, p.hi) = r.limits("limits");
          return warpOnly(std::make_shared<TwistWarp>(p));
        }}},
      {"bend",
       {{"origin", "axis", "direction", "rate", "limits"},
        [](RigReader& r) {
          BendOptions p;
          p.origin = r.vec3("origin");
          p.axis = r.vec3("axis");
          p.direction = r.vec3("direction");
          p.rate = r.number("rate");
          std::tie(p.lo, p.hi) = r.limits("limits");
          return warpOnly(std::make_shared<BendWarp>(p));
        }}},
      {"taper",
       {{"origin", "axis", "rate", "limits"},
        [](RigReader& r) {
          TaperOptions p;
          p.origin = r.vec3("origin");
          p.axis = r.vec3("axis");
          p.rate = r.number("rate");
          std::tie(p.lo, p.hi) = r.limits("limits");
          return warpOnly(std::make_shared<TaperWarp>(p));
        }}},
      {"affine",
       {{"matrix"},
        [](RigReader& r) { return warpOnly(std::make_shared<AffineWarp>(r.matrix4("matrix"))); }}},
      {"mvc", {{"cage", "pose"}, [](RigReader& r) { return detail::cageRig(r, "mvc"); }}},
      {"green", {{"cage", "pose"}, [](RigReader& r) { return detail::cageRig(r, "green"); }}},
      {"qmvc", {{"cage", "pose"}, [](RigReader& r) { return detail::cageRig(r, "qmvc"); }}},
      {"qgc", {{"cage", "pose"}, [](RigReader& r) { return detail::cageRig(r, "qgc"); }}},
      {"wachspress",
       {{"cage", "pose", "outside"},
        [](RigReader& r) { return detail::cageRig(r, "wachspress"); }}},
      {"discrete-harmonic",
       {{"cage", "pose", "outside"},
        [](RigReader& r) { return detail::cageRig(r, "discrete-harmonic"); }}},
      {"harmonic",
       {{"cage", "pose", "tets", "precision", "cache", "outside"}, detail::harmonicRig}},
      {"ffd",
       {{"basis", "ends", "origin", "size", "resolution", "axes", "outside", "falloff",
         "controlPoints", "constraints", "smoothness"},
        detail::ffdRig}},
      {"graph",
       {{"handles", "targets", "k", "nodes", "spacing", "rotationWeight", "regularizationWeight",
         "constraintWeight", "maxIterations", "tolerance"},
        detail::graphRig}},
      {"mls",
       {{"mode", "alpha", "handles", "targets", "distance", "model", "voxelSize"}, detail::mlsRig}},
      {"idw", {{"handles", "targets", "power", "radius"}, detail::idwRig}},
      {"kelvinlet",
       {{"brush", "center", "radius", "poisson", "falloff", "steps", "displacement", "axis",
         "angle", "factor", "matrix"},
        detail::kelvinletRig}},
      {"rbf",
       {{"kernel", "centers", "targets", "fixed", "smoothing", "scale", "radius"}, detail::rbfRig}},
      {"skinning",
       {{"mode", "bones", "influences", "weights", "model", "handles", "coordinates"},
        detail::skinningRig}},
      {"wires", {{"wires", "locality"}, detail::wiresRig}},
      {"compose",
       {{"warps"},
        [](RigReader& r) {
          Rig result;
          const json& warps = r.array("warps");
          // Each level recurses here: bounded so that hostile nesting cannot overflow the stack.
          if (r.depth() >= kMaxComposeDepth)  // depth counts the compose rigs around this one
            r.fail("warps", "nests compose rigs deeper than " + std::to_string(kMaxComposeDepth) +
                                " levels");
          for (std::size_t i = 0; i < warps.size(); ++i) {
            Rig next = buildRig(warps[i], r.baseDir(), r.place().nested(i), r.checking());
            if (r.checking()) continue;
            result.warp =
                result.warp ? std::make_shared<ComposedWarp>(result.warp, next.warp) : next.warp;
            for (std::string& warning : next.warnings)
              result.warnings.push_back(std::move(warning));
          }
          return result;
        }}},
  };
  return table;
}

// The JSON path of the value being parsed ("warps[2].rate") and the keys seen in each open
// object, kept by parseRigJson's callback.
class ParsePath {
 public:
  void open(bool object) { frames_.push_back({object, {}, {}, 0}); }
  void close() {
    frames_.pop_back();
    valueDone();
  }
  // Returns false if the open object already has this key.
  bool key(const std::string& k) {
    frames_.back().key = k;
    return frames_.back().keys.insert(k).second;
  }
  void valueDone() {
    if (!frames_.empty() && !frames_.back().object) ++frames_.back().index;
  }
  std::size_t depth() const { return frames_.size(); }
  std::string str() const {
    std::string p;
    for (const Frame& f : frames_) {
      if (f.object)
        p += (p.empty() ? "" : ".") + f.key;
      else
        p += "[" + std::to_string(f.index) + "]";
    }
    return p;
  }

 private:
  struct Frame {
    bool object;
    std::set<std::string> keys;
    std::string key;
    std::size_t index;
  };
  std::vector<Frame> frames_;
};

Rig buildRig(const json& rig, const std::filesystem::path& baseDir, const detail::RigPlace& place,
             bool checkOnly) {
  RigReader reader(rig, baseDir, place, checkOnly);
  const std::string method = reader.string("method");
  const auto it = factories().find(method);
  if (it == factories().end()) {
    std::string known;
    for (const std::string& m : rigMethods()) known += (known.empty() ? "" : ", ") + m;
    reader.fail("method", "'" + method + "' is not one of: " + known);
  }
  reader.allowOnly(it->second.keys, "this method", method);
  // Errors from the warps' own validation and solvers: say which rig they came from (those of
  // a rig nested in this one are placed already).
  const std::string nested = place.file + ": warps[";
  const auto located = [&](const std::string& what) {
    return what.rfind(nested, 0) == 0 ? what : prefixed(reader.where(), what);
  };
  Rig result;
  try {
    result = it->second.build(reader);
  } catch (const InvalidInput& e) {
    throw InvalidInput(located(e.what()));
  } catch (const OutOfMemory& e) {  // before its base, SolverError: exit 3, not 4
    throw OutOfMemory(located(e.what()));
  } catch (const SolverError& e) {
    throw SolverError(located(e.what()));
  } catch (const IoError& e) {
    throw IoError(located(e.what()));
  }
  reader.finish();
  return result;
}

}  // namespace

json parseRigJson(std::string_view text, const std::string& where) {
  ParsePath path;
  // The path of the value at fault, its start only when deep: "'warps[0].warps[0]...' what".
  auto located = [&](const std::string& what) {
    std::string at = path.str();
    if (at.size() > 60) at = at.substr(0, 60) + "...";
    return InvalidInput(printable(where + ": '" + at + "' " + what));
  };
  const json::parser_callback_t callback = [&](int, json::parse_event_t event, json& parsed) {
    using Event = json::parse_event_t;
    switch (event) {
      case Event::object_start:
      case Event::array_start:
        // nlohmann's parser is iterative, but what reads the result may not be: bounded here.
        if (path.depth() >= std::size_t(kMaxJsonDepth))
          throw located("nests arrays and objects deeper than " + std::to_string(kMaxJsonDepth) +
                        " levels");
        path.open(event == Event::object_start);
        break;
      case Event::object_end:
      case Event::array_end:
        path.close();
        break;
      case Event::key:
        if (!path.key(parsed.get<std::string>())) throw located("is given twice");
        break;
      case Event::value:
        path.valueDone();
        break;
    }
    return true;
  };
  try {
    return json::parse(text.begin(), text.end(), callback);
  } catch (const json::parse_error& e) {
    // nlohmann's text is "[json.exception.parse_error.101] parse error at line 1, column 2:
    // ..."; the user needs only the position and the reason.
    std::string why = e.what();
    for (const std::string prefix : {"] ", "parse error at ", "parse error: "}) {
      if (const std::size_t at = why.find(prefix); at != std::string::npos && at < 40)
        why.erase(0, at + prefix.size());
    }
    throw IoError(printable(where + ": not valid JSON: " + why));
  } catch (const json::out_of_range&) {
    // The only range error of the parser: a number too large for a double (406).
    throw located("is a number outside the range of double");
  }
}

Rig rigFromJson(const json& rig, const std::filesystem::path& baseDir, const std::string& where,
                const ProgressCallback& progress) {
  return buildRig(rig, baseDir, {where, {}, progress}, false);
}

void checkRig(const json& rig, const std::filesystem::path& baseDir, const std::string& where) {
  buildRig(rig, baseDir, {where, {}}, true);
}

json readRigFile(const std::filesystem::path& path) {
  return detail::readJsonFile(path, "rig file", "a rig");
}

Rig loadRig(const std::filesystem::path& path, const ProgressCallback& progress) {
  return rigFromJson(readRigFile(path), path.parent_path(), printable(path.string()), progress);
}

std::vector<std::string> rigMethods() {
  std::vector<std::string> names;
  for (const auto& [name, factory] : factories()) names.push_back(name);
  return names;
}

}  // namespace spacewarp
