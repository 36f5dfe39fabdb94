"""The polygon and convex cage coordinates from Python (python/src/coordinates.cpp):
QuadMeanValue, QuadGreen, Wachspress and DiscreteHarmonic, and the polygons a Cage keeps.

Properties the methods have (not values of one implementation): weights of the documented
shape, partition of unity and reproduction at rest, the same rows by class and by CLI name,
bit-identical pickles, errors mapped to spacewarp.InvalidInput, and equality with the command
line's `spacewarp weights` output bit for bit.
"""

from __future__ import annotations

import pickle

import numpy as np
import pytest

spacewarp = pytest.importorskip("spacewarp")

from conftest import (CUBE, CUBE_QUADS, OCTAHEDRON, OCTAHEDRON_TRIANGLES,  # noqa: E402
                      write_cage)

NEW_METHODS = {"qmvc": "QuadMeanValue", "qgc": "QuadGreen", "wachspress": "Wachspress",
               "discrete-harmonic": "DiscreteHarmonic"}


def pinched_box(waist: float = 0.6):
    """The box [-1, 1]^3 with its middle ring scaled by `waist`: concave, 12 vertices, 10 quads
    (tests/coords/coords_test_shapes.h's pinchedBox)."""
    ring = [(-1, -1), (1, -1), (1, 1), (-1, 1)]
    vertices = np.array([[s * x, s * y, z] for z, s in ((-1, 1.0), (0, waist), (1, 1.0))
                         for x, y in ring], dtype=float)
    faces = [[3, 2, 1, 0], [8, 9, 10, 11]]
    for r in range(2):
        for i in range(4):
            j = (i + 1) % 4
            faces.append([4 * r + i, 4 * r + j, 4 * r + 4 + j, 4 * r + 4 + i])
    return vertices, faces


@pytest.fixture(scope="module")
def cube():
    return spacewarp.Cage(CUBE, np.array(CUBE_QUADS), name="cube")


@pytest.fixture(scope="module")
def octahedron():
    return spacewarp.Cage(OCTAHEDRON, np.array(OCTAHEDRON_TRIANGLES), name="octahedron")


@pytest.fixture(scope="module")
def concave():
    vertices, faces = pinched_box()
    return spacewarp.Cage(vertices, faces, name="pinched")


@pytest.fixture
def points():
    return np.random.default_rng(20).uniform(-0.5, 0.5, size=(150, 3))


def make(method: str, cube, octahedron, concave, **options):
    """The coordinates of `method` on a cage it takes: Wachspress on the cube, DiscreteHarmonic
    (triangle faces only) on the octahedron, the others on the concave cage."""
    cage = {"wachspress": cube, "discrete-harmonic": octahedron}.get(method, concave)
    return getattr(spacewarp, NEW_METHODS[method])(cage, **options), cage


def test_the_classes_are_public_coordinates():
    assert set(NEW_METHODS.values()) <= set(spacewarp.__all__)
    assert set(NEW_METHODS) <= set(spacewarp.cage_methods())
    for name in NEW_METHODS.values():
        cls = getattr(spacewarp, name)
        assert issubclass(cls, spacewarp.Coordinates), name
        assert "(n, V" in cls.__doc__, name


def test_a_cage_keeps_its_polygons(cube, concave):
    assert cube.face_count == 6 and cube.max_face_size == 4
    assert len(cube.faces) == 6 and all(f.shape == (4,) and f.dtype == np.uint32
                                        for f in cube.faces)
    assert cube.face_offsets.tolist() == [0, 4, 8, 12, 16, 20, 24]
    assert np.array_equal(np.concatenate(cube.faces), cube.face_indices)
    # Outward with the first vertex kept: the input quads were outward already.
    assert [f.tolist() for f in cube.faces] == CUBE_QUADS
    assert len(cube.triangles) == 12
    mixed = spacewarp.Cage(CUBE, [[0, 2, 3], [0, 3, 1]] + CUBE_QUADS[1:])
    assert mixed.max_face_size == 4 and mixed.face_count == 7
    assert concave.face_count == 10


