#include "apps/view/view_session.h"

#include <algorithm>
#include <cmath>
#include <fstream>
#include <functional>
#include <limits>
#include <set>

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <spacewarp/coords/cage.h>
#include <spacewarp/core/deform.h>
#include <spacewarp/core/errors.h>
#include <spacewarp/core/io/atomic_file.h>
#include <spacewarp/core/io/mesh_io.h>
#include <spacewarp/rig/cage_rig.h>
#include <spacewarp/rig/rig.h>

namespace spacewarp::view {

namespace {

using Clock = std::chrono::steady_clock;

double millisecondsSince(Clock::time_point start) {
  return std::chrono::duration<double, std::milli>(Clock::now() - start).count();
}

bool isCageMethod(const std::string& method) {
  const std::vector<std::string> methods = cageMethods();
  return std::find(methods.begin(), methods.end(), method) != methods.end();
}

// The cage methods that take an "outside" key (CageMethodOptions::outside).
bool hasOutsidePolicy(const std::string& method) {
  return method == "harmonic" || method == "wachspress" || method == "discrete-harmonic";
}

nlohmann::json pointsJson(std::span<const Vec3> points) {
  nlohmann::json out = nlohmann::json::array();
  for (const Vec3& p : points) out.push_back({p.x, p.y, p.z});
  return out;
}

/// The box around both `a` and `b`.
BoundingBox boundsOf(std::span<const Vec3> a, std::span<const Vec3> b) {
  BoundingBox box = boundingBox(a);
  const BoundingBox other = boundingBox(b);
  box.min = glm::min(box.min, other.min);
  box.max = glm::max(box.max, other.max);
  return box;
}

// Paths inside a rig are relative to its file; a rig saved elsewhere gets them absolute.
void absolutePaths(nlohmann::json& rig, const std::filesystem::path& baseDir) {
  if (!rig.is_object()) return;
  for (const char* key : {"cage", "pose", "model", "weights", "cache"})
    if (auto it = rig.find(key); it != rig.end() && it->is_string())
      *it = std::filesystem::absolute(baseDir / it->get<std::string>()).lexically_normal().string();
  if (auto it = rig.find("warps"); it != rig.end() && it->is_array())
    for (nlohmann::json& inner : *it) absolutePaths(inner, baseDir);
}

struct BoundMethod {
  std::shared_ptr<const Coordinates> coordinates;  // null: evaluated through its rig each pose
  std::shared_ptr<const Binding> binding;          // shared with jobs run outside the lock
};

}  // namespace

struct ViewSession::State {
  ViewSessionOptions options;
  std::filesystem::path modelPath;
  PolygonSoup model;
  Vec3 origin{0.0};  // the rest model's bounding-box centre
  std::vector<std::uint32_t> triangles;

  ControlKind kind = ControlKind::None;
  std::shared_ptr<const Cage> cage;
  std::filesystem::path cagePath;  // absolute
  PolygonSoup cageSoup;            // the rest cage as read, for its faces
  CageMethodOptions cageOptions;
  std::vector<Vec3> rest, pose;
  std::vector<std::array<std::uint32_t, 2>> edges;
  std::vector<std::vector<std::uint32_t>> faces;

  nlohmann::json rig;  // the rig file's JSON (empty with --cage)
  std::filesystem::path rigDir;
  std::string rigWhere;
  std::vector<std::string> methods;
  std::string method;

  std::map<std::string, BoundMethod> bound;
  std::vector<Vec3> positions;
  std::shared_ptr<const Warp> warp;  // the current pose's warp (null: not made yet)

