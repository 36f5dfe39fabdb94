#include "apps/rig_info.h"

#include <cstdio>
#include <map>
#include <string>

#include <nlohmann/json.hpp>

#include <spacewarp/core/errors.h>
#include <spacewarp/core/io/mesh_io.h>
#include <spacewarp/rig/rig.h>
#include "apps/cli_context.h"

namespace spacewarp::cli {

namespace {

using nlohmann::json;

// A value as the rig gives it: strings bare, anything else as compact JSON.
std::string text(const json& value) {
  return value.is_string() ? value.get<std::string>() : value.dump();
}

// What the coordinates of each cage method are, by rig method.
const std::map<std::string, std::string>& cageCoordinateNames() {
  static const std::map<std::string, std::string> names = {
      {"mvc", "mean-value coordinates"},
      {"green", "Green coordinates"},
      {"harmonic", "harmonic coordinates"},
      {"qmvc", "mean-value coordinates of polygon and quad faces"},
      {"qgc", "Green coordinates of triangle and quad faces"},
      {"wachspress", "Wachspress coordinates of a convex cage"},
      {"discrete-harmonic", "discrete harmonic coordinates of a convex cage of triangles"},
  };
  return names;
}

// Reads the keys of one rig loosely, for display: what is missing or odd is shown, not judged.
class Describer {
 public:
  Describer(const json& rig, std::filesystem::path baseDir, std::string where, std::string indent,
            std::string& out)
      : rig_(rig),
        baseDir_(std::move(baseDir)),
        where_(std::move(where)),
        indent_(std::move(indent)),
        out_(out) {}

