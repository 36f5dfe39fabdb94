#include "apps/compare.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <functional>
#include <limits>
#include <map>
#include <new>
#include <set>
#include <sstream>

#include <tbb/parallel_for.h>

#include <spacewarp/coords/cage.h>
#include <spacewarp/coords/properties.h>
#include <spacewarp/core/detail/memory_budget.h>
#include <spacewarp/core/errors.h>
#include <spacewarp/core/io/atomic_file.h>
#include <spacewarp/core/progress.h>
#include <spacewarp/ffd/lattice.h>
#include <spacewarp/ffd/lattice_coordinates.h>
#include <spacewarp/rbf/rbf_coordinates.h>
#include "apps/heat_map.h"
#include "apps/jobs.h"

namespace spacewarp::cli {

namespace {

namespace fs = std::filesystem;
using nlohmann::json;
using Clock = std::chrono::steady_clock;

// A method of the comparison: how to build its coordinates for a cage, and whether its
// controls are the cage's vertices (then the whole property kit applies and control I is
// vertex I; otherwise control I is the control point nearest to vertex I).
struct Method {
  std::string description;
  std::function<std::shared_ptr<const Coordinates>(
      std::shared_ptr<const Cage>, const CageMethodOptions&, const ProgressCallback&)>
      make;
  bool cageControls = true;
  // The coordinates' own peak memory (bytes; precomputation and per-thread scratch) and their
  // column count, known before they are made.
  std::function<double(const Cage&, const CageMethodOptions&)> memory;
  std::function<std::size_t(const Cage&)> columns;
  // Throws InvalidInput, saying why, if the method cannot take the cage (a non-convex cage for
  // wachspress); by default it takes any.
  std::function<void(const Cage&)> applies = [](const Cage&) {};
};

// The lattice of the "ffd" method.
constexpr int kFfdResolution = 4;
// Weights of the slice's pixels are formed this many values (32 MB) at a time, and at least one
// row.
constexpr std::size_t kBindBlockValues = std::size_t{1} << 22;

std::map<std::string, Method> methodTable() {
  std::map<std::string, Method> table;
  for (const std::string& name : cageMethods()) {
    Method& method = table[name];
    method.description = name + " cage coordinates";
    method.make = [name](auto cage, const auto& options, const auto& progress) {
      return cageCoordinates(name, cage, options, progress);
    };
    method.memory = [name](const Cage& cage, const CageMethodOptions& options) {
      return cageCoordinatesMemory(name, cage, options);
    };
    method.columns = [name](const Cage& cage) { return cageCoordinatesColumns(name, cage); };
    method.applies = [name](const Cage& cage) { checkCageMethodApplies(name, cage); };
  }
  Method& rbf = table["rbf"];
  rbf.description = "triharmonic RBF coordinates, one handle per cage vertex";
  rbf.make = [](auto cage, const auto&, const auto&) {
    return std::make_shared<RbfCoordinates>(cage->vertices());
  };
  rbf.memory = [](const Cage& cage, const CageMethodOptions&) {
    return RbfCoordinates::memoryEstimate(cage.vertexCount());
  };
  rbf.columns = [](const Cage& cage) { return cage.vertexCount(); };
  Method& ffd = table["ffd"];
  ffd.description = "Bernstein FFD lattice (4 x 4 x 4) around the cage, padded by 5%";
  ffd.make = [](auto cage, const auto&, const auto&) {
    const BoundingBox box = boundingBox(cage->vertices());
    const Vec3 pad(0.05 * cage->diagonal());
    LatticeOptions params;
    params.origin = box.min - pad;
    params.extents = box.max - box.min + 2.0 * pad;
    params.resolution = {kFfdResolution, kFfdResolution, kFfdResolution};
    params.basis = LatticeBasis::Bernstein;
    return std::make_shared<LatticeCoordinates>(Lattice(params));
  };
  ffd.cageControls = false;
  ffd.memory = [](const Cage&, const CageMethodOptions&) { return 1e6; };  // 64 control points
  ffd.columns = [](const Cage&) -> std::size_t {
    return kFfdResolution * kFfdResolution * kFfdResolution;
  };
  return table;
}

// The slice plane's frame and the rectangle of the cage's projection onto it.
struct Slice {
  Vec3 origin, normal, u, v;
  double uMin = 0, uMax = 0, vMin = 0, vMax = 0;
  int width = 0, height = 0;

