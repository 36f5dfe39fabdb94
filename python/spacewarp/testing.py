"""The coordinate property kit: assertions for anyone's cage-coordinate test suite.

Every function takes a weight matrix (spacewarp's or any other library's) with its controls and
points and checks a property that cage coordinates are expected to have, the same figures as the
C++ kit (``coords/properties.h``). Lengths are relative to the cage size: the bounding-box
diagonal of the controls unless ``size=`` is given. On failure a :class:`PropertyError` (an
``AssertionError``, so pytest shows it) names the worst point: its row, its coordinates when
known, the measured error and the tolerance. A NaN weight fails the property it enters.

Conventions (shapes; lengths in world units):

- weights ``W``: ``(n, c)``, rows are points, columns controls. Green-style coordinates have
  ``c = V + F``: V vertex columns, then F face columns; ``vertex_columns=V`` says so (default:
  every column is a vertex column).
- column controls ``C``: ``(c, 3)``, the vertices and then (Green) the unit outward face normals;
  the reproduced position is ``W @ C``.
- cage ``vertices``: ``(V, 3)``; ``faces``: ``(F, 3)`` int triangles oriented outward, or a list
  of polygons (fan-triangulated); ``points``: ``(n, 3)``.
- ``weight_fn(points (m, 3)) -> (m, c)`` weights, called on blocks of points (bind the cage
  once, outside it).

Comparing your own coordinates with spacewarp's takes five lines::

    import spacewarp, spacewarp.testing as swt
    cage = spacewarp.Cage(V, F); W = my_library_weights(V, F, X)
    swt.assert_partition_of_unity(W)
    swt.assert_linear_reproduction(W, V, X)
    swt.assert_face_interpolation(lambda P: my_library_weights(V, F, P), V, F)

Only NumPy is needed: the kit never imports spacewarp, so it judges any library's weights.
Weight matrices are read in blocks of rows (about 32 MB each), so a 1M x 1000 matrix is never
copied whole, whatever its dtype (float32, float64, nested lists); the arithmetic is float64.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Callable, Iterable, Iterator, Optional, Sequence, Union

import numpy as np
import numpy.typing as npt

__all__ = [
    "PropertyError",
    "PropertyFigures",
    "assert_face_interpolation",
    "assert_lagrange",
    "assert_linear_reproduction",
    "assert_non_negative",
    "assert_partition_of_unity",
    "assert_similarity_reproduction",
    "green_column_controls",
    "measure_properties",
]

WeightFn = Callable[[np.ndarray], npt.ArrayLike]
"""``weight_fn(points (m, 3) float64) -> (m, c)`` weights of those points."""

ColumnControlsFn = Callable[[np.ndarray], npt.ArrayLike]
"""``column_controls(posed_vertices (V, 3)) -> (c, 3)`` the posed column controls."""

Faces = Union[npt.ArrayLike, Sequence[Sequence[int]]]
"""``(F, 3)`` int triangles, or polygons (any sequence of index sequences of length >= 3)."""

# Rows are read this many bytes at a time (at least _MIN_BLOCK_ROWS rows), as in the C++ kit:
# every figure is a maximum or a count over rows, so blocks do not change the result but keep
# the memory independent of the number of points.
_BLOCK_BYTES = 32 << 20
_MIN_BLOCK_ROWS = 256


class PropertyError(AssertionError):
    """A coordinate property does not hold.

    Attributes:
        property: which one (``"partition_of_unity"``, ``"linear_reproduction"``,
            ``"non_negative"``, ``"lagrange"``, ``"face_interpolation"``,
            ``"similarity_reproduction"``).
        index: the row of the worst point (a point, cage vertex or face sample).
        value: the measured figure there: an error (relative to the size for the
            reproductions), or for ``non_negative`` the smallest weight; NaN for a NaN weight.
        tolerance: the tolerance it broke (``atol`` or ``rtol``).
        column: the worst column of that row, when the property is per weight (else None).
        point: the worst point's coordinates ``(3,)``, when known (else None).
    """

    def __init__(self, message: str, *, prop: str, index: int, value: float, tolerance: float,
                 column: Optional[int] = None, point: Optional[np.ndarray] = None) -> None:
        super().__init__(message)
        self.property = prop
        self.index = index
        self.value = value
        self.tolerance = tolerance
        self.column = column
        self.point = point


@dataclass(frozen=True)
class PropertyFigures:
    """What :func:`measure_properties` found: the C++ ``PropertyReport`` figures.

    Errors are maxima over the rows (NaN if a weight is NaN); lengths are relative to the size.
    Only the vertex columns count for partition of unity, signs, Lagrange and face
    interpolation; every column counts for the reproductions.

    Attributes:
        sample_count: n, the number of points (rows of the weights).
        partition_of_unity: max |sum of vertex weights - 1|.
        linear_reproduction: max |W C - x| / size.
        min_weight: the smallest vertex weight.
        negative_fraction: fraction of the n x V vertex weights below zero.
        samples_with_negative: fraction of the points with a negative vertex weight.
        lagrange: max |w_i(v_j) - delta_ij| over the cage vertices; NaN when not measured (no
            ``weight_fn`` or no ``vertices``).
        face_interpolation: max |w(x) - barycentric(x)| at random points of the cage triangles;
            NaN when not measured (no ``weight_fn``, ``vertices`` or ``faces``).
        similarity_reproduction: max |W C' - S(x)| / size for the cage posed by a similarity S;
            NaN when the posed column controls cannot be built (see :func:`measure_properties`).
    """

    sample_count: int
    partition_of_unity: float
    linear_reproduction: float
    min_weight: float
    negative_fraction: float
    samples_with_negative: float
    lagrange: float
    face_interpolation: float
    similarity_reproduction: float

    def __str__(self) -> str:
        rows = [
            ("partition of unity", f"{self.partition_of_unity:.3g}", "max |sum w - 1|"),
            ("linear reproduction", f"{self.linear_reproduction:.3g}", "max |W C - x| / size"),
            ("min weight", f"{self.min_weight:.3g}", ""),
            ("negative weights", f"{100 * self.negative_fraction:.3g} %", "of n x V"),
            ("samples with negative", f"{100 * self.samples_with_negative:.3g} %", "of n"),
            ("Lagrange", f"{self.lagrange:.3g}", "max |w_i(v_j) - delta_ij|"),
            ("face interpolation", f"{self.face_interpolation:.3g}",
             "max |w - barycentric| on faces"),
            ("similarity reproduction", f"{self.similarity_reproduction:.3g}",
             "max |W C' - S(x)| / size"),
        ]
        lines = [f"coordinate properties at {self.sample_count} points:"]
        lines += [f"  {name:<24}{value:>12}  {note}".rstrip() for name, value, note in rows]
        lines.append("  (nan: not measured, or a weight is NaN)")
        return "\n".join(lines)


# --------------------------------------------------------------------------------------------
# Input checking


def _weights_array(weights: npt.ArrayLike, name: str) -> np.ndarray:
    """``weights`` as a non-empty (n, c) real array, not copied when it already is one (a
    SciPy sparse matrix is kept sparse: its blocks of rows are densified one at a time)."""
    if _is_sparse(weights):
        if len(weights.shape) != 2 or 0 in weights.shape:
            raise ValueError(f"{name} must be a non-empty (n, c) matrix, got shape "
                             f"{weights.shape}")
        return weights
    try:
        array = np.asarray(weights)
        if array.dtype.kind not in "fiub":
            array = np.asarray(weights, dtype=np.float64)
    except (TypeError, ValueError) as error:
        raise ValueError(f"{name} must be an (n, c) array of real numbers: {error}") from None
    if array.ndim != 2 or 0 in array.shape:
        raise ValueError(f"{name} must be a non-empty (n, c) array, got shape {array.shape}")
    return array


def _is_sparse(weights: object) -> bool:
    # Duck-typed, so that SciPy stays optional.
    return hasattr(weights, "toarray") and hasattr(weights, "tocsr")


def _points_array(points: npt.ArrayLike, name: str, rows: Optional[int] = None) -> np.ndarray:
    """``points`` as a finite (rows, 3) float64 array (small: 3 columns, copied if need be)."""
    try:
        array = np.asarray(points, dtype=np.float64)
    except (TypeError, ValueError) as error:
        raise ValueError(f"{name} must be an (n, 3) array of real numbers: {error}") from None
    if array.ndim != 2 or array.shape[1] != 3 or array.shape[0] == 0:
        raise ValueError(f"{name} must be a non-empty (n, 3) array, got shape {array.shape}")
    if rows is not None and array.shape[0] != rows:
        raise ValueError(f"{name} has shape {array.shape} but {rows} rows are needed")
    if not np.isfinite(array).all():
        raise ValueError(f"{name} has a non-finite coordinate (row {_first_bad_row(array)})")
    return array


def _first_bad_row(array: np.ndarray) -> int:
    return int(np.flatnonzero(~np.isfinite(array).all(axis=1))[0])


def _vertex_column_count(vertex_columns: Optional[int], columns: int) -> int:
    """The number V of vertex columns, 1 <= V <= c (default c)."""
    if vertex_columns is None:
        return columns
    if isinstance(vertex_columns, bool) or not isinstance(vertex_columns, (int, np.integer)):
        raise ValueError(f"vertex_columns must be an int, got {vertex_columns!r}")
    if not 1 <= vertex_columns <= columns:
        raise ValueError(f"vertex_columns={vertex_columns} must be in 1..{columns} "
                         f"(the weights have {columns} columns)")
    return int(vertex_columns)


def _tolerance(value: float, name: str) -> float:
    value = float(value)
    if not value >= 0.0 or math.isinf(value):
        raise ValueError(f"{name} must be finite and >= 0, got {value}")
    return value


def _cage_size(size: Optional[float], positions: np.ndarray) -> float:
    """``size``, or the bounding-box diagonal of ``positions`` (V, 3); finite and > 0."""
    if size is None:
        value = float(np.linalg.norm(positions.max(axis=0) - positions.min(axis=0)))
        if not value > 0.0:
            raise ValueError("the controls' bounding box is a single point: give size=")
        return value
    value = float(size)
    if not value > 0.0 or math.isinf(value):
        raise ValueError(f"size must be finite and > 0, got {size!r}")
    return value


def _box_center(positions: np.ndarray) -> np.ndarray:
    """The center of the bounding box of ``positions`` (V, 3)."""
    return 0.5 * (positions.min(axis=0) + positions.max(axis=0))


def _triangles(faces: Faces, vertex_count: int) -> np.ndarray:
    """``faces`` as (F, 3) int64 triangles, polygons fan-triangulated, indices checked."""
    if isinstance(faces, np.ndarray) and faces.ndim == 2:
        polygons: Iterable[Sequence[int]] = list(faces)
        if faces.dtype.kind not in "iu":
            raise ValueError(f"faces must hold integer indices, got dtype {faces.dtype}")
    else:
        polygons = faces
    triangles: list[tuple[int, int, int]] = []
    for f, polygon in enumerate(polygons):
        corners = np.asarray(polygon)
        if corners.ndim != 1 or corners.shape[0] < 3 or corners.dtype.kind not in "iu":
            raise ValueError(f"face {f} must be a sequence of >= 3 int indices, got {polygon!r}")
        if corners.min() < 0 or corners.max() >= vertex_count:
            raise ValueError(f"face {f} = {corners.tolist()} has an index outside "
                             f"0..{vertex_count - 1} (the cage has {vertex_count} vertices)")
        first = int(corners[0])
        triangles += [(first, int(corners[k]), int(corners[k + 1]))
                      for k in range(1, corners.shape[0] - 1)]
    if not triangles:
        raise ValueError("faces is empty")
    return np.array(triangles, dtype=np.int64)


def _describe_point(label: str, index: int, points: Optional[np.ndarray]) -> str:
    if points is None:
        return f"{label} {index}"
    x, y, z = points[index]
    return f"{label} {index} at ({x:.10g}, {y:.10g}, {z:.10g})"


# --------------------------------------------------------------------------------------------
# The measuring helper: every assert_* and measure_properties run checks over blocks of rows.


def _block_rows(columns: int) -> int:
    return max(_MIN_BLOCK_ROWS, _BLOCK_BYTES // (8 * max(columns, 1)))


def _array_blocks(weights: np.ndarray) -> Iterator[tuple[int, np.ndarray]]:
    """(first row, float64 rows) of ``weights`` (dense or sparse); a view when it already is
    dense float64."""
    step = _block_rows(weights.shape[1])
    rows = weights.tocsr() if _is_sparse(weights) else weights
    for start in range(0, weights.shape[0], step):
        yield start, _dense(rows[start:start + step])


def _dense(rows: npt.ArrayLike) -> np.ndarray:
    """A block of weight rows as a dense float64 array (a view when it already is one)."""
    return np.asarray(rows.toarray() if _is_sparse(rows) else rows, dtype=np.float64)


def _function_blocks(weight_fn: WeightFn, points: np.ndarray,
                     columns_hint: int) -> Iterator[tuple[int, np.ndarray]]:
    """(first row, float64 rows) of ``weight_fn`` at ``points``, a block of points per call."""
    step = _block_rows(columns_hint)
    for start in range(0, points.shape[0], step):
        part = points[start:start + step]
        block = _weights_array(weight_fn(part), "weight_fn(points)")
        if block.shape[0] != part.shape[0]:
            raise ValueError(f"weight_fn returned shape {block.shape} for {part.shape[0]} points")
        yield start, _dense(block)


def _weight_blocks(weights_or_fn: Union[npt.ArrayLike, WeightFn], points: np.ndarray,
                   columns_hint: int) -> Iterator[tuple[int, np.ndarray]]:
    """Blocks of a weight matrix with a row per point, or of ``weight_fn`` at the points."""
    if callable(weights_or_fn):
        return _function_blocks(weights_or_fn, points, columns_hint)
    weights = _weights_array(weights_or_fn, "weights")
    if weights.shape[0] != points.shape[0]:
        raise ValueError(f"weights have shape {weights.shape} but points have shape "
                         f"{points.shape}: one row of weights per point is needed")
    return _array_blocks(weights)


class _Check:
    """One property measured row by row: keeps the largest per-row error and where it is.

    A NaN error is larger than any other (NaN compares false, so it would otherwise pass);
    among equal errors the first row wins.
    """

    name = ""   # PropertyError.property
    title = ""  # the property in a failure message
    unit = ""   # what the error measures, in a failure message

    def __init__(self) -> None:
        self.value = -math.inf
        self.index = -1
        self.column: Optional[int] = None

    def begin(self, columns: int) -> None:
        """Called once with the weights' column count c before the first block."""

    def visit(self, start: int, block: np.ndarray) -> None:
        """Measures the rows ``block`` (m, c) float64, the first being row ``start``."""
        raise NotImplementedError

    def _keep(self, start: int, errors: np.ndarray, columns: Optional[np.ndarray]) -> None:
        k = int(np.argmax(errors))  # the first NaN if there is one
        error = float(errors[k])
        if math.isnan(self.value):
            return
        if math.isnan(error) or error > self.value:
            self.value, self.index = error, start + k
            self.column = None if columns is None else int(columns[k])

    def figure(self) -> float:
        """The measured figure: the largest error (NaN if a weight is NaN)."""
        return self.value

    def require(self, tolerance: float, where: Callable[[int], str],
                points: Optional[np.ndarray]) -> None:
        """Raises PropertyError unless the largest error is <= tolerance (NaN fails)."""
        if self.value <= tolerance:
            return
        nan = " (a weight is NaN)" if math.isnan(self.value) else ""
        raise PropertyError(
            f"{self.title} fails at {where(self.index)}: {self._failure(tolerance)}{nan}",
            prop=self.name, index=self.index, value=self.figure(), tolerance=tolerance,
            column=self.column, point=None if points is None else points[self.index].copy())

    def _failure(self, tolerance: float) -> str:
        return f"{self.unit} = {self.value:.3g} > atol {tolerance:.3g}"


