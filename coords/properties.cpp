#include <spacewarp/coords/properties.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <random>
#include <string>
#include <vector>

#include <glm/gtc/matrix_transform.hpp>

#include <spacewarp/core/errors.h>
#include <spacewarp/core/progress.h>

namespace spacewarp {

namespace {

// Weight rows are formed a block of about this many bytes at a time (at least kMinBlockRows
// rows, so that weightsBatch has work for every core): the kit's memory then does not grow with
// the number of points times the columns. (A 10,370-vertex cage's Green coordinates have 31,106
// columns; its 83,000 face samples took 20 GB as one array.) Every figure is a maximum or a
// count over the rows, so the blocks do not change the report.
constexpr std::size_t kBlockBytes = std::size_t{32} << 20;
constexpr std::size_t kMinBlockRows = 256;

std::size_t blockRows(std::size_t columns) {
  return std::max(kMinBlockRows,
                  kBlockBytes / (sizeof(double) * std::max<std::size_t>(columns, 1)));
}

// Calls visit(i, row) for the weight row (columnCount() entries) of every point i, in order.
template <typename Visit>
void forEachWeightRow(const Coordinates& c, std::span<const Vec3> points, Visit&& visit) {
  const std::size_t m = c.columnCount();
  const std::size_t block = blockRows(m);
  std::vector<double> rows(std::min(block, points.size()) * m);
  const ProgressCallback none;  // the kit reports no progress
  ProgressTracker untracked(none, "properties", points.size());
  forEachBlock(points.size(), block, untracked, [&](std::size_t begin, std::size_t count) {
    const std::span<double> part(rows.data(), count * m);
    c.weightsBatch(points.subspan(begin, count), part);
    for (std::size_t i = 0; i < count; ++i) visit(begin + i, part.data() + i * m);
  });
}

// The sample-based checks, shared by both overloads. `center` is the fixed point of the
// similarity; `controls` the rest control points.
PropertyReport measureSamples(const Coordinates& coordinates, std::span<const Vec3> controls,
                              std::span<const Vec3> samples, double diagonal,
                              const PropertyOptions& options) {
  const std::size_t nv = coordinates.controlPointCount();
  const std::size_t m = coordinates.columnCount();
  if (samples.empty()) throw InvalidInput("measureProperties: no sample points");
  if (!(diagonal > 0.0) || !std::isfinite(diagonal))
    throw InvalidInput("measureProperties: the diagonal must be finite and positive");

  std::vector<Vec3> restColumns(m);
  coordinates.columnControls(controls, restColumns);

  // Every sum below is taken relative to the center of the controls: in absolute coordinates
  // far from the origin (a cage at 1e8) the measurement's own round-off would swamp the
  // coordinates' errors. The vertex columns are positions (shifted), any others (Green's face
  // normals) directions.
  const BoundingBox box = boundingBox(controls);
  const Vec3 center = 0.5 * (box.min + box.max);
  const Mat3 linear = Mat3(glm::rotate(Mat4(1.0), options.similarityAngle,
                                       glm::normalize(options.similarityAxis))) *
                      options.similarityScale;
  const Vec3 translation = options.similarityTranslation * diagonal;
  // S(x) − x, the similarity's displacement (about the center).
  auto similarityDisplacement = [&](const Vec3& x) {
    const Vec3 d = x - center;
    return translation + linear * d - d;
  };
  std::vector<Vec3> posed(nv), displacement(m);
  for (std::size_t i = 0; i < nv; ++i) posed[i] = controls[i] + similarityDisplacement(controls[i]);
  coordinates.columnControls(posed, displacement);
  for (std::size_t c = 0; c < m; ++c) displacement[c] -= restColumns[c];

  PropertyReport report;
  report.sampleCount = samples.size();
  report.minWeight = std::numeric_limits<double>::infinity();
  std::size_t negative = 0, samplesNegative = 0;
  forEachWeightRow(coordinates, samples, [&](std::size_t s, const double* w) {
    double sum = 0.0;
    bool anyNegative = false;
    for (std::size_t i = 0; i < nv; ++i) {
      sum += w[i];
      report.minWeight = std::min(report.minWeight, w[i]);
      if (w[i] < 0.0) {
        ++negative;
        anyNegative = true;
      }
    }
    samplesNegative += anyNegative;
    Vec3 reproduced(0.0), moved(0.0);
    for (std::size_t c = 0; c < m; ++c) {
      reproduced += w[c] * (c < nv ? restColumns[c] - center : restColumns[c]);
      moved += w[c] * displacement[c];
    }
    report.partitionOfUnity = std::max(report.partitionOfUnity, std::abs(sum - 1.0));
    report.linearReproduction = std::max(
        report.linearReproduction, glm::length(reproduced - (samples[s] - center)) / diagonal);
    report.similarityReproduction =
        std::max(report.similarityReproduction,
                 glm::length(moved - similarityDisplacement(samples[s])) / diagonal);
  });
  report.negativeFraction =
      static_cast<double>(negative) / static_cast<double>(samples.size() * nv);
  report.samplesWithNegative =
      static_cast<double>(samplesNegative) / static_cast<double>(samples.size());
  report.lagrange = std::numeric_limits<double>::quiet_NaN();
  report.faceInterpolation = std::numeric_limits<double>::quiet_NaN();
  return report;
}

}  // namespace

PropertyReport measureProperties(const Coordinates& coordinates, std::span<const Vec3> samples,
                                 double diagonal, const PropertyOptions& options) {
  return measureSamples(coordinates, coordinates.restControlPoints(), samples, diagonal, options);
}

PropertyReport measureProperties(const Coordinates& coordinates, const Cage& cage,
                                 std::span<const Vec3> samples, const PropertyOptions& options) {
  const std::size_t nv = coordinates.controlPointCount();
  if (nv != cage.vertexCount()) {
    throw InvalidInput("measureProperties: the coordinates have " + std::to_string(nv) +
                       " control points but the cage has " + std::to_string(cage.vertexCount()) +
                       " vertices");
  }
  PropertyReport report =
      measureSamples(coordinates, cage.vertices(), samples, cage.diagonal(), options);
  report.lagrange = 0.0;
  report.faceInterpolation = 0.0;

  // Lagrange property: w_i(v_j) = δ_ij.
  forEachWeightRow(coordinates, cage.vertices(), [&](std::size_t j, const double* w) {
    for (std::size_t i = 0; i < nv; ++i)
      report.lagrange = std::max(report.lagrange, std::abs(w[i] - (i == j ? 1.0 : 0.0)));
  });

  // Interpolation on faces: at random barycentric points of every triangle of the cage.
  std::mt19937_64 rng(options.seed);
  auto unit = [&] { return static_cast<double>(rng() >> 11) * 0x1.0p-53; };
  std::vector<Vec3> onFaces;
  std::vector<Vec3> barycentric;
  for (const Triangle& t : cage.triangles()) {
    for (std::size_t k = 0; k < options.faceSamplesPerTriangle; ++k) {
      double a = unit(), b = unit();
      if (a + b > 1.0) a = 1.0 - a, b = 1.0 - b;
      const Vec3 bc(1.0 - a - b, a, b);
      barycentric.push_back(bc);
      // Relative to corner x, so that the point is on the face up to the round-off of the
      // cage's size, not of its distance from the origin.
      const Vec3 p = cage.vertices()[t.x];
      onFaces.push_back(p + bc.y * (cage.vertices()[t.y] - p) + bc.z * (cage.vertices()[t.z] - p));
    }
  }
  std::vector<double> expected(nv);
  std::vector<char> onFace(nv);
  forEachWeightRow(coordinates, onFaces, [&](std::size_t f, const double* w) {
    const std::size_t t = f / options.faceSamplesPerTriangle;
    const Triangle& tri = cage.triangles()[t];
    const auto face = cage.face(cage.triangleSource()[t]);
    double error = 0.0;
    if (face.size() == 3) {  // a triangle's interpolant is linear: the barycentric row
      std::fill(expected.begin(), expected.end(), 0.0);
      expected[tri.x] += barycentric[f].x;
      expected[tri.y] += barycentric[f].y;
      expected[tri.z] += barycentric[f].z;
      for (std::size_t i = 0; i < nv; ++i) error = std::max(error, std::abs(w[i] - expected[i]));
    } else {
      // A polygon's interpolant depends on the method (bilinear, 2D Wachspress or mean value):
      // what they share is a row supported on the face's vertices that reproduces the point.
      std::fill(onFace.begin(), onFace.end(), 0);
      for (std::uint32_t v : face) onFace[v] = 1;
      const Vec3 origin = cage.vertices()[tri.x];
      double sum = 0.0;
      Vec3 reproduced(0.0);
      for (std::size_t i = 0; i < nv; ++i) {
        if (!onFace[i]) {
          error = std::max(error, std::abs(w[i]));
          continue;
        }
        sum += w[i];
        reproduced += w[i] * (cage.vertices()[i] - origin);
      }
      error = std::max({error, std::abs(sum - 1.0),
                        glm::length(reproduced - (onFaces[f] - origin)) / cage.diagonal()});
    }
    report.faceInterpolation = std::max(report.faceInterpolation, error);
  });
  return report;
}

double measurePropertiesMemory(std::size_t columns, std::size_t cageTriangles,
                               const PropertyOptions& options) {
  const double m = static_cast<double>(columns);
  const double faceSamples =
      static_cast<double>(cageTriangles) * static_cast<double>(options.faceSamplesPerTriangle);
  return sizeof(double) * m * static_cast<double>(blockRows(columns)) +  // a block of rows
         3.0 * sizeof(Vec3) * m +            // rest columns, displacements, posed
         2.0 * sizeof(Vec3) * faceSamples +  // face points and their barycentrics
         (sizeof(double) + 1.0) * m;         // a face sample's expected row, on-face flags
}

std::vector<Vec3> interiorSamples(const Cage& cage, std::size_t count, std::uint64_t seed) {
  const BoundingBox box = boundingBox(cage.vertices());
  std::mt19937_64 rng(seed);
  auto unit = [&] { return static_cast<double>(rng() >> 11) * 0x1.0p-53; };
  std::vector<Vec3> samples;
  samples.reserve(count);
  // Cages fill a reasonable part of their box; the bound only stops a degenerate loop.
  const std::size_t maxTries = 1000 * count + 1000;
  for (std::size_t tries = 0; samples.size() < count; ++tries) {
    if (tries == maxTries)
      throw InvalidInput("interiorSamples: found no interior points; is the cage flat?");
    const Vec3 x = box.min + Vec3(unit(), unit(), unit()) * (box.max - box.min);
    if (cage.contains(x)) samples.push_back(x);
  }
  return samples;
}

}  // namespace spacewarp
