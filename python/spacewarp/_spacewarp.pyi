"""Type stubs of spacewarp._spacewarp, written by python/tools/make_stubs.py from the
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

__all__ = [
    "Affine",
    "ArapEditor",
    "ArapReport",
    "ArapResult",
    "Bend",
    "Binding",
    "Cage",
    "CageArapEditor",
    "CageArapReport",
    "CageArapResult",
    "Cancelled",
    "Compose",
    "Coordinates",
    "DeformationGraph",
    "DeformationGraphWarp",
    "DiscreteHarmonic",
    "Geometry",
    "GraphSolveReport",
    "Green",
    "HandleDistances",
    "Harmonic",
    "Identity",
    "InsideDistances",
    "InvalidInput",
    "IoError",
    "Kelvinlet",
    "Lattice",
    "LinearEditor",
    "MeanValue",
    "MeshReport",
    "Mls",
    "MlsAffine",
    "OutOfMemory",
    "QuadGreen",
    "QuadMeanValue",
    "Rbf",
    "RbfWarp",
    "Shepard",
    "Skinning",
    "SkinningBinding",
    "SolverError",
    "SurfaceMesh",
    "Taper",
    "Twist",
    "Viewer",
    "VolumeBrickPlan",
    "VolumeBrickResult",
    "Wachspress",
    "Warp",
    "Wire",
    "Wires",
    "assemble_ply",
    "cage_coordinates",
    "cage_from_bytes",
    "cage_methods",
    "coordinate_properties",
    "coordinates_from_bytes",
    "cotan_laplacian",
    "deform",
    "deform_file",
    "deform_inverse",
    "deform_ply_rows",
    "distances_from_bytes",
    "edit",
    "has_volumes",
    "interior_samples",
    "load_handles",
    "load_rig",
    "mass_matrix_diagonal",
    "plan_volume_bricks",
    "ply_layout",
    "read",
    "resolve_handles",
    "rig",
    "rig_methods",
    "view",
    "warp_dense",
    "warp_from_bytes",
    "warp_volume",
    "warp_volume_brick",
    "weld_soup",
    "write",
]

__version__: str
has_volumes: bool


class Cancelled(RuntimeError):
    """Work stopped because a progress callback returned False. Nothing was written."""


class InvalidInput(ValueError):
    """Input that violates a documented precondition: NaN coordinates, an empty set, an open
    cage, a degenerate lattice, a malformed rig. A ValueError.
    """


class IoError(OSError):
    """A file that could not be read or written, or whose content is malformed; the message names
    the file. An OSError.
    """


class SolverError(RuntimeError):
    """A numerical method that produced no result: a singular system, a failed factorisation, an
    inverse that did not converge. A RuntimeError.
    """


class OutOfMemory(SolverError, MemoryError):
    """Memory that ran out inside TetGen or CHOLMOD (which report it by a status code). A
    SolverError and a MemoryError. (A job that its memory estimate refuses before it starts is
    InvalidInput, naming what to make smaller.)
    """


class Warp:
    """A map x -> x' of 3D space (world units).

    Every warp in spacewarp is one: call it on points, ask for its Jacobian, invert it, carry normals.
    Methods release the GIL and are safe to call from several threads at once.
    """

    def __call__(
        self,
        points: _Points,
        *,
        out: Optional[_Float64Array] = None,
        progress: _Progress = None,
    ) -> _Float64Array:
        """The warped positions of `points`: (n, 3) float64 (or one (3,) point), world units.

        points: (n, 3) array-like, any float dtype and layout (copied only if not float64 C-order).
        out: optional (n, 3) float64 C-contiguous array to write into (may be `points` itself).
        progress: optional callable(stage: str, fraction: float); return False to cancel.
        Returns a new (n, 3) array, or `out`. Raises InvalidInput for non-finite points or points
        outside the warp's domain (naming the first); `out`, if given, may then be partly written.
        """

    def jacobian(self, points: _Points) -> _Float64Array:
        """The Jacobians d x'/d x at `points`: (n, 3, 3) float64, J[i, r, c] = d x'_r / d x_c
        (unitless). Analytic where the warp has one, central differences otherwise.
        """

    def transform_normals(self, points: _Points, normals: _Points) -> _Float64Array:
        """The normals `normals` (n, 3) at `points` (n, 3) carried through the warp: J^-T n,
        normalised; (n, 3) float64. Where J is singular: the image plane's normal (rank 2) or zero.
        """

    def inverse(
        self,
        points: _Points,
        *,
        tolerance: float = 1e-12,
        max_iterations: int = 50,
        length_scale: float = 0.0,
        continuation: bool = True,
        closed_form: bool = True,
        progress: _Progress = None,
    ) -> tuple[_Float64Array, Any, Any]:
        """The preimages x of `points` y (n, 3): warp(x) = y.

        Returns (x, converged, residual): x (n, 3) float64 world units, converged (n,) bool, residual
        (n,) float64 = |warp(x) - y| in world units. Converged when the residual is at most
        tolerance * length_scale (world units) if length_scale > 0, else tolerance relative to |y|.
        Closed forms where the warp has one (twist, bend, taper, affine and their compositions), else
        damped Newton with a continuation fallback (max_iterations each). Never raises for points that
        did not converge: check `converged`. Parallel; results do not depend on the thread count.
        """

    def exact_inverse(self, point: _Vec3) -> Optional[_Float64Array]:
        """The closed-form preimage of one point (3,), or None when the warp has none there."""

    def __reduce__(self) -> tuple[Any, tuple[bytes]]:
        """For pickle: the loader and this object's archive bytes."""

    def to_bytes(self) -> bytes:
        """This object as archive bytes (rig/warp_archive.h): solved state included, so that
        loading it solves nothing and gives bit-identical results. Raises InvalidInput for an object
        that cannot be saved (one that holds something defined in Python), and TypeError for an
        instance of a Python subclass (its class and attributes are not in the archive: define
        __reduce__ in the subclass to pickle it).
        """


class Affine(Warp):
    """x' = A x + t, from a (4, 4) homogeneous matrix (last row 0 0 0 1), a (3, 4) [A | t] or a
    (3, 3) A.
    """

    def __init__(self, matrix: ArrayLike) -> None: ...

    @property
    def matrix(self) -> _Float64Array:
        """The (4, 4) homogeneous matrix."""


class ArapEditor:
    """Prefactorised as-rigid-as-possible surface editing (Sorkine and Alexa 2007) of the mesh
    positions (n, 3), triangles (t, 3) with the vertices `constrained` (k,) as handles: one rotation
    per vertex acting on the edges of its triangles (energy "spokes_and_rims", Chao et al. 2010, the
    default: bounded below with obtuse triangles) or on its one-ring edges only ("spokes", the
    paper's), cotangent weights; at most max_iterations local/global iterations per solve, stopping
    when one lowers the energy by less than relative_tolerance of it (0: always max_iterations),
    with Anderson acceleration over the last acceleration_window iterations (0: none; an accelerated
    step is kept only when it lowers the energy).
    Components no handle reaches stay at rest (held_vertices).
    """

    def __init__(
        self,
        positions: _Points,
        triangles: ArrayLike,
        constrained: ArrayLike,
        *,
        energy: str = "spokes_and_rims",
        max_iterations: int = 200,
        relative_tolerance: float = 1e-06,
        acceleration_window: int = 5,
    ) -> None: ...

    def solve(self, targets: _Points, *, progress: _Progress = None) -> ArapResult:
        """Solves for the constrained vertices at `targets` (k, 3), constructor order, world
        units, starting from the Laplacian-editing solution or the handles' rigid motion (the lower
        energy). Returns an ArapResult. Reports stage "arap".
        """

    def solve_from(
        self,
        start: _Points,
        targets: _Points,
        *,
        progress: _Progress = None,
    ) -> ArapResult:
        """As solve(), continuing from `start` (n, 3), e.g. the previous frame's positions."""

    def energy(self, positions: _Points) -> float:
        """The ARAP energy of `positions` (n, 3) with its optimal rotations, world units squared."""

    @property
    def held_vertices(self) -> NDArray[np.uint32]:
        """(h,) uint32: vertices kept at rest because no handle reaches their component."""


class ArapReport:
    """What one ArapEditor solve did."""

    @property
    def energies(self) -> _Float64Array:
        """(iterations + 1,) float64: the energy at the start and after each iteration, non-
        increasing, world units squared.
        """

    @property
    def iterations(self) -> int:
        """Local/global iterations run."""

    @property
    def converged(self) -> bool:
        """Whether the relative decrease fell below relative_tolerance before max_iterations."""

    @property
    def started_rigid(self) -> bool:
        """Whether the solve started from the handles' common rigid motion (then a rigid motion
        of all handles is reproduced exactly).
        """