  Vec3 pixelCenter(int i, int j) const {
    const double a = uMin + (uMax - uMin) * (i + 0.5) / width;
    const double b = vMax - (vMax - vMin) * (j + 0.5) / height;  // row 0 at the top
    return origin + a * u + b * v;
  }
  // Fractional pixel coordinates of a point of the plane.
  std::pair<double, double> toPixel(const Vec3& p) const {
    const Vec3 d = p - origin;
    return {(glm::dot(d, u) - uMin) / (uMax - uMin) * width - 0.5,
            (vMax - glm::dot(d, v)) / (vMax - vMin) * height - 0.5};
  }
};

// The cage's cross-section with the plane, as segments.
std::vector<std::pair<Vec3, Vec3>> crossSection(const Cage& cage, const Slice& s) {
  std::vector<std::pair<Vec3, Vec3>> segments;
  for (const Triangle& t : cage.triangles()) {
    const Vec3 p[3] = {cage.vertices()[t.x], cage.vertices()[t.y], cage.vertices()[t.z]};
    double d[3];
    for (int k = 0; k < 3; ++k) d[k] = glm::dot(p[k] - s.origin, s.normal);
    std::vector<Vec3> hits;
    for (int k = 0; k < 3; ++k) {
      const int l = (k + 1) % 3;
      if (d[k] == 0.0) hits.push_back(p[k]);
      if ((d[k] < 0.0 && d[l] > 0.0) || (d[k] > 0.0 && d[l] < 0.0))
        hits.push_back(p[k] + (p[l] - p[k]) * (d[k] / (d[k] - d[l])));
    }
    if (hits.size() >= 2) segments.emplace_back(hits[0], hits[1]);
  }
  return segments;
}

Slice makeSlice(const Cage& cage, const Vec3& point, const Vec3& normal, int resolution) {
  Slice s;
  s.origin = point;
  s.normal = glm::normalize(normal);
  // In-plane axes: for axis-aligned planes the two other world axes in order (x-y, x-z, y-z),
  // so images read like the usual views; otherwise any orthonormal pair.
  const Vec3 n = s.normal;
  const Vec3 helper = std::abs(n.x) > 0.9 ? Vec3(0, 1, 0) : Vec3(1, 0, 0);
  s.u = glm::normalize(helper - glm::dot(helper, n) * n);
  s.v = glm::cross(n, s.u);
  if (std::abs(n.z) > 1.0 - 1e-12) s.u = Vec3(1, 0, 0), s.v = Vec3(0, 1, 0);
  if (std::abs(n.y) > 1.0 - 1e-12) s.u = Vec3(1, 0, 0), s.v = Vec3(0, 0, 1);
  if (std::abs(n.x) > 1.0 - 1e-12) s.u = Vec3(0, 1, 0), s.v = Vec3(0, 0, 1);
  s.uMin = s.vMin = std::numeric_limits<double>::infinity();
  s.uMax = s.vMax = -std::numeric_limits<double>::infinity();
  // Frame the cross-section (the whole cage's shadow when the plane misses it).
  std::vector<Vec3> framed;
  for (const auto& [a, b] : crossSection(cage, s)) framed.push_back(a), framed.push_back(b);
  if (framed.empty()) framed.assign(cage.vertices().begin(), cage.vertices().end());
  for (const Vec3& p : framed) {
    const double a = glm::dot(p - point, s.u), b = glm::dot(p - point, s.v);
    s.uMin = std::min(s.uMin, a), s.uMax = std::max(s.uMax, a);
    s.vMin = std::min(s.vMin, b), s.vMax = std::max(s.vMax, b);
  }
  const double pad = 0.04 * std::max(s.uMax - s.uMin, s.vMax - s.vMin);
  s.uMin -= pad, s.uMax += pad, s.vMin -= pad, s.vMax += pad;
  const double aspect = (s.uMax - s.uMin) / (s.vMax - s.vMin);
  s.width =
      aspect >= 1.0 ? resolution : std::max(1, static_cast<int>(std::lround(resolution * aspect)));
  s.height =
      aspect >= 1.0 ? std::max(1, static_cast<int>(std::lround(resolution / aspect))) : resolution;
  return s;
}

// The kind of a method's failure, for the report.
std::string errorType(const std::exception& e) {
  if (dynamic_cast<const OutOfMemory*>(&e)) return "OutOfMemory";  // a SolverError
  if (dynamic_cast<const InvalidInput*>(&e)) return "InvalidInput";
  if (dynamic_cast<const SolverError*>(&e)) return "SolverError";
  if (dynamic_cast<const IoError*>(&e)) return "IoError";
  if (dynamic_cast<const std::bad_alloc*>(&e)) return "OutOfMemory";
  return "Error";
}

json vec(const Vec3& v) { return json::array({v.x, v.y, v.z}); }

json propertiesJson(const PropertyReport& r) {
  return {{"sampleCount", r.sampleCount},
          {"partitionOfUnity", r.partitionOfUnity},
          {"linearReproduction", r.linearReproduction},
          {"similarityReproduction", r.similarityReproduction},
          {"minWeight", r.minWeight},
          {"negativeFraction", r.negativeFraction},
          {"samplesWithNegative", r.samplesWithNegative},
          {"lagrange", r.lagrange},
          {"faceInterpolation", r.faceInterpolation}};
}

std::string number(const json& j) {
  if (j.is_null() || std::isnan(j.get<double>())) return "n/a";
  std::ostringstream s;
  s.precision(3);
  s << j.get<double>();
  return s.str();
}

std::string markdown(const json& report) {
  std::ostringstream md;
  md << "# Coordinate comparison\n\n"
     << "Cage `" << report["cage"].get<std::string>() << "` (" << report["cageVertices"]
     << " vertices, " << report["cageTriangles"] << " triangles, diagonal "
     << number(report["diagonal"]) << "). Coordinate function of cage vertex " << report["control"]
     << " on the plane through " << report["slice"]["point"].dump() << " with normal "
     << report["slice"]["normal"].dump() << ".\n\n"
     << "![side by side](compare.png)\n\n";
  if (!report["failedMethods"].empty()) {
    md << "**" << report["failedMethods"].size() << " of " << report["methods"].size()
       << " methods failed** (grey panels; reasons below):";
    for (const json& name : report["failedMethods"]) md << " " << name.get<std::string>();
    md << ".\n\n";
  }
  md << "Left to right:";
  for (const json& m : report["methods"])
    md << " " << m["name"].get<std::string>() << (m["status"] == "failed" ? " (failed)" : "");
  md << ". One colour scale for all, from " << number(report["colourScale"]["min"]) << " to "
     << number(report["colourScale"]["max"])
     << ": viridis for values ≥ 0, pink to red for negative values, grey outside the cage, "
        "the cage's cross-section in black.\n\n"
     << "Properties at " << report["samples"]["count"] << " random interior points (seed "
     << report["samples"]["seed"]
     << "); errors are maxima, lengths relative to the cage diagonal.\n\n"
     << "| method | setup s | bind s | points/s | partition of unity | linear reproduction | "
        "min weight | negative fraction | Lagrange | face interpolation | slice min | slice max "
        "|\n|---|---|---|---|---|---|---|---|---|---|---|---|\n";
  for (const json& m : report["methods"]) {
    if (m["status"] == "failed") {
      md << "| " << m["name"].get<std::string>() << " | failed |";
      for (int column = 0; column < 10; ++column) md << " – |";
      md << "\n";
      continue;
    }
    const json& p = m["properties"];
    md << "| " << m["name"].get<std::string>() << " | " << number(m["setupSeconds"]) << " | "
       << number(m["bindSeconds"]) << " | " << number(m["bindPointsPerSecond"]) << " | "
       << number(p["partitionOfUnity"]) << " | " << number(p["linearReproduction"]) << " | "
       << number(p["minWeight"]) << " | " << number(p["negativeFraction"]) << " | "
       << number(p["lagrange"]) << " | " << number(p["faceInterpolation"]) << " | "
       << number(m["slice"]["min"]) << " | " << number(m["slice"]["max"]) << " |\n";
  }
  md << "\n";
  for (const json& m : report["methods"]) {
    md << "- **" << m["name"].get<std::string>() << "**: " << m["description"].get<std::string>();
    if (m["status"] == "failed")
      md << ": **failed** (" << m["errorType"].get<std::string>()
         << "): " << m["error"].get<std::string>() << "; image `" << m["image"].get<std::string>()
         << "` (grey)\n";
    else
      md << " (control " << m["controlIndex"] << " of " << m["controlCount"] << "); image `"
         << m["image"].get<std::string>() << "`\n";
  }
  return md.str();
}

// Refuses, before any work, a comparison that cannot fit in the memory available, naming the
// first method that does not fit. The methods run one after the other, so the peak is what all
// of them share (the pixels, the samples, every method's values and image) plus one method's
// own: its coordinates (precomputation, per-thread scratch), a block of pixel weights and the
// property kit's blocks.
void checkComparisonMemory(const CompareRequest& request,
                           const std::map<std::string, Method>& table,
                           const std::vector<std::string>& methods, const Cage& cage,
                           const Slice& slice) {
  const double pixels = static_cast<double>(slice.width) * static_cast<double>(slice.height);
  const double count = static_cast<double>(methods.size());
  // Besides, about 16 MB of working memory: PNG encoding, the reports, the threads' own.
  const double shared =
      pixels * (1.0 + sizeof(Vec3) + sizeof(std::size_t)) +    // inside flags, points, indices
      pixels * count * (sizeof(double) + 2.0 * sizeof(Rgb)) +  // values, panel, side by side
      static_cast<double>(request.samples) * sizeof(Vec3) + 16e6;
  for (const std::string& name : methods) {
    const Method& method = table.at(name);
    const std::size_t m = method.columns(cage);
    const double own = method.memory(cage, request.cageOptions) +
                       sizeof(double) * static_cast<double>(std::max(kBindBlockValues, m)) +
                       measurePropertiesMemory(m, method.cageControls ? cage.triangleCount() : 0);
    // Harmonic coordinates grow with the tet count: name it when it was given.
    std::string tets;
    if (name == "harmonic" && request.cageOptions.harmonicTets > 0)
      tets = " with --tets " + std::to_string(request.cageOptions.harmonicTets);
    if (name == "harmonic" && request.cageOptions.harmonicPrecision > 0) {
      std::ostringstream level;  // 5, 5.5: as the user wrote it
      level << request.cageOptions.harmonicPrecision;
      tets = " with --precision " + level.str();
    }
    detail::checkMemory(shared + own, request.cage.string() + ": comparing method '" + name + "'" +
                                          tets + " on this " + std::to_string(cage.vertexCount()) +
                                          "-vertex cage");
  }
}

// compare replaces its output folder as a whole: it may only hold what compare writes (from
// any earlier run, whatever its methods), so that nothing else is lost with it.
void checkOutputFolder(const fs::path& folder) {
  std::error_code error;
  if (!fs::exists(folder, error)) return;
  if (!fs::is_directory(folder, error))
    throw IoError(folder.string() + ": the output folder exists and is not a folder");
  std::set<std::string> ours = {"compare.png", "colour_bar.png", "report.json", "report.md"};
  for (const std::string& name : compareMethods()) ours.insert(name + ".png");
  fs::directory_iterator entries(folder, error);
  if (error) throw IoError(folder.string() + ": cannot list the output folder: " + error.message());
  for (const fs::directory_entry& entry : entries) {
    const std::string name = entry.path().filename().string();
    if (!ours.count(name) || !entry.is_regular_file(error))
      throw IoError(entry.path().string() +
                    ": not an output of compare, and compare replaces the output folder " +
                    folder.string() + " as a whole: move it away or give another folder");
  }
}

}  // namespace

std::vector<std::string> compareMethods() {
  std::vector<std::string> names;
  for (const auto& [name, method] : methodTable()) names.push_back(name);
  return names;
}

namespace {

/// The methods to run, in order: the request's, checked, or every one. Also checks the
/// request's other settings, before any work.
std::vector<std::string> checkRequest(const CompareRequest& request,
                                      const std::map<std::string, Method>& table) {
  const std::vector<std::string> methods =
      request.methods.empty() ? compareMethods() : request.methods;
  for (std::size_t k = 0; k < methods.size(); ++k) {
    const std::string& name = methods[k];
    if (!table.count(name)) {
      std::string known;
      for (const std::string& m : compareMethods()) known += (known.empty() ? "" : ", ") + m;
      throw InvalidInput("unknown method '" + name + "' (one of: " + known + ")");
    }
    if (std::find(methods.begin(), methods.begin() + k, name) != methods.begin() + k)
      throw InvalidInput("method '" + name + "' is listed twice");
  }
  if (request.resolution < 8 || request.resolution > 8192)
    throw InvalidInput("the resolution must be between 8 and 8192 pixels");
  if (!isFinite(request.planePoint) || !isFinite(request.planeNormal) ||
      glm::length(request.planeNormal) == 0.0)
    throw InvalidInput("the slice plane needs a finite point and a non-zero normal");
  return methods;
}

/// The methods that run on `cage`: every one the request names, which must all take it (else
/// InvalidInput, e.g. naming a reflex edge), or by default every method that takes it, with a
/// note per method left out.
std::vector<std::string> methodsForCage(const std::vector<std::string>& methods,
                                        const CompareRequest& request,
                                        const std::map<std::string, Method>& table,
                                        const Cage& cage, const CliContext& context,
                                        json& leftOut) {
  if (!request.methods.empty()) {
    for (const std::string& name : methods) table.at(name).applies(cage);
    return methods;
  }
  std::vector<std::string> run;
  for (const std::string& name : methods) {
    try {
      table.at(name).applies(cage);
      run.push_back(name);
    } catch (const InvalidInput& e) {
      leftOut.push_back({{"name", name}, {"reason", e.what()}});
      context.say("compare: leaving " + name + " out of the default methods: " + e.what());
    }
  }
  return run;
}

/// The pixels of the slice inside the cage: the only places where every method is defined.
struct InsidePixels {
  std::vector<Vec3> points;        ///< pixel centers, world units
  std::vector<std::size_t> pixel;  ///< their index in the image, row-major
};

InsidePixels insidePixels(const Cage& cage, const Slice& slice) {
  // The winding number costs one atan2 per cage triangle, so rows go in parallel.
  std::vector<char> isInside(std::size_t(slice.width) * slice.height);
  tbb::parallel_for(0, slice.height, [&](int j) {
    for (int i = 0; i < slice.width; ++i)
      isInside[std::size_t(j) * slice.width + i] = cage.contains(slice.pixelCenter(i, j));
  });
  InsidePixels inside;
  for (int j = 0; j < slice.height; ++j)
    for (int i = 0; i < slice.width; ++i)
      if (isInside[std::size_t(j) * slice.width + i]) {
        inside.points.push_back(slice.pixelCenter(i, j));
        inside.pixel.push_back(std::size_t(j) * slice.width + i);
      }
  return inside;
}

/// One method's outcome: its control's weight at every inside pixel and its report entry.
struct Result {
  std::string name;
  std::size_t control = 0, controlCount = 0;
  std::vector<double> values;  // per inside pixel
  bool failed = false;
  json entry;
};

/// Runs one method. A method that cannot handle this cage (a tet mesh that misses interior
/// points, a singular fit, a bad cache file) is reported as failed; the others still run.
/// Cancellation stops the whole comparison.
Result runMethod(const std::string& name, const Method& method,
                 const std::shared_ptr<const Cage>& cage, const CompareRequest& request,
                 const std::vector<Vec3>& inside, const std::vector<Vec3>& samples,
                 const ProgressCallback& progress) {
  Result r;
  r.name = name;
  try {
    const auto start = Clock::now();
    const auto coordinates = method.make(cage, request.cageOptions, progress);
    const double setup = std::chrono::duration<double>(Clock::now() - start).count();

    r.controlCount = coordinates->controlPointCount();
    r.control = request.control;
    if (!method.cageControls) {
      const Vec3 target = cage->vertices()[request.control];
      const auto controls = coordinates->restControlPoints();
      double best = std::numeric_limits<double>::infinity();
      for (std::size_t c = 0; c < controls.size(); ++c)
        if (const double d = glm::length(controls[c] - target); d < best) best = d, r.control = c;
    }

    // The weights of every inside pixel, in blocks to bound memory: the bind.
    const std::size_t m = coordinates->columnCount();
    const std::size_t block = std::max<std::size_t>(1, kBindBlockValues / m);
    std::vector<double> rows;
    r.values.resize(inside.size());
    const auto bindStart = Clock::now();
    ProgressTracker tracker(progress, "bind " + name, inside.size());
    forEachBlock(inside.size(), block, tracker, [&](std::size_t begin, std::size_t count) {
      rows.resize(count * m);
      coordinates->weightsBatch(std::span(inside).subspan(begin, count), rows);
      for (std::size_t k = 0; k < count; ++k) r.values[begin + k] = rows[k * m + r.control];
    });
    const double bind = std::chrono::duration<double>(Clock::now() - bindStart).count();

    const PropertyReport properties =
        method.cageControls ? measureProperties(*coordinates, *cage, samples)
                            : measureProperties(*coordinates, samples, cage->diagonal());
    const auto [lo, hi] = std::minmax_element(r.values.begin(), r.values.end());
    const auto negative =
        std::count_if(r.values.begin(), r.values.end(), [](double v) { return v < 0.0; });
    r.entry = {{"name", name},
               {"description", method.description},
               {"status", "ok"},
               {"controlIndex", r.control},
               {"controlCount", r.controlCount},
               {"columns", m},
               {"setupSeconds", setup},
               {"bindSeconds", bind},
               {"bindPoints", inside.size()},
               {"bindPointsPerSecond", bind > 0.0 ? inside.size() / bind : 0.0},
               {"slice", {{"min", *lo}, {"max", *hi}, {"negativePixels", negative}}},
               {"properties", propertiesJson(properties)},
               {"image", name + ".png"}};
  } catch (const Cancelled&) {
    throw;
  } catch (const std::exception& e) {
    r.failed = true;
    r.values.clear();
    r.entry = {{"name", name},       {"description", method.description},
               {"status", "failed"}, {"errorType", errorType(e)},
               {"error", e.what()},  {"image", name + ".png"}};
  }
  return r;
}

/// One colour scale for every method: from min(0, lowest) to the highest value (1 if none is
/// positive).
ColourScale commonScale(const std::vector<Result>& results) {
  ColourScale scale{0.0, 0.0};
  for (const Result& r : results)
    for (double v : r.values)
      scale.min = std::min(scale.min, v), scale.max = std::max(scale.max, v);
  if (scale.max <= 0.0) scale.max = 1.0;
  return scale;
}

/// One image per method: its values, the cage's cross-section, the control vertex marked when
/// near the plane; a grey panel saying "failed" for a failed method.
std::vector<Image> methodImages(const std::vector<Result>& results, const Cage& cage,
                                const CompareRequest& request, const Slice& slice,
                                const std::vector<std::size_t>& insidePixel,
                                const ColourScale& scale, int textScale) {
  const auto segments = crossSection(cage, slice);
  const Vec3 controlPoint = cage.vertices()[request.control];
  const double controlDistance = glm::dot(controlPoint - slice.origin, slice.normal);
  std::vector<Image> images;
  for (const Result& r : results) {
    Image image(slice.width, slice.height, r.failed ? kFailed : kOutside);
    for (std::size_t k = 0; k < r.values.size(); ++k)
      image.pixels[insidePixel[k]] = scale(r.values[k]);
    for (const auto& [a, b] : segments) {
      const auto [x0, y0] = slice.toPixel(a);
      const auto [x1, y1] = slice.toPixel(b);
      image.line(x0, y0, x1, y1, Rgb{0, 0, 0});
    }
    if (r.failed) {
      image.text((slice.width - textWidth("failed", textScale)) / 2,
                 (slice.height - textHeight(textScale)) / 2, "failed", textScale,
                 Rgb{255, 255, 255});
    } else if (std::abs(controlDistance) <= 0.05 * cage.diagonal()) {
      const auto [cx, cy] = slice.toPixel(controlPoint - controlDistance * slice.normal);
      image.line(cx - 4, cy, cx + 4, cy, Rgb{255, 255, 255});
      image.line(cx, cy - 4, cx, cy + 4, Rgb{255, 255, 255});
    }
    images.push_back(std::move(image));
  }
  return images;
}

/// compare.png: the method images side by side under their names, the labelled colour bar
/// underneath; `layout` says where things are, pixels from its top-left corner.
struct SideBySide {
  Image image{1, 1, Rgb{255, 255, 255}};
  json layout;
  std::vector<double> labelled;  ///< the colour bar's labelled ticks
};

SideBySide sideBySide(const std::vector<Result>& results, const std::vector<Image>& images,
                      const Slice& slice, const ColourScale& scale, int textScale) {
  const int gap = 8, barHeight = 16;
  const int titleHeight = textHeight(textScale) + gap;
  const int totalWidth = static_cast<int>(results.size()) * (slice.width + gap) - gap;
  const LabelledBar bar = labelledColourBar(scale, totalWidth, barHeight, textScale);
  const int barTop = titleHeight + slice.height + gap;
  SideBySide out;
  out.image = Image(totalWidth, barTop + bar.image.height + gap / 2, Rgb{255, 255, 255});
  json panels = json::array();
  for (std::size_t k = 0; k < images.size(); ++k) {
    const int left = static_cast<int>(k) * (slice.width + gap);
    // The title centered over its panel and clipped to it, so long names never run into the
    // next one.
    Image title(slice.width, titleHeight, Rgb{255, 255, 255});
    title.text(std::max(0, (slice.width - textWidth(results[k].name, textScale)) / 2), gap / 2,
               results[k].name, textScale, Rgb{0, 0, 0});
    out.image.paste(title, left, 0);
    out.image.paste(images[k], left, titleHeight);
    panels.push_back({{"name", results[k].name}, {"left", left}, {"top", titleHeight}});
  }
  out.image.paste(bar.image, 0, barTop);
  out.layout = {{"titleHeight", titleHeight},
                {"panels", panels},
                {"panelSize", {slice.width, slice.height}},
                {"bar",
                 {{"left", bar.barLeft},
                  {"top", barTop},
                  {"width", bar.barWidth},
                  {"height", bar.barHeight},
                  {"labelTop", barTop + bar.labelTop}}}};
  out.labelled = bar.labelled;
  return out;
}

json reportJson(const CompareRequest& request, const Cage& cage, const Slice& slice,
                std::size_t insideCount, const ColourScale& scale, const SideBySide& strip,
                std::size_t sampleCount, const std::vector<Result>& results) {
  json report = {
      {"cage", request.cage.string()},
      {"cageVertices", cage.vertexCount()},
      {"cageTriangles", cage.triangleCount()},
      {"diagonal", cage.diagonal()},
      {"control", request.control},
      {"slice",
       {{"point", vec(slice.origin)},
        {"normal", vec(slice.normal)},
        {"u", vec(slice.u)},
        {"v", vec(slice.v)},
        {"uRange", {slice.uMin, slice.uMax}},
        {"vRange", {slice.vMin, slice.vMax}}}},
      {"resolution", {slice.width, slice.height}},
      {"insidePixels", insideCount},
      {"colourScale", {{"min", scale.min}, {"max", scale.max}, {"labelledTicks", strip.labelled}}},
      {"samples", {{"count", sampleCount}, {"seed", request.seed}}},
      {"images",
       {{"sideBySide", "compare.png"}, {"colourBar", "colour_bar.png"}, {"layout", strip.layout}}},
      {"methods", json::array()}};
  report["failedMethods"] = json::array();
  for (const Result& r : results) {
    report["methods"].push_back(r.entry);
    if (r.failed) report["failedMethods"].push_back(r.name);
  }
  return report;
}

}  // namespace

json runComparison(const CompareRequest& request, const CliContext& context) {
  const std::map<std::string, Method> table = methodTable();
  const std::vector<std::string> requested = checkRequest(request, table);
  checkOutputFolder(request.output);  // before the work, and again before the write

  auto cage = std::make_shared<const Cage>(Cage::fromFile(request.cage));
  json leftOut = json::array();
  const std::vector<std::string> methods =
      methodsForCage(requested, request, table, *cage, context, leftOut);
  if (request.control >= cage->vertexCount())
    throw InvalidInput(request.cage.string() + ": control " + std::to_string(request.control) +
                       " is out of range (the cage has " + std::to_string(cage->vertexCount()) +
                       " vertices)");
  const Slice slice = makeSlice(*cage, request.planePoint, request.planeNormal, request.resolution);
  checkComparisonMemory(request, table, methods, *cage, slice);
  const InsidePixels inside = insidePixels(*cage, slice);
  if (inside.points.empty())
    throw InvalidInput(request.cage.string() + ": the slice plane does not cut the cage");
  const std::vector<Vec3> samples = interiorSamples(*cage, request.samples, request.seed);

  std::vector<Result> results;
  const ProgressCallback progress = context.progress();
  for (const std::string& name : methods)
    results.push_back(
        runMethod(name, table.at(name), cage, request, inside.points, samples, progress));

  const ColourScale scale = commonScale(results);
  // Text at twice the font's size once panels are wide enough for the longer names.
  const int textScale = slice.width >= 192 ? 2 : 1;
  const std::vector<Image> images =
      methodImages(results, *cage, request, slice, inside.pixel, scale, textScale);
  const SideBySide strip = sideBySide(results, images, slice, scale, textScale);
  json report = reportJson(request, *cage, slice, inside.points.size(), scale, strip,
                           samples.size(), results);
  report["leftOutMethods"] = leftOut;

  // Everything is computed: only now touch the output folder, replaced as a whole, so that a
  // failure or an interruption leaves the previous comparison complete.
  checkOutputFolder(request.output);
  writeFolderAtomically(request.output, [&](const fs::path& folder) {
    for (std::size_t k = 0; k < images.size(); ++k)
      writePng(images[k], folder / (results[k].name + ".png"));
    writePng(strip.image, folder / "compare.png");
    writePng(labelledColourBar(scale, 512, 24, 2).image, folder / "colour_bar.png");
    writeJsonFile(report, folder / "report.json");
    const std::string md = markdown(report);
    writeFileAtomically(folder / "report.md", [&](std::ostream& out) { out << md; });
  });
  // Even with --quiet: a missing result is not information to hide (demo calls this too).
  for (const Result& r : results)
    if (r.failed)
      std::fprintf(stderr, "spacewarp: warning: compare: %s failed: %s\n", r.name.c_str(),
                   r.entry["error"].get<std::string>().c_str());
  return report;
}

}  // namespace spacewarp::cli