@pytest.mark.parametrize("method", NEW_METHODS)
def test_weights_have_the_documented_shape_and_reproduce_at_rest(method, cube, octahedron,
                                                                 concave, points):
    coordinates, cage = make(method, cube, octahedron, concave)
    w = coordinates.weights(points)
    vertices = len(cage.vertices)
    columns = vertices + (4 * cage.face_count if method == "qgc" else 0)
    assert w.shape == (len(points), columns) and w.dtype == np.float64
    assert coordinates.column_count == columns
    assert np.abs(w[:, :vertices].sum(axis=1) - 1.0).max() <= 1e-12
    # At rest the warp is the identity (qgc through its face columns as well).
    moved = coordinates.warp(cage.vertices)(points)
    assert np.abs(moved - points).max() <= 1e-12 * cage.diagonal
    if method != "qgc":
        assert np.abs(w @ cage.vertices - points).max() <= 1e-12 * cage.diagonal


@pytest.mark.parametrize("method", NEW_METHODS)
def test_by_name_equals_the_class_and_pickles_bit_identically(method, cube, octahedron, concave,
                                                              points):
    coordinates, cage = make(method, cube, octahedron, concave)
    by_name = spacewarp.cage_coordinates(method, cage)
    assert type(by_name) is type(coordinates)
    assert np.array_equal(by_name.weights(points), coordinates.weights(points))
    loaded = pickle.loads(pickle.dumps(coordinates))
    assert type(loaded) is type(coordinates)
    assert loaded.to_bytes() == coordinates.to_bytes()
    assert np.array_equal(loaded.weights(points), coordinates.weights(points))
    pose = cage.vertices + 0.1 * np.sin(np.arange(cage.vertices.size)).reshape(-1, 3)
    warp = coordinates.warp(pose)
    assert np.array_equal(pickle.loads(pickle.dumps(warp))(points), warp(points))


def test_options_are_keyword_arguments_and_reach_the_archive(cube, octahedron, concave):
    assert (spacewarp.QuadMeanValue(concave, snap_tolerance=1e-12).to_bytes()
            != spacewarp.QuadMeanValue(concave).to_bytes())
    assert (spacewarp.QuadGreen(concave, surface_tolerance=1e-12).to_bytes()
            != spacewarp.QuadGreen(concave).to_bytes())
    for cls, cage in ((spacewarp.Wachspress, cube), (spacewarp.DiscreteHarmonic, octahedron)):
        assert cls(cage, outside="nearest").to_bytes() != cls(cage).to_bytes()
        with pytest.raises(TypeError):
            cls(cage, 1e-12)  # keyword only


def test_errors_are_invalid_input(cube, octahedron, concave):
    for cls, cage in ((spacewarp.Wachspress, cube), (spacewarp.DiscreteHarmonic, octahedron)):
        with pytest.raises(spacewarp.InvalidInput, match="pinched.*edge|edge.*pinched"):
            cls(concave)
        with pytest.raises(spacewarp.InvalidInput, match="outside"):
            cls(cage, outside="sometimes")
        outside = np.array([[0.0, 0.0, 0.0], [3.0, 0.0, 0.0]])
        with pytest.raises(spacewarp.InvalidInput):
            cls(cage).weights(outside)
        assert cls(cage, outside="nearest").weights(outside).shape == (2, len(cage.vertices))
    # DiscreteHarmonic takes triangle faces only: the cube's quads are refused, naming one.
    with pytest.raises(spacewarp.InvalidInput, match="cube.*quad.*triangle faces"):
        spacewarp.DiscreteHarmonic(cube)
    # A hexagonal face: QuadGreen takes triangles and quads only; QuadMeanValue any polygon.
    hexagon = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [2.0, 0.5, 0.0], [2.0, 1.5, 0.0],
               [1.0, 2.0, 0.0], [0.0, 1.0, 0.0]]
    prism = np.array(hexagon + [[x, y, 1.0] for x, y, _ in hexagon])
    faces = [[5, 4, 3, 2, 1, 0], [6, 7, 8, 9, 10, 11]] + [
        [i, (i + 1) % 6, (i + 1) % 6 + 6, i + 6] for i in range(6)]
    prism_cage = spacewarp.Cage(prism, faces, name="prism")
    assert prism_cage.max_face_size == 6
    with pytest.raises(spacewarp.InvalidInput, match="face 0"):
        spacewarp.QuadGreen(prism_cage)
    assert spacewarp.QuadMeanValue(prism_cage).weights([[1.0, 1.0, 0.5]]).shape == (1, 12)
    # A polygon a little off planar (one hexagon corner lifted 1e-4, ~3e-5 diagonals off the
    # face's plane): refused naming the face by default (1e-6 diagonals), taken when
    # polygon_planarity allows it, and a tolerance out of [0, 1e-2] is refused.
    lifted = prism.copy()
    lifted[2, 2] += 1e-4
    lifted_cage = spacewarp.Cage(lifted, faces, name="lifted")
    with pytest.raises(spacewarp.InvalidInput, match="lifted.*face 0"):
        spacewarp.QuadMeanValue(lifted_cage)
    qmvc = spacewarp.QuadMeanValue(lifted_cage, polygon_planarity=1e-3)
    assert abs(qmvc.weights([[1.0, 1.0, 0.5]]).sum() - 1.0) <= 1e-12
    looser = spacewarp.QuadMeanValue(lifted_cage, polygon_planarity=2e-3)
    assert qmvc.to_bytes() != looser.to_bytes()  # the option is kept in the archive
    with pytest.raises(spacewarp.InvalidInput, match="polygonPlanarity"):
        spacewarp.QuadMeanValue(prism_cage, polygon_planarity=0.1)
    with pytest.raises(spacewarp.InvalidInput, match="point 1 is not finite"):
        spacewarp.QuadMeanValue(concave).weights([[0.0, 0.0, 0.0], [np.nan, 0.0, 0.0]])