class ArapResult:
    """The result of an ArapEditor solve."""

    @property
    def positions(self) -> _Float64Array:
        """(n, 3) float64, all vertices, world units (read-only)."""

    @property
    def report(self) -> ArapReport:
        """The ArapReport."""


class Bend(Warp):
    """Bends the axis (through origin) into a circular arc towards `direction`: curvature
    `rate` (1 / world units), the bent part limited to lo <= y <= hi along the axis.
    """

    def __init__(
        self,
        *,
        origin: _Vec3 = ...,
        axis: _Vec3 = ...,
        direction: _Vec3 = ...,
        rate: float = 0.0,
        lo: float = ...,
        hi: float = ...,
    ) -> None: ...


class Binding:
    """The weights of a fixed point set, computed once (Coordinates.bind): deform() re-poses
    the points by one matrix product. Weights are stored dense or sparse (CSR) as the coordinates
    suit; `weights` shows them without a copy.
    """

    def deform(self, posed: _Points, *, out: Optional[_Float64Array] = None) -> _Float64Array:
        """The bound points deformed by the posed control points `posed` (V, 3): (n, 3)
        float64, world units, a new array (or `out`).
        """

    @property
    def point_count(self) -> int:
        """Points bound (n)."""

    @property
    def column_count(self) -> int:
        """Columns of the weight matrix."""

    @property
    def is_sparse(self) -> bool:
        """Whether the weights are stored sparse (CSR): at most a quarter of the columns non-zero
        per point.
        """

    @property
    def rest_points(self) -> _Float64Array:
        """The points as bound (n, 3)."""

    @property
    def weights(self) -> Any:
        """The weight matrix (n, columns): a read-only view of the binding's own dense matrix,
        or a scipy.sparse.csr_matrix over its CSR arrays when is_sparse (needs SciPy).
        """


class Cage:
    """A closed, outward-oriented cage: vertices (V, 3) world units and polygons (an (F, k)
    integer array, or a list of index lists for mixed sizes). The polygons are kept (faces) for
    QuadMeanValue, QuadGreen, Wachspress and DiscreteHarmonic, and triangulated (triangles) for
    MeanValue, Green and Harmonic.
    Raises InvalidInput naming the element for an open, non-manifold or degenerate cage.
    """

    def __init__(self, vertices: _Points, faces: _Faces, *, name: str = "cage") -> None: ...

    @staticmethod
    def from_file(path: _Path) -> Cage:
        """A cage read from an OBJ, OFF or PLY file."""

    @property
    def vertices(self) -> _Float64Array:
        """(V, 3) float64, world units."""

    @property
    def triangles(self) -> NDArray[np.uint32]:
        """(T, 3) uint32 vertex indices, outward oriented."""

    @property
    def triangle_source(self) -> NDArray[np.uint32]:
        """(T,) the input polygon each triangle was cut from."""

    @property
    def face_count(self) -> int:
        """Faces (input polygons), F."""

    @property
    def faces(self) -> list[NDArray[np.uint32]]:
        """The F faces as the polygons they were given as, outward (counter-clockwise seen from
        outside, first vertex kept): a list of (k,) uint32 vertex-index arrays.
        """

    @property
    def face_offsets(self) -> NDArray[np.uint32]:
        """(F + 1,) uint32: face f is face_indices[face_offsets[f]:face_offsets[f + 1]]."""

    @property
    def face_indices(self) -> NDArray[np.uint32]:
        """uint32 vertex indices of every face in turn (see face_offsets)."""

    @property
    def max_face_size(self) -> int:
        """The most vertices of a face: 3 for a triangle cage, 4 with quads."""

    @property
    def diagonal(self) -> float:
        """Bounding-box diagonal, world units."""

    @property
    def volume(self) -> float:
        """Enclosed volume, world units^3."""

    @property
    def reoriented_count(self) -> int:
        """Faces (input polygons) reversed for a consistent outward orientation."""

    def winding_number(self, points: _Points) -> _Float64Array:
        """The generalised winding number (n,) at points (n, 3): 1 inside, 0 outside."""

    def contains(self, points: _Points) -> NDArray[np.bool_]:
        """(n,) bool: whether each point is strictly inside."""

    def posed_vertices(self, path: _Path) -> _Float64Array:
        """The vertices (V, 3) of a posed cage file, checked against this cage."""

    def __reduce__(self) -> tuple[Any, tuple[bytes]]:
        """For pickle: the loader and this object's archive bytes."""

    def to_bytes(self) -> bytes:
        """This object as archive bytes (rig/warp_archive.h): solved state included, so that
        loading it solves nothing and gives bit-identical results. Raises InvalidInput for an object
        that cannot be saved (one that holds something defined in Python), and TypeError for an
        instance of a Python subclass (its class and attributes are not in the archive: define
        __reduce__ in the subclass to pickle it).
        """


class CageArapEditor:
    """ARAP in a cage's subspace (Huang et al. 2006): the unknowns are the control points of
    `coordinates` (MeanValue, Green, Harmonic, Lattice, Rbf, ... weighing every vertex of the mesh
    positions (n, 3), triangles (t, 3)); the model follows through its binding, and the energy is
    its ARAP energy (`energy` as ArapEditor's) with one rotation per cluster of vertices (rotation_clusters; 0: 4 per control
    point, at least 64, at most n) plus soft handle constraints on `constrained` (k,) weighted by
    handle_weight (relative to the ARAP stiffness). At most max_iterations iterations, stopping
    below relative_tolerance (Anderson acceleration over acceleration_window iterations, as
    ArapEditor's); handles left farther than reach_tolerance x the model's diagonal are
    reported unreached. Building binds the model (stage "bind") and the subspace ("subspace");
    raises InvalidInput as LinearEditor does (and for options out of range, or matrices that would
    not fit in memory), SolverError when the subspace system cannot be factorised.
    """

    def __init__(
        self,
        positions: _Points,
        triangles: ArrayLike,
        coordinates: Coordinates,
        constrained: ArrayLike,
        *,
        energy: str = "spokes_and_rims",
        rotation_clusters: int = 0,
        handle_weight: float = 100.0,
        max_iterations: int = 200,
        relative_tolerance: float = 1e-07,
        acceleration_window: int = 5,
        reach_tolerance: float = 0.001,
        progress: _Progress = None,
    ) -> None: ...

    def solve(self, targets: _Points, *, progress: _Progress = None) -> CageArapResult:
        """The cage pose that best moves the constrained vertices to `targets` (k, 3),
        constructor order, world units, starting from the handles' rigid motion or the rotation-free
        solution (the lower energy). Returns a CageArapResult. Reports stage "cage-arap".
        """

    def solve_from(
        self,
        start_control_points: _Points,
        targets: _Points,
        *,
        progress: _Progress = None,
    ) -> CageArapResult:
        """As solve(), continuing from a cage pose `start_control_points` (m, 3)."""

    @property
    def cluster_count(self) -> int:
        """Rotation clusters K (n gives exactly the surface ARAP energy)."""


class CageArapReport:
    """What one CageArapEditor solve did."""

    @property
    def energies(self) -> _Float64Array:
        """(iterations + 1,) float64: total energy (ARAP + handle term) at the start and after
        each iteration, non-increasing.
        """

    @property
    def iterations(self) -> int:
        """Iterations run."""

    @property
    def converged(self) -> bool:
        """Whether the relative decrease fell below relative_tolerance before max_iterations."""

    @property
    def started_rigid(self) -> bool:
        """Whether the solve started from the handles' common rigid motion."""

    @property
    def handle_residuals(self) -> _Float64Array:
        """(k,) float64: distance of each constrained vertex from its target, world units."""

    @property
    def unreached(self) -> NDArray[np.uint32]:
        """(u,) uint32: constrained vertices (mesh indices) left farther than reach_tolerance
        from their targets: the cage cannot carry them there rigidly (or at all).
        """

    @property
    def max_residual(self) -> float:
        """The largest handle residual, world units."""


class CageArapResult:
    """The result of a CageArapEditor solve."""

    @property
    def control_points(self) -> _Float64Array:
        """(m, 3) float64: the posed control points (cage vertices), world units (read-only);
        coordinates.warp(control_points) carries any other geometry the same way.
        """

    @property
    def positions(self) -> _Float64Array:
        """(n, 3) float64: the model's vertices, world units (read-only)."""

    @property
    def report(self) -> CageArapReport:
        """The CageArapReport."""


class Compose(Warp):
    """The warps applied one after the other: Compose(a, b)(x) = b(a(x))."""

    def __init__(self, *warps: Warp) -> None: ...


