#include <spacewarp/coords/tet_mesh.h>

// TetGen is used as a library (compiled with TETLIBRARY): it reports failures by `throw int`
// (1 out of memory, 2 internal error, 3 self-intersection, 4 tiny feature, 5 close facets,
// 10 input error) and prints nothing with the Q switch. Its PLC mesher does not always detect
// a self-intersecting input (it can crash on one), so the input is first checked with the d
// switch, which returns the intersecting input faces.
//
// Debian's TetGen 1.5.0 is built with its assertions on, and some inputs fail one (tetgen.cxx:
// 11026 in locate(), while refining a box with a pinched waist at 10k to 30k tets): that would
// abort the whole process. So TetGen runs in a forked child that sends its output back through
// a pipe, and a child that dies becomes a SolverError with TetGen's message.

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <functional>
#include <limits>
#include <string>
#include <vector>

#include <poll.h>
#include <signal.h>
#include <sys/prctl.h>
#include <sys/wait.h>
#include <unistd.h>

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

// ---- TetGen in a child process ----

// Writes all of `data` to fd (the child's side); false on a failed write.
bool writeAll(int fd, const void* data, std::size_t size) {
  const char* p = static_cast<const char*>(data);
  while (size > 0) {
    const ssize_t n = ::write(fd, p, size);
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) return false;
    p += n;
    size -= static_cast<std::size_t>(n);
  }
  return true;
}

// Reads both pipes to their ends (the parent's side), whichever has data, so that neither
// side can block the other: the child's output and what it wrote to stderr. Calls `tick` every
// tenth of a second of waiting (a cancel it throws ends the read).
void readBoth(int data, int errors, std::string& output, std::string& message,
              const std::function<void()>& tick) {
  pollfd fds[2] = {{data, POLLIN, 0}, {errors, POLLIN, 0}};
  std::string* into[2] = {&output, &message};
  char buffer[1 << 16];
  int open = 2;
  while (open > 0) {
    const int ready = ::poll(fds, 2, 100);
    if (ready < 0 && errno != EINTR) return;
    if (ready <= 0) {
      tick();
      continue;
    }
    for (int i = 0; i < 2; ++i) {
      if (fds[i].fd < 0 || fds[i].revents == 0) continue;
      const ssize_t n = ::read(fds[i].fd, buffer, sizeof buffer);
      if (n < 0 && errno == EINTR) continue;
      if (n <= 0) {
        fds[i].fd = -1;  // poll ignores it from now on
        --open;
        continue;
      }
      into[i]->append(buffer, static_cast<std::size_t>(n));
    }
  }
}

// What the callers read of TetGen's output, as the child sends it: the error code (0: none),
// then counts and arrays of points, tets and boundary faces.
struct Counts {
  int code = 0, points = 0, tets = 0, corners = 0, faces = 0, markers = 0;
};

// The child: runs TetGen and writes its output to fd; never returns.
[[noreturn]] void runChild(char* switches, tetgenio& in, int fd) {
  tetgenio out;
  Counts counts;
  try {
    tetrahedralize(switches, &in, &out);
  } catch (int code) {
    counts.code = code;
  } catch (...) {
    counts.code = 1;  // std::bad_alloc
  }
  if (counts.code == 0) {
    counts.points = std::max(out.numberofpoints, 0);
    counts.tets = out.tetrahedronlist ? std::max(out.numberoftetrahedra, 0) : 0;
    counts.corners = out.numberofcorners;
    counts.faces = out.trifacelist ? std::max(out.numberoftrifaces, 0) : 0;
    counts.markers = out.trifacemarkerlist ? counts.faces : 0;
  }
  const auto n = [](int count, std::size_t each) { return static_cast<std::size_t>(count) * each; };
  const bool ok =
      writeAll(fd, &counts, sizeof counts) &&
      writeAll(fd, out.pointlist, n(counts.points, 3 * sizeof(REAL))) &&
      writeAll(fd, out.tetrahedronlist,
               n(counts.tets, static_cast<std::size_t>(counts.corners) * sizeof(int))) &&
      writeAll(fd, out.trifacelist, n(counts.faces, 3 * sizeof(int))) &&
      writeAll(fd, out.trifacemarkerlist, n(counts.markers, sizeof(int)));
  ::_exit(ok ? 0 : 1);  // no atexit handlers or stdio flushes of the parent's state
}

// Fills `out` from what the child sent; false if it is truncated or inconsistent.
template <typename T>
bool take(const std::string& data, std::size_t& at, int count, std::size_t each, T*& list) {
  if (count < 0) return false;
  const std::size_t bytes = static_cast<std::size_t>(count) * each * sizeof(T);
  if (data.size() - at < bytes) return false;
  list = nullptr;
  if (count > 0) {
    list = new T[static_cast<std::size_t>(count) * each];  // tetgenio deletes them with delete[]
    std::memcpy(list, data.data() + at, bytes);
  }
  at += bytes;
  return true;
}