def _vertex_part(block: np.ndarray, vertex_columns: int) -> np.ndarray:
    return block if block.shape[1] == vertex_columns else block[:, :vertex_columns]


class _PartitionCheck(_Check):
    """|sum of the vertex weights - 1| (a row sum: no block-sized temporary)."""

    name, title = "partition_of_unity", "partition of unity"
    unit = "|sum of vertex weights - 1|"

    def __init__(self, vertex_columns: int) -> None:
        super().__init__()
        self.vertex_columns = vertex_columns

    def visit(self, start: int, block: np.ndarray) -> None:
        sums = _vertex_part(block, self.vertex_columns).sum(axis=1)
        self._keep(start, np.abs(sums - 1.0), None)


class _SignCheck(_Check):
    """The smallest vertex weight (kept as its negation, the "error"), and negative counts."""

    name, title = "non_negative", "non-negativity"

    def __init__(self, vertex_columns: int) -> None:
        super().__init__()
        self.vertex_columns = vertex_columns
        self.negative = 0
        self.rows_with_negative = 0

    def visit(self, start: int, block: np.ndarray) -> None:
        part = _vertex_part(block, self.vertex_columns)
        columns = np.argmin(part, axis=1)  # a NaN is the minimum
        smallest = part[np.arange(part.shape[0]), columns]
        self._keep(start, -smallest, columns)
        negative = part < 0.0
        self.negative += int(np.count_nonzero(negative))
        self.rows_with_negative += int(np.count_nonzero(negative.any(axis=1)))

    def figure(self) -> float:
        """The smallest weight (NaN if a weight is NaN)."""
        return -self.value

    def _failure(self, tolerance: float) -> str:
        return (f"weight [{self.index}, {self.column}] = {self.figure():.3g} < -atol "
                f"(atol {tolerance:.3g})")


