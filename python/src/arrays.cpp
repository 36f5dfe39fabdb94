#include <algorithm>
#include <cstdio>
#include <limits>
#include <string>

#include <spacewarp/core/errors.h>

#include "common.h"

namespace spacewarp::python {
namespace {

static_assert(sizeof(Vec3) == 3 * sizeof(double), "Vec3 must be three packed doubles");

std::string shapeText(const py::array& array) {
  std::string text = "(";
  for (py::ssize_t d = 0; d < array.ndim(); ++d) {
    if (d > 0) text += ", ";
    text += std::to_string(array.shape(d));
  }
  if (array.ndim() == 1) text += ",";
  return text + ")";
}

}  // namespace

std::size_t firstNonFinite(std::span<const Vec3> points) {
  // One vectorisable pass: x - x is 0 for finite x and NaN otherwise, and NaN survives the sum.
  double sum = 0.0;
  for (const Vec3& p : points) sum += (p.x - p.x) + (p.y - p.y) + (p.z - p.z);
  if (sum == 0.0) return points.size();
  return static_cast<std::size_t>(
      std::find_if(points.begin(), points.end(), [](const Vec3& p) { return !isFinite(p); }) -
      points.begin());
}

void requireFinite(std::span<const Vec3> points, const char* name) {
  if (const std::size_t i = firstNonFinite(points); i < points.size()) {
    // "point 2 is not finite", as the library says it; "normals row 2 ..." for other arrays.
    const std::string what = std::string_view(name) == "points" ? "point " + std::to_string(i)
                             : points.size() > 1 ? std::string(name) + " row " + std::to_string(i)
                                                 : std::string(name);
    throw InvalidInput(what + " is not finite");
  }
}

Points toPoints(py::handle object, const char* name, bool allowSingle) {
  if (py::isinstance<py::array>(object) &&
      py::reinterpret_borrow<py::array>(object).dtype().kind() == 'c')
    throw InvalidInput(std::string(name) + " must be real numbers, not complex");
  Points points;
  points.array = DoubleArray::ensure(object);
  if (!points.array) {
    PyErr_Clear();
    throw InvalidInput(std::string(name) + " must be an array of numbers of shape (n, 3), not " +
                       std::string(py::str(py::type::of(object).attr("__name__"))));
  }
  const py::array& a = points.array;
  if (allowSingle && a.ndim() == 1 && a.shape(0) == 3) {
    points.single = true;
  } else if (a.ndim() != 2 || a.shape(1) != 3) {
    throw InvalidInput(std::string(name) + " must have shape (n, 3)" +
                       (allowSingle ? " or (3,)" : "") + ", not " + shapeText(a));
  }
  const std::size_t n = points.single ? 1 : static_cast<std::size_t>(a.shape(0));
  points.span = {reinterpret_cast<const Vec3*>(points.array.data()), n};
  return points;
}

DoubleArray outputPoints(std::size_t n, const std::optional<py::array>& out, bool single) {
  if (!out) {
    if (single) return DoubleArray(std::vector<py::ssize_t>{3});
    return DoubleArray(std::vector<py::ssize_t>{static_cast<py::ssize_t>(n), 3});
  }
  const py::array& a = *out;
  const bool shapeOk =
      single ? (a.ndim() == 1 && a.shape(0) == 3)
             : (a.ndim() == 2 && a.shape(0) == static_cast<py::ssize_t>(n) && a.shape(1) == 3);
  if (!shapeOk) {
    throw InvalidInput("out must have shape " +
                       (single ? std::string("(3,)") : "(" + std::to_string(n) + ", 3)") +
                       ", not " + shapeText(a));
  }
  if (!py::isinstance<DoubleArray>(a) || !(a.flags() & py::array::c_style) || !a.writeable()) {
    throw InvalidInput("out must be a writable C-contiguous float64 array");
  }
  return py::reinterpret_borrow<DoubleArray>(a);
}

std::span<Vec3> pointsOf(DoubleArray& array) {
  return {reinterpret_cast<Vec3*>(array.mutable_data()),
          static_cast<std::size_t>(array.size() / 3)};
}

DoubleArray copyPoints(std::span<const Vec3> points) {
  DoubleArray array(std::vector<py::ssize_t>{static_cast<py::ssize_t>(points.size()), 3});
  std::copy(points.begin(), points.end(), pointsOf(array).begin());
  return array;
}

Vec3 toVec3(py::handle object, const char* name) {
  const Points p = toPoints(object, name, true);
  if (!p.single) throw InvalidInput(std::string(name) + " must be three numbers (x, y, z)");
  return p.span[0];
}

Polygons toPolygons(py::handle faces, std::size_t vertexCount) {
  Polygons polygons;
  const auto add = [&](long long index) {
    const std::size_t face = polygons.offsets.size() - 1;
    if (index < 0 || static_cast<unsigned long long>(index) >= vertexCount)
      throw InvalidInput("face " + std::to_string(face) + " refers to vertex " +
                         std::to_string(index) + ", not one of the " + std::to_string(vertexCount) +
                         " vertices");
    polygons.indices.push_back(static_cast<std::uint32_t>(index));
  };
  const auto close = [&] {
    polygons.offsets.push_back(static_cast<std::uint32_t>(polygons.indices.size()));
  };
  if (py::isinstance<py::array>(faces)) {
    const auto a = py::reinterpret_borrow<py::array>(faces);
    const char kind = a.dtype().kind();
    if (kind != 'i' && kind != 'u')
      throw InvalidInput("faces must be an integer array, not " + std::string(py::str(a.dtype())));
    if (a.ndim() != 2) throw InvalidInput("faces must have shape (m, k), not " + shapeText(a));
    // Unsigned indices past the range of long long are out of range, not negative.
    const auto values = py::array_t<double, py::array::c_style | py::array::forcecast>::ensure(a);
    for (py::ssize_t f = 0; f < values.shape(0); ++f) {
      for (py::ssize_t c = 0; c < values.shape(1); ++c) {
        const double v = values.at(f, c);
        add(v >= 9.2e18 ? std::numeric_limits<long long>::max() : static_cast<long long>(v));
      }
      close();
    }
    return polygons;
  }
  if (py::isinstance<py::str>(faces) || !py::isinstance<py::iterable>(faces))
    throw InvalidInput("faces must be an (m, k) integer array or a sequence of polygons");
  for (py::handle face : faces) {
    if (py::isinstance<py::str>(face) || !py::isinstance<py::iterable>(face))
      throw InvalidInput("face " + std::to_string(polygons.offsets.size() - 1) +
                         " is not a sequence of vertex indices");
    for (py::handle index : face) {
      PyObject* integer = PyNumber_Index(index.ptr());
      if (integer == nullptr) {
        PyErr_Clear();
        throw InvalidInput("face " + std::to_string(polygons.offsets.size() - 1) + ": index " +
                           std::string(py::repr(index)) + " is not an integer");
      }
      add(py::reinterpret_steal<py::int_>(integer).cast<long long>());
    }
    close();
  }
  return polygons;
}

std::vector<std::uint32_t> toIndices(py::handle object, const std::string& name,
                                     std::size_t count) {
  const auto fail = [&](std::size_t k, const std::string& value, bool negative) {
    throw InvalidInput(name + "[" + std::to_string(k) + "]: index " + value +
                       (negative ? " is negative"
                        : count == std::size_t{1} << 32
                            ? " is too large"
                            : " is out of range (" + std::to_string(count) + " vertices)"));
  };
  std::vector<std::uint32_t> indices;
  if (py::isinstance<py::array>(object)) {
    const auto a = py::reinterpret_borrow<py::array>(object);
    if (a.ndim() != 1) throw InvalidInput(name + " must have shape (k,), not " + shapeText(a));
    if (a.size() == 0) return indices;
    const char kind = a.dtype().kind();
    if (kind != 'i' && kind != 'u')
      throw InvalidInput(name + " must be integers, not " + std::string(py::str(a.dtype())));
    // As in toPolygons: through double, so that unsigned values past 2^63 stay out of range.
    const auto values = py::array_t<double, py::array::c_style | py::array::forcecast>::ensure(a);
    for (py::ssize_t k = 0; k < values.shape(0); ++k) {
      const double v = values.at(k);
      if (v < 0.0 || v >= static_cast<double>(count)) {
        char text[32];
        std::snprintf(text, sizeof text, "%.0f", v);
        fail(static_cast<std::size_t>(k), text, v < 0.0);
      }
      indices.push_back(static_cast<std::uint32_t>(v));
    }
    return indices;
  }
  if (py::isinstance<py::str>(object) || !py::isinstance<py::iterable>(object))
    throw InvalidInput(name + " must be a sequence of vertex indices, not " +
                       std::string(py::str(py::type::of(object).attr("__name__"))));
  for (py::handle item : object) {
    const std::size_t k = indices.size();
    // True and False are ints to Python, but never meant as vertex 1 and 0.
    PyObject* integer = PyBool_Check(item.ptr()) ? nullptr : PyNumber_Index(item.ptr());
    if (integer == nullptr) {
      PyErr_Clear();
      throw InvalidInput(name + "[" + std::to_string(k) + "]: " + std::string(py::repr(item)) +
                         " is not an integer");
    }
    const auto owned = py::reinterpret_steal<py::int_>(integer);
    int overflow = 0;
    const long long v = PyLong_AsLongLongAndOverflow(integer, &overflow);
    if (overflow < 0 || (overflow == 0 && v < 0)) fail(k, std::string(py::str(owned.ptr())), true);
    if (overflow > 0 || static_cast<unsigned long long>(v) >= count)
      fail(k, std::string(py::str(owned.ptr())), false);
    indices.push_back(static_cast<std::uint32_t>(v));
  }
  return indices;
}

std::vector<std::array<std::uint32_t, 3>> toTriangles(py::handle triangles,
                                                      std::size_t vertexCount) {
  const Polygons polygons = toPolygons(triangles, vertexCount);
  const std::size_t m = polygons.offsets.size() - 1;
  std::vector<std::array<std::uint32_t, 3>> out(m);
  for (std::size_t t = 0; t < m; ++t) {
    if (polygons.offsets[t + 1] - polygons.offsets[t] != 3)
      throw InvalidInput("triangles must have 3 vertices each; triangle " + std::to_string(t) +
                         " has " + std::to_string(polygons.offsets[t + 1] - polygons.offsets[t]));
    std::copy_n(polygons.indices.begin() + polygons.offsets[t], 3, out[t].begin());
  }
  return out;
}

}  // namespace spacewarp::python
