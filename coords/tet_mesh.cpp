#include <spacewarp/coords/tet_mesh.h>

// TetGen is used as a library (compiled with TETLIBRARY): it reports failures by `throw int`
// (1 out of memory, 2 internal error, 3 self-intersection, 4 tiny feature, 5 close facets,
// 10 input error) and prints nothing with the Q switch. Its PLC mesher does not always detect
// a self-intersecting input (it can crash on one), so the input is first checked with the d
// switch, which returns the intersecting input faces.

#include <cmath>
#include <cstdio>
#include <cstring>
#include <limits>
#include <mutex>
#include <string>
#include <vector>

#include <tetgen.h>

#include <spacewarp/core/errors.h>

namespace spacewarp {

namespace {

std::string reasonOf(int code) {
  switch (code) {
    case 1:
      return "out of memory";
    case 2:
      return "internal error";
    case 3:
      return "the cage intersects itself";
    case 4:
      return "a very small input feature size (nearly touching parts of the cage)";
    case 5:
      return "two very close cage faces";
    case 10:
      return "invalid input";
    default:
      return "error code " + std::to_string(code);
  }
}

// The cage as a TetGen PLC: its vertices in the cage frame, one facet per triangle, with
// marker triangle + 1.
void fillInput(const Cage& cage, tetgenio& in) {
  in.firstnumber = 0;
  in.numberofpoints = static_cast<int>(cage.vertexCount());
  in.pointlist = new REAL[3 * cage.vertexCount()];
  for (std::size_t i = 0; i < cage.vertexCount(); ++i) {
    const Vec3 p = cage.frame().toLocal(cage.vertices()[i]);
    in.pointlist[3 * i] = p.x;
    in.pointlist[3 * i + 1] = p.y;
    in.pointlist[3 * i + 2] = p.z;
  }
  const std::size_t nT = cage.triangleCount();
  in.numberoffacets = static_cast<int>(nT);
  in.facetlist = new tetgenio::facet[nT];
  in.facetmarkerlist = new int[nT];
  for (std::size_t t = 0; t < nT; ++t) {
    tetgenio::facet& f = in.facetlist[t];
    tetgenio::init(&f);
    f.numberofpolygons = 1;
    f.polygonlist = new tetgenio::polygon[1];
    tetgenio::init(&f.polygonlist[0]);
    f.polygonlist[0].numberofvertices = 3;
    f.polygonlist[0].vertexlist = new int[3];
    const Triangle& tri = cage.triangles()[t];
    f.polygonlist[0].vertexlist[0] = static_cast<int>(tri.x);
    f.polygonlist[0].vertexlist[1] = static_cast<int>(tri.y);
    f.polygonlist[0].vertexlist[2] = static_cast<int>(tri.z);
    in.facetmarkerlist[t] = static_cast<int>(t) + 1;
  }
}

// TetGen's exact-arithmetic predicates keep their constants in globals that every call
// re-initialises: calls are serialised.
std::mutex tetgenMutex;

// Runs TetGen, mapping its error codes to exceptions.
void run(const std::string& switches, tetgenio& in, tetgenio& out) {
  std::vector<char> buffer(switches.begin(), switches.end());
  buffer.push_back('\0');
  const std::lock_guard lock(tetgenMutex);
  try {
    tetrahedralize(buffer.data(), &in, &out);
  } catch (int code) {
    const std::string what = "tetrahedralising the cage: TetGen failed: " + reasonOf(code);
    if (code == 1) throw OutOfMemory(what);
    if (code == 2) throw SolverError(what);
    throw InvalidInput(what);
  }
}

std::string number(double value) {
  char text[32];
  std::snprintf(text, sizeof text, "%.17g", value);
  return text;
}

}  // namespace

std::vector<Vec3> worldVertices(const Cage& cage, const CageFrame& frame,
                                std::span<const Vec3> localVertices) {
  std::vector<Vec3> world(localVertices.size());
  for (std::size_t i = 0; i < world.size(); ++i)
    world[i] = i < cage.vertexCount() ? cage.vertices()[i] : frame.toWorld(localVertices[i]);
  return world;
}

namespace {

void checkOptions(const TetMeshOptions& options) {
  if (!(std::isfinite(options.radiusEdgeRatio) && options.radiusEdgeRatio >= 1.0)) {
    throw InvalidInput("tetrahedralising the cage: radiusEdgeRatio must be finite and >= 1, got " +
                       number(options.radiusEdgeRatio));
  }
  if (!(std::isfinite(options.maxTetVolume) && options.maxTetVolume >= 0.0)) {
    throw InvalidInput("tetrahedralising the cage: maxTetVolume must be finite and >= 0, got " +
                       number(options.maxTetVolume));
  }
}

// Self-intersection check first: TetGen's PLC mesher may crash on such input.
void requireNoSelfIntersection(const Cage& cage) {
  tetgenio in, out;
  fillInput(cage, in);
  run("pzQd", in, out);
  if (out.numberoftrifaces <= 0) return;
  std::string example;
  if (out.trifacemarkerlist != nullptr) {
    example = " (e.g. triangle " + std::to_string(out.trifacemarkerlist[0] - 1);
    for (int f = 1; f < out.numberoftrifaces; ++f) {
      if (out.trifacemarkerlist[f] != out.trifacemarkerlist[0]) {
        example += " and triangle " + std::to_string(out.trifacemarkerlist[f] - 1);
        break;
      }
    }
    example += ")";
  }
  throw InvalidInput("tetrahedralising the cage: TetGen found that the cage intersects itself: " +
                     std::to_string(out.numberoftrifaces) + " triangles are involved" + example);
}

// TetGen's points in the cage's frame; the cage's own vertices must come first, unmoved.
void takeVertices(const tetgenio& out, const Cage& cage, TetMesh& mesh) {
  const std::size_t nP = mesh.localVertices.size();
  for (std::size_t i = 0; i < nP; ++i) {
    mesh.localVertices[i] =
        Vec3(out.pointlist[3 * i], out.pointlist[3 * i + 1], out.pointlist[3 * i + 2]);
  }
  for (std::size_t i = 0; i < cage.vertexCount(); ++i) {
    if (mesh.localVertices[i] != mesh.frame.toLocal(cage.vertices()[i])) {
      throw InvalidInput("tetrahedralising the cage: TetGen merged or moved cage vertex " +
                         std::to_string(i) + " (is it a duplicate of another vertex?)");
    }
  }
}

// TetGen's tets, each positively oriented.
void takeTets(const tetgenio& out, TetMesh& mesh) {
  const std::size_t nP = mesh.localVertices.size();
  for (std::size_t t = 0; t < mesh.tets.size(); ++t) {
    std::array<std::uint32_t, 4> tet;
    for (int c = 0; c < 4; ++c) {
      const int v = out.tetrahedronlist[4 * t + static_cast<std::size_t>(c)];
      if (v < 0 || static_cast<std::size_t>(v) >= nP)
        throw SolverError("tetrahedralising the cage: TetGen returned a corner out of range");
      tet[static_cast<std::size_t>(c)] = static_cast<std::uint32_t>(v);
    }
    const std::vector<Vec3>& p = mesh.localVertices;
    const double det =
        glm::dot(p[tet[1]] - p[tet[0]], glm::cross(p[tet[2]] - p[tet[0]], p[tet[3]] - p[tet[0]]));
    if (det < 0.0) std::swap(tet[2], tet[3]);
    mesh.tets[t] = tet;
  }
}

// Boundary vertices: the corners of the boundary faces, marked with their cage triangle.
void markBoundary(const tetgenio& out, const Cage& cage, TetMesh& mesh) {
  mesh.boundaryTriangle.assign(mesh.localVertices.size(), -1);
  const auto nF = static_cast<std::size_t>(std::max(out.numberoftrifaces, 0));
  if (nF == 0 || out.trifacemarkerlist == nullptr)
    throw SolverError("tetrahedralising the cage: TetGen returned no boundary faces");
  for (std::size_t f = 0; f < nF; ++f) {
    const int marker = out.trifacemarkerlist[f] - 1;
    if (marker < 0 || static_cast<std::size_t>(marker) >= cage.triangleCount())
      throw SolverError("tetrahedralising the cage: TetGen returned an unmarked boundary face");
    for (int c = 0; c < 3; ++c) {
      std::int32_t& b = mesh.boundaryTriangle[static_cast<std::size_t>(
          out.trifacelist[3 * f + static_cast<std::size_t>(c)])];
      if (b < 0 || marker < b) b = marker;
    }
  }
  for (std::size_t i = 0; i < cage.vertexCount(); ++i) {
    if (mesh.boundaryTriangle[i] < 0)
      throw SolverError("tetrahedralising the cage: cage vertex " + std::to_string(i) +
                        " is not on the mesh boundary");
  }
}

}  // namespace

TetMesh tetrahedraliseCage(const Cage& cage, const TetMeshOptions& options,
                           const ProgressCallback& progress) {
  checkOptions(options);
  ProgressTracker tracker(progress, "tetrahedralise", 1);
  tracker.check();
  requireNoSelfIntersection(cage);

  tetgenio in, out;
  fillInput(cage, in);
  // Appended piece by piece: GCC 12 warns falsely (-Wrestrict) about "a" + number(...) here.
  std::string switches = "pzQq";
  switches += number(options.radiusEdgeRatio);
  const CageFrame& frame = cage.frame();
  if (options.maxTetVolume > 0.0) {
    switches += 'a';
    switches += number(options.maxTetVolume / (frame.scale * frame.scale * frame.scale));
  }
  run(switches, in, out);
  tracker.check();

  const std::size_t nV = cage.vertexCount();
  const auto nP = static_cast<std::size_t>(std::max(out.numberofpoints, 0));
  const auto nTet = static_cast<std::size_t>(std::max(out.numberoftetrahedra, 0));
  if (nTet == 0 || nP < nV || out.numberofcorners != 4) {
    throw InvalidInput("tetrahedralising the cage: TetGen produced no tetrahedra (" +
                       std::to_string(nTet) + " tets, " + std::to_string(nP) + " vertices)");
  }
  TetMesh mesh;
  mesh.frame = frame;
  mesh.localVertices.resize(nP);
  takeVertices(out, cage, mesh);
  mesh.vertices = worldVertices(cage, frame, mesh.localVertices);
  mesh.tets.resize(nTet);
  takeTets(out, mesh);
  markBoundary(out, cage, mesh);
  tracker.finish();
  return mesh;
}

}  // namespace spacewarp