class _ReproductionCheck(_Check):
    """|W K - T| / size: K the column controls (vertex columns relative to a center o), T the
    expected positions relative to o, so that the figure does not depend on the world origin."""

    def __init__(self, name: str, unit: str, make_columns: Callable[[int], np.ndarray],
                 targets: np.ndarray, size: float) -> None:
        super().__init__()
        self.name, self.title, self.unit = name, name.replace("_", " "), unit
        self.make_columns = make_columns
        self.targets = targets
        self.size = size
        self.columns = np.empty((0, 3))

    def begin(self, columns: int) -> None:
        self.columns = self.make_columns(columns)

    def visit(self, start: int, block: np.ndarray) -> None:
        difference = block @ self.columns - self.targets[start:start + block.shape[0]]
        self._keep(start, np.sqrt(np.einsum("ij,ij->i", difference, difference)) / self.size,
                   None)

    def _failure(self, tolerance: float) -> str:
        return (f"{self.unit} = {self.value * self.size:.3g} = {self.value:.3g} x size "
                f"> rtol {tolerance:.3g} (size {self.size:.6g})")


class _InterpolationCheck(_Check):
    """|w_i - e_i| over the vertex columns, where the expected row e has a few nonzeros:
    ``values[r]`` at columns ``indices[r]`` (the identity for Lagrange, a triangle's
    barycentric coordinates for face interpolation)."""

    def __init__(self, name: str, title: str, unit: str, vertex_columns: int,
                 indices: np.ndarray, values: np.ndarray) -> None:
        super().__init__()
        self.name, self.title, self.unit = name, title, unit
        self.vertex_columns = vertex_columns
        self.indices, self.values = indices, values

    def visit(self, start: int, block: np.ndarray) -> None:
        part = _vertex_part(block, self.vertex_columns)
        rows = part.shape[0]
        expected = np.zeros((rows, self.vertex_columns))
        stop = start + rows
        # add.at, not assignment: a degenerate polygon may repeat a corner.
        np.add.at(expected, (np.arange(rows)[:, None], self.indices[start:stop]),
                  self.values[start:stop])
        deviation = np.abs(part - expected)
        columns = np.argmax(deviation, axis=1)
        self._keep(start, deviation[np.arange(rows), columns], columns)

    def _failure(self, tolerance: float) -> str:
        return (f"{self.unit} in column {self.column} = {self.value:.3g} > atol "
                f"{tolerance:.3g}")


