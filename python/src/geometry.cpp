// Polygon soups and point clouds (Geometry), their files, and deform() / deform_inverse().

#include <pybind11/stl.h>
#include <pybind11/stl/filesystem.h>

#include <algorithm>
#include <unordered_map>

#include <spacewarp/core/deform.h>
#include <spacewarp/core/errors.h>
#include <spacewarp/core/geometry.h>
#include <spacewarp/core/io/mesh_io.h>

#include "common.h"

namespace spacewarp::python {
namespace {

using namespace pybind11::literals;
using GeometryPtr = std::shared_ptr<PolygonSoup>;

/// The geometries that a call is reading or changing with the GIL released (write, deform):
/// touched with the GIL held only. Changing one of them from another thread meanwhile would
/// reallocate what the call reads, so the setters refuse.
std::unordered_map<const PolygonSoup*, int>& busyGeometries() {
  static std::unordered_map<const PolygonSoup*, int> busy;
  return busy;
}

/// Throws unless no call is using `soup` (see busyGeometries()).
void requireIdle(const PolygonSoup& soup) {
  if (busyGeometries().count(&soup))
    throw py::value_error(
        "this Geometry is being read or changed by spacewarp in another thread (write, deform)");
}

std::string joined(const std::string& head, const std::vector<std::string>& parts) {
  std::string line = head;
  for (std::size_t k = 0; k < parts.size(); ++k) line += (k ? "; " : "") + parts[k];
  return line;
}

std::vector<Vec3> pointVector(py::handle points, const char* name) {
  const Points p = toPoints(points, name, false);
  return {p.span.begin(), p.span.end()};
}

/// Sets the polygons of `soup` (none for None). Per-face and per-corner data (face attributes,
/// corner normals, texture coordinates, OBJ groups) describe the old polygons: they are kept
/// when the polygon sizes are the same, dropped otherwise. Nothing changes on an error.
void setFaces(PolygonSoup& soup, py::handle faces) {
  requireIdle(soup);
  Polygons polygons = faces.is_none() ? Polygons{} : toPolygons(faces, soup.size());
  if (polygons.offsets != soup.faceOffsets) {
    soup.faceAttributes.clear();
    soup.cornerNormals = {};
    soup.texcoords = {};
    soup.objStatements.clear();
  }
  soup.faceOffsets = std::move(polygons.offsets);
  soup.faceIndices = std::move(polygons.indices);
}

/// The polygons as an (m, k) array when all have k vertices, else a list of (k_i,) arrays.
py::object facesOf(const PolygonSoup& soup) {
  const std::size_t m = soup.polygonCount();
  const std::size_t k = m ? soup.polygon(0).size() : 3;
  bool uniform = true;
  for (std::size_t p = 0; p < m && uniform; ++p) uniform = soup.polygon(p).size() == k;
  if (uniform) {
    py::array_t<std::uint32_t> a(
        std::vector<py::ssize_t>{static_cast<py::ssize_t>(m), static_cast<py::ssize_t>(k)});
    std::copy(soup.faceIndices.begin(), soup.faceIndices.end(), a.mutable_data());
    return a;
  }
  py::list polygons;
  for (std::size_t p = 0; p < m; ++p) {
    const auto polygon = soup.polygon(p);
    polygons.append(
        py::array_t<std::uint32_t>(static_cast<py::ssize_t>(polygon.size()), polygon.data()));
  }
  return polygons;
}

py::dict attributesOf(const std::vector<ScalarAttribute>& attributes) {
  py::dict d;
  for (const ScalarAttribute& a : attributes)
    d[py::str(a.name)] =
        py::array_t<double>(static_cast<py::ssize_t>(a.values.size()), a.values.data());
  return d;
}

ScalarType scalarTypeOf(const std::string& dtype) {
  static const std::pair<const char*, ScalarType> kTypes[] = {
      {"int8", ScalarType::Int8},       {"uint8", ScalarType::UInt8},
      {"int16", ScalarType::Int16},     {"uint16", ScalarType::UInt16},
      {"int32", ScalarType::Int32},     {"uint32", ScalarType::UInt32},
      {"float32", ScalarType::Float32}, {"float64", ScalarType::Float64}};
  for (const auto& [name, type] : kTypes)
    if (dtype == name) return type;
  throw InvalidInput(
      "dtype must be one of int8, uint8, int16, uint16, int32, uint32, float32, float64, not '" +
      dtype + "'");
}

void setAttribute(std::vector<ScalarAttribute>& attributes, std::size_t count, const char* what,
                  const std::string& name, py::handle values, const std::string& dtype) {
  const auto v = py::array_t<double, py::array::c_style | py::array::forcecast>::ensure(values);
  if (!v || v.ndim() != 1 || static_cast<std::size_t>(v.shape(0)) != count)
    throw InvalidInput(std::string(what) + " attribute '" + name + "' must have shape (" +
                       std::to_string(count) + ",)");
  ScalarAttribute attribute{name, scalarTypeOf(dtype),
                            std::vector<double>(v.data(), v.data() + count)};
  const auto same = std::find_if(attributes.begin(), attributes.end(),
                                 [&](const auto& a) { return a.name == name; });
  if (same != attributes.end())
    *same = std::move(attribute);
  else
    attributes.push_back(std::move(attribute));
}

void bindGeometryClass(py::module_& m) {
  py::class_<PolygonSoup, GeometryPtr>(
      m, "Geometry",
      R"(A polygon soup or point cloud: positions (n, 3) world units, optional unit normals
(n, 3), polygons of any size, per-vertex and per-face scalar attributes; what read() keeps of a
file (texture coordinates, per-corner normals, OBJ groups) travels with it to write(). Array
properties return copies; assign to change them.)")
      .def(py::init([](py::handle positions, py::handle faces, py::handle normals) {
             auto soup = std::make_shared<PolygonSoup>();
             soup->positions = pointVector(positions, "positions");
             setFaces(*soup, faces);
             if (!normals.is_none()) soup->normals = pointVector(normals, "normals");
             soup->validate();
             return soup;
           }),
           "positions"_a, "faces"_a = py::none(), py::kw_only(), "normals"_a = py::none())
      .def_property(
          "positions", [](const PolygonSoup& s) { return copyPoints(s.positions); },
          [](PolygonSoup& s, py::handle p) {
            requireIdle(s);
            std::vector<Vec3> v = pointVector(p, "positions");
            if (v.size() != s.size())
              throw InvalidInput("positions must keep the vertex count " +
                                 std::to_string(s.size()));
            s.positions = std::move(v);
          },
          "(n, 3) float64, world units (a copy).")
      .def_property(
          "normals",
          [](const PolygonSoup& s) -> py::object {
            if (!s.hasNormals()) return py::none();
            return copyPoints(s.normals);
          },
          [](PolygonSoup& s, py::handle n) {
            requireIdle(s);
            std::vector<Vec3> v = n.is_none() ? std::vector<Vec3>{} : pointVector(n, "normals");
            if (!v.empty() && v.size() != s.size())
              throw InvalidInput("normals must have one row per vertex");
            s.normals = std::move(v);
          },
          "(n, 3) unit normals per vertex, or None.")
      .def_property(
          "faces", &facesOf, [](PolygonSoup& s, py::handle f) { setFaces(s, f); },
          "The polygons: (m, k) uint32 when all have k vertices, else a list of index arrays. "
          "Assigning "
          "polygons of other sizes drops the per-face and per-corner data.")
      .def_property_readonly(
          "vertex_attributes", [](const PolygonSoup& s) { return attributesOf(s.attributes); },
          "dict of name -> (n,) float64 per-vertex values (copies).")
      .def_property_readonly(
          "face_attributes", [](const PolygonSoup& s) { return attributesOf(s.faceAttributes); },
          "dict of name -> (m,) float64 per-polygon values (copies).")
      .def(
          "set_vertex_attribute",
          [](PolygonSoup& s, const std::string& name, py::handle values, const std::string& dtype) {
            requireIdle(s);
            setAttribute(s.attributes, s.size(), "vertex", name, values, dtype);
          },
          "name"_a, "values"_a, py::kw_only(), "dtype"_a = "float64",
          "Sets the per-vertex attribute `name` (n,), stored as `dtype` in PLY files.")
      .def(
          "set_face_attribute",
          [](PolygonSoup& s, const std::string& name, py::handle values, const std::string& dtype) {
            requireIdle(s);
            setAttribute(s.faceAttributes, s.polygonCount(), "face", name, values, dtype);
          },
          "name"_a, "values"_a, py::kw_only(), "dtype"_a = "float64",
          "Sets the per-polygon attribute `name` (m,), stored as `dtype` in PLY files.")
      .def_property_readonly("point_count", &PolygonSoup::size, "Vertices or points (n).")
      .def_property_readonly("polygon_count", &PolygonSoup::polygonCount,
                             "Polygons (m); 0 for a point cloud.")
      .def(
          "copy", [](const PolygonSoup& s) { return std::make_shared<PolygonSoup>(s); },
          "A deep copy.")
      .def(
          "__copy__", [](const PolygonSoup& s) { return std::make_shared<PolygonSoup>(s); },
          "A deep copy (copy.copy): a Geometry shares no storage.")
      .def(
          "__deepcopy__",
          [](const PolygonSoup& s, const py::dict&) { return std::make_shared<PolygonSoup>(s); },
          "memo"_a, "A deep copy (copy.deepcopy).")
      .def("__len__", &PolygonSoup::size)
      .def("__repr__", [](const PolygonSoup& s) {
        return "<spacewarp.Geometry: " + std::to_string(s.size()) + " points, " +
               std::to_string(s.polygonCount()) + " polygons" +
               (s.hasNormals() ? ", normals" : "") + ">";
      });
}

/// `geometry` itself (in_place) or a copy: what deform() and deform_inverse() change.
GeometryPtr target(const GeometryPtr& geometry, bool inPlace) {
  return inPlace ? geometry : std::make_shared<PolygonSoup>(*geometry);
}

void warnSingular(std::size_t singular, std::size_t total) {
  if (singular == 0) return;
  warnAll({"the warp is singular at " + std::to_string(singular) + " of " + std::to_string(total) +
           " vertices: their normals are undefined (the flattened surface's normal, or zero)"});
}

void bindFiles(py::module_& m) {
  m.def(
      "read",
      [](const std::filesystem::path& path) {
        GeometryPtr soup;
        withoutGil([&] { soup = std::make_shared<PolygonSoup>(readSoup(path)); });
        if (!soup->notKept.empty())
          warnAll({joined(path.string() + ": not kept: ", soup->notKept)});
        return soup;
      },
      "path"_a,
      R"(Reads a soup or point cloud from an OBJ, OFF or PLY file (format by extension) as a
Geometry. Raises IoError naming the file and line or element at fault. What the file holds but
spacewarp does not keep (OBJ line elements, PLY edges, ...) is a warning.)");
  m.def(
      "write",
      [](const std::filesystem::path& path, const PolygonSoup& geometry, bool ascii) {
        WriteOptions options;
        if (ascii) options.plyEncoding = PlyEncoding::Ascii;
        {
          const InUse busy(geometry);
          withoutGil([&] { writeSoup(geometry, path, options); });
        }
        const auto lost = unstoredContent(geometry, formatFromPath(path));
        if (!lost.empty()) warnAll({joined(path.string() + ": the format cannot store: ", lost)});
      },
      "path"_a, "geometry"_a, py::kw_only(), "ascii"_a = false,
      R"(Writes a Geometry to an OBJ, OFF or PLY file (binary PLY unless ascii), atomically:
on any failure no partial file is left and an existing file is untouched.)");
  m.def(
      "deform",
      [](const Warp& warp, const GeometryPtr& geometry, bool inPlace, const py::object& progress) {
        const GeometryPtr out = target(geometry, inPlace);
        const InUse busy(*out);
        DeformReport report;
        runCancellable(progress, [&](const ProgressCallback& callback) {
          report = deform(warp, *out, callback);
        });
        warnSingular(report.singularNormals, out->size());
        return out;
      },
      "warp"_a, "geometry"_a, py::kw_only(), "in_place"_a = false, "progress"_a = py::none(),
      R"(The Geometry moved through `warp`: positions warped, normals carried by J^-T (the same
code as `spacewarp deform`). Returns a new Geometry, or `geometry` itself changed when in_place.
All or nothing: raises InvalidInput naming the first vertex that is not finite.)");
  m.def(
      "deform_inverse",
      [](const Warp& warp, const GeometryPtr& geometry, double tolerance, int maxIterations,
         bool inPlace, const py::object& progress) {
        const GeometryPtr out = target(geometry, inPlace);
        InverseOptions options;
        options.tolerance = tolerance;
        options.maxIterations = maxIterations;
        options.lengthScale = boundingBox(out->positions).diagonal();
        InverseDeformReport report;
        const InUse busy(*out);
        runCancellable(progress, [&](const ProgressCallback& callback) {
          report = deformInverse(warp, *out, options, callback);
        });
        warnSingular(report.singularNormals, out->size());
        return out;
      },
      "warp"_a, "geometry"_a, py::kw_only(), "tolerance"_a = 1e-12, "max_iterations"_a = 50,
      "in_place"_a = false, "progress"_a = py::none(),
      R"(The inverse of deform(): every vertex moved to its preimage under `warp` (as
`spacewarp inverse`; tolerance relative to the geometry's bounding-box diagonal). All or nothing:
raises SolverError naming the first vertex whose inverse did not converge.)");
}

}  // namespace

InUse::InUse(const PolygonSoup& soup) : soup_(&soup) { ++busyGeometries()[soup_]; }

InUse::~InUse() {
  auto& busy = busyGeometries();
  if (--busy[soup_] == 0) busy.erase(soup_);
}

void bindGeometry(py::module_& m) {
  bindGeometryClass(m);
  bindFiles(m);
}

}  // namespace spacewarp::python
