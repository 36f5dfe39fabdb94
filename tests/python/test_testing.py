"""Tests of spacewarp.testing, the coordinate property kit.

Closed-form coordinates (a tetrahedron's barycentric coordinates, a box's trilinear weights,
hand-made Green-style weights) must pass; deliberately broken weights must fail and name the
worst point. Runs without the compiled extension: testing.py is loaded by path if the package
cannot be imported.
"""

from __future__ import annotations

import importlib.util
import math
import sys
import tracemalloc
from pathlib import Path
from types import ModuleType
from typing import Callable, ContextManager, Optional

import numpy as np
import pytest

try:
    import spacewarp.testing as swt
except ImportError:  # the package's __init__ needs the extension, which is not built yet
    _PATH = Path(__file__).resolve().parents[2] / "python" / "spacewarp" / "testing.py"
    _SPEC = importlib.util.spec_from_file_location("spacewarp_testing", _PATH)
    assert _SPEC is not None and _SPEC.loader is not None
    swt = importlib.util.module_from_spec(_SPEC)
    sys.modules["spacewarp_testing"] = swt  # dataclasses look their module up here
    _SPEC.loader.exec_module(swt)

PropertyError = swt.PropertyError

# A tetrahedron in general position, its faces oriented outward.
TET = np.array([[0.1, 0.2, -0.3], [1.3, 0.1, 0.2], [0.2, 1.1, 0.3], [0.3, 0.4, 1.2]])
TET_FACES = np.array([[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]])

# A box [0, 2] x [0, 1] x [0, 3]: corner i + 2 j + 4 k is at (2 i, j, 3 k); faces outward quads.
BOX_LOW, BOX_HIGH = np.array([0.0, 0.0, 0.0]), np.array([2.0, 1.0, 3.0])
BOX = np.array([BOX_LOW + (BOX_HIGH - BOX_LOW) * [i, j, k]
                for k in (0, 1) for j in (0, 1) for i in (0, 1)])
BOX_QUADS = [[0, 2, 3, 1], [4, 5, 7, 6], [0, 1, 5, 4], [2, 6, 7, 3], [0, 4, 6, 2], [1, 3, 7, 5]]


def barycentric(vertices: np.ndarray, points: np.ndarray) -> np.ndarray:
    """(n, 4) barycentric coordinates of points (n, 3) in the tetrahedron vertices (4, 3)."""
    edges = (vertices[1:] - vertices[0]).T
    rest = np.linalg.solve(edges, (np.asarray(points, dtype=float) - vertices[0]).T).T
    return np.column_stack([1.0 - rest.sum(axis=1), rest])


def trilinear(points: np.ndarray) -> np.ndarray:
    """(n, 8) trilinear weights of the BOX corners."""
    t = (np.asarray(points) - BOX_LOW) / (BOX_HIGH - BOX_LOW)
    return np.column_stack([
        (t[:, 0] if i else 1 - t[:, 0]) * (t[:, 1] if j else 1 - t[:, 1])
        * (t[:, 2] if k else 1 - t[:, 2])
        for k in (0, 1) for j in (0, 1) for i in (0, 1)])


def inside_tet(vertices: np.ndarray, count: int, seed: int = 0) -> np.ndarray:
    """Random points strictly inside the tetrahedron."""
    mix = np.random.default_rng(seed).uniform(0.05, 1.0, (count, 4))
    return (mix / mix.sum(axis=1, keepdims=True)) @ vertices


def signed_volume(vertices: np.ndarray, triangles: np.ndarray) -> float:
    """Volume enclosed by the triangles: positive when they are oriented outward."""
    a, b, c = (vertices[triangles[:, k]] for k in range(3))
    return float(np.einsum("ij,ij->i", a, np.cross(b, c)).sum() / 6.0)


def fan(polygons: list[list[int]]) -> np.ndarray:
    return np.array([[p[0], p[k], p[k + 1]] for p in polygons for k in range(1, len(p) - 1)])