def _run(blocks: Iterable[tuple[int, np.ndarray]], checks: Sequence[_Check],
         vertex_columns: Optional[int] = None) -> int:
    """Feeds every block to every check; returns the number of rows. Checks that the column
    count is the same in every block and at least ``vertex_columns``."""
    columns = -1
    rows = 0
    for start, block in blocks:
        if columns < 0:
            columns = block.shape[1]
            if vertex_columns is not None and columns < vertex_columns:
                raise ValueError(f"the weights have {columns} columns but {vertex_columns} "
                                 "vertex columns are needed")
            for check in checks:
                check.begin(columns)
        elif block.shape[1] != columns:
            raise ValueError(f"weight rows have {block.shape[1]} columns after {columns}")
        for check in checks:
            check.visit(start, block)
        rows += block.shape[0]
    return rows


# --------------------------------------------------------------------------------------------
# The checks' inputs, shared by the asserts and measure_properties.


def _linear_check(columns: np.ndarray, vertex_columns: int, points: np.ndarray,
                  size: float) -> _ReproductionCheck:
    """|W C - x| / size, measured around the center o of the vertex columns' bounding box
    (vertex columns shifted by o, face columns are directions and are not)."""
    center = _box_center(columns[:vertex_columns])
    shifted = columns.copy()
    shifted[:vertex_columns] -= center

    def make_columns(count: int) -> np.ndarray:
        if count != columns.shape[0]:
            raise ValueError(f"columns has shape {columns.shape} but the weights have "
                             f"{count} columns: one row of columns per weight column is needed")
        return shifted

    return _ReproductionCheck("linear_reproduction", "|W C - x|", make_columns,
                              points - center, size)