  // The rig of `name` posed by `posed`, with the cage methods' pose file `poseFile`.
  nlohmann::json rigFor(const std::string& name, std::span<const Vec3> posed,
                        const std::string& poseFile) const {
    if (kind == ControlKind::None) {
      nlohmann::json out = rig;
      absolutePaths(out, rigDir);
      return out;
    }
    if (kind == ControlKind::Lattice) {
      nlohmann::json out = rig;
      absolutePaths(out, rigDir);
      out["controlPoints"] = pointsJson(posed);
      return out;
    }
    if (isCageMethod(name)) {
      nlohmann::json out = {{"method", name}, {"cage", cagePath.string()}, {"pose", poseFile}};
      if (name == "harmonic") {
        if (cageOptions.harmonicTets > 0) out["tets"] = cageOptions.harmonicTets;
        if (!cageOptions.harmonicCache.empty()) out["cache"] = cageOptions.harmonicCache.string();
      }
      if (hasOutsidePolicy(name) && cageOptions.outside != "raise")
        out["outside"] = cageOptions.outside;
      return out;
    }
    nlohmann::json out;
    if (kind == ControlKind::Handles && rig.value("method", "") == name) {
      out = rig;  // the rig's own method keeps its parameters
      absolutePaths(out, rigDir);
    } else {
      out = {{"method", name}};
    }
    if (name == "ffd") {
      // A cubic B-spline lattice over the cage's bounds padded by 5% of its diagonal, fitted to
      // take the rest cage vertices to the posed ones.
      const BoundingBox box = boundingBox(rest);
      const Vec3 pad(0.05 * box.diagonal());
      const Vec3 lo = box.min - pad, size = box.extent() + 2.0 * pad;
      const int r = options.ffdResolution;
      out["basis"] = "bspline";
      out["origin"] = {lo.x, lo.y, lo.z};
      out["size"] = {size.x, size.y, size.z};
      out["resolution"] = {r, r, r};
      out["constraints"] = {{"from", pointsJson(rest)}, {"to", pointsJson(posed)}};
      return out;
    }
    out[name == "rbf" ? "centers" : "handles"] = pointsJson(rest);
    out.erase(name == "rbf" ? "handles" : "centers");
    out["targets"] = pointsJson(posed);
    if (name == "graph" && !out.contains("spacing") && !out.contains("nodes"))
      out["spacing"] = std::max(boundingBox(rest).diagonal() / 4.0, 1e-300);
    return out;
  }

  Rig buildRig(const std::string& name, std::span<const Vec3> posed) const {
    const std::string where =
        rigWhere.empty() ? "view: " + name + " rig" : rigWhere + " (as " + name + ")";
    return rigFromJson(rigFor(name, posed, ""), rigDir, where);
  }

  BoundMethod& bind(const std::string& name) {
    if (auto it = bound.find(name); it != bound.end()) return it->second;
    BoundMethod method;
    if (kind == ControlKind::Cage && isCageMethod(name)) {
      method.coordinates = cageCoordinates(name, cage, cageOptions);
    } else if (kind != ControlKind::None && !(kind == ControlKind::Cage && name == "ffd")) {
      // Linear handle methods (rbf, idw) and lattices: their coordinates do not depend on the
      // pose. mls and graph have none.
      Rig built = buildRig(name, pose);
      if (built.coordinates && built.coordinates->controlPointCount() == rest.size())
        method.coordinates = built.coordinates;
    }
    if (method.coordinates)
      method.binding = std::make_shared<const Binding>(method.coordinates, model.positions);
    return bound.emplace(name, std::move(method)).first->second;
  }

  void deform() {
    BoundMethod& m = bind(method);
    positions.resize(model.positions.size());
    if (m.binding) {
      m.binding->deform(pose, positions);
      warp.reset();
    } else {
      warp = buildRig(method, pose).warp;
      warp->applyBatch(model.positions, positions);
    }
  }

  std::shared_ptr<const Warp> currentWarp() {
    if (!warp) warp = makeWarp(bound.at(method).coordinates, pose);
    return warp;
  }

