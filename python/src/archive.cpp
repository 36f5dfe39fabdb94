// Pickling: every spacewarp.Warp, Coordinates, HandleDistances and Cage reduces to a loader
// function and its archive bytes (rig/warp_archive.h), so it crosses processes (multiprocessing,
// Dask) with its solved state and gives bit-identical results there. Defined once on the base
// classes: pybind11 returns the most-derived registered class of what the loader builds.

#include <memory>
#include <string>
#include <string_view>

#include <spacewarp/rig/warp_archive.h>

#include "common.h"

namespace spacewarp::python {

namespace {

using namespace pybind11::literals;

// The bytes of any bytes-like `data` (bytes, bytearray, memoryview, a NumPy uint8 array: the
// buffer protocol, contiguous), viewed while this object lives.
class ByteView {
 public:
  explicit ByteView(py::handle data) {
    if (PyObject_GetBuffer(data.ptr(), &buffer_, PyBUF_SIMPLE) != 0) {
      PyErr_Clear();
      throw py::type_error(
          std::string("expected a bytes-like object (bytes, bytearray, memoryview, a contiguous "
                      "NumPy uint8 array), not ") +
          std::string(py::str(py::type::of(data).attr("__name__"))));
    }
  }
  ~ByteView() { PyBuffer_Release(&buffer_); }
  ByteView(const ByteView&) = delete;
  ByteView& operator=(const ByteView&) = delete;
  std::string_view bytes() const {
    return {static_cast<const char*>(buffer_.buf), static_cast<std::size_t>(buffer_.len)};
  }

 private:
  Py_buffer buffer_{};
};

template <class T>
py::bytes save(const T& object, std::string (*saveObject)(const T&)) {
  std::string bytes;
  withoutGil([&] { bytes = saveObject(object); });
  return py::bytes(bytes);
}

// The object archived in any bytes-like `data`, loaded by `loadObject` without the GIL.
template <class T>
std::shared_ptr<T> loadFrom(py::handle data,
                            std::shared_ptr<const T> (*loadObject)(std::string_view)) {
  const ByteView view(data);
  const std::string_view bytes = view.bytes();
  std::shared_ptr<const T> object;
  withoutGil([&] { object = loadObject(bytes); });
  return std::const_pointer_cast<T>(object);
}

std::shared_ptr<Warp> loadWarpFrom(py::handle data) { return loadFrom<Warp>(data, &loadWarp); }

std::shared_ptr<Coordinates> loadCoordinatesFrom(py::handle data) {
  return loadFrom<Coordinates>(data, &loadCoordinates);
}

std::shared_ptr<HandleDistances> loadDistancesFrom(py::handle data) {
  return loadFrom<HandleDistances>(data, &loadDistances);
}

// Refuses an instance of a class defined in Python (a subclass of a spacewarp class): the archive
// stores the spacewarp object only, so its class and attributes would be lost without a word.
void refusePythonSubclass(py::handle self, const char* method) {
  const py::handle type = py::type::of(self);
  if (py::str(type.attr("__module__")).cast<std::string>() == "spacewarp._spacewarp") return;
  std::string base = "a spacewarp class";
  for (const py::handle b : py::reinterpret_borrow<py::tuple>(type.attr("__mro__"))) {
    if (py::str(b.attr("__module__")).cast<std::string>() == "spacewarp._spacewarp") {
      base = "spacewarp." + py::str(b.attr("__name__")).cast<std::string>();
      break;
    }
  }
  const std::string name = py::str(type.attr("__qualname__"));
  throw py::type_error(std::string(method) + ": " + name + " is a Python subclass of " + base +
                       ", which is not supported (its class and attributes would be lost); " +
                       "define __reduce__ in " + name + " to pickle it");
}

// Adds __reduce__ and to_bytes to the already bound class `name`, reducing to the function
// `loader` of the package (spacewarp/__init__.py): a Python function, which pickle stores by
// name, where a pybind11 function would be pickled through its capsule.
template <class T>
void addPickling(py::module_& m, const char* name, std::string (*saveObject)(const T&),
                 const char* loader) {
  py::object cls = m.attr(name);
  cls.attr("__reduce__") = py::cpp_function(
      [saveObject, loader](py::handle self) {
        refusePythonSubclass(self, "__reduce__");
        return py::make_tuple(py::module_::import("spacewarp").attr(loader),
                              py::make_tuple(save(initialised<T>(self), saveObject)));
      },
      py::name("__reduce__"), py::is_method(cls),
      "For pickle: the loader and this object's archive bytes.");
  cls.attr("to_bytes") = py::cpp_function(
      [saveObject](py::handle self) {
        refusePythonSubclass(self, "to_bytes");
        return save(initialised<T>(self), saveObject);
      },
      py::name("to_bytes"), py::is_method(cls),
      R"(This object as archive bytes (rig/warp_archive.h): solved state included, so that
loading it solves nothing and gives bit-identical results. Raises InvalidInput for an object
that cannot be saved (one that holds something defined in Python), and TypeError for an
instance of a Python subclass (its class and attributes are not in the archive: define
__reduce__ in the subclass to pickle it).)");
}

}  // namespace

void bindArchive(py::module_& m) {
  m.def(
      "warp_from_bytes", &loadWarpFrom, "data"_a,
      R"(The warp saved in `data` (bytes from Warp.to_bytes(), or saveWarp() in C++; any bytes-like
object: bytes, bytearray, memoryview, a contiguous NumPy uint8 array), as its own
class. Nothing is solved again. Raises InvalidInput for bytes that are not a warp archive of this
version (naming the byte at fault).)");
  m.def("coordinates_from_bytes", &loadCoordinatesFrom, "data"_a,
        R"(The coordinates saved in `data` (bytes from Coordinates.to_bytes()), as their own class.
Nothing is solved again. Raises InvalidInput for bytes that are not a coordinates archive.)");
  addPickling<Warp>(m, "Warp", &saveWarp, "_load_warp");
  addPickling<Coordinates>(m, "Coordinates", &saveCoordinates, "_load_coordinates");
  m.def("distances_from_bytes", &loadDistancesFrom, "data"_a,
        R"(The HandleDistances saved in `data` (bytes from HandleDistances.to_bytes()), as their
own class (InsideDistances: its grid of distances, nothing marched again). Raises InvalidInput
for bytes that are not a distances archive.)");
  addPickling<HandleDistances>(m, "HandleDistances", &saveDistances, "_load_distances");
  m.def(
      "cage_from_bytes",
      [](py::handle data) {
        const ByteView view(data);
        const std::string_view bytes = view.bytes();
        std::shared_ptr<Cage> cage;
        withoutGil([&] { cage = std::make_shared<Cage>(loadCage(bytes)); });
        return cage;
      },
      "data"_a,
      R"(The Cage saved in `data` (bytes from Cage.to_bytes()), rebuilt from its polygons. Raises
InvalidInput for bytes that are not a cage archive.)");
  addPickling<Cage>(m, "Cage", &saveCage, "_load_cage");
}

}  // namespace spacewarp::python