class Coordinates:
    """Coordinates of points with respect to controls (cage vertices, lattice points, RBF
    handles): x' = x + sum_c w_c(x) (C_c(posed) - C_c(rest)). Thread-safe; the GIL is released.
    """

    def weights(self, points: _Points, *, progress: _Progress = None) -> _Float64Array:
        """The weights of `points` (n, 3): an (n, column_count) float64 array, one row per
        point. Raises InvalidInput for non-finite points or points outside the domain (naming the first).
        """

    def sparse_weights(self, points: _Points) -> Any:
        """The weights as a scipy.sparse.csr_matrix (n, column_count) of the non-zeros (needs
        SciPy).
        """

    def bind(self, points: _Points, *, progress: _Progress = None) -> Binding:
        """The Binding of `points` (n, 3): their weights computed once, in parallel."""

    def warp(self, posed: _Points) -> Warp:
        """The Warp of these coordinates posed by `posed` (control_point_count, 3)."""

    def column_controls(self, posed: _Points) -> _Float64Array:
        """The column controls C (column_count, 3) of posed control points (V, 3): the points,
        plus Green's scaled face normals.
        """

    @property
    def control_point_count(self) -> int:
        """Control points a user poses (V): cage vertices, lattice points, handles."""

    @property
    def column_count(self) -> int:
        """Columns of a weight row: V, plus one per cage face for Green."""

    @property
    def rest_control_points(self) -> _Float64Array:
        """(V, 3) world units."""

    @property
    def column_names(self) -> list[str]:
        """One name per column: "v<i>" for control point i, "f<j>" for face j."""

    def __reduce__(self) -> tuple[Any, tuple[bytes]]:
        """For pickle: the loader and this object's archive bytes."""

    def to_bytes(self) -> bytes:
        """This object as archive bytes (rig/warp_archive.h): solved state included, so that
        loading it solves nothing and gives bit-identical results. Raises InvalidInput for an object
        that cannot be saved (one that holds something defined in Python), and TypeError for an
        instance of a Python subclass (its class and attributes are not in the archive: define
        __reduce__ in the subclass to pickle it).
        """


class DeformationGraph:
    """The embedded deformation graph (Sumner et al. 2007) over `positions` (n, 3): nodes
    sampled every `spacing` world units (sampling "voxel" or "poisson"), or given as `nodes` (m, 3);
    each point follows its k nearest nodes. solve() poses it; warp() is the posed Warp.
    """

    def __init__(
        self,
        positions: _Points,
        *,
        spacing: float = 0.0,
        k: int = 4,
        sampling: Literal["voxel", "poisson"] = "voxel",
        nodes: Optional[_Points] = None,
    ) -> None: ...

    @property
    def nodes(self) -> _Float64Array:
        """The node positions (m, 3), world units."""

    @property
    def k(self) -> int:
        """Nodes that influence each point."""

    @property
    def edges(self) -> NDArray[np.uint32]:
        """The graph's edges (e, 2), node indices."""

    def solve(
        self,
        handles: _Points,
        targets: _Points,
        *,
        rotation_weight: float = 1.0,
        regularization_weight: float = 10.0,
        constraint_weight: float = 100.0,
        max_iterations: int = 50,
        tolerance: float = 1e-06,
        progress: _Progress = None,
    ) -> GraphSolveReport:
        """Poses the graph so that the points `handles` (k, 3) reach `targets` (k, 3), world
        units (Gauss-Newton on the paper's energy; weights as in the paper). Returns a GraphSolveReport;
        check `converged`.
        """

    def reset(self) -> None:
        """Back to the rest pose."""

    def warp(self) -> DeformationGraphWarp:
        """The graph's current pose as a Warp (a snapshot: later solves do not change it)."""


class DeformationGraphWarp(Warp):
    """A posed deformation graph (DeformationGraph.warp())."""


class DiscreteHarmonic(Coordinates):
    """Discrete harmonic coordinates of a convex Cage of triangles (CLI "discrete-harmonic"; as
    CGAL 6.2): (n, V) weights, which may be negative inside. Raises InvalidInput naming a reflex edge
    for a cage that is not convex, and naming the face for a polygon face (or coplanar triangles that
    merge into one), where the closed form has poles: use Wachspress for those. outside: "raise" or
    "nearest", as Wachspress. snap_tolerance: relative to the cage diagonal. planarity: as
    Wachspress.
    """

    def __init__(
        self,
        cage: Cage,
        *,
        snap_tolerance: float = 1e-14,
        outside: Literal["raise", "nearest"] = "raise",
        planarity: float = 1e-06,
    ) -> None: ...

    @property
    def cage(self) -> Cage:
        """The Cage (a copy)."""


class Geometry:
    """A polygon soup or point cloud: positions (n, 3) world units, optional unit normals
    (n, 3), polygons of any size, per-vertex and per-face scalar attributes; what read() keeps of a
    file (texture coordinates, per-corner normals, OBJ groups) travels with it to write(). Array
    properties return copies; assign to change them.
    """

    def __init__(
        self,
        positions: _Points,
        faces: Optional[_Faces] = None,
        *,
        normals: Optional[_Points] = None,
    ) -> None: ...

    @property
    def positions(self) -> _Float64Array:
        """(n, 3) float64, world units (a copy)."""
    @positions.setter
    def positions(self, value: _Points) -> None: ...

    @property
    def normals(self) -> Optional[_Float64Array]:
        """(n, 3) unit normals per vertex, or None."""
    @normals.setter
    def normals(self, value: Optional[_Points]) -> None: ...

    @property
    def faces(self) -> Union[NDArray[np.uint32], list[NDArray[np.uint32]]]:
        """The polygons: (m, k) uint32 when all have k vertices, else a list of index arrays.
        Assigning polygons of other sizes drops the per-face and per-corner data.
        """
    @faces.setter
    def faces(self, value: Optional[_Faces]) -> None: ...

    @property
    def vertex_attributes(self) -> dict[str, _Float64Array]:
        """dict of name -> (n,) float64 per-vertex values (copies)."""

    @property
    def face_attributes(self) -> dict[str, _Float64Array]:
        """dict of name -> (m,) float64 per-polygon values (copies)."""

    def set_vertex_attribute(
        self,
        name: str,
        values: ArrayLike,
        *,
        dtype: _Dtype = "float64",
    ) -> None:
        """Sets the per-vertex attribute `name` (n,), stored as `dtype` in PLY files."""

    def set_face_attribute(
        self,
        name: str,
        values: ArrayLike,
        *,
        dtype: _Dtype = "float64",
    ) -> None:
        """Sets the per-polygon attribute `name` (m,), stored as `dtype` in PLY files."""

    @property
    def point_count(self) -> int:
        """Vertices or points (n)."""

    @property
    def polygon_count(self) -> int:
        """Polygons (m); 0 for a point cloud."""

    def copy(self) -> Geometry:
        """A deep copy."""

    def __copy__(self) -> Geometry:
        """A deep copy (copy.copy): a Geometry shares no storage."""

    def __deepcopy__(self, memo: dict[str, Any]) -> Geometry:
        """A deep copy (copy.deepcopy)."""

    def __len__(self) -> int: ...

    def __repr__(self) -> str: ...


class GraphSolveReport:
    """What DeformationGraph.solve() found."""

    @property
    def energies(self) -> list[float]:
        """Energy after each accepted step."""

    @property
    def iterations(self) -> int:
        """Accepted Gauss-Newton steps."""

    @property
    def converged(self) -> bool:
        """Whether the energy stopped changing within the tolerance."""

    @property
    def rotation_energy(self) -> float:
        """E_rot at the end (unitless)."""

    @property
    def regularization_energy(self) -> float:
        """E_reg at the end, in units of the nodes' largest extent squared."""

    @property
    def constraint_energy(self) -> float:
        """E_con at the end, in units of the nodes' largest extent squared."""

    @property
    def component_count(self) -> int:
        """Connected parts of the graph."""

    @property
    def unconstrained_nodes(self) -> list[int]:
        """Nodes of parts of the graph that no handle reaches."""


class Green(Coordinates):
    """Green coordinates (Lipman et al. 2008) of a Cage: (n, V + F) weights, vertex columns then
    face columns.
    """

    def __init__(self, cage: Cage, *, surface_tolerance: float = 1e-14) -> None: ...

    @property
    def cage(self) -> Cage:
        """The Cage (a copy)."""


