#!/usr/bin/env python3
"""Writes the type stubs python/spacewarp/{_spacewarp,__init__}.pyi from the built extension.

    PYTHONPATH=build/python /usr/bin/python3 python/tools/make_stubs.py [--check]

The signatures come from the pybind11 docstrings of the built module (their first line), the
documentation from the rest of each docstring. pybind11 only knows C++ types, so the arguments
it calls `handle` or `object` (array-likes, 3-vectors, callbacks) and the results it calls
`object`, `tuple` or `list` get their Python types from the tables below. A name the tables
should cover but do not is an error, so a new binding cannot slip into the stubs as `Any`
unnoticed. --check compares the file with what would be written (exit 1 when it differs).

__init__.pyi re-exports the extension's names, __version__ and `testing`: the package's __all__.
"""

from __future__ import annotations

import argparse
import ast
import inspect
import math
import re
import sys
import textwrap
from pathlib import Path
from typing import Optional

import spacewarp._spacewarp as ext

PACKAGE = Path(__file__).resolve().parent.parent / "spacewarp"

PACKAGE_HEADER = '''"""Type stubs of the spacewarp package, written by python/tools/make_stubs.py:
the extension's API (_spacewarp.pyi) and the property kit spacewarp.testing (typed inline)."""

from . import testing as testing
from ._spacewarp import *
from ._spacewarp import __version__ as __version__
'''

HEADER = '''"""Type stubs of spacewarp._spacewarp, written by python/tools/make_stubs.py from the
built module's pybind11 signatures and docstrings. Do not edit: run the generator."""

import os
from typing import Any, Callable, Literal, Optional, Sequence, Union

import numpy as np
from numpy.typing import ArrayLike, NDArray

_Float64Array = NDArray[np.float64]
_Points = ArrayLike
"""(n, 3) array-like of numbers (any float dtype and layout), world units."""
_Vec3 = Union[Sequence[float], NDArray[np.floating[Any]]]
"""Three numbers (x, y, z)."""
_Faces = Union[NDArray[np.integer[Any]], Sequence[Sequence[int]]]
"""An (m, k) integer array, or a sequence of polygons (index sequences of any length)."""
_Progress = Optional[Callable[[str, float], Optional[bool]]]
"""callable(stage, fraction in [0, 1]); returning False cancels (spacewarp.Cancelled)."""
_Path = Union[str, os.PathLike[str]]
_Kernel = Literal["triharmonic", "biharmonic", "thin-plate", "gaussian", "inverse-multiquadric",
                  "wendland"]
_Basis = Literal["trilinear", "bernstein", "bspline"]
_Sampler = Literal["trilinear", "triquadratic"]
_Dtype = Literal["int8", "uint8", "int16", "uint16", "int32", "uint32", "float32", "float64"]
'''

# Arguments pybind11 shows as `handle` / `Optional[handle]` / `object`, by name.
HANDLE_ARGS = {
    # Viewer.__exit__: the context manager protocol's exception triple
    "exc_type": "Any",
    "exc": "Any",
    "traceback": "Any",
    "origin": "_Vec3",
    "axis": "_Vec3",
    "direction": "_Vec3",
    "extents": "_Vec3",
    "point": "_Vec3",
    "center": "_Vec3",
    "displacement": "_Vec3",
    "faces": "_Faces",
    "data": "bytes | bytearray | memoryview | NDArray[np.uint8]",  # any bytes-like object
    "matrix": "ArrayLike",
    "values": "ArrayLike",
    "axes": "ArrayLike",
    "triangles": "ArrayLike",
    "constrained": "ArrayLike",
    "bones": "ArrayLike",
}
POINT_ARGS = {"points", "posed", "normals", "positions", "handles", "targets", "centers", "fixed",
              "nodes", "samples", "vertices", "from_points", "to_points", "rest", "start",
              "start_control_points", "mesh_positions"}