def _rotation(angle: float, axis: npt.ArrayLike) -> np.ndarray:
    """The (3, 3) rotation by ``angle`` (radians) about ``axis`` (Rodrigues' formula)."""
    k = np.asarray(axis, dtype=np.float64).reshape(3)
    length = float(np.linalg.norm(k))
    if not length > 0.0 or not math.isfinite(length):
        raise ValueError(f"axis must be a finite nonzero 3-vector, got {axis!r}")
    k = k / length
    cross = np.array([[0.0, -k[2], k[1]], [k[2], 0.0, -k[0]], [-k[1], k[0], 0.0]])
    return (math.cos(angle) * np.eye(3) + math.sin(angle) * cross
            + (1.0 - math.cos(angle)) * np.outer(k, k))


def _scaled_normals(rest: np.ndarray, triangles: np.ndarray, posed: np.ndarray) -> np.ndarray:
    """Green's posed face columns s_j n'_j (F, 3), see green_column_controls()."""
    u = rest[triangles[:, 1]] - rest[triangles[:, 0]]
    v = rest[triangles[:, 2]] - rest[triangles[:, 0]]
    rest_area = 0.5 * np.linalg.norm(np.cross(u, v), axis=1)
    if not (rest_area > 0.0).all():
        raise ValueError(f"rest triangle {int(np.argmin(rest_area))} has zero area")
    pu = posed[triangles[:, 1]] - posed[triangles[:, 0]]
    pv = posed[triangles[:, 2]] - posed[triangles[:, 0]]
    cross = np.cross(pu, pv)
    length = np.linalg.norm(cross, axis=1)

    def dot(a: np.ndarray, b: np.ndarray) -> np.ndarray:
        return np.einsum("ij,ij->i", a, b)

    radicand = dot(pu, pu) * dot(v, v) - 2.0 * dot(pu, pv) * dot(u, v) + dot(pv, pv) * dot(u, u)
    stretch = np.sqrt(np.maximum(radicand, 0.0)) / (math.sqrt(8.0) * rest_area)
    # A posed triangle of zero area has no normal: its column is zero, as in the C++ kit.
    scale = np.divide(stretch, length, out=np.zeros_like(length), where=length > 0.0)
    return cross * scale[:, None]


def green_column_controls(vertices: npt.ArrayLike, faces: Faces,
                          posed_vertices: npt.ArrayLike) -> np.ndarray:
    """Green coordinates' posed column controls (Lipman, Levin, Cohen-Or 2008).

    Args:
        vertices: (V, 3) rest cage vertices.
        faces: (F, 3) int outward triangles, or polygons (fan-triangulated into F triangles).
        posed_vertices: (V, 3) posed cage vertices, same order.

    Returns:
        (V + F, 3) float64: the posed vertices, then for every triangle j the posed unit outward
        normal n'_j times the stretch factor
        ``s_j = sqrt(|u'|^2 |v|^2 - 2 (u'.v')(u.v) + |v'|^2 |u|^2) / (sqrt(8) area_j)``
        (u, v the rest edge vectors v_b - v_a, v_c - v_a; u', v' the posed ones; area_j the rest
        area): s_j = 1 at rest, k for a similarity of scale k. A posed triangle of zero area gets
        the zero vector. Units: world units for the vertices, unitless for the face columns.

    Raises:
        ValueError: wrong shapes, a non-finite coordinate, a bad index or a zero-area rest
            triangle.
    """
    rest = _points_array(vertices, "vertices")
    posed = _points_array(posed_vertices, "posed_vertices", rows=rest.shape[0])
    triangles = _triangles(faces, rest.shape[0])
    return np.vstack([posed, _scaled_normals(rest, triangles, posed)])


@dataclass(frozen=True)
class _Similarity:
    """S(x) = o + shift + linear (x - o), o the center of the cage's bounding box."""

    center: np.ndarray
    linear: np.ndarray
    shift: np.ndarray

    @staticmethod
    def make(vertices: np.ndarray, size: float, angle: float, axis: npt.ArrayLike,
             scale: float, translation: npt.ArrayLike) -> "_Similarity":
        if not float(scale) > 0.0 or not math.isfinite(float(scale)):
            raise ValueError(f"scale must be finite and > 0, got {scale!r}")
        shift = np.asarray(translation, dtype=np.float64).reshape(3) * size
        return _Similarity(_box_center(vertices), float(scale) * _rotation(float(angle), axis),
                           shift)

    def relative(self, points: np.ndarray) -> np.ndarray:
        """S(x) - o for points (n, 3): no cancellation against a far-away origin."""
        return self.shift + (points - self.center) @ self.linear.T


