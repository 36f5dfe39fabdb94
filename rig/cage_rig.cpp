#include <spacewarp/rig/cage_rig.h>

#include <unistd.h>

#include <cmath>
#include <functional>
#include <map>

#include <tbb/global_control.h>

#include <spacewarp/coords/green.h>
#ifdef SPACEWARP_HAVE_HARMONIC
#include <spacewarp/coords/harmonic.h>
#endif
#include <spacewarp/coords/mean_value.h>
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

#ifdef SPACEWARP_HAVE_HARMONIC
HarmonicOptions harmonicOptions(const CageMethodOptions& options) {
  HarmonicOptions harmonic;
  if (options.harmonicTets > 0 && options.harmonicPrecision != 0)
    throw InvalidInput("give the harmonic tet count (tets) or the precision, not both");
  if (options.harmonicTets > 0) harmonic.targetTetCount = options.harmonicTets;
  if (options.harmonicPrecision != 0)
    harmonic.targetTetCount = harmonicPrecisionTets(options.harmonicPrecision);
  if (options.harmonicOutside == "nearest") {
    harmonic.outside = HarmonicOutsidePolicy::NearestPoint;
  } else if (options.harmonicOutside != "raise") {
    throw InvalidInput("--outside must be 'raise' or 'nearest', not '" + options.harmonicOutside +
                       "'");
  }
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

struct Factory {
  std::function<std::shared_ptr<const Coordinates>(
      std::shared_ptr<const Cage>, const CageMethodOptions&, const ProgressCallback&)>
      make;
  std::function<double(const Cage&, const CageMethodOptions&)> memory;
};

const std::map<std::string, Factory>& factories() {
  static const std::map<std::string, Factory> table = {
      {"mvc",
       {[](auto cage, auto&, auto&) { return std::make_shared<MeanValueCoordinates>(cage); },
        [](const Cage& cage, auto&) { return cageKernelMemory(cage); }}},
      {"green",
       {[](auto cage, auto&, auto&) { return std::make_shared<GreenCoordinates>(cage); },
        [](const Cage& cage, auto&) { return cageKernelMemory(cage); }}},
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
    Cage::fromFile(cage).posedVerticesFromFile(pose);
    return {};
  }
  return cageRig(method, cage, pose, options);
}

}  // namespace

Rig cageRig(RigReader& reader, const std::string& method) {
  const std::filesystem::path cage = reader.path("cage"), pose = reader.path("pose");
  return cageRigOf(reader, method, cage, pose, {});
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
  if (reader.has("outside")) {
    options.harmonicOutside = reader.string("outside");
    if (options.harmonicOutside != "raise" && options.harmonicOutside != "nearest")
      reader.fail("outside", "must be \"raise\" or \"nearest\"");
  }
  return cageRigOf(reader, "harmonic", cage, pose, options);
#else
  reader.fail("method",
              "'harmonic' is not available: spacewarp was built without TetGen "
              "(SPACEWARP_WITH_TETGEN=OFF)");
#endif
}

}  // namespace detail

}  // namespace spacewarp