class HandleDistances:
    """Distances from each of n handles to any point, which an Mls warp weighs its handles by
    instead of Euclidean distances (Mls(..., distances=...)). Built by InsideDistances.
    """

    @property
    def handles(self) -> _Float64Array:
        """The handles (n, 3), world units, the distances are measured from."""

    def distances(self, points: _Points) -> _Float64Array:
        """The distance from every handle to every point: points (m, 3) -> (m, n), world
        units; 0 exactly at a handle.
        """

    def __reduce__(self) -> tuple[Any, tuple[bytes]]:
        """For pickle: the loader and this object's archive bytes."""

    def to_bytes(self) -> bytes:
        """This object as archive bytes (rig/warp_archive.h): solved state included, so that
        loading it solves nothing and gives bit-identical results. Raises InvalidInput for an object
        that cannot be saved (one that holds something defined in Python), and TypeError for an
        instance of a Python subclass (its class and attributes are not in the archive: define
        __reduce__ in the subclass to pickle it).
        """


class Harmonic(Coordinates):
    """Harmonic coordinates (Joshi et al. 2007) of a Cage: a Laplace solve on a TetGen mesh of
    about `tets` tetrahedra (0: the library's default, about 200k), or at a `precision` level, a
    number in [1, 7] (200000 * 4**(p - 5) tets, so 5.5 lies between 5 and 6; 0: none; not with tets). cache: a file of solved coordinates, loaded when it matches the cage and
    tets, else solved and saved there. outside: "raise" or "nearest" for points outside the cage.
    """

    def __init__(
        self,
        cage: Cage,
        *,
        tets: int = 0,
        precision: float = 0.0,
        cache: Optional[_Path] = None,
        outside: Literal["raise", "nearest"] = "raise",
        progress: _Progress = None,
    ) -> None: ...

    @property
    def tet_count(self) -> int:
        """Tetrahedra of the mesh solved on."""

    def save(self, path: _Path) -> None:
        """Writes the solve to a file (atomically)."""


class Identity(Warp):
    """x' = x."""

    def __init__(self) -> None: ...


class InsideDistances(HandleDistances):
    """The distances from handles (n, 3) to any point measured inside a closed model (Zhu &
    Gortler 2007): shortest paths that stay in the solid, by fast marching on voxels of
    `voxel_size` world units (0: the model's bounding-box diagonal / 128). `model` is a Geometry
    or the path of an OBJ, OFF or PLY file; handles must be inside it (or within 2 voxels of its
    surface). Outside the model a point takes its nearest inside voxel's distance, extrapolated.
    Raises InvalidInput naming the handle or parameter at fault.
    """

    def __init__(
        self,
        model: Union[Geometry, _Path],
        handles: _Points,
        *,
        voxel_size: float = 0.0,
    ) -> None: ...

    @property
    def voxel_size(self) -> float:
        """The voxel edge used, world units."""

    @property
    def grid_size(self) -> list[int]:
        """The grid's voxel counts along x, y, z."""


class Kelvinlet(Warp):
    """A regularized Kelvinlet brush (de Goes and James 2017): the displacement of an infinite
    elastic medium under a force spread over `radius` (epsilon > 0, world units) around `center` (3,).
    brush "grab" moves the center by `displacement` (3,); "twist" rotates the center's neighbourhood
    by `angle` (radians) about `axis` (3,) (the Jacobian there is I + angle [axis]x); "scale" scales it
    by `factor` (> 0); "pinch" gives it the displacement gradient `matrix` (3, 3), symmetric and
    traceless. poisson: Poisson ratio in [0, 0.5] (default 0.45). falloff: "single" (default),
    "bi" or "tri": the brush at radii epsilon, 2 epsilon (and 4 epsilon) combined so that it fades
    faster with distance (grab 1/r, 1/r^3, 1/r^5), the center unchanged. steps: the brush applied as that
    many sub-brushes (1 = the closed form; more avoid folds for large edits, at steps times the cost).
    Keys of another brush raise InvalidInput.
    """

    def __init__(
        self,
        *,
        brush: str,
        center: _Vec3,
        radius: float,
        poisson: float = 0.45,
        displacement: Optional[_Vec3] = None,
        axis: Optional[_Vec3] = None,
        angle: Optional[float] = None,
        factor: Optional[float] = None,
        matrix: Optional[ArrayLike] = None,
        falloff: str = "single",
        steps: int = 1,
    ) -> None: ...

    @property
    def brush(self) -> str:
        """"grab", "twist", "scale" or "pinch"."""

    @property
    def radius(self) -> float:
        """The regularisation radius epsilon, world units."""

    @property
    def poisson(self) -> float:
        """The Poisson ratio."""


class Lattice(Coordinates):
    """A free-form deformation lattice (Sederberg and Parry 1986): a box at `origin` along
    `axes` (3 unit vectors) with `extents` (world units), resolution (l, m, n) control points,
    basis "trilinear", "bernstein" or "bspline"; ends of the bspline basis: "extrapolate" (linear
    phantom controls, the default) or "repeat" (the end control repeated, Blender's lattice); given
    with another basis it is an error, as the rig's key; points
    outside: "identity", "clamp" or "falloff" (over falloff x the box diagonal). Control point
    (i, j, k) is index i + l (j + m k).
    """

    def __init__(
        self,
        *,
        origin: _Vec3 = ...,
        axes: ArrayLike = ...,
        extents: _Vec3 = ...,
        resolution: Sequence[int] = ...,
        basis: _Basis = "trilinear",
        outside: Literal["identity", "clamp", "falloff"] = "identity",
        falloff: float = 0.1,
        ends: Optional[str] = None,
    ) -> None: ...

    @staticmethod
    def around(
        points: _Points,
        *,
        padding: float = 0.05,
        resolution: Sequence[int] = ...,
        basis: _Basis = "trilinear",
        ends: Optional[str] = None,
    ) -> Lattice:
        """An axis-aligned lattice around `points` (n, 3), padded by `padding` x the box
        diagonal; `ends` as for the constructor.
        """

    def fit(
        self,
        from_points: _Points,
        to_points: _Points,
        *,
        smoothness: float = 0.0001,
        progress: _Progress = None,
    ) -> tuple[_Float64Array, float, float]:
        """Direct manipulation (Hsu et al. 1992): the posed control points (V, 3) that carry
        `from_points` (k, 3) to `to_points` (k, 3) in least squares with a smoothness regulariser.
        Returns (posed, rms_residual, max_residual), world units.
        """

    @property
    def resolution(self) -> list[int]:
        """Control points per axis (l, m, n)."""


class LinearEditor:
    """Prefactorised linear surface editing of the mesh positions (n, 3), triangles (t, 3)
    with the vertices `constrained` (k,) as handles: the free vertices' displacement is harmonic
    (method "laplacian", Sorkine et al. 2004) or biharmonic ("bilaplacian", Botsch and Kobbelt
    2004). Reproduces translations exactly but cannot follow rotations (use ArapEditor). Components
    no handle reaches stay at rest (held_vertices).
    """

    def __init__(
        self,
        positions: _Points,
        triangles: ArrayLike,
        constrained: ArrayLike,
        *,
        method: Literal["laplacian", "bilaplacian"] = "laplacian",
    ) -> None: ...

    def solve(self, targets: _Points) -> _Float64Array:
        """All n vertices (n, 3) for the constrained vertices at `targets` (k, 3), one per
        constrained vertex in the constructor's order, world units (a back-substitution).
        """

    @property
    def held_vertices(self) -> NDArray[np.uint32]:
        """(h,) uint32: vertices kept at rest because no handle reaches their component."""


class MeanValue(Coordinates):
    """Mean-value coordinates (Ju et al. 2005) of a Cage: (n, V) weights, everywhere in space."""

    def __init__(self, cage: Cage, *, snap_tolerance: float = 1e-14) -> None: ...

    @property
    def cage(self) -> Cage:
        """The Cage (a copy)."""


class MeshReport:
    """What weld_soup() found about a surface (mesh vertex and triangle
    indices; polygon indices of the soup). Arrays are read-only views.
    """

    @property
    def boundary_edges(self) -> int:
        """Edges with one triangle (holes, open sheets: fine for every method)."""

    @property
    def non_manifold_edges(self) -> NDArray[np.uint32]:
        """(k, 2) uint32: edges shared by more than two triangles, smaller vertex first."""

    @property
    def non_manifold_vertices(self) -> NDArray[np.uint32]:
        """(k,) uint32: vertices whose triangles do not form one fan."""

    @property
    def dropped_polygons(self) -> NDArray[np.uint32]:
        """(k,) uint32: soup polygons that welding collapsed (not in the mesh)."""

    @property
    def degenerate_triangles(self) -> NDArray[np.uint32]:
        """(k,) uint32: mesh triangles without area (collinear corners): in the mesh, but in no
        energy.
        """

    @property
    def isolated_vertices(self) -> NDArray[np.uint32]:
        """(k,) uint32: mesh vertices no triangle uses."""

    @property
    def component_count(self) -> int:
        """Connected components of the triangles (isolated vertices not counted)."""

    @property
    def is_manifold(self) -> bool:
        """Whether every edge has at most two triangles and every vertex one fan."""

    def __repr__(self) -> str: ...