def _similarity_check(vertices: np.ndarray, triangles: Optional[np.ndarray],
                      column_controls: Optional[ColumnControlsFn], points: np.ndarray,
                      size: float, similarity: _Similarity) -> _ReproductionCheck:
    """|W C' - S(x)| / size, C' the column controls of the posed cage, around its center o."""
    count = vertices.shape[0]
    posed = similarity.relative(vertices)  # posed vertices minus o

    def make_columns(columns: int) -> np.ndarray:
        if column_controls is not None:
            controls = _points_array(column_controls(posed + similarity.center),
                                     "column_controls(posed_vertices)", rows=columns)
            return np.vstack([controls[:count] - similarity.center, controls[count:]])
        if columns == count:
            return posed
        if triangles is not None and columns == count + triangles.shape[0]:
            # Normals depend on edge vectors only, so the shifted posed cage gives the same.
            return np.vstack([posed, _scaled_normals(vertices, triangles, posed)])
        faces_note = ("no faces were given" if triangles is None
                      else f"{triangles.shape[0]} triangles")
        raise ValueError(f"the weights have {columns} columns but the cage has {count} vertices "
                         f"and {faces_note}: expected V = {count} or V + F columns, or give "
                         "column_controls")

    return _ReproductionCheck("similarity_reproduction", "|W C' - S(x)|", make_columns,
                              similarity.relative(points), size)


def _lagrange_check(vertex_count: int) -> _InterpolationCheck:
    identity = np.arange(vertex_count)[:, None]
    return _InterpolationCheck("lagrange", "Lagrange property", "|w_i(v_j) - delta_ij|",
                               vertex_count, identity, np.ones((vertex_count, 1)))


@dataclass(frozen=True)
class _FaceSamples:
    """Random points on the cage triangles: ``points`` (m, 3), the triangle of each, its
    corners (m, 3) and barycentric coordinates (m, 3)."""

    points: np.ndarray
    triangle: np.ndarray
    corners: np.ndarray
    barycentric: np.ndarray

    @staticmethod
    def make(vertices: np.ndarray, triangles: np.ndarray, per_face: int,
             seed: int) -> "_FaceSamples":
        if isinstance(per_face, bool) or not isinstance(per_face, (int, np.integer)) \
                or per_face < 1:
            raise ValueError(f"samples_per_face must be an int >= 1, got {per_face!r}")
        ab = np.random.default_rng(seed).random((triangles.shape[0] * per_face, 2))
        folded = ab.sum(axis=1) > 1.0  # fold the unit square onto the triangle: uniform
        ab[folded] = 1.0 - ab[folded]
        barycentric = np.column_stack([1.0 - ab.sum(axis=1), ab])
        triangle = np.repeat(np.arange(triangles.shape[0]), per_face)
        corners = triangles[triangle]
        # Relative to the first corner: on the face up to the round-off of the cage's size, not
        # of its distance from the origin.
        first = vertices[corners[:, 0]]
        points = (first + ab[:, :1] * (vertices[corners[:, 1]] - first)
                  + ab[:, 1:] * (vertices[corners[:, 2]] - first))
        return _FaceSamples(points, triangle, corners, barycentric)

    def check(self, vertex_count: int) -> _InterpolationCheck:
        return _InterpolationCheck("face_interpolation", "face interpolation",
                                   "|w - barycentric|", vertex_count, self.corners,
                                   self.barycentric)

    def where(self, index: int) -> str:
        return _describe_point(f"triangle {self.triangle[index]}, sample", index, self.points)


# --------------------------------------------------------------------------------------------
# The public assertions


def assert_partition_of_unity(weights: npt.ArrayLike, *, vertex_columns: Optional[int] = None,
                              atol: float = 1e-10, points: Optional[npt.ArrayLike] = None
                              ) -> None:
    """Asserts max_i |sum_j w_ij - 1| <= atol over the vertex columns.

    Args:
        weights: (n, c) weights (any real dtype, or nested lists).
        vertex_columns: V, how many leading columns are vertex columns (default c).
        atol: absolute tolerance (weights are unitless).
        points: optional (n, 3) points, only to give the failing point's coordinates.

    Raises:
        PropertyError: at the worst row (a NaN weight fails).
        ValueError: empty or misshapen input.
    """
    w = _weights_array(weights, "weights")
    where_points = None if points is None else _points_array(points, "points", w.shape[0])
    check = _PartitionCheck(_vertex_column_count(vertex_columns, w.shape[1]))
    _run(_array_blocks(w), [check])
    check.require(_tolerance(atol, "atol"), lambda i: _describe_point("point", i, where_points),
                  where_points)


def assert_linear_reproduction(weights: npt.ArrayLike, columns: npt.ArrayLike,
                               points: npt.ArrayLike, *, vertex_columns: Optional[int] = None,
                               size: Optional[float] = None, rtol: float = 1e-10) -> None:
    """Asserts |W C - x| <= rtol * size at every point.

    Measured around the center o of the vertex columns' bounding box (vertex columns shifted by
    o, face columns not), as the C++ kit does, so that a cage far from the origin loses no
    precision; equal to |W C - x| when the vertex weights sum to 1.

    Args:
        weights: (n, c) weights.
        columns: (c, 3) column controls: the vertices, then (Green) unit outward face normals.
        points: (n, 3) the points the weight rows belong to (world units).
        vertex_columns: V, how many leading columns are positions (default c).
        size: the length errors are relative to (default: bounding-box diagonal of the first V
            rows of ``columns``).
        rtol: tolerance relative to ``size``.

    Raises:
        PropertyError: at the worst point (its coordinates and error in the message).
        ValueError: empty or misshapen input, non-finite columns or points.
    """
    w = _weights_array(weights, "weights")
    x = _points_array(points, "points", rows=w.shape[0])
    c = _points_array(columns, "columns")
    count = _vertex_column_count(vertex_columns, w.shape[1])
    check = _linear_check(c, count, x, _cage_size(size, c[:count]))
    _run(_array_blocks(w), [check])
    check.require(_tolerance(rtol, "rtol"), lambda i: _describe_point("point", i, x), x)