def unit_normals(vertices: np.ndarray, triangles: np.ndarray) -> np.ndarray:
    cross = np.cross(vertices[triangles[:, 1]] - vertices[triangles[:, 0]],
                     vertices[triangles[:, 2]] - vertices[triangles[:, 0]])
    return cross / np.linalg.norm(cross, axis=1, keepdims=True)


def rotation(angle: float, axis: np.ndarray) -> np.ndarray:
    """Rotation matrix by exponentiating the cross-product matrix (independent of the kit)."""
    k = np.asarray(axis, dtype=float) / np.linalg.norm(axis)
    cross = np.array([[0, -k[2], k[1]], [k[2], 0, -k[0]], [-k[1], k[0], 0]])
    result, term = np.eye(3), np.eye(3)
    for n in range(1, 40):
        term = term @ (angle * cross) / n
        result = result + term
    return result


def green_style_weights(vertices: np.ndarray, triangles: np.ndarray, points: np.ndarray,
                        seed: int = 3) -> np.ndarray:
    """(n, V + F) weights x = sum phi_i v_i + sum psi_j n_j with random psi >= 0 and phi the
    barycentric coordinates of x - sum psi_j n_j: they reproduce similarities exactly when the
    face columns are posed as Green's scaled normals, as Green coordinates do."""
    size = np.linalg.norm(vertices.max(axis=0) - vertices.min(axis=0))
    psi = np.random.default_rng(seed).uniform(0.0, 0.05 * size, (points.shape[0], len(triangles)))
    phi = barycentric(vertices, points - psi @ unit_normals(vertices, triangles))
    return np.column_stack([phi, psi])


def raises_at(index: int, prop: str) -> ContextManager[pytest.ExceptionInfo[PropertyError]]:
    """pytest.raises for a PropertyError of `prop` whose message names row `index`."""
    return pytest.raises(PropertyError, match=rf"{prop.replace('_', ' ')} fails at .*\b{index}\b")


# ---------------------------------------------------------------------------------------------
# Closed-form coordinates pass


def test_cages_are_oriented_outward() -> None:
    assert signed_volume(TET, TET_FACES) > 0
    assert signed_volume(BOX, fan(BOX_QUADS)) == pytest.approx(6.0)


def test_tetrahedron_barycentric_coordinates_have_every_property() -> None:
    points = inside_tet(TET, 200)
    weights = barycentric(TET, points)
    swt.assert_partition_of_unity(weights, atol=1e-14)
    swt.assert_linear_reproduction(weights, TET, points, rtol=1e-14)
    swt.assert_lagrange(barycentric(TET, TET), atol=1e-14)
    swt.assert_face_interpolation(lambda p: barycentric(TET, p), TET, TET_FACES, atol=1e-14)
    swt.assert_non_negative(weights)
    swt.assert_similarity_reproduction(weights, TET, TET_FACES, points, rtol=1e-14)
    swt.assert_similarity_reproduction(lambda p: barycentric(TET, p), TET, None, points,
                                       rtol=1e-14)

    figures = swt.measure_properties(weights, TET, points, vertices=TET, faces=TET_FACES,
                                     weight_fn=lambda p: barycentric(TET, p))
    assert figures.sample_count == 200
    for value in (figures.partition_of_unity, figures.linear_reproduction, figures.lagrange,
                  figures.face_interpolation, figures.similarity_reproduction):
        assert 0.0 <= value <= 1e-14
    assert figures.min_weight == pytest.approx(weights.min(), abs=0)
    assert figures.min_weight > 0
    assert figures.negative_fraction == 0 and figures.samples_with_negative == 0


def test_box_trilinear_weights_pass_all_but_face_linearity() -> None:
    points = np.random.default_rng(1).uniform(BOX_LOW, BOX_HIGH, (300, 3))
    weights = trilinear(points)
    swt.assert_partition_of_unity(weights, atol=1e-14)
    swt.assert_linear_reproduction(weights, BOX, points, rtol=1e-14)
    swt.assert_lagrange(trilinear(BOX), atol=1e-14)
    swt.assert_non_negative(weights)
    swt.assert_similarity_reproduction(weights, BOX, BOX_QUADS, points, rtol=1e-14)

    # Trilinear weights are bilinear on a box face, not linear on its triangles: up to 1/4.
    with pytest.raises(PropertyError, match="face interpolation fails at triangle") as failure:
        swt.assert_face_interpolation(trilinear, BOX, BOX_QUADS)
    assert failure.value.property == "face_interpolation"
    assert 0.01 < failure.value.value <= 0.25
    swt.assert_face_interpolation(trilinear, BOX, BOX_QUADS, atol=0.25)