class Mls(Warp):
    """Moving least squares (Schaefer et al. 2006): handles (k, 3) move to targets (k, 3);
    each point gets the affine, similarity or rigid map that best fits the handles weighted by
    1 / |p - x|^(2 alpha). mode: "affine", "similarity" or "rigid" (default). distances: a
    HandleDistances built for the same handles (e.g. InsideDistances, distances measured inside a
    model), used instead of |p - x|; None (default): Euclidean.
    """

    def __init__(
        self,
        handles: _Points,
        targets: _Points,
        *,
        mode: Literal["rigid", "similarity", "affine"] = "rigid",
        alpha: float = 1.0,
        distances: Optional[HandleDistances] = None,
    ) -> None: ...


class MlsAffine(Coordinates):
    """The coordinates of affine moving least squares over `handles` (k, 3)."""

    def __init__(self, handles: _Points, *, alpha: float = 1.0) -> None: ...


class QuadGreen(Coordinates):
    """Green coordinates of a cage of triangles and quads (CLI "qgc"; Thiery and Boubekeur
    2022): (n, V + T + 4 Q) weights for T triangle and Q quad faces: the vertex columns, then one
    normal column per triangle face and four per quad face, in face order (column_names). Raises
    InvalidInput naming a face of more than 4 vertices. surface_tolerance: relative to the cage
    diagonal, in [0, 1e-3]. Rows sum to 1 over the vertex columns and reproduce the point at rest
    to round-off (they are projected onto those constraints); within ~1e-12 of the diagonal of a cage
    vertex single weights may still be off by up to ~5e-6.
    """

    def __init__(self, cage: Cage, *, surface_tolerance: float = 1e-14) -> None: ...

    @property
    def cage(self) -> Cage:
        """The Cage (a copy)."""


class QuadMeanValue(Coordinates):
    """Mean-value coordinates of a polygon Cage, quads included (CLI "qmvc"): Langer et al. 2006
    for polygons, Thiery et al. 2018 for quads (bilinear patches, planar or not); no face is
    triangulated. (n, V) weights that sum to 1 and reproduce the point, everywhere in space; equal
    to MeanValue on an all-triangle cage. snap_tolerance: relative to the cage diagonal, in
    [0, 1e-3]. polygon_planarity: how far (relative to the cage diagonal, in [0, 1e-2]) a vertex of a
    face of more than 4 vertices may be from the face's best-fit plane; the default admits
    coordinates written in float32 or with 6 decimals (cages of diagonal >= 1). Raises
    InvalidInput naming a face farther from planar (quads may be non-planar).
    """

    def __init__(
        self,
        cage: Cage,
        *,
        snap_tolerance: float = 1e-14,
        polygon_planarity: float = 1e-06,
    ) -> None: ...

    @property
    def cage(self) -> Cage:
        """The Cage (a copy)."""


class Rbf(Coordinates):
    """RBF handle coordinates (Botsch and Kobbelt 2005, the fit folded in): handles `centers`
    (k, 3), `fixed` (f, 3) held in place; kernel and options as RbfWarp. warp(posed) is the RbfWarp
    that moves the centers to `posed`.
    """

    def __init__(
        self,
        centers: _Points,
        fixed: Optional[_Points] = None,
        *,
        kernel: _Kernel = "triharmonic",
        scale: float = 1.0,
        radius: float = 1.0,
        smoothing: float = 0.0,
        progress: _Progress = None,
    ) -> None: ...


class RbfWarp(Warp):
    """A radial-basis displacement field (Botsch and Kobbelt 2005) that moves `centers` (k, 3)
    to `targets` (k, 3) and keeps `fixed` (f, 3) in place, plus a linear polynomial. kernel:
    "triharmonic" (r^3, default), "biharmonic", "thin-plate", "gaussian", "inverse-multiquadric",
    "wendland"; scale (world units) for gaussian/inverse multiquadric; radius (world units) for
    Wendland; smoothing >= 0 turns interpolation into approximation.
    """

    def __init__(
        self,
        centers: _Points,
        targets: _Points,
        fixed: Optional[_Points] = None,
        *,
        kernel: _Kernel = "triharmonic",
        scale: float = 1.0,
        radius: float = 1.0,
        smoothing: float = 0.0,
        progress: _Progress = None,
    ) -> None: ...


class Shepard(Coordinates):
    """Shepard's inverse-distance weighting over `handles` (k, 3), world units:
    w_i(x) = d_i^-power / sum_j d_j^-power (power > 0, default 2), or with a support `radius`
    (world units, > 0) Franke and Nielson's ((R - d_i)+ / (R d_i))^power, zero beyond it. The weights
    are non-negative, sum to 1 and interpolate the handles; warp(targets) moves every point by the
    weighted mean of the handles' displacements (translations are reproduced, linear maps are not).
    For power > 1 the warp's Jacobian is the identity at every handle (Shepard's flat spots). With a
    radius, points farther than it from every handle have no weights: weights() and the warp raise
    InvalidInput for them.
    """

    def __init__(
        self,
        handles: _Points,
        *,
        power: float = 2.0,
        radius: Optional[float] = None,
    ) -> None: ...

    @property
    def power(self) -> float:
        """The weight exponent."""

    @property
    def radius(self) -> Optional[float]:
        """The support radius (world units), or None for global weights."""


class Skinning(Warp):
    """Skeletal skinning of space. bones: (b, 4, 4) row-major transforms from the
    rest pose to the posed one (world units). The weights of a point x come either from `weights`
    (n, b) of the vertices of `model` (n, 3) — x takes its nearest vertex's weights, so the warp is
    exact on the model — or from `coordinates` (a Coordinates with one control point per bone,
    e.g. MlsAffine or Rbf of the bones' handles). Per point the `influences` largest weights are
    kept and normalised to sum 1: 0 keeps all; default None: 4 of `weights`, all of `coordinates`
    (exact and smooth). Truncating clamps negative weights to 0 (no poles) and, for coordinates,
    fades the kept ones by the next largest (continuous in space).
    mode: "lbs" (linear blend skinning: the bones' matrices averaged; any
    affine bones) or "dqs" (dual-quaternion skinning, Kavan et al. 2008: the rigid motions averaged
    as unit dual quaternions, each in the hemisphere of the point's largest-weight bone; rigid bones
    only).
    """

    def __init__(
        self,
        bones: ArrayLike,
        *,
        weights: Optional[ArrayLike] = None,
        model: Optional[_Points] = None,
        coordinates: Optional[Coordinates] = None,
        mode: str = "lbs",
        influences: Optional[int] = None,
    ) -> None: ...

    @property
    def mode(self) -> str:
        """"lbs" or "dqs"."""

    @property
    def bone_count(self) -> int:
        """b."""


class SkinningBinding:
    """A fixed point set bound to b bones, re-posed by deform(bones): the fast path (SIMD,
    parallel, deterministic; bit-identical to Skinning at the same points). points: (n, 3), world
    units. weights: (n, b) dense weights, or a Coordinates with one control point per bone, whose
    weights at the points are computed once. The `influences` largest weights per point are kept
    and normalised to sum 1, as in Skinning: 0 keeps all; default None: 4 of dense weights, all of
    coordinates.
    """

    def __init__(
        self,
        points: _Points,
        weights: Union[ArrayLike, Coordinates],
        *,
        influences: Optional[int] = None,
    ) -> None: ...

    def deform(
        self,
        bones: ArrayLike,
        *,
        mode: str = "lbs",
        out: Optional[_Float64Array] = None,
    ) -> _Float64Array:
        """The posed points (n, 3) for bones (b, 4, 4), into `out` if given.
        mode: "lbs" (linear blend skinning: the bones' matrices averaged; any
        affine bones) or "dqs" (dual-quaternion skinning, Kavan et al. 2008: the rigid motions averaged
        as unit dual quaternions, each in the hemisphere of the point's largest-weight bone; rigid bones
        only).
        """

    @property
    def point_count(self) -> int:
        """n."""

    @property
    def bone_count(self) -> int:
        """b."""

    @property
    def rest_points(self) -> _Float64Array:
        """The bound points (n, 3), a copy."""

    @property
    def influences(self) -> tuple[NDArray[np.uint32], _Float64Array]:
        """The kept influences as (bones (n, k) uint32, weights (n, k) float64), largest weight
        first, each row summing to 1.
        """

    def __getstate__(
        self,
    ) -> tuple[_Float64Array, tuple[NDArray[np.uint32], _Float64Array], int]: ...

    def __setstate__(self, arg0: tuple[Any, ...]) -> None: ...