# Types by qualified name ("Class.member.argument", "Class.member.return", "function.return",
# "Class.property", "Class.property.set") where the pybind11 signature says too little.
OVERRIDES = {
    "Warp.inverse.return": "tuple[_Float64Array, Any, Any]",
    # a py::object so that a bool can be refused (pybind11's float would take True as 1)
    "Harmonic.__init__.precision": "float",
    "cage_coordinates.precision": "float",
    "Warp.exact_inverse.return": "Optional[_Float64Array]",
    "Warp.__call__.out": "Optional[_Float64Array]",
    "Binding.deform.out": "Optional[_Float64Array]",
    "Cage.contains.return": "NDArray[np.bool_]",
    "Coordinates.sparse_weights.return": "Any",
    "Binding.weights": "Any",
    "InsideDistances.__init__.model": "Union[Geometry, _Path]",
    "InsideDistances.grid_size": "list[int]",
    "Mls.__init__.distances": "Optional[HandleDistances]",
    "Geometry.__init__.faces": "Optional[_Faces]",
    "Geometry.__init__.normals": "Optional[_Points]",
    "Geometry.normals": "Optional[_Float64Array]",
    "Geometry.normals.set": "Optional[_Points]",
    "Geometry.faces": "Union[NDArray[np.uint32], list[NDArray[np.uint32]]]",
    "Geometry.faces.set": "Optional[_Faces]",
    "Geometry.positions.set": "_Points",
    "Geometry.vertex_attributes": "dict[str, _Float64Array]",
    "Geometry.face_attributes": "dict[str, _Float64Array]",
    "Lattice.fit.return": "tuple[_Float64Array, float, float]",
    "Lattice.__init__.resolution": "Sequence[int]",
    "Lattice.around.resolution": "Sequence[int]",
    "Lattice.resolution": "list[int]",
    "Compose.__init__.*args": "*warps: Warp",
    "coordinate_properties.cage": "Optional[Cage]",
    "coordinate_properties.return": "dict[str, float]",
    "rig.description": "dict[str, Any]",
    "warp_dense.values": "NDArray[Any]",
    "warp_dense.return": "tuple[NDArray[Any], _Float64Array]",
    "warp_volume.return": "list[dict[str, Any]]",
    "cotan_laplacian.return": "Any",
    "resolve_handles.regions": "Sequence[dict[str, Any]]",
    "load_handles.path": "_Path",
    "load_handles.return": "list[dict[str, NDArray[Any]]]",
    "resolve_handles.return": "tuple[NDArray[np.uint32], _Float64Array]",
    "edit.handles": "Sequence[dict[str, Any]]",
    "edit.coordinates": "Optional[Coordinates]",
    "Skinning.__init__.weights": "Optional[ArrayLike]",
    "Skinning.__init__.model": "Optional[_Points]",
    "Skinning.__init__.coordinates": "Optional[Coordinates]",
    "SkinningBinding.__init__.weights": "Union[ArrayLike, Coordinates]",
    "SkinningBinding.deform.out": "Optional[_Float64Array]",
    "SkinningBinding.influences": "tuple[NDArray[np.uint32], _Float64Array]",
}

# String options: their accepted values (checked in C++; a Literal lets editors complete them).
for _where in ("RbfWarp.__init__", "Rbf.__init__"):
    OVERRIDES[f"{_where}.kernel"] = "_Kernel"
for _where in ("Lattice.__init__", "Lattice.around"):
    OVERRIDES[f"{_where}.basis"] = "_Basis"
for _where in ("warp_dense", "warp_volume"):
    OVERRIDES[f"{_where}.sampler"] = "_Sampler"
for _where in ("Geometry.set_vertex_attribute", "Geometry.set_face_attribute"):
    OVERRIDES[f"{_where}.dtype"] = "_Dtype"
OVERRIDES.update({
    "Mls.__init__.mode": 'Literal["rigid", "similarity", "affine"]',
    "Wire.__init__.deformed": "_Points",
    "Wires.__init__.wires": "Sequence[Wire]",
    "Wires.wires": "list[Wire]",
    "Wire.__init__.dropoff": 'Literal["smooth", "linear"]',
    "Wire.__init__.curve": 'Literal["polyline", "catmull-rom"]',
    "DeformationGraph.__init__.sampling": 'Literal["voxel", "poisson"]',
    "Lattice.__init__.outside": 'Literal["identity", "clamp", "falloff"]',
    "Harmonic.__init__.outside": 'Literal["raise", "nearest"]',
    "Wachspress.__init__.outside": 'Literal["raise", "nearest"]',
    "DiscreteHarmonic.__init__.outside": 'Literal["raise", "nearest"]',
    "Cage.faces.return": "list[NDArray[np.uint32]]",
    "cage_coordinates.outside": 'Literal["raise", "nearest"]',
    "warp_volume.vectors": 'Literal["auto", "push", "normal", "keep"]',
    "warp_volume.redistance": 'Literal["normalize", "rebuild", "none"]',
    "LinearEditor.__init__.method": 'Literal["laplacian", "bilaplacian"]',
    "edit.method": 'Literal["laplacian", "bilaplacian", "arap", "cage-arap"]',
    "Warp.__reduce__.return": "tuple[Any, tuple[bytes]]",
    "Coordinates.__reduce__.return": "tuple[Any, tuple[bytes]]",
    "Cage.__reduce__.return": "tuple[Any, tuple[bytes]]",
    "HandleDistances.__reduce__.return": "tuple[Any, tuple[bytes]]",
    "SkinningBinding.__getstate__.return":
        "tuple[_Float64Array, tuple[NDArray[np.uint32], _Float64Array], int]",
    "SkinningBinding.__setstate__.arg0": "tuple[Any, ...]",
})

