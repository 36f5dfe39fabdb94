#pragma once
// Harmonic coordinates (Joshi, Meyer, DeRose, Green, Sanocki: "Harmonic coordinates for
// character articulation", SIGGRAPH 2007) through a tetrahedralisation of the cage's interior
// and a sparse Laplace solve. Only built when SPACEWARP_WITH_TETGEN is ON (then
// SPACEWARP_HAVE_HARMONIC is defined for every user of spacewarp::coords).
//
// The cage's interior is tetrahedralised by TetGen, conforming to the cage (coords/tet_mesh.h).
// Every coordinate function w_i is the linear-FEM solution of Laplace's equation on the tets
// with Dirichlet values on the boundary vertices: the piecewise-linear hat of cage vertex i
// (δ_ij at cage vertices, barycentric on cage faces, so the boundary values are exact). The
// stiffness (cotangent) matrix of the interior vertices is factorised once by CHOLMOD's
// supernodal sparse Cholesky, and all k = cage-vertex-count functions are solved for at once
// (multi-column BLAS-3 solves, parallel in the BLAS).
//
// The coordinates of a point are the barycentric mix of the values at the 4 corners of the tet
// that contains it (found through a uniform grid over the tets, coords/tet_locator.h): they are
// piecewise linear on the tets, continuous, sum to 1 and reproduce linear functions up to the
// solver's round-off, interpolate (Lagrange property at cage vertices, linear on cage faces)
// and are smooth inside up to the mesh's resolution. The discrete maximum principle holds
// where the cotangent weights are non-negative, which Delaunay refinement nearly but not
// always gives; HarmonicOptions::nonNegative (on by default) projects the few vertex rows that
// dip below zero, so that weights are in [0, 1] everywhere. Every row is dense
// (all k columns are non-zero inside the cage). Gradients (for normals) are constant per tet.
//
// A solve can be saved and loaded (save(), load()) so a bind is reused across runs; the file
// format is documented at save(). To warp, HarmonicWarp (coords/harmonic_warp.h) is the fast
// Warp view (CoordinateWarp works too, forming every point's whole weight row).

#include <array>
#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <memory>
#include <span>
#include <string>

#include <spacewarp/coords/cage.h>
#include <spacewarp/coords/tet_locator.h>
#include <spacewarp/coords/tet_mesh.h>
#include <spacewarp/core/coordinates.h>
#include <spacewarp/core/progress.h>