class SurfaceMesh:
    """A triangle mesh welded from a Geometry (weld_soup): positions (n, 3) world units,
    triangles (t, 3), and the maps back to the soup. Arrays are read-only views (no copy); the
    editors take mesh.positions and mesh.triangles.
    """

    @property
    def positions(self) -> _Float64Array:
        """(n, 3) float64 mesh vertices, world units."""

    @property
    def triangles(self) -> NDArray[np.uint32]:
        """(t, 3) uint32 vertex indices, oriented as the soup's polygons."""

    @property
    def soup_to_mesh(self) -> NDArray[np.uint32]:
        """(soup n,) uint32: the mesh vertex of each soup vertex."""

    @property
    def triangle_to_polygon(self) -> NDArray[np.uint32]:
        """(t,) uint32: the soup polygon each triangle was cut from."""

    @property
    def vertex_component(self) -> NDArray[np.uint32]:
        """(n,) uint32: the component of each vertex, 0 .. component_count - 1; isolated vertices
        get component_count and up, one each.
        """

    @property
    def report(self) -> MeshReport:
        """The MeshReport of the weld."""

    @property
    def vertex_count(self) -> int:
        """Mesh vertices (n)."""

    def to_soup_positions(self, mesh_positions: _Points) -> _Float64Array:
        """The soup's vertices (soup n, 3) moved as the mesh vertices (n, 3) they were welded
        into: out[v] = mesh_positions[soup_to_mesh[v]]. Raises InvalidInput for a wrong count.
        """

    def to_soup(self) -> Geometry:
        """A Geometry of the mesh's triangles (no attributes), e.g. to write it."""

    def __repr__(self) -> str: ...


class Taper(Warp):
    """Scales the cross-sections of an axis by 1 + rate * s (s along the axis from origin,
    clamped to [lo, hi]; rate in 1 / world units).
    """

    def __init__(
        self,
        *,
        origin: _Vec3 = ...,
        axis: _Vec3 = ...,
        rate: float = 0.0,
        lo: float = ...,
        hi: float = ...,
    ) -> None: ...


class Twist(Warp):
    """Rotation about an axis by an angle proportional to the position along it: rate radians
    per world unit, s (the position along the axis from origin) clamped to [lo, hi].
    """

    def __init__(
        self,
        *,
        origin: _Vec3 = ...,
        axis: _Vec3 = ...,
        rate: float = 0.0,
        lo: float = ...,
        hi: float = ...,
    ) -> None: ...


class Viewer:
    """A running viewer (spacewarp.view): `url` is the page's address, `stop()`
    ends it (requests in flight finish first); also a context manager that stops on exit.
    """

    @property
    def url(self) -> str:
        """"http://HOST:PORT/", the page's address."""

    @property
    def port(self) -> int:
        """The port listened on."""

    def stop(self) -> None:
        """Stops serving; a second call does nothing."""

    def __enter__(self) -> Viewer: ...

    def __exit__(self, exc_type: Any, exc: Any, traceback: Any) -> None: ...


class VolumeBrickPlan:
    """The plan of spacewarp.dask.warp_volume for one
    VDB file (made by plan_volume_bricks, kept by the caller): its bricks, and the merge.
    """

    @property
    def bricks(self) -> list[tuple[Any, ...]]:
        """The bricks of every grid, in order: plain tuples (grid index, grid name, clipped
        read, rigid, output min, output max, input min, input max, cells (k, 3) int32; boxes in index
        space, inclusive) to pass to warp_volume_brick.
        """

    def merge(
        self,
        warp: Warp,
        results: list[VolumeBrickResult],
        output: _Path,
    ) -> list[dict[str, Any]]:
        """Merges the results of warp_volume_brick (one per brick, any order), warps the grids
        that are not bricked (point data grids) here, re-distances level sets once over each merged
        grid, and writes every grid to `output` atomically, as spacewarp.warp_volume does. Returns one
        report dict per grid.
        """


class VolumeBrickResult:
    """A warped brick (OpenVDB stream bytes and its counts); pickles."""

    @property
    def halo_misses(self) -> int:
        """Voxels whose preimage left the brick's clipped input; the brick
        was then warped again from the whole grid.
        """

    @property
    def size(self) -> int:
        """Bytes of the brick's grid."""

    def __getstate__(self) -> tuple[Any, ...]: ...

    def __setstate__(self, arg0: tuple[Any, ...]) -> None: ...


class Wachspress(Coordinates):
    """Wachspress coordinates of a convex Cage (CLI "wachspress"; Warren et al. 2007, as CGAL
    6.2): (n, V) weights, positive inside. Raises InvalidInput naming a reflex edge for a cage that
    is not convex. outside: "raise" (points outside are an InvalidInput) or "nearest" (the
    coordinates of the nearest cage point). snap_tolerance: relative to the cage diagonal.
    planarity: relative to the cage diagonal, in [0, 1e-2]: how far a corner may be off its face's
    best-fit plane (or above a neighbouring face's plane) and count as on it; the default admits
    coordinates written in float32 or with 6 decimals (cages of diagonal >= 1).
    """

    def __init__(
        self,
        cage: Cage,
        *,
        snap_tolerance: float = 1e-14,
        outside: Literal["raise", "nearest"] = "raise",
        planarity: float = 1e-06,
    ) -> None: ...

    @property
    def cage(self) -> Cage:
        """The Cage (a copy)."""


class Wire:
    """One wire of spacewarp.Wires: the reference curve `rest` (n, 3) and the
    deformed curve `deformed` (n, 3), n >= 2, world units, point k of each at parameter k;
    `radius` (> 0, world units) of influence; `inner_radius` in [0, radius): full influence
    within it (a rigid motion of the wire moves that tube rigidly); `scale` (> 0) about the curve;
    `dropoff` "smooth" ((1 - x^2)^2, default) or "linear"; `curve` "polyline" (default) or
    "catmull-rom". Checked when a Wires is built from it.
    """

    def __init__(
        self,
        rest: _Points,
        deformed: _Points,
        radius: float,
        *,
        inner_radius: float = 0.0,
        scale: float = 1.0,
        dropoff: Literal["smooth", "linear"] = "smooth",
        curve: Literal["polyline", "catmull-rom"] = "polyline",
    ) -> None: ...

    @property
    def rest(self) -> _Float64Array:
        """The reference curve (n, 3)."""

    @property
    def deformed(self) -> _Float64Array:
        """The deformed curve (n, 3)."""

    @property
    def radius(self) -> float:
        """Radius of influence, world units."""

    @property
    def inner_radius(self) -> float:
        """Radius of full influence, world units."""

    @property
    def scale(self) -> float:
        """Scale about the curve."""

    @property
    def dropoff(self) -> str:
        """The drop-off: "smooth" or "linear"."""

    @property
    def curve(self) -> str:
        """The curve: "polyline" or "catmull-rom"."""


class Wires(Warp):
    """Wires (Singh & Fiume 1998): points within a wire's radius of its rest curve follow the
    curve to its deformed one (scaled, turned and moved about their closest rest point, fading
    out at the radius); several wires blend as x + sum(d_i |d_i|^m) / sum(|d_i|^m), m =
    `locality` (>= 0, default 1). `wires`: a sequence of spacewarp.Wire.
    """

    def __init__(self, wires: Sequence[Wire], *, locality: float = 1.0) -> None: ...

    @property
    def wires(self) -> list[Wire]:
        """The wires (a list of spacewarp.Wire)."""

    @property
    def locality(self) -> float:
        """The blend's exponent m."""


def assemble_ply(input: _Path, parts: list[_Path], output: _Path) -> None:
    """Writes `output` atomically: the PLY header deform_file writes for `input`, the files
    `parts` in order (from deform_ply_rows, together every vertex row of `input`), then `input`'s
    faces. The result is byte-identical to deform_file(warp, input, output). Parts are raw rows
    with no header: only their sizes are checked, so their order (by first_row) and that they all
    come from the same warp of this `input` are the caller's job; parts in the wrong order or from
    another warp give a wrong output without an error. Raises InvalidInput naming the part that is
    `input` itself or whose size is not a whole number of output rows, or when the parts do not add
    up to the vertex count.
    """