# spacewarp.dask's brick functions (python/src/volume_bricks.cpp).
OVERRIDES.update({
    "VolumeBrickPlan.bricks": "list[tuple[Any, ...]]",
    "VolumeBrickPlan.merge.return": "list[dict[str, Any]]",
    "VolumeBrickPlan.merge.results": "list[VolumeBrickResult]",
    "VolumeBrickResult.__getstate__.return": "tuple[Any, ...]",
    "VolumeBrickResult.__setstate__.arg0": "tuple[Any, ...]",
    "warp_volume_brick.brick": "tuple[Any, ...]",
})
for _where in ("plan_volume_bricks", "warp_volume_brick"):
    OVERRIDES[f"{_where}.sampler"] = "_Sampler"
    OVERRIDES[f"{_where}.vectors"] = OVERRIDES["warp_volume.vectors"]
    OVERRIDES[f"{_where}.redistance"] = OVERRIDES["warp_volume.redistance"]

USED: set[str] = set()  # the OVERRIDES keys the module still has (an unused one is an error)


def override(key: str) -> Optional[str]:
    if key in OVERRIDES:
        USED.add(key)
        return OVERRIDES[key]
    return None


# Module attributes that are not functions or classes.
VALUES = {"__version__": "str", "has_volumes": "bool"}

# pybind11's names for types -> stub types.
SIMPLE = {
    "None": "None",
    "int": "int",
    "float": "float",
    "bool": "bool",
    "str": "str",
    "bytes": "bytes",
    "dict": "dict[str, Any]",
    "os.PathLike": "_Path",
    "numpy.ndarray[numpy.float64]": "_Float64Array",
    "numpy.ndarray[numpy.uint32]": "NDArray[np.uint32]",
    "List[str]": "list[str]",
    "List[int]": "list[int]",
    "List[float]": "list[float]",
    "List[os.PathLike]": "list[_Path]",
}


class StubError(Exception):
    pass


def translate(pybind: str, where: str, name: Optional[str] = None) -> str:
    """The stub type of a pybind11 type string, for the argument `name` (None: a result)."""
    key = f"{where}.{name}" if name else f"{where}.return"
    if override(key):
        return OVERRIDES[key]
    pybind = pybind.strip()
    optional = re.fullmatch(r"Optional\[(.*)\]", pybind)
    if optional:
        return f"Optional[{translate(optional.group(1), where + '#', name)}]"
    if pybind in SIMPLE:
        return SIMPLE[pybind]
    named = re.fullmatch(r"(?:spacewarp\._spacewarp\.|spacewarp::)(\w+)", pybind)
    if named and hasattr(ext, named.group(1)):
        return named.group(1)
    if name is not None and pybind == "handle":
        if name in HANDLE_ARGS:
            return HANDLE_ARGS[name]
        if name in POINT_ARGS:
            return "_Points"
    if name == "progress" and pybind == "object":
        return "_Progress"
    raise StubError(f"{key}: no stub type for pybind11's {pybind!r}; add it to the tables")


def split_top(text: str) -> list[str]:
    """`text` split at the commas outside brackets and quotes."""
    parts, depth, quote, start = [], 0, None, 0
    for i, ch in enumerate(text):
        if quote:
            if ch == quote:
                quote = None
        elif ch in "'\"":
            quote = ch
        elif ch in "([{":
            depth += 1
        elif ch in ")]}":
            depth -= 1
        elif ch == "," and depth == 0:
            parts.append(text[start:i].strip())
            start = i + 1
    if text[start:].strip():
        parts.append(text[start:].strip())
    return parts