namespace spacewarp {

/// What the harmonic coordinates of a point outside the cage (in no tet) are.
enum class HarmonicOutsidePolicy {
  /// Throw InvalidInput, saying how many points of the call are outside.
  Throw,
  /// The coordinates of the nearest point on the cage surface (its barycentric coordinates on
  /// the nearest cage triangle; ties go to the lowest triangle index). They are continuous
  /// across the cage, constant along the surface normal, and reproduce the nearest point, not x.
  NearestPoint,
};

/// Options of HarmonicCoordinates.
struct HarmonicOptions {
  /// The size of the tetrahedralisation as a target tet count, used when maxTetVolumeFraction is 0:
  /// the volume bound is then derived from the cage's volume so that the mesh has roughly
  /// this many tets (within a factor ~1.5; coarse cages get more, since the quality bound
  /// refines near small cage features). The default gives the Ju et al. armadillo cage about
  /// 190k tets (tetrahedralisation, factorisation and solve in about 1.2 s on two cores; 170 MB
  /// peak). Must be ≥ 1.
  std::size_t targetTetCount = 200000;
  /// Upper bound on every tet's volume, relative to the cage's volume (0: use targetTetCount).
  /// Must be finite and in [0, 1].
  double maxTetVolumeFraction = 0.0;
  /// Upper bound on each tet's circumradius / shortest edge (TetGen's -q); see TetMeshOptions.
  double radiusEdgeRatio = 2.0;
  /// Whether to enforce non-negative coordinates. The linear-FEM solution obeys the discrete
  /// maximum principle only where the mesh's cotangent weights are non-negative; TetGen's
  /// meshes have some obtuse dihedral angles, and a few interior vertices near the cage (a
  /// handful per thousand tets, by up to a few percent at coarse resolutions, shrinking with
  /// refinement) get slightly negative values. With this on, the row of every such vertex is
  /// replaced by its least-squares projection onto the non-negative rows that keep partition
  /// of unity and linear reproduction at that vertex (a 4-unknown dual Newton solve per
  /// row), so every point's coordinates are ≥ 0 and ≤ 1 while both properties still hold to
  /// round-off. Off: the raw FEM solution.
  bool nonNegative = true;
  /// Points outside the cage: see HarmonicOutsidePolicy.
  HarmonicOutsidePolicy outside = HarmonicOutsidePolicy::Throw;
};

/// The precision levels of the harmonic set-up, a simple knob over the tet budget (the rig key
/// "precision", the command line's --precision, Python's precision=): level p targets
/// 200000 · 4^(p − 5) tets (HarmonicOptions::targetTetCount), so 5 is the default resolution and
/// each level quadruples the tets (edges about 1.6 times shorter). Levels between the whole
/// ones (5.5: 400,000 tets) land between them on the accuracy/time frontier. On the Ju et al.
/// armadillo (15k model vertices, 110-vertex cage; bench/harmonic_frontier.py) the max deviation
/// from a converged solve, relative to the cage's diagonal,
/// went 1.4e-2, 8.3e-3, 5.1e-3, 3.6e-3, 1.4e-3 from level 2 to 6 (README, "Harmonic coordinates").
constexpr int kHarmonicMinPrecision = 1, kHarmonicMaxPrecision = 7;

/// The target tet count of precision level `precision` (see kHarmonicMinPrecision), any number
/// in [1, 7]: 781 at 1, 200000 at 5, 3.2M at 7 (whole levels exactly, others rounded to the
/// nearest count). Throws InvalidInput, naming the value, outside [1, 7] or not finite.
std::size_t harmonicPrecisionTets(double precision);

/// Harmonic coordinates of a closed, outward-oriented triangle cage. One column per cage vertex
/// (controlPointCount() = columnCount() = cage vertex count). Every method is const and
/// thread-safe; every row is bit-identical whether it comes from weights() or weightsBatch(),
/// for any number of threads, and the solve itself does not depend on the thread count.
class HarmonicCoordinates final : public Coordinates {
 public:
  /// Tetrahedralises, factorises and solves (progress stages "tetrahedralise", "factorise",
  /// "solve"; a callback returning false throws Cancelled). Throws InvalidInput if `cage` is
  /// null, an option is out of range, TetGen rejects the cage (e.g. a self-intersecting
  /// one, with TetGen's reason) or the job needs more memory than is available (see
  /// memoryEstimate()), SolverError if TetGen dies (some tet counts of some cages fail one of
  /// its assertions; another count may not) or the factorisation fails, and OutOfMemory (a
  /// SolverError) if TetGen or CHOLMOD run out of memory.
  explicit HarmonicCoordinates(std::shared_ptr<const Cage> cage,
                               const HarmonicOptions& options = {},
                               const ProgressCallback& progress = {});

  /// Coordinates solved earlier and saved by save(), for the same cage (checked: vertex and
  /// triangle counts and a hash of its vertices and triangles). The mesh options in `options`
  /// are ignored (the file's mesh is used); `outside` applies. Throws IoError naming the file if
  /// it cannot be read or is not a valid coordinate file (bad magic, unsupported version,
  /// truncated, trailing bytes, checksum mismatch, inconsistent content), and InvalidInput
  /// naming the file if it was solved for another cage.
  static std::shared_ptr<const HarmonicCoordinates> load(const std::filesystem::path& path,
                                                         std::shared_ptr<const Cage> cage,
                                                         const HarmonicOptions& options = {});

  ~HarmonicCoordinates() override;
  HarmonicCoordinates(const HarmonicCoordinates&) = delete;
  HarmonicCoordinates& operator=(const HarmonicCoordinates&) = delete;

  /// Writes the mesh and the solved values atomically (a failure leaves no partial file; throws
  /// IoError naming the file). The format, version 2, all little-endian:
  ///
  ///     offset  size  content
  ///     0       8     magic "SWHARMC\0"
  ///     8       4     u32 version (1)
  ///     12      4     u32 reserved (0)
  ///     16      8     u64 cage vertex count k
  ///     24      8     u64 cage triangle count
  ///     32      8     u64 cage hash (see cageHash())
  ///     40      8     u64 mesh vertex count n
  ///     48      8     u64 tet count m
  ///     56      8     f64 radius-edge bound the mesh was made with
  ///     64      8     f64 absolute tet volume bound the mesh was made with (world units³)
  ///     72      24n   mesh vertices in the cage's frame (TetMesh::localVertices), f64 x, y, z
  ///                   each
  ///     ...     16m   tets, 4 × u32 corners each
  ///     ...     4n    per mesh vertex: i32 cage triangle it lies on, or −1 (interior)
  ///     ...     8nk   the coordinate values, f64, row-major (n rows of k)
  ///     end−8   8     u64 checksum: FNV-1a (64-bit) of every byte before it
  ///
  /// Version 1 is the same with the mesh vertices in world units; load() reads both.
  void save(const std::filesystem::path& path) const;

