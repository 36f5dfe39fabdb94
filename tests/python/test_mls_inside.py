"""MLS with distances measured inside a model: spacewarp.InsideDistances given to spacewarp.Mls,
the same as the command line's "distance": "inside" rig, bit for bit."""

from __future__ import annotations

import numpy as np
import pytest

spacewarp = pytest.importorskip("spacewarp")
if not hasattr(spacewarp, "InsideDistances"):
    pytest.skip("spacewarp was built without OpenVDB", allow_module_level=True)

from conftest import as_list, write_json  # noqa: E402

# Two fingers (x = 0 and x = 4, y = 1..4) on a palm (y = 0): unit cells, one thick in z.
CELLS = [(x, 0, 0) for x in range(5)] + [(x, y, 0) for y in range(1, 5) for x in (0, 4)]
HANDLES = np.array([[0.5, 4.5, 0.5], [0.5, 0.5, 0.5], [2.5, 0.5, 0.8], [4.5, 0.5, 0.5],
                    [4.5, 2.5, 0.5], [4.5, 4.5, 0.5]])
TARGETS = HANDLES + np.array([[1.5, 0.0, 0.0]] + [[0.0, 0.0, 0.0]] * 5)


def blocks(cells) -> "spacewarp.Geometry":
    """The closed surface of a union of unit cubes: outward quads, shared corners."""
    occupied = set(cells)
    corners: dict[tuple[int, int, int], int] = {}
    faces = []
    for cell in sorted(occupied):
        for axis in range(3):
            u, v = (axis + 1) % 3, (axis + 2) % 3
            for side in (0, 1):
                nxt = list(cell)
                nxt[axis] += 1 if side else -1
                if tuple(nxt) in occupied:
                    continue
                quad = []
                for du, dv in ((0, 0), (1, 0), (1, 1), (0, 1)):
                    c = list(cell)
                    c[axis] += side
                    c[u] += du
                    c[v] += dv
                    quad.append(corners.setdefault(tuple(c), len(corners)))
                if not side:
                    quad[1], quad[3] = quad[3], quad[1]
                faces.append(quad)
    positions = np.array(sorted(corners, key=corners.get), dtype=float)
    return spacewarp.Geometry(positions, faces)


@pytest.fixture(scope="module")
def fingers():
    return blocks(CELLS)


def test_the_other_finger_stays_put(fingers):
    distances = spacewarp.InsideDistances(fingers, HANDLES, voxel_size=0.05)
    assert distances.voxel_size == 0.05
    inside = spacewarp.Mls(HANDLES, TARGETS, distances=distances)
    euclidean = spacewarp.Mls(HANDLES, TARGETS)
    finger_b = fingers.positions[(fingers.positions[:, 0] >= 4) & (fingers.positions[:, 1] >= 1)]
    moved_inside = np.linalg.norm(inside(finger_b) - finger_b, axis=1).max()
    moved_euclidean = np.linalg.norm(euclidean(finger_b) - finger_b, axis=1).max()
    assert moved_inside < 0.02 * 1.5
    assert moved_euclidean > 3 * moved_inside
    assert np.array_equal(inside(HANDLES), TARGETS)  # interpolates


def test_distances_are_inside_lengths(fingers, tmp_path):
    distances = spacewarp.InsideDistances(fingers, HANDLES[:1], voxel_size=0.05)
    # From finger A's tip to finger B's tip: down A, across the palm, up B, around two corners.
    around = 2 * np.hypot(0.5, 3.5) + 3.0
    d = distances.distances(np.array([[4.5, 4.5, 0.5], [0.5, 2.5, 0.5]]))
    assert d.shape == (2, 1)
    assert d[0, 0] == pytest.approx(around, abs=0.5 * 0.05)  # half a voxel
    assert d[1, 0] == pytest.approx(2.0, abs=0.01)
    assert np.array_equal(distances.handles, HANDLES[:1])
    # A model given by its path reads the same.
    spacewarp.write(tmp_path / "fingers.obj", fingers)
    from_file = spacewarp.InsideDistances(tmp_path / "fingers.obj", HANDLES[:1], voxel_size=0.05)
    assert np.array_equal(from_file.distances(fingers.positions), distances.distances(fingers.positions))


def test_equals_the_cli_and_the_rig_bit_for_bit(fingers, cli, tmp_path):
    spacewarp.write(tmp_path / "fingers.obj", fingers)
    rig = {"method": "mls", "distance": "inside", "model": str(tmp_path / "fingers.obj"),
           "voxelSize": 0.05, "handles": as_list(HANDLES), "targets": as_list(TARGETS)}
    ours = spacewarp.Mls(HANDLES, TARGETS,
                         distances=spacewarp.InsideDistances(fingers, HANDLES, voxel_size=0.05))
    points = np.random.default_rng(4).uniform(-0.5, 5.5, (500, 3)) * [1, 1, 0.3]
    assert np.array_equal(cli.deform(rig, points, tmp_path), ours(points))
    assert np.array_equal(spacewarp.rig(rig)(points), ours(points))
    assert np.array_equal(spacewarp.load_rig(write_json(tmp_path / "rig.json", rig))(points),
                          ours(points))


def test_bad_input_is_named(fingers):
    outside = HANDLES.copy()
    outside[2] = [2.5, 3.0, 0.5]
    with pytest.raises(spacewarp.InvalidInput, match="handle 2 .* is outside the model"):
        spacewarp.InsideDistances(fingers, outside)
    with pytest.raises(spacewarp.InvalidInput, match="voxelSize"):
        spacewarp.InsideDistances(fingers, HANDLES, voxel_size=-1.0)
    distances = spacewarp.InsideDistances(fingers, HANDLES, voxel_size=0.1)
    with pytest.raises(spacewarp.InvalidInput, match="built for 6 handles, not 5"):
        spacewarp.Mls(HANDLES[:5], TARGETS[:5], distances=distances)
    with pytest.raises(spacewarp.IoError, match="missing.obj"):
        spacewarp.InsideDistances("missing.obj", HANDLES)