def cage_coordinates(
    method: str,
    cage: Cage,
    *,
    tets: int = 0,
    precision: float = 0.0,
    cache: Optional[_Path] = None,
    outside: Literal["raise", "nearest"] = "raise",
    progress: _Progress = None,
) -> Coordinates:
    """The coordinates of a cage method by its CLI name (see cage_methods()). tets, precision and
    cache: harmonic's; outside: harmonic's, wachspress's and discrete-harmonic's.
    """


def cage_from_bytes(data: bytes | bytearray | memoryview | NDArray[np.uint8]) -> Cage:
    """The Cage saved in `data` (bytes from Cage.to_bytes()), rebuilt from its polygons. Raises
    InvalidInput for bytes that are not a cage archive.
    """


def cage_methods() -> list[str]:
    """The cage methods of this build, sorted: "discrete-harmonic", "green", "harmonic" (with
    TetGen), "mvc", "qgc", "qmvc", "wachspress".
    """


def coordinate_properties(
    coordinates: Coordinates,
    samples: _Points,
    *,
    cage: Optional[Cage] = None,
    diagonal: Optional[float] = None,
) -> dict[str, float]:
    """The C++ property kit (the figures of `spacewarp compare`) for spacewarp Coordinates at
    `samples` (n, 3): a dict of partition_of_unity, linear_reproduction (relative to the cage
    diagonal), min_weight, negative_fraction, samples_with_negative, lagrange, face_interpolation,
    similarity_reproduction (NaN where a check needs the cage). For any weight matrix, see
    spacewarp.testing.
    """


def coordinates_from_bytes(
    data: bytes | bytearray | memoryview | NDArray[np.uint8],
) -> Coordinates:
    """The coordinates saved in `data` (bytes from Coordinates.to_bytes()), as their own class.
    Nothing is solved again. Raises InvalidInput for bytes that are not a coordinates archive.
    """


def cotan_laplacian(positions: _Points, triangles: ArrayLike) -> Any:
    """The cotangent stiffness matrix L (n, n) of the mesh positions (n, 3), triangles (t, 3):
    a scipy.sparse.csc_matrix, symmetric positive semi-definite, rows summing to 0,
    L_ij = -(cot a_ij + cot b_ij) / 2 over the angles opposite edge ij, dimensionless; x^T L x is the
    Dirichlet energy of the piecewise-linear function x (needs SciPy). Triangles below 1e-12 of
    their longest edge squared in area contribute nothing.
    """


def deform(
    warp: Warp,
    geometry: Geometry,
    *,
    in_place: bool = False,
    progress: _Progress = None,
) -> Geometry:
    """The Geometry moved through `warp`: positions warped, normals carried by J^-T (the same
    code as `spacewarp deform`). Returns a new Geometry, or `geometry` itself changed when in_place.
    All or nothing: raises InvalidInput naming the first vertex that is not finite.
    """


def deform_file(
    warp: Warp,
    input: _Path,
    output: _Path,
    *,
    chunk_points: Optional[int] = None,
    ascii: bool = False,
    progress: _Progress = None,
) -> dict[str, Any]:
    """Warps the soup or point cloud file `input` (OBJ, OFF, PLY) into `output` (any of them),
    as `spacewarp deform` does, with the same bytes. A binary PLY input written to PLY is streamed:
    read, warped and written `chunk_points` rows at a time (default 1048576), so memory stays bounded
    whatever the file size; chunk_points=0 reads the whole file instead, as do ASCII PLY input, a
    pipe (it cannot be read twice) and OBJ/OFF on either side ('streamed' in the result says which).
    A warp's domain error names `input` and the point by its index in the file, as the whole-file
    path does, but counts "at least" the points of the first chunk that failed (exactly the file's
    when that chunk is the last). ascii: write PLY as ASCII. The output is written atomically: after an
    error or a cancel (Ctrl-C, or `progress(stage, fraction)` returning False) no output or
    temporary file is left. Returns {'points', 'faces', 'chunks', 'streamed', 'singular_normals'}.
    """


def deform_inverse(
    warp: Warp,
    geometry: Geometry,
    *,
    tolerance: float = 1e-12,
    max_iterations: int = 50,
    in_place: bool = False,
    progress: _Progress = None,
) -> Geometry:
    """The inverse of deform(): every vertex moved to its preimage under `warp` (as
    `spacewarp inverse`; tolerance relative to the geometry's bounding-box diagonal). All or nothing:
    raises SolverError naming the first vertex whose inverse did not converge.
    """


def deform_ply_rows(
    warp: Warp,
    input: _Path,
    part: _Path,
    first_row: int,
    row_count: int,
    *,
    chunk_points: Optional[int] = None,
    progress: _Progress = None,
) -> dict[str, Any]:
    """Warps vertex rows [first_row, first_row + row_count) of the binary PLY file `input` and
    writes, atomically, to `part` exactly the bytes those rows take in the binary output of
    deform_file (row_count × ply_layout(input)['output_row_bytes'] bytes: no header, no faces).
    assemble_ply joins the parts. Errors name the file and the vertex by its index in the whole file
    (a warp's "N of M points ..." counts "at least" the points of the first chunk that failed, out
    of the file's vertices). Raises InvalidInput when `part` is `input` (also through a link).
    Returns the same dict as deform_file.
    """


def distances_from_bytes(
    data: bytes | bytearray | memoryview | NDArray[np.uint8],
) -> HandleDistances:
    """The HandleDistances saved in `data` (bytes from HandleDistances.to_bytes()), as their
    own class (InsideDistances: its grid of distances, nothing marched again). Raises InvalidInput
    for bytes that are not a distances archive.
    """


def edit(
    geometry: Geometry,
    handles: Sequence[dict[str, Any]],
    *,
    method: Literal["laplacian", "bilaplacian", "arap", "cage-arap"] = "arap",
    coordinates: Optional[Coordinates] = None,
    weld_tolerance: float = 1e-09,
    energy: Optional[str] = None,
    max_iterations: Optional[int] = None,
    acceleration_window: Optional[int] = None,
    relative_tolerance: Optional[float] = None,
    rotation_clusters: Optional[int] = None,
    handle_weight: Optional[float] = None,
    reach_tolerance: Optional[float] = None,
    progress: _Progress = None,
) -> Geometry:
    """The Geometry edited by its surface, as `spacewarp edit` does: welded (weld_soup with
    weld_tolerance), the handle regions resolved (resolve_handles; vertex indices are the geometry's,
    as in the CLI's handles file) and carried to the mesh, solved by method "laplacian",
    "bilaplacian", "arap" or "cage-arap" (which needs `coordinates`, e.g. MeanValue(cage)), and
    returned as a new Geometry with the polygons, attributes and groups of the input. Per-vertex
    normals are recomputed from the edited polygons (area-weighted, on the side the input's pointed
    to); per-corner normals turn with their polygon. Options left None take the editor's defaults
    (ArapEditor, CageArapEditor); an option the method does not use raises InvalidInput. A solve
    that did not converge, handles left unreached and parts no handle reaches are UserWarnings.
    """


def interior_samples(cage: Cage, count: int, *, seed: int = 1) -> _Float64Array:
    """`count` points (count, 3) uniformly inside the cage, deterministic for a seed."""


def load_handles(path: _Path) -> list[dict[str, NDArray[Any]]]:
    """The handle regions of a handles file, read as `spacewarp edit --handles` reads it (the same
    C++ reader: the same checks and messages).

    The file is JSON: {"handles": [REGION, ...]}, each region {"vertices": [i, ...], "matrix":
    [[4 numbers] x 4 rows]} (the vertices move by that affine map, last row 0 0 0 1; the identity
    pins them) or {"vertices": [i, ...], "targets": [[x, y, z], ...]} (one target per vertex, world
    units). Indices are the model's vertices in file order.

    Returns a list of dicts {"vertices": (k,) uint32, "matrix": (4, 4) float64} or {"vertices": (k,)
    uint32, "targets": (k, 3) float64}, as edit() and resolve_handles() take them (which check the
    indices against the model). Raises IoError when the file cannot be read or is not JSON (NaN,
    duplicate keys), InvalidInput naming the file and the key path at fault
    ("h.json: handles[2].vertices[5]: ...") for content that is not a handles file.
    """


def load_rig(path: _Path, *, progress: _Progress = None) -> Warp:
    """The Warp a rig file (JSON, as `spacewarp deform --rig`) describes; the same warp the
    CLI builds. Paths inside the rig are relative to its folder. Warnings (a graph solve that did
    not converge) are Python warnings. Raises InvalidInput naming the key at fault, IoError.
    """


