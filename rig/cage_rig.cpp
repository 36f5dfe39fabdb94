#include <spacewarp/rig/cage_rig.h>

#include <unistd.h>

#include <cmath>
#include <functional>
#include <map>

#include <tbb/global_control.h>

#include <spacewarp/coords/convex_cage.h>
#include <spacewarp/coords/detail/quad_fold.h>
#include <spacewarp/coords/discrete_harmonic.h>
#include <spacewarp/coords/green.h>
#ifdef SPACEWARP_HAVE_HARMONIC
#include <spacewarp/coords/harmonic.h>
#endif
#include <spacewarp/coords/mean_value.h>
#include <spacewarp/coords/quad_green.h>
#include <spacewarp/coords/quad_mean_value.h>
#include <spacewarp/coords/wachspress.h>
#include <spacewarp/core/errors.h>
#include <spacewarp/rig/detail/harmonic_rig.h>

namespace spacewarp {

namespace {

// The precomputation and per-thread scratch of mean-value and Green coordinates, measured on a
// 10,370-vertex, 20,736-triangle cage: 0.3 MB and 4.3 MB of precomputation, and 5.7 MB and
// 8 MB of scratch per worker thread (one weight row and the per-vertex, -edge and -face
// terms), plus what the threads themselves touch. Rounded up per cage vertex and triangle:
// `spacewarp compare` of that cage (2 threads) peaked 104 MB (mvc) and 143 MB (green) above
// the process's 40 MB at start, where its whole estimate (with this) is 158 and 190 MB.
double cageKernelMemory(const Cage& cage) {
  const double elements = static_cast<double>(cage.vertexCount() + cage.triangleCount());
  const auto threads = static_cast<double>(
      tbb::global_control::active_value(tbb::global_control::max_allowed_parallelism));
  return 200.0 * elements + 1024.0 * elements * threads;
}

// The --outside / "outside" option, for the methods that have the choice: nearest or not.
bool outsideNearest(const CageMethodOptions& options) {
  if (options.outside != "raise" && options.outside != "nearest")
    throw InvalidInput("--outside must be 'raise' or 'nearest', not '" + options.outside + "'");
  return options.outside == "nearest";
}

// Wachspress and discrete harmonic coordinates, whose options share the outside policy.
template <class Coords, class Options>
std::shared_ptr<const Coordinates> convexCoordinates(std::shared_ptr<const Cage> cage,
                                                     const CageMethodOptions& options,
                                                     const ProgressCallback&) {
  Options own;
  own.outside =
      outsideNearest(options) ? ConvexOutsidePolicy::NearestPoint : ConvexOutsidePolicy::Throw;
  return std::make_shared<Coords>(std::move(cage), own);
}

// Columns of the coordinates whose only controls are the cage vertices.
std::size_t vertexColumns(const Cage& cage) { return cage.vertexCount(); }

// QuadGreenCoordinates' columns: the vertices, one normal per triangle face, four per quad face.
std::size_t quadGreenColumns(const Cage& cage) {
  std::size_t columns = cage.vertexCount();
  for (std::size_t f = 0; f < cage.faceCount(); ++f) columns += cage.face(f).size() == 3 ? 1 : 4;
  return columns;
}

// Refuses the faces QuadGreenCoordinates cannot take (more than four vertices), naming the first.
void checkTriQuadFaces(const Cage& cage) {
  for (std::size_t f = 0; f < cage.faceCount(); ++f)
    if (cage.face(f).size() > 4)
      throw InvalidInput(cage.name() + ": qgc takes triangle and quad faces only, but face " +
                         std::to_string(f) + " has " + std::to_string(cage.face(f).size()) +
                         " vertices");
}

// Refuses a quad whose bilinear patch folds over (coords/detail/quad_fold.h), as qmvc's and qgc's
// constructors do, but named by the method's CLI name and before any work.
void checkQuadsUnfolded(const Cage& cage, const char* method) {
  for (std::size_t f = 0; f < cage.faceCount(); ++f)
    if (cage.face(f).size() == 4)
      detail::checkQuadUnfolded(cage.vertices(), cage.face(f), f, method, cage.name());
}

#ifdef SPACEWARP_HAVE_HARMONIC
HarmonicOptions harmonicOptions(const CageMethodOptions& options) {
  HarmonicOptions harmonic;
  if (options.harmonicTets > 0 && options.harmonicPrecision != 0)
    throw InvalidInput("give the harmonic tet count (tets) or the precision, not both");
  if (options.harmonicTets > 0) harmonic.targetTetCount = options.harmonicTets;
  if (options.harmonicPrecision != 0)
    harmonic.targetTetCount = harmonicPrecisionTets(options.harmonicPrecision);
  if (outsideNearest(options)) harmonic.outside = HarmonicOutsidePolicy::NearestPoint;
  return harmonic;
}

// Refuses, before a solve that the cache would then lose, a cache path that is a folder or whose
// folder is missing or not writable.
void checkCacheBeforeTheSolve(const std::filesystem::path& cache) {
  if (cache.empty()) return;
  std::error_code error;
  if (std::filesystem::is_directory(cache, error))
    throw IoError(cache.string() + ": is a folder, not a harmonic coordinate file");
  if (std::filesystem::exists(cache, error)) return;  // read (or refused) as it is
  const std::filesystem::path folder = cache.has_parent_path() ? cache.parent_path() : ".";
  if (!std::filesystem::is_directory(folder, error) || ::access(folder.c_str(), W_OK | X_OK) != 0)
    throw IoError(cache.string() + ": cannot be written (its folder is missing or not writable); " +
                  "checked before the solve, which it would keep");
}

// Harmonic coordinates, through the cache file when one is given.
std::shared_ptr<const Coordinates> harmonicCoordinates(std::shared_ptr<const Cage> cage,
                                                       const CageMethodOptions& options,
                                                       const ProgressCallback& progress) {
  const HarmonicOptions harmonic = harmonicOptions(options);
  const std::filesystem::path& cache = options.harmonicCache;
  checkCacheBeforeTheSolve(cache);
  if (!cache.empty() && std::filesystem::exists(cache)) {
    // Not a coordinate file at all: an error (IoError), never overwritten.
    const HarmonicCoordinates::FileInfo info = HarmonicCoordinates::readFileInfo(cache);
    if (info.cageHash == HarmonicCoordinates::cageHash(*cage) &&
        info.cageVertexCount == cage->vertexCount() &&
        info.cageTriangleCount == cage->triangleCount() &&
        info.maxTetVolume == HarmonicCoordinates::tetVolumeBound(*cage, harmonic) &&
        info.radiusEdgeRatio == harmonic.radiusEdgeRatio) {
      return HarmonicCoordinates::load(cache, cage, harmonic);
    }
  }
  auto coordinates = std::make_shared<const HarmonicCoordinates>(cage, harmonic, progress);
  if (!cache.empty()) coordinates->save(cache);
  return coordinates;
}
#endif

// A method: how to make its coordinates, their peak memory (cageCoordinatesMemory()), their
// column count before they are made, and which cages it refuses (nothing: any cage).
struct Factory {
  std::function<std::shared_ptr<const Coordinates>(
      std::shared_ptr<const Cage>, const CageMethodOptions&, const ProgressCallback&)>
      make;
  std::function<double(const Cage&, const CageMethodOptions&)> memory;
  std::function<std::size_t(const Cage&)> columns = vertexColumns;
  std::function<void(const Cage&)> check = [](const Cage&) {};
};

// A closed-form method without options.
template <class Coords>
std::shared_ptr<const Coordinates> plainCoordinates(std::shared_ptr<const Cage> cage,
                                                    const CageMethodOptions&,
                                                    const ProgressCallback&) {
  return std::make_shared<Coords>(std::move(cage));
}

// Taken to be cageKernelMemory() for every closed-form method: the polygon and convex methods
// precompute per vertex and face as mvc and green do (not yet measured separately).
double closedFormMemory(const Cage& cage, const CageMethodOptions&) {
  return cageKernelMemory(cage);
}

const std::map<std::string, Factory>& factories() {
  // The convex-cage checks, named in their messages: wachspress takes any convex cage,
  // discrete-harmonic only simplicial ones (its constructor's own refusal, made beforehand).
  const auto convex = [](const char* name) {
    return [name](const Cage& cage) { checkConvexCage(cage, name); };
  };
  const auto simplicial = [](const char* name) {
    return [name](const Cage& cage) { checkSimplicialConvexCage(cage, name); };
  };
  static const std::map<std::string, Factory> table = {
      {"mvc", {plainCoordinates<MeanValueCoordinates>, closedFormMemory}},
      {"green",
       {plainCoordinates<GreenCoordinates>, closedFormMemory,
        [](const Cage& cage) { return cage.vertexCount() + cage.triangleCount(); }}},
      {"qmvc",
       {plainCoordinates<QuadMeanValueCoordinates>, closedFormMemory, vertexColumns,
        [](const Cage& cage) { checkQuadsUnfolded(cage, "qmvc"); }}},
      {"qgc",
       {plainCoordinates<QuadGreenCoordinates>, closedFormMemory, quadGreenColumns,
        [](const Cage& cage) {
          checkTriQuadFaces(cage);
          checkQuadsUnfolded(cage, "qgc");
        }}},
      {"wachspress",
       {convexCoordinates<WachspressCoordinates, WachspressOptions>, closedFormMemory,
        vertexColumns, convex("wachspress")}},
      {"discrete-harmonic",
       {convexCoordinates<DiscreteHarmonicCoordinates, DiscreteHarmonicOptions>, closedFormMemory,
        vertexColumns, simplicial("discrete-harmonic")}},
#ifdef SPACEWARP_HAVE_HARMONIC
      {"harmonic",
       {harmonicCoordinates,
        [](const Cage& cage, const CageMethodOptions& options) {
          return HarmonicCoordinates::memoryEstimate(cage, harmonicOptions(options));
        }}},
#endif
  };
  return table;
}

const Factory& factory(const std::string& method) {
  const auto it = factories().find(method);
  if (it == factories().end()) {
    std::string known;
    for (const std::string& m : cageMethods()) known += (known.empty() ? "" : ", ") + m;
    throw InvalidInput("unknown cage method '" + method + "' (one of: " + known + ")");
  }
  return it->second;
}

}  // namespace

std::vector<std::string> cageMethods() {
  std::vector<std::string> names;
  for (const auto& [name, factory] : factories()) names.push_back(name);
  return names;
}

std::shared_ptr<const Coordinates> cageCoordinates(const std::string& method,
                                                   std::shared_ptr<const Cage> cage,
                                                   const CageMethodOptions& options,
                                                   const ProgressCallback& progress) {
  return factory(method).make(std::move(cage), options, progress);
}

void checkCageMethodApplies(const std::string& method, const Cage& cage) {
  factory(method).check(cage);
}

std::size_t cageCoordinatesColumns(const std::string& method, const Cage& cage) {
  return factory(method).columns(cage);
}

double cageCoordinatesMemory(const std::string& method, const Cage& cage,
                             const CageMethodOptions& options) {
  return factory(method).memory(cage, options);
}

Rig cageRig(const std::string& method, const std::filesystem::path& cage,
            const std::filesystem::path& pose, const CageMethodOptions& options,
            const ProgressCallback& progress) {
  auto rest = std::make_shared<const Cage>(Cage::fromFile(cage));
  const std::vector<Vec3> posed = rest->posedVerticesFromFile(pose);
  // The coordinates' own checks (TetGen's self-intersection, a solver's failure) do not know
  // the cage's file.
  auto coordinates =
      namingFile(cage.string(), [&] { return cageCoordinates(method, rest, options, progress); });
  return {makeWarp(coordinates, posed), coordinates};
}

namespace detail {

namespace {

// A cage rig read from `reader`; when checking, the cage and the pose are read and checked
// (a closed cage, a pose of as many vertices) but no coordinates are solved.
Rig cageRigOf(const RigReader& reader, const std::string& method, const std::filesystem::path& cage,
              const std::filesystem::path& pose, const CageMethodOptions& options) {
  if (reader.checking()) {
    const Cage rest = Cage::fromFile(cage);
    rest.posedVerticesFromFile(pose);
    namingFile(cage.string(), [&] { checkCageMethodApplies(method, rest); });
    return {};
  }
  return cageRig(method, cage, pose, options);
}

// The "outside" key, where the method's key list allows it.
void readOutside(RigReader& reader, CageMethodOptions& options) {
  if (!reader.has("outside")) return;
  options.outside = reader.string("outside");
  if (options.outside != "raise" && options.outside != "nearest")
    reader.fail("outside", "must be \"raise\" or \"nearest\"");
}

}  // namespace

Rig cageRig(RigReader& reader, const std::string& method) {
  const std::filesystem::path cage = reader.path("cage"), pose = reader.path("pose");
  CageMethodOptions options;
  readOutside(reader, options);
  return cageRigOf(reader, method, cage, pose, options);
}

Rig harmonicRig(RigReader& reader) {
#ifdef SPACEWARP_HAVE_HARMONIC
  const std::filesystem::path cage = reader.path("cage"), pose = reader.path("pose");
  CageMethodOptions options;
  if (reader.has("tets")) {
    const double tets = reader.number("tets");
    if (!(tets >= 1.0 && tets <= 1e9 && tets == std::floor(tets)))
      reader.fail("tets", "must be a whole number in [1, 1e9]");
    options.harmonicTets = static_cast<std::size_t>(tets);
  }
  if (reader.has("precision")) {
    if (reader.has("tets"))
      reader.fail("precision", "cannot be given with \"tets\" (give one of them)");
    const double precision = reader.number("precision");
    if (!(precision >= kHarmonicMinPrecision && precision <= kHarmonicMaxPrecision))
      reader.fail("precision", "must be a number in [" + std::to_string(kHarmonicMinPrecision) +
                                   ", " + std::to_string(kHarmonicMaxPrecision) + "]");
    options.harmonicPrecision = precision;
  }
  if (reader.has("cache")) options.harmonicCache = reader.path("cache");
  readOutside(reader, options);
  return cageRigOf(reader, "harmonic", cage, pose, options);
#else
  reader.fail("method",
              "'harmonic' is not available: spacewarp was built without TetGen "
              "(SPACEWARP_WITH_TETGEN=OFF)");
#endif
}

}  // namespace detail

}  // namespace spacewarp
