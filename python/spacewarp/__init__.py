"""spacewarp: space deformations and cage coordinates, from NumPy.

Every deformation is a :class:`Warp` (a map x -> x' of 3D space, world units) that applies to
``(n, 3)`` float64 arrays, :class:`Geometry` (polygon soups and point clouds read from OBJ, OFF and
PLY files) and OpenVDB volumes (:func:`warp_volume`). Coordinate functions (:class:`MeanValue`,
:class:`Green`, :class:`Harmonic`, :class:`Lattice`, :class:`Rbf`) give weight matrices and bind
point sets. The computations run in C++ with the GIL released; Ctrl-C cancels long ones.

    import numpy as np, spacewarp
    twist = spacewarp.Twist(axis=(0, 0, 1), rate=0.5)
    moved = twist(np.random.rand(1000, 3))

Surface editing moves a mesh by handle regions (:func:`edit`, :class:`LinearEditor`,
:class:`ArapEditor`, :class:`CageArapEditor` over a :func:`weld_soup` mesh; :func:`load_handles`
reads the CLI's handles files). :mod:`spacewarp.testing` holds the property kit for any
library's weights.
"""

import sys as _sys
import warnings as _warnings

if "pyopenvdb" in _sys.modules:
    # libopenvdb binds its chunk readers when it is loaded: loaded by pyopenvdb, they are not
    # spacewarp's size-checked ones, and warp_volume then refuses to read files.
    _warnings.warn("spacewarp was imported after pyopenvdb: warp_volume cannot read VDB files safely in "
                   "this process (import spacewarp first)", stacklevel=2)

from ._spacewarp import *  # noqa: F401,F403,E402  (the bindings are the API)
from ._spacewarp import __version__  # noqa: F401,E402

from . import _spacewarp as _ext  # noqa: E402
__all__ = [name for name in dir(_ext) if not name.startswith("_")] + ["__version__", "testing"]


def _load_warp(data: bytes):
    """The loader of pickled warps (Warp.__reduce__): warp_from_bytes, by a name pickle stores."""
    return warp_from_bytes(data)  # noqa: F405


def _load_coordinates(data: bytes):
    """The loader of pickled coordinates (Coordinates.__reduce__)."""
    return coordinates_from_bytes(data)  # noqa: F405


def _load_distances(data: bytes):
    """The loader of pickled handle distances (HandleDistances.__reduce__)."""
    return distances_from_bytes(data)  # noqa: F405


def _load_cage(data: bytes):
    """The loader of pickled cages (Cage.__reduce__)."""
    return cage_from_bytes(data)  # noqa: F405


def __getattr__(name: str):
    # spacewarp.testing on first use, so `import spacewarp` stays cheap.
    if name == "testing":
        import importlib

        return importlib.import_module(".testing", __name__)
    raise AttributeError(f"module 'spacewarp' has no attribute {name!r}")