def test_polygon_faces_are_fan_triangulated() -> None:
    def face_figure(faces: object) -> float:
        return swt.measure_properties(trilinear(BOX), BOX, BOX, vertices=BOX, faces=faces,
                                      weight_fn=trilinear).face_interpolation

    expected = face_figure(fan(BOX_QUADS))
    assert expected > 0.01
    assert face_figure(BOX_QUADS) == expected  # a list of polygons
    assert face_figure(np.array(BOX_QUADS)) == expected  # an (F, 4) array
    green = swt.green_column_controls(BOX, BOX_QUADS, BOX)
    assert green.shape == (8 + 12, 3)
    np.testing.assert_allclose(green[8:], unit_normals(BOX, fan(BOX_QUADS)), atol=1e-15)


def test_face_samples_are_deterministic_for_a_seed() -> None:
    def failure_value(seed: int) -> float:
        with pytest.raises(PropertyError) as failure:
            swt.assert_face_interpolation(trilinear, BOX, BOX_QUADS, seed=seed)
        return failure.value.value

    assert failure_value(5) == failure_value(5)
    assert failure_value(5) != failure_value(6)


# ---------------------------------------------------------------------------------------------
# Green's stretch factor and similarity reproduction


@pytest.mark.parametrize("scale", [0.4, 1.0, 1.3, 7.0])
def test_green_stretch_factor_is_the_scale_of_a_similarity(scale: float) -> None:
    turn = rotation(0.9, np.array([0.3, -1.0, 2.0]))
    posed = scale * TET @ turn.T + np.array([5.0, -2.0, 1.0])
    columns = swt.green_column_controls(TET, TET_FACES, posed)
    np.testing.assert_array_equal(columns[:4], posed)
    np.testing.assert_allclose(np.linalg.norm(columns[4:], axis=1), scale, rtol=1e-14)
    np.testing.assert_allclose(columns[4:], scale * unit_normals(TET, TET_FACES) @ turn.T,
                               atol=1e-14 * scale)


def test_green_stretch_factor_of_an_in_plane_stretch() -> None:
    # u = (1, 0, 0), v = (0, 1, 0) stretched to (a, 0, 0), (0, b, 0): s = sqrt((a^2 + b^2) / 2),
    # the root mean square of the singular values.
    rest = np.array([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]])
    posed = rest * [2.0, 0.5, 1.0]
    columns = swt.green_column_controls(rest, [[0, 1, 2]], posed)
    np.testing.assert_allclose(columns[3], [0.0, 0.0, math.sqrt((4.0 + 0.25) / 2.0)],
                               rtol=1e-15)
    flat = swt.green_column_controls(rest, [[0, 1, 2]], rest * [1.0, 0.0, 1.0])
    np.testing.assert_array_equal(flat[3], 0.0)  # a posed triangle of zero area