  void requireWeights(std::size_t control) const {
    const auto it = bound.find(method);
    if (it == bound.end() || !it->second.binding)
      throw NotAvailable("method " + method + " has no coordinates to show");
    if (control >= rest.size())
      throw InvalidInput("control " + std::to_string(control) + " is out of range (" +
                         std::to_string(rest.size()) + " controls)");
  }
};

namespace {

std::vector<std::uint32_t> fanTriangles(const PolygonSoup& soup) {
  std::vector<std::uint32_t> out;
  for (std::size_t f = 0; f < soup.polygonCount(); ++f) {
    const std::uint32_t begin = soup.faceOffsets[f], end = soup.faceOffsets[f + 1];
    for (std::uint32_t c = begin + 1; c + 1 < end; ++c) {
      out.push_back(soup.faceIndices[begin]);
      out.push_back(soup.faceIndices[c]);
      out.push_back(soup.faceIndices[c + 1]);
    }
  }
  return out;
}

std::unique_ptr<ViewSession::State> loadModel(const std::filesystem::path& model,
                                              const ViewSessionOptions& options) {
  auto state = std::make_unique<ViewSession::State>();
  state->options = options;
  if (options.ffdResolution < 4)
    throw InvalidInput("view: ffdResolution must be at least 4, not " +
                       std::to_string(options.ffdResolution));
  state->modelPath = std::filesystem::absolute(model).lexically_normal();
  state->model = readSoup(model);
  state->triangles = fanTriangles(state->model);
  if (const BoundingBox box = boundingBox(state->model.positions); !box.empty())
    state->origin = 0.5 * (box.min + box.max);
  return state;
}

void setCageControls(ViewSession::State& s, const std::filesystem::path& cagePath) {
  s.kind = ControlKind::Cage;
  s.cagePath = std::filesystem::absolute(cagePath).lexically_normal();
  s.cageSoup = readSoup(cagePath);
  s.cage = std::make_shared<const Cage>(
      namingFile(cagePath.string(), [&] { return Cage(s.cageSoup, cagePath.string()); }));
  s.rest.assign(s.cage->vertices().begin(), s.cage->vertices().end());
  s.pose = s.rest;
  std::set<std::array<std::uint32_t, 2>> edges;
  for (std::size_t f = 0; f < s.cageSoup.polygonCount(); ++f) {
    const std::uint32_t begin = s.cageSoup.faceOffsets[f], end = s.cageSoup.faceOffsets[f + 1];
    s.faces.emplace_back(s.cageSoup.faceIndices.begin() + begin,
                         s.cageSoup.faceIndices.begin() + end);
    for (std::uint32_t c = begin; c < end; ++c) {
      std::uint32_t a = s.cageSoup.faceIndices[c];
      std::uint32_t b = s.cageSoup.faceIndices[c + 1 < end ? c + 1 : begin];
      edges.insert({std::min(a, b), std::max(a, b)});
    }
  }
  s.edges.assign(edges.begin(), edges.end());
  // The cage methods that take this cage (wachspress needs a convex one, discrete-harmonic a
  // convex one of triangles; harmonic is there where built with TetGen).
  s.methods.clear();
  for (const std::string& method : cageMethods()) {
    try {
      checkCageMethodApplies(method, *s.cage);
      s.methods.push_back(method);
    } catch (const InvalidInput&) {
    }
  }
  for (const char* m : {"ffd", "rbf", "idw", "mls"}) s.methods.push_back(m);
}

ViewSession finish(std::unique_ptr<ViewSession::State> s, const std::string& defaultMethod) {
  s->method = s->options.method.empty() ? defaultMethod : s->options.method;
  if (std::find(s->methods.begin(), s->methods.end(), s->method) == s->methods.end()) {
    std::string list;
    for (const std::string& m : s->methods) list += (list.empty() ? "" : ", ") + m;
    throw InvalidInput("--method " + s->method + ": not available for these controls (" + list +
                       ")");
  }
  s->deform();
  return ViewSession(std::move(s));
}

}  // namespace

ViewSession::ViewSession(std::unique_ptr<State> state) : state_(std::move(state)) {}
ViewSession::ViewSession(ViewSession&&) noexcept = default;
ViewSession& ViewSession::operator=(ViewSession&&) noexcept = default;
ViewSession::~ViewSession() = default;

ViewSession ViewSession::withCage(const std::filesystem::path& model,
                                  const std::filesystem::path& cage,
                                  const ViewSessionOptions& options) {
  auto s = loadModel(model, options);
  setCageControls(*s, cage);
  s->cageOptions.harmonicTets = options.harmonicTets;
  s->rigDir = std::filesystem::current_path();
  return finish(std::move(s), "mvc");
}

ViewSession ViewSession::withRig(const std::filesystem::path& model,
                                 const std::filesystem::path& rigPath,
                                 const ViewSessionOptions& options) {
  auto s = loadModel(model, options);
  s->rig = readRigFile(rigPath);
  s->rigDir = std::filesystem::absolute(rigPath).parent_path();
  s->rigWhere = rigPath.string();
  const std::string method = s->rig.is_object() ? s->rig.value("method", "") : "";
  const auto points = [&](const char* key) {
    std::vector<Vec3> out;
    const auto it = s->rig.find(key);
    if (it == s->rig.end() || !it->is_array()) return out;
    for (const nlohmann::json& p : *it) {
      if (!p.is_array() || p.size() != 3)
        throw InvalidInput(rigPath.string() + ": '" + key + "' must hold [x, y, z] points");
      out.emplace_back(p[0].get<double>(), p[1].get<double>(), p[2].get<double>());
    }
    return out;
  };
  checkRig(s->rig, s->rigDir, s->rigWhere);  // every key, before reading any of them here
  if (isCageMethod(method)) {
    setCageControls(*s, s->rigDir / s->rig.at("cage").get<std::string>());
    s->pose = s->cage->posedVerticesFromFile(s->rigDir / s->rig.at("pose").get<std::string>());
    s->cageOptions.harmonicTets = s->rig.value("tets", options.harmonicTets);
    s->cageOptions.outside = s->rig.value("outside", std::string("raise"));
    if (s->rig.contains("cache"))
      s->cageOptions.harmonicCache = s->rigDir / s->rig.at("cache").get<std::string>();
  } else if (method == "ffd" && s->rig.contains("controlPoints")) {
    s->kind = ControlKind::Lattice;
    const Rig built = rigFromJson(s->rig, s->rigDir, s->rigWhere);
    const auto rest = built.coordinates->restControlPoints();
    s->rest.assign(rest.begin(), rest.end());
    s->pose = points("controlPoints");
    const nlohmann::json& r = s->rig.at("resolution");
    const std::uint32_t l = r[0], m = r[1], n = r[2];
    const auto index = [&](std::uint32_t i, std::uint32_t j, std::uint32_t k) {
      return i + l * (j + m * k);
    };
    for (std::uint32_t k = 0; k < n; ++k)
      for (std::uint32_t j = 0; j < m; ++j)
        for (std::uint32_t i = 0; i < l; ++i) {
          if (i + 1 < l) s->edges.push_back({index(i, j, k), index(i + 1, j, k)});
          if (j + 1 < m) s->edges.push_back({index(i, j, k), index(i, j + 1, k)});
          if (k + 1 < n) s->edges.push_back({index(i, j, k), index(i, j, k + 1)});
        }
    s->methods = {"ffd"};
  } else if (method == "rbf" || method == "idw" || method == "mls" || method == "graph") {
    s->kind = ControlKind::Handles;
    s->rest = points(method == "rbf" ? "centers" : "handles");
    s->pose = points("targets");
    s->methods = {"rbf", "idw", "mls", "graph"};
  } else {
    s->kind = ControlKind::None;
    s->methods = {method};
  }
  return finish(std::move(s), method);
}

const std::filesystem::path& ViewSession::modelPath() const { return state_->modelPath; }
const PolygonSoup& ViewSession::model() const { return state_->model; }
bool ViewSession::isCloud() const { return state_->model.polygonCount() == 0; }
const std::vector<std::uint32_t>& ViewSession::triangles() const { return state_->triangles; }
Vec3 ViewSession::origin() const { return state_->origin; }
ControlKind ViewSession::controlKind() const { return state_->kind; }
std::span<const Vec3> ViewSession::restControls() const { return state_->rest; }
std::span<const Vec3> ViewSession::pose() const { return state_->pose; }
const std::vector<std::array<std::uint32_t, 2>>& ViewSession::controlEdges() const {
  return state_->edges;
}
const std::vector<std::vector<std::uint32_t>>& ViewSession::controlFaces() const {
  return state_->faces;
}
const std::vector<std::string>& ViewSession::methods() const { return state_->methods; }
const std::string& ViewSession::method() const { return state_->method; }
std::span<const Vec3> ViewSession::positions() const { return state_->positions; }

bool ViewSession::hasWeights() const {
  const auto it = state_->bound.find(state_->method);
  return it != state_->bound.end() && it->second.binding != nullptr;
}

std::filesystem::path savePath(const std::filesystem::path& dir, const std::string& name) {
  const std::filesystem::path path = std::filesystem::absolute(dir / name);
  std::error_code error;
  if (std::filesystem::is_symlink(std::filesystem::symlink_status(path, error)))
    throw Refused("refused: " + path.string() +
                  " is a symbolic link; remove it to save there (the viewer does not write "
                  "through links)");
  return path;
}

const char* controlKindName(ControlKind kind) {
  switch (kind) {
    case ControlKind::Cage:
      return "cage";
    case ControlKind::Lattice:
      return "lattice";
    case ControlKind::Handles:
      return "handles";
    case ControlKind::None:
      break;
  }
  return "none";
}

nlohmann::json ViewSession::sceneJson() const {
  const State& s = *state_;
  const BoundingBox box = boundingBox(s.model.positions);
  nlohmann::json edges = nlohmann::json::array();
  for (const auto& e : s.edges) edges.push_back({e[0], e[1]});
  nlohmann::json controls = {{"kind", controlKindName(s.kind)},
                             {"count", s.rest.size()},
                             {"rest", pointsJson(s.rest)},
                             {"pose", pointsJson(s.pose)},
                             {"edges", edges}};
  if (s.kind == ControlKind::Cage) controls["faces"] = s.faces;
  return {{"model",
           {{"path", s.modelPath.string()},
            {"kind", isCloud() ? "cloud" : "soup"},
            {"vertexCount", s.model.positions.size()},
            {"triangleCount", s.triangles.size() / 3},
            {"bounds", {{box.min.x, box.min.y, box.min.z}, {box.max.x, box.max.y, box.max.z}}}}},
          {"origin", {s.origin.x, s.origin.y, s.origin.z}},
          {"controls", controls},
          {"methods", s.methods},
          {"method", s.method},
          {"hasWeights", hasWeights()}};
}

double ViewSession::setPose(std::span<const Vec3> pose) {
  State& s = *state_;
  if (pose.size() != s.rest.size())
    throw InvalidInput("pose: " + std::to_string(pose.size()) + " points for " +
                       std::to_string(s.rest.size()) + " controls");
  for (std::size_t i = 0; i < pose.size(); ++i)
    if (!std::isfinite(pose[i].x) || !std::isfinite(pose[i].y) || !std::isfinite(pose[i].z))
      throw InvalidInput("pose: control " + std::to_string(i) + " is not finite");
  const auto start = Clock::now();
  std::vector<Vec3> previous = std::move(s.pose);
  s.pose.assign(pose.begin(), pose.end());
  try {
    s.deform();
    // Finite controls far out (1e200) can still overflow the positions.
    const auto bad = std::find_if(s.positions.begin(), s.positions.end(), [](const Vec3& p) {
      return !(std::isfinite(p.x) && std::isfinite(p.y) && std::isfinite(p.z));
    });
    if (bad != s.positions.end())
      throw InvalidInput("pose: vertex " + std::to_string(bad - s.positions.begin()) +
                         " of the model is not finite under this pose (controls too far out)");
  } catch (...) {
    // A pose the method refuses (a singular fit, overflowing positions) is not kept.
    s.pose = std::move(previous);
    s.warp.reset();
    s.deform();  // the previous pose's positions again (it deformed before)
    throw;
  }
  return millisecondsSince(start);
}

double ViewSession::setMethod(const std::string& method) {
  State& s = *state_;
  if (std::find(s.methods.begin(), s.methods.end(), method) == s.methods.end())
    throw InvalidInput("method '" + method + "' is not one of this scene's methods");
  const bool bound = s.bound.contains(method);
  const auto start = Clock::now();
  const std::string previous = s.method;
  s.method = method;
  try {
    s.bind(method);
    const double bindMs = bound ? 0.0 : millisecondsSince(start);
    s.deform();
    return bindMs;
  } catch (...) {
    s.method = previous;
    s.warp.reset();
    throw;
  }
}

std::vector<double> ViewSession::weights(std::size_t control) const {
  return weightsJob(control)();
}

std::function<std::vector<double>()> ViewSession::weightsJob(std::size_t control) const {
  const State& s = *state_;
  s.requireWeights(control);
  return [b = s.bound.at(s.method).binding, control] {
    std::vector<double> out(b->pointCount(), 0.0);
    if (b->isSparse()) {
      const Binding::SparseMatrix& w = b->sparse();
      for (Eigen::Index row = 0; row < w.outerSize(); ++row)
        for (Binding::SparseMatrix::InnerIterator it(w, row); it; ++it)
          if (it.col() == static_cast<Eigen::Index>(control)) out[row] = it.value();
    } else {
      for (std::size_t i = 0; i < out.size(); ++i)
        out[i] = b->dense()(static_cast<Eigen::Index>(i), static_cast<Eigen::Index>(control));
    }
    return out;
  };
}

ViewSession::Slice ViewSession::slice(std::size_t control, int axis, double value,
                                      int resolution) const {
  return sliceJob(control, axis, value, resolution)();
}

std::function<ViewSession::Slice()> ViewSession::sliceJob(std::size_t control, int axis,
                                                          double value, int resolution) const {
  const State& s = *state_;
  s.requireWeights(control);
  if (axis < 0 || axis > 2 || resolution < 2 || !std::isfinite(value))
    throw InvalidInput("slice: bad axis, value or resolution");
  BoundingBox box = boundsOf(s.rest, s.model.positions);
  const Vec3 pad(0.05 * box.diagonal());
  box.min -= pad;
  box.max += pad;
  const int ua = axis == 0 ? 1 : 0, va = axis == 2 ? 1 : 2;
  Slice out;
  out.resolution = resolution;
  out.origin = box.min;
  out.origin[axis] = value;
  out.u = Vec3(0.0);
  out.u[ua] = box.max[ua] - box.min[ua];
  out.v = Vec3(0.0);
  out.v[va] = box.max[va] - box.min[va];
  return [out, c = s.bound.at(s.method).coordinates, control]() mutable {
    const std::size_t r = static_cast<std::size_t>(out.resolution);
    out.values.assign(r * r, std::numeric_limits<double>::quiet_NaN());
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, r * r, 256), [&](const auto& range) {
      std::vector<double> row(c->columnCount());
      for (std::size_t k = range.begin(); k < range.end(); ++k) {
        const double a = double(k % r) / double(r - 1), b = double(k / r) / double(r - 1);
        const Vec3 x = out.origin + a * out.u + b * out.v;
        try {
          c->weights(x, row);
          out.values[k] = row[control];
        } catch (const InvalidInput&) {
          // undefined there (outside a harmonic cage): stays NaN
        } catch (const SolverError&) {
          // no weights there (a mean-value weight sum that vanishes far from the cage): NaN
        }
      }
    });
    return std::move(out);
  };
}