def hexagonal_prism():
    """The prism of height 1 over a regular hexagon of circumradius 1: two hexagons, six quads."""
    angles = np.arange(6) * np.pi / 3
    ring = np.stack([np.cos(angles), np.sin(angles)], axis=1)
    vertices = np.array([[x, y, z] for z in (0.0, 1.0) for x, y in ring])
    faces = [[5, 4, 3, 2, 1, 0], [6, 7, 8, 9, 10, 11]]
    faces += [[i, (i + 1) % 6, 6 + (i + 1) % 6, 6 + i] for i in range(6)]
    return vertices, faces


def test_exported_precision_cages_are_accepted_and_planarity_is_a_keyword():
    # F11: a rotated hexagonal prism written in float32 (hexagons ~1e-8 diagonals off planar) is
    # accepted by the polygon and convex methods with their default planarity; planarity=0
    # refuses it naming the face, and planarity is kept in the archive.
    vertices, faces = hexagonal_prism()
    rng = np.random.default_rng(4)
    for _ in range(5):
        q, _ = np.linalg.qr(rng.normal(size=(3, 3)))
        rotated = (vertices @ q.T).astype(np.float32).astype(float)
        cage = spacewarp.Cage(rotated, faces, name="exported")
        inside = rotated.mean(axis=0, keepdims=True)
        for coordinates in (spacewarp.Wachspress(cage), spacewarp.QuadMeanValue(cage)):
            row = coordinates.weights(inside)
            assert np.abs(row @ rotated - inside).max() <= 1e-6
        with pytest.raises(spacewarp.InvalidInput, match="exported: face .* planarity = 0"):
            spacewarp.Wachspress(cage, planarity=0.0)
    assert (spacewarp.Wachspress(cage, planarity=1e-5).to_bytes() !=
            spacewarp.Wachspress(cage).to_bytes())
    with pytest.raises(spacewarp.InvalidInput, match="planarity must be in"):
        spacewarp.DiscreteHarmonic(spacewarp.Cage(OCTAHEDRON, np.array(OCTAHEDRON_TRIANGLES)),
                                   planarity=0.5)
    # F3: an exact tetrahedron far from the origin is as convex as at the origin.
    tet = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]], dtype=float) + 2.0**27
    tet_cage = spacewarp.Cage(tet, [[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]])
    for method in (spacewarp.Wachspress, spacewarp.DiscreteHarmonic):
        row = method(tet_cage).weights(tet.mean(axis=0, keepdims=True))
        assert np.abs(row - 0.25).max() <= 1e-6


@pytest.mark.parametrize("method", NEW_METHODS)
def test_weights_equal_the_cli(method, cli, tmp_path, cube, octahedron, concave, points):
    coordinates, cage = make(method, cube, octahedron, concave)
    faces = [f.tolist() for f in cage.faces]
    cage_file = write_cage(tmp_path / "cage.obj", cage.vertices, faces)
    points_file = tmp_path / "points.ply"
    spacewarp.write(points_file, spacewarp.Geometry(points))
    out = tmp_path / "w.npy"
    cli("weights", "--method", method, "--cage", cage_file, points_file, "-o", out)
    theirs = np.load(out)
    ours = coordinates.weights(points)
    assert theirs.shape == ours.shape
    assert np.array_equal(ours, theirs), np.abs(ours - theirs).max()