def test_green_style_weights_reproduce_similarities_with_scaled_normals() -> None:
    points = inside_tet(TET, 100)
    weights = green_style_weights(TET, TET_FACES, points)
    columns = np.vstack([TET, unit_normals(TET, TET_FACES)])
    swt.assert_partition_of_unity(weights, vertex_columns=4, atol=1e-14)
    swt.assert_linear_reproduction(weights, columns, points, vertex_columns=4, rtol=1e-14)
    swt.assert_similarity_reproduction(weights, TET, TET_FACES, points, rtol=1e-13)
    figures = swt.measure_properties(weights, columns, points, vertices=TET, faces=TET_FACES)
    assert figures.similarity_reproduction <= 1e-13
    assert math.isnan(figures.lagrange) and math.isnan(figures.face_interpolation)

    def unit_posed_normals(posed: np.ndarray) -> np.ndarray:  # forgets the stretch factor
        return np.vstack([posed, unit_normals(posed, TET_FACES)])

    swt.assert_similarity_reproduction(weights, TET, TET_FACES, points, scale=1.0, rtol=1e-13,
                                       column_controls=unit_posed_normals)
    with pytest.raises(PropertyError, match="similarity reproduction fails"):
        swt.assert_similarity_reproduction(weights, TET, TET_FACES, points,
                                           column_controls=unit_posed_normals)
    with pytest.raises(PropertyError, match="similarity reproduction fails"):  # inward faces
        swt.assert_similarity_reproduction(weights, TET, TET_FACES[:, ::-1], points)


# ---------------------------------------------------------------------------------------------
# Broken weights fail and name the worst point


def test_perturbed_row_is_named() -> None:
    points = inside_tet(TET, 60)
    weights = barycentric(TET, points)
    weights[37, 2] += 1e-3
    weights[12, 1] += 1e-6  # also wrong, but less: the worst row is 37

    for check in (lambda: swt.assert_partition_of_unity(weights, points=points),
                  lambda: swt.assert_linear_reproduction(weights, TET, points),
                  lambda: swt.assert_similarity_reproduction(weights, TET, TET_FACES, points)):
        with pytest.raises(PropertyError, match=r"fails at point 37 at \(") as failure:
            check()
        assert failure.value.index == 37
        np.testing.assert_array_equal(failure.value.point, points[37])
        assert failure.value.tolerance == 1e-10
        assert f"{points[37, 0]:.10g}" in str(failure.value)
    with raises_at(37, "partition_of_unity") as failure:
        swt.assert_partition_of_unity(weights)
    assert failure.value.value == pytest.approx(1e-3, rel=1e-9)
    assert failure.value.point is None
    swt.assert_partition_of_unity(weights, atol=1.1e-3)


def test_property_error_is_an_assertion_error_with_attributes() -> None:
    weights = barycentric(TET, inside_tet(TET, 10))
    weights[4] *= 2.0
    with pytest.raises(AssertionError) as failure:
        swt.assert_partition_of_unity(weights, atol=1e-12)
    error = failure.value
    assert isinstance(error, PropertyError)
    assert (error.property, error.index, error.tolerance) == ("partition_of_unity", 4, 1e-12)
    assert error.value == pytest.approx(1.0)
    assert "1e-12" in str(error)


def test_broken_lagrange_and_face_interpolation_are_named() -> None:
    swapped = [0, 1, 3, 2]  # columns 2 and 3 exchanged
    with raises_at(2, "Lagrange property") as failure:
        swt.assert_lagrange(barycentric(TET, TET)[:, swapped], vertices=TET)
    assert (failure.value.index, failure.value.column) == (2, 2)
    assert "(0.2, 1.1, 0.3)" in str(failure.value)
    with pytest.raises(PropertyError, match=r"face interpolation fails at triangle \d") as failure:
        swt.assert_face_interpolation(lambda p: barycentric(TET, p)[:, swapped], TET, TET_FACES)
    assert failure.value.column in (2, 3)
    with pytest.raises(ValueError, match="4 columns but 5 vertex columns"):
        swt.assert_lagrange(np.eye(5, 4))


def test_negative_weight_is_named_with_its_column() -> None:
    points = inside_tet(TET, 30)
    weights = barycentric(TET, points)
    weights[21, 0] += weights[21, 3] + 0.2  # still a partition of unity
    weights[21, 3] = -0.2
    weights[8, 1] = -0.01
    swt.assert_partition_of_unity(weights[20:], atol=1e-14)
    with raises_at(21, "non-negativity") as failure:
        swt.assert_non_negative(weights, points=points)
    assert (failure.value.index, failure.value.column) == (21, 3)
    assert failure.value.value == pytest.approx(weights[21, 3])
    assert "weight [21, 3]" in str(failure.value)
    swt.assert_non_negative(weights, atol=0.3)
    swt.assert_non_negative(weights[:, :3], atol=0.01)  # vertex columns only: row 8 remains
    with raises_at(8, "non-negativity"):
        swt.assert_non_negative(weights, vertex_columns=3)


