"""spacewarp.Wire and spacewarp.Wires (python/src/wires.cpp): the same warp as the command line's
"wires" rig bit for bit, built directly or through spacewarp.rig / load_rig; the wire's points
go onto the deformed wire; bad parameters raise InvalidInput naming them."""

from __future__ import annotations

import numpy as np
import pytest

spacewarp = pytest.importorskip("spacewarp")

from conftest import as_list, central_jacobian, write_json  # noqa: E402

_REST = np.array([[-1.0, 0.0, 0.0], [-0.3, 0.2, 0.0], [0.4, 0.1, 0.1], [1.0, -0.2, 0.0]])
_DEFORMED = _REST + np.array([[0.0, 0.0, 0.1], [0.0, 0.3, 0.0], [0.0, 0.3, 0.2], [0.0, 0.2, 0.0]])
_REST2 = np.array([[0.0, -1.0, 0.0], [0.1, 0.0, 0.2], [0.0, 1.0, 0.0]])
_DEFORMED2 = np.array([[0.0, -1.0, 0.0], [0.4, 0.0, 0.1], [0.0, 1.0, 0.0]])

_RIG = {"method": "wires", "locality": 2.0, "wires": [
    {"rest": as_list(_REST), "deformed": as_list(_DEFORMED), "radius": 0.6, "innerRadius": 0.1,
     "scale": 1.2, "dropoff": "linear", "curve": "catmull-rom"},
    {"rest": as_list(_REST2), "deformed": as_list(_DEFORMED2), "radius": 0.5}]}


def _warp() -> spacewarp.Wires:
    return spacewarp.Wires(
        [spacewarp.Wire(_REST, _DEFORMED, 0.6, inner_radius=0.1, scale=1.2, dropoff="linear",
                        curve="catmull-rom"),
         spacewarp.Wire(_REST2, _DEFORMED2, 0.5)], locality=2.0)


def _points(n: int = 400, seed: int = 3) -> np.ndarray:
    return np.random.default_rng(seed).uniform(-1.2, 1.2, size=(n, 3))


def test_equals_the_cli_and_the_rig_readers(cli, tmp_path):
    points = _points()
    warp = _warp()
    expected = warp(points)
    assert np.count_nonzero(np.any(expected != points, axis=1)) > 40  # the wires move points
    assert np.array_equal(cli.deform(_RIG, points, tmp_path), expected)
    assert np.array_equal(spacewarp.rig(_RIG)(points), expected)
    path = write_json(tmp_path / "wires.json", _RIG)
    assert np.array_equal(spacewarp.load_rig(path)(points), expected)


def test_the_rest_wire_goes_onto_the_deformed_wire_and_far_points_stay():
    warp = spacewarp.Wires([spacewarp.Wire(_REST, _DEFORMED, 0.4)])
    np.testing.assert_allclose(warp(_REST), _DEFORMED, rtol=0, atol=1e-12)
    far = np.array([[0.0, 3.0, 0.0], [5.0, 5.0, 5.0]])
    assert np.array_equal(warp(far), far)
    single = warp(_REST[1])
    assert single.shape == (3,)


def test_attributes_mirror_the_arguments():
    warp = _warp()
    assert warp.locality == 2.0
    first, second = warp.wires
    assert np.array_equal(first.rest, _REST) and np.array_equal(first.deformed, _DEFORMED)
    assert (first.radius, first.inner_radius, first.scale) == (0.6, 0.1, 1.2)
    assert (first.dropoff, first.curve) == ("linear", "catmull-rom")
    assert (second.dropoff, second.curve, second.scale) == ("smooth", "polyline", 1.0)


def test_jacobian_near_the_wire_matches_central_differences():
    warp = spacewarp.Wires([spacewarp.Wire(_REST, _DEFORMED, 0.6, curve="catmull-rom")])
    points = _REST[1:3] + np.array([[0.05, 0.02, -0.03], [0.0, -0.04, 0.05]])
    np.testing.assert_allclose(warp.jacobian(points), central_jacobian(warp, points), atol=1e-6)


@pytest.mark.parametrize("kwargs, message", [
    ({"radius": 0.0}, "wire 0: radius must be finite and > 0"),
    ({"radius": 1.0, "inner_radius": 1.0}, "wire 0: innerRadius must be in"),
    ({"radius": 1.0, "scale": -1.0}, "wire 0: scale must be finite and > 0"),
])
def test_bad_parameters_raise_naming_them(kwargs, message):
    with pytest.raises(spacewarp.InvalidInput, match=message):
        spacewarp.Wires([spacewarp.Wire(_REST, _DEFORMED, **kwargs)])


def test_bad_curves_and_names_raise():
    with pytest.raises(spacewarp.InvalidInput, match="4 rest points but 3 deformed points"):
        spacewarp.Wires([spacewarp.Wire(_REST, _DEFORMED[:3], 1.0)])
    with pytest.raises(spacewarp.InvalidInput, match="rest needs at least 2 points"):
        spacewarp.Wires([spacewarp.Wire(_REST[:1], _DEFORMED[:1], 1.0)])
    nan = _REST.copy()
    nan[2, 1] = np.nan
    with pytest.raises(spacewarp.InvalidInput, match=r"rest\[2\] is not finite"):
        spacewarp.Wires([spacewarp.Wire(nan, _DEFORMED, 1.0)])
    with pytest.raises(spacewarp.InvalidInput, match="'gauss' is not one of: smooth, linear"):
        spacewarp.Wire(_REST, _DEFORMED, 1.0, dropoff="gauss")
    with pytest.raises(spacewarp.InvalidInput, match="locality must be finite and >= 0"):
        spacewarp.Wires([spacewarp.Wire(_REST, _DEFORMED, 1.0)], locality=-1.0)
    with pytest.raises(spacewarp.InvalidInput, match="no wires"):
        spacewarp.Wires([])