std::vector<std::uint8_t> ViewSession::folds() const { return foldsJob()(); }

std::function<std::vector<std::uint8_t>()> ViewSession::foldsJob() const {
  State& s = *state_;
  // The rest model never changes after loading: the job reads it in place.
  return [warp = s.currentWarp(), &x = s.model.positions] {
    std::vector<std::uint8_t> out(x.size(), 0);
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, x.size(), 1024), [&](const auto& range) {
      for (std::size_t i = range.begin(); i < range.end(); ++i) {
        const double det = glm::determinant(warp->jacobian(x[i]));
        out[i] = !(std::isfinite(det) && det > 0.0) ? 1 : 0;
      }
    });
    return out;
  };
}

nlohmann::json ViewSession::rigJson(const std::string& poseFile) const {
  return state_->rigFor(state_->method, state_->pose, poseFile);
}

std::filesystem::path ViewSession::writePose(const std::filesystem::path& dir) const {
  const State& s = *state_;
  if (s.kind == ControlKind::None) throw NotAvailable("this rig has no controls to save");
  PolygonSoup soup;
  if (s.kind == ControlKind::Cage) soup = s.cageSoup;
  soup.positions = s.pose;
  soup.normals.clear();
  const std::filesystem::path path = savePath(dir, s.modelPath.stem().string() + "_pose.obj");
  writeSoup(soup, path);
  return path;
}