def parse_signature(line: str) -> tuple[str, list[str], str]:
    """(name, [argument texts], return type) of a pybind11 signature line."""
    match = re.fullmatch(r"(\w+)\((.*)\) -> (.*)", line.strip())
    if not match:
        raise StubError(f"not a pybind11 signature: {line!r}")
    return match.group(1), split_top(match.group(2)), match.group(3)


def stub_default(text: str) -> str:
    """A default as stubs show it: simple literals (numbers, strings, bools, None) as they are,
    anything else (tuples, inf) as `...`."""
    try:
        value = ast.literal_eval(text)
    except (ValueError, SyntaxError):
        return "..."
    if isinstance(value, str) and '"' not in value and "\\" not in value:
        return f'"{value}"'
    if value is None or isinstance(value, bool):
        return repr(value)
    if isinstance(value, (int, float)) and math.isfinite(value):
        return repr(value)
    return "..."


def stub_args(args: list[str], where: str, method: bool) -> str:
    out = []
    for i, arg in enumerate(args):
        if method and i == 0:
            out.append("self")
            continue
        if arg in ("*", "/"):
            out.append(arg)
            continue
        if arg.startswith("*"):
            key = f"{where}.{arg.split(':')[0]}"
            variadic = override(key)
            if variadic is None:
                raise StubError(f"{key}: variadic argument needs an override")
            out.append(variadic)
            continue
        head, _, default = arg.partition(" = ")
        name, _, pybind = head.partition(": ")
        text = f"{name}: {translate(pybind, where, name)}"
        out.append(text + (f" = {stub_default(default)}" if default else ""))
    return ", ".join(out)


def doc_body(doc: Optional[str], lines_of_signature: int = 1) -> str:
    """A docstring without pybind11's signature line(s)."""
    if not doc:
        return ""
    lines = doc.strip("\n").split("\n")[lines_of_signature:]
    return "\n".join(lines).strip()


WIDTH = 100


def docstring(text: str, indent: str) -> list[str]:
    if not text:
        return []
    if "\n" not in text and len(indent) + len(text) + 6 > WIDTH:
        text = textwrap.fill(text, WIDTH - len(indent) - 6)
    text = text.replace("\\", "\\\\").replace('"""', '\\"\\"\\"')
    lines = text.split("\n")
    if len(lines) == 1:
        return [f'{indent}"""{text}"""']
    return [f'{indent}"""{lines[0]}'] + [(indent + l) if l else "" for l in lines[1:]] + \
        [f'{indent}"""']


def function_stub(obj: object, where: str, indent: str, method: bool,
                  static: bool = False) -> list[str]:
    doc = obj.__doc__ or ""
    lines = doc.strip("\n").split("\n")
    if lines and lines[0].endswith("Overloaded function."):
        raise StubError(f"{where}: overloads are not handled yet")
    name, args, ret = parse_signature(lines[0])
    out = [f"{indent}@staticmethod"] if static else []
    arguments = stub_args(args, where, method)
    result = translate(ret, where)
    signature = f"{indent}def {name}({arguments}) -> {result}:"
    if len(signature) + 4 > WIDTH:  # one argument a line
        listed = "".join(f"{indent}    {a},\n" for a in split_top(arguments))
        signature = f"{indent}def {name}(\n{listed}{indent}) -> {result}:"
    body = docstring(doc_body(doc), indent + "    ")
    if body:
        out += [signature] + body
    else:
        out.append(signature + " ...")
    return out


def property_stub(cls: type, name: str, prop: property, indent: str) -> list[str]:
    where = f"{cls.__name__}.{name}"
    getter_doc = prop.fget.__doc__ or ""
    first = getter_doc.strip("\n").split("\n")[0]
    match = re.fullmatch(r"\((?:arg0|self): [\w.:]+\) -> (.*)", first.strip())
    if not match:
        raise StubError(f"{where}: unexpected property signature {first!r}")
    kind = override(where) or translate(match.group(1), where)
    out = [f"{indent}@property"]
    own = prop.__doc__ if prop.__doc__ != getter_doc else doc_body(getter_doc)
    body = docstring(inspect.cleandoc(own or ""), indent + "    ")
    out += [f"{indent}def {name}(self) -> {kind}:"] + body if body else \
        [f"{indent}def {name}(self) -> {kind}: ..."]
    if prop.fset is not None:
        accepted = override(f"{where}.set")
        if accepted is None:
            raise StubError(f"{where}.set: a settable property needs the type it accepts")
        out += [f"{indent}@{name}.setter",
                f"{indent}def {name}(self, value: {accepted}) -> None: ..."]
    return out