bool readOutput(const std::string& data, Counts& counts, tetgenio& out) {
  if (data.size() < sizeof counts) return false;
  std::memcpy(&counts, data.data(), sizeof counts);
  if (counts.code != 0) return data.size() == sizeof counts;
  if (counts.corners < 0 || counts.markers > counts.faces) return false;
  std::size_t at = sizeof counts;
  out.firstnumber = 0;
  out.numberofpoints = counts.points;
  out.numberoftetrahedra = counts.tets;
  out.numberofcorners = counts.corners;
  out.numberoftrifaces = counts.faces;
  return take(data, at, counts.points, 3, out.pointlist) &&
         take(data, at, counts.tets, static_cast<std::size_t>(counts.corners),
              out.tetrahedronlist) &&
         take(data, at, counts.faces, 3, out.trifacelist) &&
         take(data, at, counts.markers, 1, out.trifacemarkerlist) && at == data.size();
}

// The first line of what the child wrote to stderr (TetGen's assertion), trimmed.
std::string firstLine(const std::string& text) {
  std::string line = text.substr(0, text.find('\n'));
  if (line.size() > 300) line.resize(300);
  return line;
}

// Runs TetGen in a child process (each has its own copy of TetGen's global predicate
// constants, so calls need no lock), mapping its error codes and its death to exceptions.
// `cageName` names the cage in the message of a death. A cancel (`tracker`, polled while TetGen
// runs) kills the child.
void run(const std::string& switches, tetgenio& in, tetgenio& out, const std::string& cageName,
         ProgressTracker& tracker) {
  std::vector<char> buffer(switches.begin(), switches.end());
  buffer.push_back('\0');
  int data[2], errors[2];
  if (::pipe(data) != 0) throw SolverError("tetrahedralising the cage: cannot create a pipe");
  if (::pipe(errors) != 0) {
    ::close(data[0]);
    ::close(data[1]);
    throw SolverError("tetrahedralising the cage: cannot create a pipe");
  }
  const pid_t parent = ::getpid();
  const pid_t child = ::fork();
  if (child == 0) {
    // Die with the parent, however it ends (a signal that ends it at once leaves no time to
    // kill the child; an orphan would compute on, holding the caller's stdout and stderr).
    ::prctl(PR_SET_PDEATHSIG, SIGKILL);
    if (::getppid() != parent) ::_exit(1);
    ::close(data[0]);
    ::close(errors[0]);
    ::dup2(errors[1], STDERR_FILENO);
    runChild(buffer.data(), in, data[1]);
  }
  ::close(data[1]);
  ::close(errors[1]);
  if (child < 0) {
    ::close(data[0]);
    ::close(errors[0]);
    throw SolverError("tetrahedralising the cage: cannot start TetGen's process");
  }
  std::string output, message;
  const auto reap = [&] {
    ::close(data[0]);
    ::close(errors[0]);
    int status = 0;
    while (::waitpid(child, &status, 0) < 0 && errno == EINTR) {
    }
    return status;
  };
  try {
    readBoth(data[0], errors[0], output, message, [&] { tracker.poll(); });
  } catch (...) {
    ::kill(child, SIGKILL);
    reap();
    throw;
  }
  const int status = reap();
  Counts counts;
  if (!(WIFEXITED(status) && WEXITSTATUS(status) == 0 && readOutput(output, counts, out))) {
    // Appended piece by piece (GCC 12's false -Wrestrict on "literal" + std::string).
    std::string what = cageName;
    what += ": tetrahedralising the cage: TetGen ";
    what += WIFSIGNALED(status) ? "died (signal " + std::to_string(WTERMSIG(status)) + ")"
                                : std::string("failed to return its mesh");
    if (!message.empty()) what += ": " + firstLine(message);
    what += "; another tet count (targetTetCount or maxTetVolumeFraction) may avoid it";
    throw SolverError(what);
  }
  if (counts.code != 0) {
    const std::string what = "tetrahedralising the cage: TetGen failed: " + reasonOf(counts.code);
    if (counts.code == 1) throw OutOfMemory(what);
    if (counts.code == 2) throw SolverError(what);
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
void requireNoSelfIntersection(const Cage& cage, ProgressTracker& tracker) {
  tetgenio in, out;
  fillInput(cage, in);
  run("pzQd", in, out, cage.name(), tracker);
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
  requireNoSelfIntersection(cage, tracker);

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
  run(switches, in, out, cage.name(), tracker);
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