def test_outside_points_negative_weights_are_counted() -> None:
    points = np.random.default_rng(2).uniform(-0.5, 1.5, (400, 3))
    weights = barycentric(TET, points)
    figures = swt.measure_properties(weights, TET, points)
    assert figures.negative_fraction == np.mean(weights < 0)
    assert figures.samples_with_negative == np.mean((weights < 0).any(axis=1))
    assert figures.min_weight == weights.min()
    assert figures.linear_reproduction <= 1e-14
    row, column = np.unravel_index(np.argmin(weights), weights.shape)
    with raises_at(int(row), "non-negativity") as failure:
        swt.assert_non_negative(weights)
    assert failure.value.column == column


def test_nan_weight_fails_every_property() -> None:
    points = inside_tet(TET, 20)
    weights = barycentric(TET, points)
    weights[9, 3] = np.nan
    for check in (lambda: swt.assert_partition_of_unity(weights, atol=1e9),
                  lambda: swt.assert_linear_reproduction(weights, TET, points, rtol=1e9),
                  lambda: swt.assert_non_negative(weights, atol=1e9),
                  lambda: swt.assert_similarity_reproduction(weights, TET, TET_FACES, points,
                                                             rtol=1e9)):
        with pytest.raises(PropertyError, match=r"point 9\b.*a weight is NaN") as failure:
            check()
        assert failure.value.index == 9 and math.isnan(failure.value.value)

    def nan_at_vertex_2(p: np.ndarray) -> np.ndarray:
        result = barycentric(TET, p)
        result[np.all(np.isclose(p, TET[2]), axis=1), 0] = np.nan
        return result

    with raises_at(2, "Lagrange property"):
        swt.assert_lagrange(nan_at_vertex_2(TET), atol=1e9)
    figures = swt.measure_properties(weights, TET, points, vertices=TET, faces=TET_FACES,
                                     weight_fn=nan_at_vertex_2)
    assert math.isnan(figures.partition_of_unity) and math.isnan(figures.min_weight)
    assert math.isnan(figures.linear_reproduction)
    assert math.isnan(figures.similarity_reproduction) and math.isnan(figures.lagrange)
    assert figures.face_interpolation <= 1e-14