def mass_matrix_diagonal(positions: _Points, triangles: ArrayLike) -> _Float64Array:
    """The lumped mass (n,) of the mesh positions (n, 3), triangles (t, 3): the mixed Voronoi
    area of each vertex (Meyer et al. 2003), world units squared, summing to the surface area;
    vertices without area get the smallest positive mass.
    """


def plan_volume_bricks(
    warp: Warp,
    input: _Path,
    *,
    brick: int = 64,
    halo: int = 4,
    sampler: _Sampler = "trilinear",
    conserve_mass: bool = False,
    vectors: Literal["auto", "push", "normal", "keep"] = "auto",
    redistance: Literal["normalize", "rebuild", "none"] = "normalize",
    seed_spacing: int = 4,
) -> VolumeBrickPlan:
    """Plans warping the VDB file `input` by `warp` in bricks of `brick` output voxels per
    edge (rounded up to a multiple of 8): reads the file, evaluates the warp at the seeding cells
    of each float, double and vec3s grid and lists the bricks their images reach, each with the
    cells that reach it and the input box (index space, those cells widened by `halo` + 4 voxels) it
    reads. Options as spacewarp.warp_volume (no cache_spacing). Used by spacewarp.dask.
    """


def ply_layout(path: _Path) -> dict[str, Any]:
    """The byte layout of the binary PLY file `path` (vertex rows of scalar properties only), as
    a dict: 'vertex_count', 'vertex_offset' (bytes from the start of the file to vertex row 0),
    'vertex_row_bytes', 'vertex_properties' (a list of (name, NumPy type code, byte offset in the
    row)), 'dtype' (the NumPy structured dtype of one vertex row, so that
    np.memmap(path, dtype, 'r', vertex_offset, (vertex_count,)) views the rows), 'elements' (every
    element in file order: {'name', 'count', 'offset', 'bytes'}), 'face_count', 'largest_polygon',
    'file_bytes', 'encoding', 'path', and 'output_row_bytes' (bytes of one vertex row in the binary
    output that deform_ply_rows writes). Reads through elements with list properties (faces) once,
    checking them as the reader does. Raises IoError for an ASCII file, vertex list properties, a
    malformed or truncated file; InvalidInput for a pipe (streaming reads a file twice).
    """


def read(path: _Path) -> Geometry:
    """Reads a soup or point cloud from an OBJ, OFF or PLY file (format by extension) as a
    Geometry. Raises IoError naming the file and line or element at fault. What the file holds but
    spacewarp does not keep (OBJ line elements, PLY edges, ...) is a warning.
    """


def resolve_handles(
    regions: Sequence[dict[str, Any]],
    rest: _Points,
) -> tuple[NDArray[np.uint32], _Float64Array]:
    """The constraints of handle regions on the vertices `rest` (n, 3), world units: returns
    (vertices, targets), (k,) uint32 in increasing order and (k, 3) float64. Each region is a dict
    as in the CLI's handles file: {"vertices": [i, ...], "matrix": 4 rows of 4} (the vertices move
    by that affine map; the identity pins them) or {"vertices": [i, ...], "targets": (k, 3)}. A
    vertex in several regions must get the same target from each. Raises InvalidInput naming the
    region and entry at fault (TypeError for a region that is not a dict).
    """


def rig(
    description: dict[str, Any],
    *,
    base_dir: Optional[_Path] = None,
    progress: _Progress = None,
) -> Warp:
    """The Warp a rig given as a dict (the JSON of a rig file) describes; relative paths in it
    are resolved against base_dir (default: the current folder).
    """


def rig_methods() -> list[str]:
    """The rig methods ("twist", "mvc", ...) this build knows."""


def view(
    model: _Path,
    cage: Optional[_Path] = None,
    rig: Optional[_Path] = None,
    method: Optional[str] = None,
    port: int = 0,
    host: str = "127.0.0.1",
    save_dir: _Path = ".",
    web_dir: Optional[_Path] = None,
) -> Viewer:
    """Serves `model` (an OBJ/OFF/PLY soup or point cloud) with its controls — a `cage` file or
    a `rig` file — to the viewer page, from a background thread, as `spacewarp view` does; returns
    a Viewer (its `url`, `stop()`, a context manager). `method`: the first method (default: the
    rig's, or "mvc" with a cage); `port` 0 picks a free port; `host` other than 127.0.0.1 makes the
    viewer reachable from the network; saves go to `save_dir`; `web_dir`: the page's folder
    (default: $SPACEWARP_WEB_DIR, the build's web/dist, the installed copy). Raises IoError when no
    page is found or a file cannot be read, InvalidInput for bad input, RuntimeError when the port
    is in use.
    """


def warp_dense(
    warp: Warp,
    values: NDArray[Any],
    *,
    voxel_size: float = 1.0,
    origin: _Vec3 = ...,
    background: float = 0.0,
    level_set: bool = False,
    sampler: _Sampler = "trilinear",
    conserve_mass: bool = False,
    progress: _Progress = None,
) -> tuple[NDArray[Any], _Float64Array]:
    """Warps a dense block of voxel values (nx, ny, nz) (float32 stays float32, anything else
    is float64): voxel (i, j, k) is centered at origin + voxel_size * (i, j, k), world units; values
    equal to `background` are inactive. level_set: the values are signed distances (re-distanced
    after the warp). Returns (values, origin): the output's active bounding block and the world
    position of its voxel (0, 0, 0). For grids of pyopenvdb, copy them to and from dense arrays
    (copyToArray / copyFromArray), or go through files with warp_volume.
    """


def warp_from_bytes(data: bytes | bytearray | memoryview | NDArray[np.uint8]) -> Warp:
    """The warp saved in `data` (bytes from Warp.to_bytes(), or saveWarp() in C++; any bytes-like
    object: bytes, bytearray, memoryview, a contiguous NumPy uint8 array), as its own
    class. Nothing is solved again. Raises InvalidInput for bytes that are not a warp archive of this
    version (naming the byte at fault).
    """


def warp_volume(
    warp: Warp,
    input: _Path,
    output: _Path,
    *,
    sampler: _Sampler = "trilinear",
    conserve_mass: bool = False,
    vectors: Literal["auto", "push", "normal", "keep"] = "auto",
    redistance: Literal["normalize", "rebuild", "none"] = "normalize",
    seed_spacing: int = 4,
    cache_spacing: float = 0.0,
    progress: _Progress = None,
) -> list[dict[str, Any]]:
    """Warps every grid of the VDB file `input` (float, double, vec3s grids: level sets, fog
    volumes, fields; point data grids) by `warp` and writes them atomically to `output`, as
    `spacewarp deform` does. sampler: "trilinear" or "triquadratic"; conserve_mass (fog volumes);
    vectors: "auto", "push", "normal", "keep"; redistance (level sets): "normalize", "rebuild",
    "none"; seed_spacing: seeding cells in voxels; cache_spacing: a displacement cache lattice in
    voxels (0: the exact warp). Returns one dict per grid written (active voxels, inverse failures,
    mass, ...). Voxels lost are warnings; on any error nothing is written.
    """


def warp_volume_brick(
    warp: Warp,
    input: _Path,
    brick: tuple[Any, ...],
    *,
    clip: bool = False,
    sampler: _Sampler = "trilinear",
    conserve_mass: bool = False,
    vectors: Literal["auto", "push", "normal", "keep"] = "auto",
    redistance: Literal["normalize", "rebuild", "none"] = "normalize",
    seed_spacing: int = 4,
) -> VolumeBrickResult:
    """Warps one brick of VolumeBrickPlan.bricks (same warp, input and options as the plan):
    resamples the brick's output voxels from its seeding cells and returns a VolumeBrickResult for
    VolumeBrickPlan.merge. The input: read whole once per process and kept for the next bricks of
    the same file (clip False, the default), or only the brick's input box of its grid (clip True:
    OpenVDB's clipped read, whose cost is close to a whole read since every compressed leaf buffer
    is passed; the whole grid when a preimage leaves that box).
    """


def weld_soup(geometry: Geometry, *, relative_tolerance: float = 1e-09) -> SurfaceMesh:
    """The SurfaceMesh of a Geometry: vertices closer than relative_tolerance x the bounding-box
    diagonal welded into one (the default welds copies of the same point only; 0: exactly equal
    positions), polygons fanned into triangles, boundaries, non-manifold parts, dropped polygons and
    components reported (mesh.report), never refused. Raises InvalidInput for a geometry without
    polygons.
    """


def write(path: _Path, geometry: Geometry, *, ascii: bool = False) -> None:
    """Writes a Geometry to an OBJ, OFF or PLY file (binary PLY unless ascii), atomically:
    on any failure no partial file is left and an existing file is untouched.
    """