  void print() const {
    if (!rig_.is_object() || !rig_.contains("method") || !rig_["method"].is_string())
      throw InvalidInput(where_ + ": a rig must be a JSON object with a string \"method\"");
    const std::string method = rig_["method"].get<std::string>();
    if (method == "twist" || method == "bend" || method == "taper") {
      analytic(method);
    } else if (method == "affine") {
      line("method", "affine");
      line("matrix", get("matrix"));
      line("does", "applies the row-major 4 x 4 matrix to every point: x' = M [x, 1]");
    } else if (cageCoordinateNames().count(method)) {
      cage(method);
    } else if (method == "ffd") {
      ffd();
    } else if (method == "rbf") {
      line("method", "rbf (" + get("kernel", "triharmonic") + " kernel)");
      line("centers", count(rig_, "centers") + ", moved to as many targets");
      line("fixed", rig_.contains("fixed") ? count(rig_, "fixed") : "0");
      line("smoothing", get("smoothing", "0 (interpolation)"));
      line("does",
           "fits a radial-basis warp (plus a linear part) that takes each center to its "
           "target and keeps the fixed points, then moves every point by it");
    } else if (method == "graph") {
      line("method", "graph (embedded deformation)");
      line("handles", count(rig_, "handles") + ", moved to as many targets");
      line("nodes", rig_.contains("nodes")
                        ? count(rig_, "nodes") + " given"
                        : "a grid of spacing " + get("spacing") + " over the handles' box");
      line("k", get("k", "4"));
      line("does",
           "solves the graph's node transforms (Gauss-Newton) so that the handles reach "
           "their targets, then moves each point by its k nearest nodes");
    } else if (method == "mls") {
      line("method", "mls (moving least squares, " + get("mode", "rigid") + ")");
      line("handles", count(rig_, "handles") + ", moved to as many targets");
      line("alpha", get("alpha", "1"));
      const bool inside = get("distance", "euclidean") == "inside";
      if (inside) {
        line("distance", "inside the model " + get("model") + ", on voxels of " +
                             get("voxelSize", "1/128 of its bounding-box diagonal"));
      }
      line("does", "moves each point by its own best " + get("mode", "rigid") +
                       " transform of the handles onto the targets, weighted by distance" +
                       (inside ? " measured inside the model (not across gaps)" : ""));
    } else if (method == "wires") {
      line("method", "wires (Singh & Fiume)");
      line("wires", count(rig_, "wires"));
      line("locality", get("locality", "1"));
      line("does",
           "moves the points within each wire's radius of its rest curve as the curve moves to "
           "its deformed one (scaled, turned and shifted about the closest rest point, fading "
           "with the distance), blending several wires by the size of their moves");
    } else if (method == "idw") {
      line("method", "idw (Shepard's inverse-distance weighting)");
      line("handles", count(rig_, "handles") + ", moved to as many targets");
      line("power", get("power", "2"));
      line("radius", get("radius", "none (every handle weighs everywhere)"));
      line("does",
           "moves each point by the mean of the handles' displacements, weighted by "
           "distance^-power" +
               std::string(rig_.contains("radius")
                               ? " (Franke-Nielson weights, zero beyond the radius; points out of "
                                 "every handle's reach are refused)"
                               : ""));
    } else if (method == "kelvinlet") {
      const std::string brush = get("brush");
      line("method", "kelvinlet (regularized Kelvinlet " + brush + " brush)");
      line("center", get("center"));
      line("radius", get("radius"));
      line("poisson", get("poisson", "0.45"));
      if (brush == "grab") line("displacement", get("displacement"));
      if (brush == "twist") {
        line("axis", get("axis"));
        line("angle", get("angle"));
      }
      if (brush == "scale") line("factor", get("factor"));
      if (brush == "pinch") line("matrix", get("matrix"));
      line("falloff", get("falloff", "single"));
      line("steps", get("steps", "1"));
      line("does", "displaces space as an infinite elastic medium under a " + brush +
                       " brush spread over the radius around the center; the effect fades with "
                       "distance and never stops entirely");
    } else if (method == "skinning") {
      const bool dqs = get("mode", "lbs") == "dqs";
      line("method", std::string("skinning (") + (dqs ? "dual-quaternion" : "linear blend") + ")");
      line("bones", count(rig_, "bones"));
      line("weights", rig_.contains("weights")
                          ? get("weights") + ", of the vertices of " + get("model") +
                                " (other points take their nearest vertex's)"
                          : get("coordinates", "rbf") + " coordinates of " +
                                count(rig_, "handles") + " handles, one per bone");
      line("influences",
           get("influences", rig_.contains("weights") ? "4" : "0") + " per point (0: all)");
      line("does",
           std::string("moves each point by the weighted blend of its bones' transforms (") +
               (dqs ? "as dual quaternions: twists keep their volume" : "of the matrices") + ")");
    } else if (method == "compose") {
      compose();
    } else {
      std::string known;
      for (const std::string& m : rigMethods()) known += (known.empty() ? "" : ", ") + m;
      throw InvalidInput(where_ + ": 'method' '" + method + "' is not one of: " + known);
    }
  }

 private:
  void line(const std::string& label, const std::string& value) const {
    char head[64];
    std::snprintf(head, sizeof head, "%-11s ", (label + ":").c_str());
    out_ += indent_ + head + value + "\n";
  }

  std::string get(const char* key, const std::string& fallback = "(missing)") const {
    return rig_.contains(key) ? text(rig_[key]) : fallback;
  }

  static std::string count(const json& object, const char* key) {
    if (!object.is_object() || !object.contains(key) || !object[key].is_array()) return "?";
    return groupDigits(object[key].size());
  }

  // Twist, bend and taper: their parameters and what they do with them.
  void analytic(const std::string& method) const {
    line("method", method);
    line("origin", get("origin"));
    line("axis", get("axis"));
    if (method == "bend") line("direction", get("direction"));
    line("rate", get("rate"));
    line("limits", get("limits", "none"));
    const std::string clamp = rig_.contains("limits") ? ", with s clamped to the limits" : "";
    if (method == "twist")
      line("does",
           "rotates each point about the axis through origin by rate * s radians, s "
           "its signed distance along the axis from origin" +
               clamp);
    else if (method == "bend")
      line("does",
           "bends the spine through origin along the axis into a circular arc of "
           "curvature rate (radians per unit) towards direction" +
               clamp);
    else
      line("does",
           "scales the components perpendicular to the axis by 1 + rate * s, s the "
           "signed distance along the axis from origin" +
               clamp);
  }