def class_stub(cls: type) -> list[str]:
    bases = [b.__name__ for b in cls.__bases__ if b.__name__ != "pybind11_object"]
    head = f"class {cls.__name__}({', '.join(bases)}):" if bases else f"class {cls.__name__}:"
    out = [head] + docstring(inspect.cleandoc(cls.__doc__ or ""), "    ")
    if issubclass(cls, BaseException):
        return out if len(out) > 1 else [head + " ..."]
    members = []
    for name, value in cls.__dict__.items():
        if name in ("__doc__", "__module__", "__dict__", "__weakref__"):
            continue
        if isinstance(value, property):
            members.append(property_stub(cls, name, value, "    "))
        elif isinstance(value, staticmethod):
            members.append(function_stub(getattr(cls, name), f"{cls.__name__}.{name}", "    ",
                                         method=False, static=True))
        elif name == "__init__" and "Initialize self" in (getattr(cls, name).__doc__ or ""):
            continue  # no constructor: made by the library (Binding, DeformationGraphWarp, ...)
        elif callable(value):
            members.append(function_stub(getattr(cls, name), f"{cls.__name__}.{name}", "    ",
                                         method=True))
        else:
            raise StubError(f"{cls.__name__}.{name}: unexpected class attribute {value!r}")
    for member in members:
        out += [""] + member
    if len(out) == 1:
        out.append("    ...")
    return out


def class_order(names: list[str]) -> list[str]:
    """Classes with their bases first (exceptions first of all), else alphabetical."""
    classes = [n for n in names if inspect.isclass(getattr(ext, n))]
    done: list[str] = []

    def visit(name: str) -> None:
        if name in done:
            return
        for base in getattr(ext, name).__bases__:
            if base.__name__ in classes:
                visit(base.__name__)
        done.append(name)

    errors = sorted(n for n in classes if issubclass(getattr(ext, n), BaseException))
    for name in errors + sorted(classes):
        visit(name)
    return done


def generate_package() -> str:
    # The extension's names come from its own stub's __all__ (type checkers follow `+=` of a
    # submodule's __all__), so the list is written once.
    return (PACKAGE_HEADER + "from . import _spacewarp as _spacewarp\n\n"
            + '__all__ = ["__version__", "testing"]\n'
            + "__all__ += _spacewarp.__all__\n")


def generate() -> str:
    names = [n for n in dir(ext) if not n.startswith("_") or n in VALUES]
    out = [HEADER.rstrip("\n"), ""]
    public = sorted(n for n in names if not n.startswith("_"))
    out.append("__all__ = [")
    out += [f'    "{n}",' for n in public]
    out += ["]", ""]
    for name in sorted(VALUES):
        if not hasattr(ext, name):
            raise StubError(f"{name}: listed in VALUES but not in the module")
        out.append(f"{name}: {VALUES[name]}")
    for name in class_order(names):
        out += ["", ""] + class_stub(getattr(ext, name))
    for name in sorted(names):
        value = getattr(ext, name)
        if inspect.isclass(value) or name in VALUES:
            continue
        if not callable(value):
            raise StubError(f"{name}: a module value not listed in VALUES")
        out += ["", ""] + function_stub(value, name, "", method=False)
    unused = sorted(set(OVERRIDES) - USED)
    if unused:
        raise StubError(f"overrides for names the module no longer has: {', '.join(unused)}")
    return "\n".join(out) + "\n"


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--check", action="store_true",
                        help="only compare with the stub file; exit 1 when it differs")
    parser.add_argument("-o", "--output-dir", type=Path, default=PACKAGE,
                        help="where to write the .pyi files (default: python/spacewarp)")
    options = parser.parse_args()
    try:
        files = {"_spacewarp.pyi": generate(), "__init__.pyi": generate_package()}
    except StubError as error:
        print(f"make_stubs: {error}", file=sys.stderr)
        return 2
    stale = 0
    for name, text in files.items():
        path = options.output_dir / name
        if options.check:
            if not path.exists() or path.read_text() != text:
                print(f"make_stubs: {path} is out of date; run {sys.argv[0]}", file=sys.stderr)
                stale = 1
            continue
        path.write_text(text)
        print(f"wrote {path}")
    return stale


if __name__ == "__main__":
    sys.exit(main())