def assert_lagrange(weights_at_vertices: npt.ArrayLike, *, atol: float = 1e-10,
                    vertices: Optional[npt.ArrayLike] = None) -> None:
    """Asserts |w_i(v_j) - delta_ij| <= atol: the weights at the cage vertices are the identity.

    Args:
        weights_at_vertices: (V, c) weights evaluated at the V cage vertices, c >= V; row j
            must be 1 in column j and 0 in the other vertex columns (later columns, such as
            Green's face columns, are not checked).
        atol: absolute tolerance (unitless).
        vertices: optional (V, 3) cage vertices, only to give the failing vertex's coordinates.

    Raises:
        PropertyError: at the worst vertex, naming the column.
        ValueError: empty input, or fewer columns than rows.
    """
    w = _weights_array(weights_at_vertices, "weights_at_vertices")
    count = w.shape[0]
    where_points = None if vertices is None else _points_array(vertices, "vertices", count)
    check = _lagrange_check(count)
    _run(_array_blocks(w), [check], vertex_columns=count)
    check.require(_tolerance(atol, "atol"),
                  lambda i: _describe_point("cage vertex", i, where_points), where_points)


def assert_face_interpolation(weight_fn: WeightFn, vertices: npt.ArrayLike, faces: Faces, *,
                              samples_per_face: int = 4, seed: int = 1, atol: float = 1e-10
                              ) -> None:
    """Asserts that the weights are linear on the cage faces: at ``samples_per_face`` uniform
    random points of every triangle (deterministic for ``seed``), the V vertex weights equal the
    triangle's barycentric coordinates at its three corners and 0 elsewhere, within ``atol``.

    Args:
        weight_fn: ``weight_fn(points (m, 3)) -> (m, c)`` weights, c >= V (columns after the
            first V are not checked).
        vertices: (V, 3) cage vertices.
        faces: (F, 3) int triangles, or polygons (fan-triangulated).
        samples_per_face: random points per triangle.
        seed: seed of NumPy's default_rng for those points.
        atol: absolute tolerance (unitless).

    Raises:
        PropertyError: at the worst sample (its triangle, coordinates and column).
        ValueError: misshapen input, bad face indices, or weight_fn returning a wrong shape.
    """
    v = _points_array(vertices, "vertices")
    samples = _FaceSamples.make(v, _triangles(faces, v.shape[0]), samples_per_face, seed)
    check = samples.check(v.shape[0])
    _run(_function_blocks(weight_fn, samples.points, v.shape[0]), [check],
         vertex_columns=v.shape[0])
    check.require(_tolerance(atol, "atol"), samples.where, samples.points)


def assert_non_negative(weights: npt.ArrayLike, *, vertex_columns: Optional[int] = None,
                        atol: float = 0.0, points: Optional[npt.ArrayLike] = None) -> None:
    """Asserts that every vertex weight is >= -atol.

    Args:
        weights: (n, c) weights.
        vertex_columns: V, how many leading columns are checked (default c).
        atol: how negative a weight may be (unitless, >= 0).
        points: optional (n, 3) points, only to give the failing point's coordinates.

    Raises:
        PropertyError: at the smallest weight (``.value``), naming its row and column; a NaN
            weight fails.
        ValueError: empty or misshapen input.
    """
    w = _weights_array(weights, "weights")
    where_points = None if points is None else _points_array(points, "points", w.shape[0])
    check = _SignCheck(_vertex_column_count(vertex_columns, w.shape[1]))
    _run(_array_blocks(w), [check])
    check.require(_tolerance(atol, "atol"), lambda i: _describe_point("point", i, where_points),
                  where_points)


