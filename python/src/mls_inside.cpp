// Distances measured inside a model, for MLS weights that do not reach across gaps:
// spacewarp.HandleDistances and spacewarp.InsideDistances (volume/inside_distance.h), given to
// spacewarp.Mls as `distances`.

#include <pybind11/stl.h>
#include <pybind11/stl/filesystem.h>

#include <filesystem>
#include <memory>
#include <vector>

#include <spacewarp/core/errors.h>
#include <spacewarp/core/geometry.h>
#include <spacewarp/core/handle_distances.h>
#include <spacewarp/core/io/mesh_io.h>
#ifdef SPACEWARP_WITH_OPENVDB
#include <spacewarp/volume/inside_distance.h>
#endif
#include "common.h"

namespace spacewarp::python {

using namespace pybind11::literals;

namespace {

// d_i(x) of every point (m, 3) for every handle: an (m, n) array.
DoubleArray distancesOf(const HandleDistances& d, py::handle points) {
  const Points in = toPoints(points, "points", false);
  const std::size_t n = d.handles().size();
  DoubleArray result(
      std::vector<py::ssize_t>{static_cast<py::ssize_t>(in.size()), static_cast<py::ssize_t>(n)});
  double* out = result.mutable_data();
  forEachPointCancellable(in.size(), "distances", [&](std::size_t i) {
    d.distances(in.span[i], std::span<double>(out + i * n, n));
  });
  return result;
}

}  // namespace

void bindMlsInside(py::module_& m) {
  py::class_<HandleDistances, std::shared_ptr<HandleDistances>>(
      m, "HandleDistances",
      R"(Distances from each of n handles to any point, which an Mls warp weighs its handles by
instead of Euclidean distances (Mls(..., distances=...)). Built by InsideDistances.)")
      .def_property_readonly(
          "handles",
          [](const HandleDistances& d) {
            return copyPoints(std::vector<Vec3>(d.handles().begin(), d.handles().end()));
          },
          "The handles (n, 3), world units, the distances are measured from.")
      .def("distances", &distancesOf, "points"_a,
           R"(The distance from every handle to every point: points (m, 3) -> (m, n), world
units; 0 exactly at a handle.)");

#ifdef SPACEWARP_WITH_OPENVDB
  py::class_<InsideDistances, HandleDistances, std::shared_ptr<InsideDistances>>(
      m, "InsideDistances",
      R"(The distances from handles (n, 3) to any point measured inside a closed model (Zhu &
Gortler 2007): shortest paths that stay in the solid, by fast marching on voxels of
`voxel_size` world units (0: the model's bounding-box diagonal / 128). `model` is a Geometry
or the path of an OBJ, OFF or PLY file; handles must be inside it (or within 2 voxels of its
surface). Outside the model a point takes its nearest inside voxel's distance, extrapolated.
Raises InvalidInput naming the handle or parameter at fault.)")
      .def(py::init([](py::object model, py::handle handles, double voxelSize) {
             const Points h = toPoints(handles, "handles", false);
             std::vector<Vec3> points(h.span.begin(), h.span.end());
             InsideDistanceOptions options;
             options.voxelSize = voxelSize;
             std::shared_ptr<InsideDistances> result;
             if (py::isinstance<PolygonSoup>(model)) {
               const PolygonSoup& soup = model.cast<const PolygonSoup&>();
               const InUse inUse(soup);
               withoutGil([&] {
                 result = std::make_shared<InsideDistances>(soup, std::move(points), options);
               });
             } else {
               const auto path = model.cast<std::filesystem::path>();
               withoutGil([&] {
                 const PolygonSoup soup = readSoup(path);
                 result = std::make_shared<InsideDistances>(soup, std::move(points), options);
               });
             }
             return result;
           }),
           "model"_a, "handles"_a, py::kw_only(), "voxel_size"_a = 0.0)
      .def_property_readonly("voxel_size", &InsideDistances::voxelSize,
                             "The voxel edge used, world units.")
      .def_property_readonly("grid_size", &InsideDistances::gridSize,
                             "The grid's voxel counts along x, y, z.");
#endif
}

}  // namespace spacewarp::python
