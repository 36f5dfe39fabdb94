#pragma once
// The state of `spacewarp view`, without HTTP: a model, its controls (a cage, a lattice, handles
// or none), the methods that can drive them, each bound once to the model's vertices, and the
// current pose. Every pose is also a rig: writeRig() saves the rig JSON that `spacewarp deform
// --rig` turns into exactly positions(). Not thread-safe: the server guards it with a mutex.

#include <array>
#include <chrono>
#include <cstdint>
#include <filesystem>
#include <functional>
#include <map>
#include <memory>
#include <span>
#include <stdexcept>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include <spacewarp/core/binding.h>
#include <spacewarp/core/coordinates.h>
#include <spacewarp/core/geometry.h>
#include <spacewarp/core/warp.h>

namespace spacewarp::view {

/// A request that is well-formed but that the current method cannot answer (weights of a method
/// without coordinates, saving the pose of a rig without controls): HTTP 409.
class NotAvailable : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

/// A save that would write through a symbolic link at its name in the save folder: HTTP 403.
class Refused : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

/// dir/name, absolute, for a save. Throws Refused when that name is a symbolic link: the atomic
/// writer follows links (the CLI keeps a user's links), which would let a link planted in the
/// save folder redirect the viewer's writes anywhere.
std::filesystem::path savePath(const std::filesystem::path& dir, const std::string& name);

/// Options of ViewSession.
struct ViewSessionOptions {
  /// The first method; empty: the rig's own method, or "mvc" with a cage.
  std::string method;
  /// harmonic with a cage given by --cage: the target tet count (0: the library's default,
  /// about 200k tets; a harmonic rig's own `tets` wins).
  std::size_t harmonicTets = 0;
  /// ffd with a cage: control points per axis of the cubic B-spline lattice (≥ 4) fitted to the
  /// posed cage vertices.
  int ffdResolution = 5;
};

/// What the controls are, for the page.
enum class ControlKind { Cage, Lattice, Handles, None };

/// The model, controls, methods and pose of one viewer.
class ViewSession {
 public:
  /// The model (OBJ/OFF/PLY soup or cloud) with a cage file: methods: every cage method that
  /// takes the cage (cageMethods() through checkCageMethodApplies(): wachspress needs a convex
  /// cage, discrete-harmonic a convex cage of triangles, harmonic TetGen), ffd, rbf, idw, mls; the
  /// pose starts at the rest cage. Throws IoError/InvalidInput naming the file at fault.
  static ViewSession withCage(const std::filesystem::path& model, const std::filesystem::path& cage,
                              const ViewSessionOptions& options = {});
  /// The model with a rig file: a cage rig (any of cageMethods()) poses its cage, an ffd rig with
  /// controlPoints its lattice, an rbf/idw/mls/graph rig its handles (the pose starts at the
  /// rig's targets); any other rig is shown deformed, with no controls.
  static ViewSession withRig(const std::filesystem::path& model, const std::filesystem::path& rig,
                             const ViewSessionOptions& options = {});
  ViewSession(ViewSession&&) noexcept;
  ViewSession& operator=(ViewSession&&) noexcept;
  ~ViewSession();

  // --- the scene ---
  const std::filesystem::path& modelPath() const;
  const PolygonSoup& model() const;  ///< rest model (positions in world units)
  /// The rest model's bounding-box centre: the API's float32 positions are relative to it, so
  /// that a model far from the world origin keeps float32 precision of its size.
  Vec3 origin() const;
  bool isCloud() const;
  /// Triangles for display: each polygon fanned from its first vertex, 3 indices each.
  const std::vector<std::uint32_t>& triangles() const;
  ControlKind controlKind() const;
  std::span<const Vec3> restControls() const;
  std::span<const Vec3> pose() const;
  const std::vector<std::array<std::uint32_t, 2>>& controlEdges() const;
  const std::vector<std::vector<std::uint32_t>>& controlFaces() const;  ///< cage only
  const std::vector<std::string>& methods() const;
  const std::string& method() const;
  /// Whether weights() and slice() answer for the current method.
  bool hasWeights() const;
  /// GET /api/scene's JSON (saveDir added by the server).
  nlohmann::json sceneJson() const;

  // --- posing ---
  /// Poses the controls (restControls().size() points, finite) and recomputes positions().
  /// Returns the deform time in milliseconds. Throws InvalidInput for a wrong size or a
  /// non-finite point (naming its index).
  double setPose(std::span<const Vec3> pose);
  /// Switches method (binding it on first use) and recomputes positions() for the same pose;
  /// returns the bind time in milliseconds (0 when already bound). Throws InvalidInput for a
  /// method not in methods(), and what binding throws (e.g. a harmonic cage that misses model
  /// vertices).
  double setMethod(const std::string& method);
  /// The deformed model's vertex positions for the current pose and method.
  std::span<const Vec3> positions() const;

  // --- looking inside ---
  /// Control i's coordinate function at the model's vertices (n values). NotAvailable unless
  /// hasWeights(); InvalidInput for i out of range.
  std::vector<double> weights(std::size_t control) const;
  /// A slice of control i's coordinate function: r × r values, row-major (u fastest), on the
  /// plane axis = value (axis 0..2) over the rest controls' and model's bounds padded by 5% of
  /// their diagonal, sampled at origin + U·a/(r − 1) + V·b/(r − 1); NaN where undefined.
  struct Slice {
    Vec3 origin, u, v;  ///< the corner and the two full edge vectors (world units)
    int resolution = 0;
    std::vector<double> values;
  };
  Slice slice(std::size_t control, int axis, double value, int resolution) const;
  /// 1 where det J ≤ 0 or is not finite at the vertex for the current pose and method.
  std::vector<std::uint8_t> folds() const;

  // --- the same, in two steps: the *Job functions check their arguments and take a snapshot of
  // what they read (shared references to the bound method and the pose's warp, a copy of the
  // pose's positions) under the caller's lock; the job they return runs without it, so that
  // poses go on while a slice is computed. A job must not outlive the session. ---
  std::function<std::vector<double>()> weightsJob(std::size_t control) const;
  std::function<Slice()> sliceJob(std::size_t control, int axis, double value,
                                  int resolution) const;
  std::function<std::vector<std::uint8_t>()> foldsJob() const;
  std::function<std::filesystem::path()> writeModelJob(const std::filesystem::path& dir) const;

  // --- saving ---
  /// The rig JSON of the current method and pose; `poseFile` is the posed cage file it
  /// references (the cage methods), relative to the rig's folder.
  nlohmann::json rigJson(const std::string& poseFile) const;
  /// Writes `<stem>_pose.obj` (the posed cage with its faces, or the posed points) into `dir`
  /// atomically; returns its path. NotAvailable without controls.
  std::filesystem::path writePose(const std::filesystem::path& dir) const;
  /// Writes `<stem>_rig.json` (and the pose file it references); returns the paths written.
  std::vector<std::filesystem::path> writeRig(const std::filesystem::path& dir) const;
  /// Writes `<stem>_deformed.<ext of the model>`; returns its path.
  std::filesystem::path writeModel(const std::filesystem::path& dir) const;

  /// The session's state (defined in view_session.cpp only).
  struct State;
  explicit ViewSession(std::unique_ptr<State> state);

 private:
  std::unique_ptr<State> state_;
};

/// The name of a control kind in the API ("cage", "lattice", "handles", "none").
const char* controlKindName(ControlKind kind);

}  // namespace spacewarp::view