def test_nan_in_a_later_block_beats_a_larger_error(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(swt, "_BLOCK_BYTES", 8 * 4 * 100)  # 256 rows a block (the minimum)
    points = inside_tet(TET, 1000)
    weights = barycentric(TET, points)
    weights[3, 0] += 100.0
    weights[900, 1] = np.nan
    with raises_at(900, "partition_of_unity"):
        swt.assert_partition_of_unity(weights, atol=1e9)
    with raises_at(900, "non-negativity"):
        swt.assert_non_negative(weights)


def test_blocks_do_not_change_the_figures(monkeypatch: pytest.MonkeyPatch) -> None:
    points = np.random.default_rng(4).uniform(-0.5, 1.5, (2000, 3))
    weights = green_style_weights(TET, TET_FACES, points)
    weights[1500, 2] += 1e-7
    columns = np.vstack([TET, unit_normals(TET, TET_FACES)])

    def measure() -> swt.PropertyFigures:
        return swt.measure_properties(weights, columns, points, vertices=TET, faces=TET_FACES,
                                      weight_fn=lambda p: green_style_weights(TET, TET_FACES, p))

    whole = measure()
    monkeypatch.setattr(swt, "_BLOCK_BYTES", 1)  # 256 rows a block
    assert measure() == whole
    assert whole.partition_of_unity == pytest.approx(1e-7, rel=1e-6)


def test_weight_fn_is_called_on_blocks_of_points(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(swt, "_BLOCK_BYTES", 1)  # 256 rows a block
    sizes: list[int] = []

    def weight_fn(p: np.ndarray) -> np.ndarray:
        sizes.append(len(p))
        return trilinear(p)

    points = np.random.default_rng(5).uniform(BOX_LOW, BOX_HIGH, (600, 3))
    swt.assert_similarity_reproduction(weight_fn, BOX, None, points, rtol=1e-14)
    assert sizes == [256, 256, 88]

    def broken_at_590(p: np.ndarray) -> np.ndarray:
        result = trilinear(p)
        result[np.all(p == points[590], axis=1), 5] += 1e-6
        return result

    with raises_at(590, "similarity_reproduction"):
        swt.assert_similarity_reproduction(broken_at_590, BOX, None, points)


# ---------------------------------------------------------------------------------------------
# Tolerances are relative to the cage size; inputs of any real dtype


@pytest.mark.parametrize("scale, offset", [(1.0, 0.0), (1e6, 1e8), (1e-6, -2e-5)])
def test_tolerances_are_relative_to_the_cage_size(scale: float, offset: float) -> None:
    cage = TET * scale + offset
    points = inside_tet(cage, 100)
    weights = barycentric(cage, points)
    swt.assert_linear_reproduction(weights, cage, points, rtol=1e-12)
    swt.assert_similarity_reproduction(weights, cage, TET_FACES, points, rtol=1e-12)
    swt.assert_face_interpolation(lambda p: barycentric(cage, p), cage, TET_FACES, atol=1e-12)
    # Sums 1 + 1e-11: around the cage center the error is 1e-11 of the size; measured from
    # the world origin it would be 1e-11 x 1e8 / 1e6 = 1e-9 of it.
    swt.assert_linear_reproduction(weights * (1 + 1e-11), cage, points, rtol=1e-10)

    shifted = points.copy()
    shifted[44] += 1e-6 * scale  # a point off by 1.7e-6 of the size (diagonal 2.17)
    with raises_at(44, "linear_reproduction") as failure:
        swt.assert_linear_reproduction(weights, cage, shifted, rtol=1e-7)
    size = np.linalg.norm(TET.max(axis=0) - TET.min(axis=0))
    assert failure.value.value == pytest.approx(math.sqrt(3) * 1e-6 / size, rel=1e-4)
    swt.assert_linear_reproduction(weights, cage, shifted, rtol=1e-7, size=100 * scale)


def test_float32_and_lists_are_accepted() -> None:
    points = inside_tet(TET, 50)
    weights = barycentric(TET, points)
    single = weights.astype(np.float32)
    swt.assert_partition_of_unity(single, atol=1e-6)
    swt.assert_linear_reproduction(single, TET.astype(np.float32), points.astype(np.float32),
                                   rtol=1e-6)
    with pytest.raises(PropertyError):  # float32 round-off is seen, not hidden
        swt.assert_linear_reproduction(single, TET, points, rtol=1e-12)
    swt.assert_partition_of_unity(weights.tolist(), atol=1e-14)
    swt.assert_linear_reproduction(weights.tolist(), TET.tolist(), points.tolist(), rtol=1e-14)
    swt.assert_face_interpolation(lambda p: barycentric(TET, p).tolist(), TET.tolist(),
                                  TET_FACES.tolist(), atol=1e-14)
    swt.assert_partition_of_unity([[1, 0], [0, 1]], atol=0)  # integers


def test_sparse_weights_are_read_by_blocks(monkeypatch: pytest.MonkeyPatch) -> None:
    sparse = pytest.importorskip("scipy.sparse")
    monkeypatch.setattr(swt, "_BLOCK_BYTES", 1)  # 256 rows a block
    points = np.random.default_rng(8).uniform(BOX_LOW, BOX_HIGH, (600, 3))
    points[:, 2] = 0.0  # on the bottom face: the top corners' weights are zero
    weights = sparse.csc_matrix(trilinear(points))
    assert weights.nnz == 600 * 4
    swt.assert_linear_reproduction(weights, BOX, points, rtol=1e-14)
    swt.assert_face_interpolation(lambda p: sparse.csr_matrix(trilinear(p)), BOX,
                                  BOX_QUADS[:1], atol=0.25)
    broken = weights.tolil()
    broken[555, 6] = -1e-3
    with raises_at(555, "non-negativity"):
        swt.assert_non_negative(broken.tocsr())


def test_large_weights_are_not_copied(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(swt, "_BLOCK_BYTES", 1 << 20)
    columns = 500
    rng = np.random.default_rng(6)
    weights = rng.random((4000, columns), dtype=np.float32)  # 8 MB, 16 MB as float64
    weights /= weights.sum(axis=1, keepdims=True)
    controls = rng.random((columns, 3))
    points = weights.astype(np.float64) @ controls
    tracemalloc.start()
    try:
        swt.assert_partition_of_unity(weights, atol=1e-5)
        swt.assert_linear_reproduction(weights, controls, points, rtol=1e-5)
        swt.measure_properties(weights, controls, points)
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert peak < 6 << 20, f"peak {peak / 2**20:.1f} MB"


def test_figures_print_readably() -> None:
    points = inside_tet(TET, 10)
    text = str(swt.measure_properties(barycentric(TET, points), TET, points))
    assert text.startswith("coordinate properties at 10 points:")
    for name in ("partition of unity", "linear reproduction", "min weight", "Lagrange",
                 "face interpolation", "similarity reproduction"):
        assert name in text
    assert "nan" in text  # Lagrange and face interpolation were not measured


# ---------------------------------------------------------------------------------------------
# Wrong input raises ValueError naming the shapes

_W = barycentric(TET, inside_tet(TET, 5))
_X = inside_tet(TET, 5)


@pytest.mark.parametrize("call, message", [
    (lambda: swt.assert_partition_of_unity(np.ones(5)), r"shape \(5,\)"),
    (lambda: swt.assert_partition_of_unity(np.ones((0, 4))), r"shape \(0, 4\)"),
    (lambda: swt.assert_partition_of_unity(np.ones((3, 0))), r"shape \(3, 0\)"),
    (lambda: swt.assert_partition_of_unity([[1.0, 0.0], [1.0]]), "real numbers"),
    (lambda: swt.assert_partition_of_unity(_W, vertex_columns=5), "vertex_columns=5"),
    (lambda: swt.assert_partition_of_unity(_W, atol=-1.0), "atol"),
    (lambda: swt.assert_partition_of_unity(_W, points=_X[:3]), r"\(3, 3\) but 5 rows"),
    (lambda: swt.assert_linear_reproduction(_W, TET[:3], _X), r"\(3, 3\) but the weights have 4"),
    (lambda: swt.assert_linear_reproduction(_W, TET, _X[:4]), r"shape \(4, 3\) but 5 rows"),
    (lambda: swt.assert_linear_reproduction(_W, TET, _X[:, :2]), r"shape \(5, 2\)"),
    (lambda: swt.assert_linear_reproduction(_W, TET, np.full((5, 3), np.nan)), "non-finite"),
    (lambda: swt.assert_linear_reproduction(_W, TET, _X, size=0.0), "size"),
    (lambda: swt.assert_linear_reproduction(_W, np.zeros((4, 3)), _X), "single point"),
    (lambda: swt.assert_face_interpolation(lambda p: _W, TET, TET_FACES),
     r"shape \(5, 4\) for 16"),
    (lambda: swt.assert_face_interpolation(lambda p: barycentric(TET, p), TET, [[0, 1, 4]]),
     "outside 0..3"),
    (lambda: swt.assert_face_interpolation(lambda p: barycentric(TET, p), TET, [[0, 1]]),
     ">= 3"),
    (lambda: swt.assert_face_interpolation(lambda p: barycentric(TET, p), TET,
                                           TET_FACES.astype(float)), "integer"),
    (lambda: swt.assert_face_interpolation(lambda p: barycentric(TET, p), TET, []), "empty"),
    (lambda: swt.assert_face_interpolation(lambda p: barycentric(TET, p), TET, TET_FACES,
                                           samples_per_face=0), "samples_per_face"),
    (lambda: swt.assert_similarity_reproduction(np.hstack([_W, _W]), TET, None, _X),
     "8 columns but the cage has 4 vertices and no faces"),
    (lambda: swt.assert_similarity_reproduction(np.hstack([_W, _W[:, :3]]), TET, TET_FACES, _X),
     "7 columns .* 4 triangles"),
    (lambda: swt.assert_similarity_reproduction(_W, TET, None, _X, axis=(0, 0, 0)), "axis"),
    (lambda: swt.assert_similarity_reproduction(_W, TET, None, _X, scale=-1.0), "scale"),
    (lambda: swt.assert_similarity_reproduction(_W, TET, None, _X,
                                                column_controls=lambda p: p[:3]),
     r"column_controls\(posed_vertices\) has shape \(3, 3\)"),
    (lambda: swt.assert_similarity_reproduction(_W, TET, None, _X[:2]), r"\(5, 4\) but points"),
    (lambda: swt.measure_properties(_W, TET, _X, vertices=TET[:3], vertex_columns=4),
     r"\(3, 3\) but vertex_columns=4"),
    (lambda: swt.green_column_controls(TET, TET_FACES, TET[:3]), r"\(3, 3\) but 4 rows"),
    (lambda: swt.green_column_controls(np.zeros((4, 3)), TET_FACES, TET), "zero area"),
])
def test_wrong_input_raises_value_error(call: Callable[[], None], message: str) -> None:
    with pytest.raises(ValueError, match=message):
        call()


# ---------------------------------------------------------------------------------------------
# spacewarp's own coordinates (needs the compiled module)


def _compiled_spacewarp() -> Optional[ModuleType]:
    try:
        import spacewarp
        from spacewarp import Cage, Green, MeanValue  # noqa: F401  (the extension's names)
    except ImportError:
        return None
    return spacewarp


_SPACEWARP = _compiled_spacewarp()


@pytest.mark.skipif(_SPACEWARP is None, reason="the compiled spacewarp module is not importable")
def test_spacewarp_coordinates_of_a_unit_cube() -> None:
    sw = _SPACEWARP
    cube = BOX / BOX_HIGH  # the unit cube
    cage = sw.Cage(cube, fan(BOX_QUADS).astype(np.int32))
    triangles = cage.triangles  # the order of Green's face columns
    points = np.random.default_rng(7).uniform(0.05, 0.95, (500, 3))

    mean_value = sw.MeanValue(cage)
    weights = mean_value.weights(points)
    assert weights.shape == (500, 8) and weights.dtype == np.float64
    swt.assert_partition_of_unity(weights, atol=1e-12)
    swt.assert_linear_reproduction(weights, cube, points, rtol=1e-12)
    swt.assert_non_negative(weights)  # mean value coordinates are positive in a convex cage
    swt.assert_lagrange(mean_value.weights(cube), atol=1e-9, vertices=cube)
    swt.assert_face_interpolation(mean_value.weights, cube, triangles, atol=1e-9)
    swt.assert_similarity_reproduction(weights, cube, triangles, points, rtol=1e-12)

    green = sw.Green(cage)
    weights = green.weights(points)
    assert weights.shape == (500, 8 + 12)
    rest_columns = green.column_controls(cube)
    swt.assert_partition_of_unity(weights, vertex_columns=8, atol=1e-12)
    swt.assert_linear_reproduction(weights, rest_columns, points, vertex_columns=8, rtol=1e-12)
    swt.assert_similarity_reproduction(weights, cube, triangles, points, rtol=1e-12,
                                       column_controls=green.column_controls)
    swt.assert_similarity_reproduction(weights, cube, triangles, points, rtol=1e-12)
    posed = cube * 1.5 @ rotation(0.3, np.array([1.0, 0.0, 1.0])).T + 2.0
    np.testing.assert_allclose(green.column_controls(posed),
                               swt.green_column_controls(cube, triangles, posed), atol=1e-13)
    figures = swt.measure_properties(weights, rest_columns, points, vertices=cube,
                                     faces=triangles, column_controls=green.column_controls)
    assert figures.similarity_reproduction <= 1e-12