  void ffd() const {
    line("method", "ffd (" + get("basis") + " lattice)");
    line("origin", get("origin"));
    line("size", get("size"));
    const std::string resolution = get("resolution");
    std::string controls = "?";
    if (rig_.contains("resolution") && rig_["resolution"].is_array()) {
      std::size_t n = 1;
      for (const json& v : rig_["resolution"])
        n *= v.is_number_integer() && v.get<long long>() >= 1 && v.get<long long>() <= 1 << 20
                 ? static_cast<std::size_t>(v.get<long long>())
                 : 0;
      if (n > 0) controls = groupDigits(n);
    }
    line("controls", resolution + " = " + controls + " control points");
    if (rig_.contains("constraints"))
      line("posed by", "least-squares fit to " + count(rig_["constraints"], "from") +
                           " point constraints (smoothness " + get("smoothness", "1e-4") + ")");
    else
      line("posed by", count(rig_, "controlPoints") + " posed control points");
    if (get("basis") == "bspline") line("ends", get("ends", "extrapolate"));
    line("outside", get("outside", "identity"));
    line("does",
         "moves points inside the box by the lattice's displacement of its controls; "
         "points outside follow 'outside'");
  }

  // The composed warps, each described below it, indented.
  void compose() const {
    line("method", "compose");
    if (!rig_.contains("warps") || !rig_["warps"].is_array())
      throw InvalidInput(where_ + ": 'warps' must be a non-empty array");
    const json& warps = rig_["warps"];
    line("does", "applies the " + std::to_string(warps.size()) + " warps below in order");
    for (std::size_t i = 0; i < warps.size(); ++i) {
      out_ += indent_ + "warps[" + std::to_string(i) + "]:\n";
      Describer(warps[i], baseDir_, where_ + ": warps[" + std::to_string(i) + "]", indent_ + "  ",
                out_)
          .print();
    }
  }

  // Cage rigs: the cage files are read (not solved) for their counts.
  void cage(const std::string& method) const {
    const std::string& what = cageCoordinateNames().at(method);
    line("method", method + " (" + what + ")");
    std::size_t vertices = 0;
    for (const char* key : {"cage", "pose"}) {
      if (!rig_.contains(key) || !rig_[key].is_string()) {
        line(key, "(missing)");
        continue;
      }
      const std::filesystem::path file = rig_[key].get<std::string>();
      const PolygonSoup soup = readSoup(file.is_absolute() ? file : baseDir_ / file);
      line(key, file.string() + " (" + groupDigits(soup.size()) + " vertices, " +
                    groupDigits(soup.polygonCount()) + " faces)");
      if (std::string(key) == "cage") vertices = soup.size();
    }
    std::string does = "moves every point with the cage: its " + what +
                       " relative to the rest cage's " + groupDigits(vertices) +
                       " vertices, applied to the posed vertices";
    if (method == "green" || method == "qgc") does += " (and the faces' normals: shape-preserving)";
    if (method == "wachspress" || method == "discrete-harmonic")
      line("outside", get("outside", "raise"));
    if (method == "harmonic") {
      if (rig_.contains("precision"))
        line("precision", get("precision", "") + " (a target tet count, see --precision)");
      else
        line("tets", get("tets", "200000 (default)"));
      line("cache", get("cache", "none"));
      line("outside", get("outside", "raise"));
      does +=
          "; the coordinates are first solved on a tetrahedralisation of the cage, unless "
          "the cache file matches";
    }
    line("does", does);
  }

  const json& rig_;
  std::filesystem::path baseDir_;
  std::string where_, indent_;
  std::string& out_;
};

}  // namespace

void printRigInfo(const std::filesystem::path& path) {
  const json rig = readRigFile(path);
  // Refused exactly as `deform` refuses it (the same checks, without the solves), and before
  // anything is printed: a failed info prints nothing on stdout.
  checkRig(rig, path.parent_path(), printable(path.string()));
  std::string text = "file:       " + path.string() + "\n";
  Describer(rig, path.parent_path(), path.string(), "", text).print();
  std::fputs(text.c_str(), stdout);
}

}  // namespace spacewarp::cli