  /// A hash (FNV-1a, 64-bit) of a cage's vertex coordinates (bit patterns) and triangle indices:
  /// what a saved file is checked against.
  static std::uint64_t cageHash(const Cage& cage);

  /// What a saved file's header says, without reading the rest (no checksum verification).
  struct FileInfo {
    std::uint32_t version = 0;
    std::uint64_t cageVertexCount = 0, cageTriangleCount = 0, cageHash = 0;
    std::uint64_t meshVertexCount = 0, tetCount = 0;
    double radiusEdgeRatio = 0.0, maxTetVolume = 0.0;  ///< maxTetVolume in world units³
  };
  /// Throws IoError naming the file if it cannot be read, is too short for a header, or has a
  /// bad magic or an unsupported version.
  static FileInfo readFileInfo(const std::filesystem::path& path);

  /// The peak memory (bytes) the constructor is expected to need for `cage` with `options`:
  /// TetGen, the mesh, the sparse Cholesky factor and the dense values (mesh vertices × cage
  /// vertices, three times during the solve), from the mesh size the volume bound implies. An
  /// upper bound within a small factor (measured: 1.7 to 2.3 times the peak RSS). The constructor
  /// throws InvalidInput when it exceeds the memory available (detail::checkMemory), before
  /// meshing, and checks the solve again once the mesh's size is known.
  static double memoryEstimate(const Cage& cage, const HarmonicOptions& options);

  /// The absolute tet volume bound (world units³) `options` gives for `cage`.
  static double tetVolumeBound(const Cage& cage, const HarmonicOptions& options);

  std::size_t controlPointCount() const override;
  std::span<const Vec3> restControlPoints() const override;

  /// The coordinates of x (world units) into `row` (cage vertex count entries). Throws
  /// InvalidInput if x is not finite, the row has the wrong size, or x is outside the cage and
  /// the policy is Throw ("1 point is outside the cage").
  void weights(const Vec3& x, std::span<double> row) const override;

  /// The gradients of the weights: constant per tet (the tet that contains x). Returns false
  /// for points outside the cage (callers then use finite differences).
  bool weightGradients(const Vec3& x, std::span<Vec3> out) const override;

  /// Where x is in the mesh: whether it is in a tet, which, and its barycentric coordinates
  /// there. Throws InvalidInput if x is not finite.
  TetLocator::Hit locate(const Vec3& x) const;

  const Cage& cage() const;
  const HarmonicOptions& options() const;
  /// The tetrahedralisation the coordinates were solved on.
  const TetMesh& mesh() const;
  /// The coordinate values at the mesh vertices: mesh().vertices.size() rows of
  /// controlPointCount(), row-major.
  std::span<const double> vertexValues() const;
  /// The absolute tet volume bound the mesh was made with (world units³).
  double meshVolumeBound() const;

  /// Archive (core/archive.h): tag "harmonic", the cage, the options and the solved field in
  /// the format of save(path) (mesh and vertex values, checksummed). load(ArchiveReader&)
  /// checks it as load(path) does and solves nothing.
  void save(ArchiveWriter& out) const override;
  static std::shared_ptr<const HarmonicCoordinates> load(ArchiveReader& in);

 protected:
  /// A HarmonicWarp: a 4-term mix of per-vertex displacements per point.
  std::shared_ptr<const Warp> makeWarpFor(std::shared_ptr<const Coordinates> self,
                                          std::span<const Vec3> posed) const override;
  /// Points outside the cage are reported under the policy Throw: weightsBatch() then throws
  /// InvalidInput with their number and the first one's index.
  std::size_t batchGrain() const override;
  UnmappedPoints weightsRange(std::span<const Vec3> points, std::span<double> rows,
                              std::size_t begin, std::size_t end) const override;
  [[noreturn]] void throwUnmapped(const UnmappedPoints& unmapped,
                                  std::span<const Vec3> points) const override;

 private:
  struct Impl;
  struct FromImpl {};
  HarmonicCoordinates(FromImpl, std::unique_ptr<Impl> impl);
  std::unique_ptr<const Impl> impl_;
};

}  // namespace spacewarp