std::vector<std::filesystem::path> ViewSession::writeRig(const std::filesystem::path& dir) const {
  const State& s = *state_;
  std::vector<std::filesystem::path> paths;
  std::string poseFile;
  if (s.kind == ControlKind::Cage && isCageMethod(s.method)) {
    paths.push_back(writePose(dir));
    poseFile = paths.back().filename().string();
  }
  const std::filesystem::path path = savePath(dir, s.modelPath.stem().string() + "_rig.json");
  const std::string text = rigJson(poseFile).dump(2) + "\n";
  writeFileAtomically(path, [&](std::ostream& out) { out << text; });
  paths.push_back(path);
  return paths;
}

std::filesystem::path ViewSession::writeModel(const std::filesystem::path& dir) const {
  return writeModelJob(dir)();
}

std::function<std::filesystem::path()> ViewSession::writeModelJob(
    const std::filesystem::path& dir) const {
  State& s = *state_;
  const bool normals = s.model.hasNormals() || !s.model.cornerNormals.empty();
  const std::filesystem::path path =
      savePath(dir, s.modelPath.stem().string() + "_deformed" + s.modelPath.extension().string());
  return [warp = normals ? s.currentWarp() : nullptr, positions = s.positions, &model = s.model,
          path] {
    PolygonSoup soup = model;
    // Normals follow the warp (J^-T n); the positions are the session's own, bit for bit.
    if (warp) deform(*warp, soup);
    soup.positions = positions;
    writeSoup(soup, path);
    return path;
  };
}

}  // namespace spacewarp::view
