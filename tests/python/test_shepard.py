"""spacewarp.Shepard (python/src/shepard.cpp): inverse-distance-weighting coordinates.

The weights interpolate, sum to 1 and are non-negative; the warp of the coordinates equals the
"idw" rig built by spacewarp.rig(dict) and the command line bit for bit; points out of every
handle's reach raise InvalidInput; bad parameters name themselves.
"""

from __future__ import annotations

import numpy as np
import pytest

spacewarp = pytest.importorskip("spacewarp")

from conftest import as_list, central_jacobian  # noqa: E402

_RNG = np.random.default_rng(3)
_HANDLES = _RNG.uniform(-1.0, 1.0, size=(10, 3))
_TARGETS = _HANDLES + _RNG.uniform(-0.3, 0.3, size=(10, 3))


def _points(n: int = 200, seed: int = 5, lo: float = -1.2, hi: float = 1.2) -> np.ndarray:
    return np.random.default_rng(seed).uniform(lo, hi, size=(n, 3))


def test_weights_interpolate_and_form_a_partition_of_unity():
    coords = spacewarp.Shepard(_HANDLES, power=2.5)
    assert isinstance(coords, spacewarp.Coordinates)
    assert coords.power == 2.5 and coords.radius is None
    assert np.array_equal(coords.weights(_HANDLES), np.eye(len(_HANDLES)))
    w = coords.weights(_points())
    assert w.shape == (200, 10) and w.dtype == np.float64
    assert np.abs(w.sum(axis=1) - 1.0).max() <= 1e-12
    assert w.min() >= 0.0


def test_warp_maps_handles_to_targets_and_has_flat_spots():
    warp = spacewarp.Shepard(_HANDLES).warp(_TARGETS)
    assert isinstance(warp, spacewarp.Warp)
    assert np.array_equal(warp(_HANDLES), _TARGETS)
    # Jacobian = identity at every handle for power > 1, whatever the targets.
    assert np.array_equal(warp.jacobian(_HANDLES), np.broadcast_to(np.eye(3), (10, 3, 3)))
    points = _points(30)
    assert np.abs(warp.jacobian(points) - central_jacobian(warp, points)).max() < 1e-6


def test_translation_is_reproduced_but_not_a_scale():
    coords = spacewarp.Shepard(_HANDLES)
    points = _points()
    shift = np.array([0.3, -0.1, 2.0])
    assert np.abs(coords.warp(_HANDLES + shift)(points) - (points + shift)).max() < 1e-14
    assert np.abs(coords.warp(2.0 * _HANDLES)(points) - 2.0 * points).max() > 0.1


def test_rig_and_cli_equal_the_class_bit_for_bit(cli, tmp_path):
    points = _points(300, lo=-0.8, hi=0.8)
    rig = {"method": "idw", "power": 3, "radius": 2.0, "handles": as_list(_HANDLES),
           "targets": as_list(_TARGETS)}
    ours = spacewarp.Shepard(_HANDLES, power=3, radius=2.0).warp(_TARGETS)(points)
    assert np.array_equal(spacewarp.rig(rig)(points), ours)
    assert np.array_equal(cli.deform(rig, points, tmp_path), ours)
    assert not np.array_equal(ours, points)


def test_local_support_and_points_out_of_reach():
    coords = spacewarp.Shepard(_HANDLES, radius=0.5)
    assert coords.radius == 0.5
    near = _HANDLES + 0.1
    w = coords.weights(near)
    d = np.linalg.norm(near[:, None, :] - _HANDLES[None, :, :], axis=2)
    assert np.all(w[d >= 0.5] == 0.0)
    with pytest.raises(spacewarp.InvalidInput, match="farther than the radius 0.5"):
        coords.weights(np.array([[5.0, 5.0, 5.0]]))
    with pytest.raises(spacewarp.InvalidInput, match="farther than the radius 0.5"):
        coords.warp(_TARGETS)(np.array([[0.0, 0.0, 0.0], [5.0, 5.0, 5.0]]))


@pytest.mark.parametrize("kwargs, message", [
    ({"power": 0.0}, "power must be finite and > 0"),
    ({"power": float("nan")}, "power must be finite and > 0"),
    ({"radius": -1.0}, "radius must be > 0"),
    ({"radius": 0.0}, "radius must be > 0"),
])
def test_bad_parameters_name_themselves(kwargs, message):
    with pytest.raises(spacewarp.InvalidInput, match=message):
        spacewarp.Shepard(_HANDLES, **kwargs)


def test_coincident_and_missing_handles():
    with pytest.raises(spacewarp.InvalidInput, match="handles 0 and 10 coincide"):
        spacewarp.Shepard(np.vstack([_HANDLES, _HANDLES[:1]]))
    with pytest.raises(spacewarp.InvalidInput, match="needs at least 1 handle"):
        spacewarp.Shepard(np.zeros((0, 3)))
    with pytest.raises(spacewarp.InvalidInput, match="10 handles but 3 targets"):
        spacewarp.Shepard(_HANDLES).warp(_TARGETS[:3])