def assert_similarity_reproduction(
        weight_fn_or_weights: Union[WeightFn, npt.ArrayLike], vertices: npt.ArrayLike,
        faces: Optional[Faces], points: npt.ArrayLike, *,
        column_controls: Optional[ColumnControlsFn] = None, angle: float = 0.7,
        axis: npt.ArrayLike = (1.0, 2.0, 3.0), scale: float = 1.3,
        translation: npt.ArrayLike = (0.1, -0.2, 0.3), size: Optional[float] = None,
        rtol: float = 1e-10) -> None:
    """Asserts |W C' - S(x)| <= rtol * size for the cage posed by a similarity S.

    S rotates by ``angle`` (radians) about ``axis`` and scales by ``scale`` about the center o
    of the cage's bounding box, then translates by ``translation`` x size. The posed column
    controls C' are, by default, the posed vertices for weights with V columns, or for V + F
    columns the posed vertices then Green's scaled posed normals (see green_column_controls);
    else ``column_controls(posed_vertices (V, 3)) -> (c, 3)``. A similarity is affine, so
    linearly precise coordinates pass; Green coordinates pass because they reproduce
    similarities.

    Args:
        weight_fn_or_weights: (n, c) weights at ``points``, or ``weight_fn(points) -> (m, c)``.
        vertices: (V, 3) rest cage vertices (the first V columns).
        faces: (F, 3) int outward triangles or polygons; only needed for Green's default
            columns (may be None otherwise).
        points: (n, 3) points (world units).
        column_controls: optional builder of the posed column controls.
        angle, axis, scale, translation: the similarity (radians, a 3-vector, > 0, units of
            size).
        size: the length errors are relative to (default: the vertices' bounding-box diagonal).
        rtol: tolerance relative to ``size``.

    Raises:
        PropertyError: at the worst point.
        ValueError: misshapen input, or column counts that match neither V nor V + F.
    """
    v = _points_array(vertices, "vertices")
    x = _points_array(points, "points")
    length = _cage_size(size, v)
    triangles = None if faces is None else _triangles(faces, v.shape[0])
    similarity = _Similarity.make(v, length, angle, axis, scale, translation)
    check = _similarity_check(v, triangles, column_controls, x, length, similarity)
    hint = v.shape[0] + (0 if triangles is None else triangles.shape[0])
    _run(_weight_blocks(weight_fn_or_weights, x, hint), [check], vertex_columns=v.shape[0])
    check.require(_tolerance(rtol, "rtol"), lambda i: _describe_point("point", i, x), x)


def measure_properties(
        weights: npt.ArrayLike, columns: npt.ArrayLike, points: npt.ArrayLike, *,
        vertex_columns: Optional[int] = None, vertices: Optional[npt.ArrayLike] = None,
        faces: Optional[Faces] = None, weight_fn: Optional[WeightFn] = None,
        size: Optional[float] = None, column_controls: Optional[ColumnControlsFn] = None,
        samples_per_face: int = 4, seed: int = 1, angle: float = 0.7,
        axis: npt.ArrayLike = (1.0, 2.0, 3.0), scale: float = 1.3,
        translation: npt.ArrayLike = (0.1, -0.2, 0.3)) -> PropertyFigures:
    """Measures every property the asserts check, with the same helper, without asserting.

    Args:
        weights: (n, c) weights at ``points``.
        columns: (c, 3) rest column controls.
        points: (n, 3) points (world units).
        vertex_columns: V (default: the number of ``vertices`` if given, else c).
        vertices: (V, 3) cage vertices: enables Lagrange (with ``weight_fn``) and face
            interpolation (with ``weight_fn`` and ``faces``).
        faces: (F, 3) int outward triangles or polygons.
        weight_fn: ``weight_fn(points (m, 3)) -> (m, c)``, evaluated at the cage vertices and at
            random face points.
        size: the length the reproductions are relative to (default: bounding-box diagonal of
            the first V rows of ``columns``); the similarity's translation is in this unit too.
        column_controls: optional builder of posed column controls (see
            assert_similarity_reproduction).
        samples_per_face, seed: the face samples (see assert_face_interpolation).
        angle, axis, scale, translation: the similarity (see assert_similarity_reproduction).

    Returns:
        The PropertyFigures. similarity_reproduction poses the vertex columns (or ``vertices``)
        and is NaN when the posed column controls cannot be built: no ``column_controls``, and
        c is neither V nor V + F with ``faces`` given. A NaN weight makes the figures it enters
        NaN.

    Raises:
        ValueError: misshapen input (shapes named in the message).
    """
    w = _weights_array(weights, "weights")
    x = _points_array(points, "points", rows=w.shape[0])
    c = _points_array(columns, "columns")
    v = None if vertices is None else _points_array(vertices, "vertices")
    if vertex_columns is None and v is not None:
        vertex_columns = v.shape[0]
    count = _vertex_column_count(vertex_columns, w.shape[1])
    if v is not None and v.shape[0] != count:
        raise ValueError(f"vertices has shape {v.shape} but vertex_columns={count}")
    cage = c[:count] if v is None else v
    length = _cage_size(size, c[:count])
    triangles = None if faces is None else _triangles(faces, count)

    partition, signs = _PartitionCheck(count), _SignCheck(count)
    checks: list[_Check] = [partition, signs, _linear_check(c, count, x, length)]
    posable = (column_controls is not None or w.shape[1] == count
               or (triangles is not None and w.shape[1] == count + triangles.shape[0]))
    if posable:
        similarity = _Similarity.make(cage, length, angle, axis, scale, translation)
        checks.append(_similarity_check(cage, triangles, column_controls, x, length,
                                        similarity))
    rows = _run(_array_blocks(w), checks)

    lagrange = face = math.nan
    if weight_fn is not None and v is not None:
        check = _lagrange_check(count)
        _run(_function_blocks(weight_fn, v, w.shape[1]), [check], vertex_columns=count)
        lagrange = check.figure()
        if triangles is not None:
            samples = _FaceSamples.make(v, triangles, samples_per_face, seed)
            check = samples.check(count)
            _run(_function_blocks(weight_fn, samples.points, w.shape[1]), [check],
                 vertex_columns=count)
            face = check.figure()

    return PropertyFigures(
        sample_count=rows,
        partition_of_unity=partition.figure(),
        linear_reproduction=checks[2].figure(),
        min_weight=signs.figure(),
        negative_fraction=signs.negative / (rows * count),
        samples_with_negative=signs.rows_with_negative / rows,
        lagrange=lagrange,
        face_interpolation=face,
        similarity_reproduction=checks[3].figure() if posable else math.nan,
    )
