"""spacewarp.Kelvinlet (python/src/kelvinlet.cpp): regularized Kelvinlet brushes.

Each brush does what its parameters say at its centre, equals the "kelvinlet" rig built by
spacewarp.rig(dict) and the command line bit for bit, has Jacobians that match central
differences, and refuses bad or misplaced parameters by name.
"""

from __future__ import annotations

import numpy as np
import pytest

spacewarp = pytest.importorskip("spacewarp")

from conftest import as_list, central_jacobian  # noqa: E402

_CENTER = np.array([0.2, -0.1, 0.3])
_PINCH = np.array([[0.2, 0.1, 0.0], [0.1, -0.3, 0.05], [0.0, 0.05, 0.1]])


def _points(n: int = 200, seed: int = 5) -> np.ndarray:
    return np.random.default_rng(seed).uniform(-1.5, 1.5, size=(n, 3))


_BRUSHES = {
    "grab": {"displacement": [0.3, -0.2, 0.1]},
    "twist": {"axis": [0.0, 1.0, 1.0], "angle": 0.6},
    "scale": {"factor": 1.4},
    "pinch": {"matrix": _PINCH},
}


def _brush(name: str, **extra) -> spacewarp.Kelvinlet:
    return spacewarp.Kelvinlet(brush=name, center=_CENTER, radius=0.8, poisson=0.4,
                               **_BRUSHES[name], **extra)


def test_each_brush_at_its_centre():
    grab = _brush("grab")
    assert isinstance(grab, spacewarp.Warp) and grab.brush == "grab" and grab.radius == 0.8
    assert np.abs(grab(_CENTER) - (_CENTER + [0.3, -0.2, 0.1])).max() < 1e-15
    axis = np.array([0.0, 1.0, 1.0]) / np.sqrt(2.0)
    skew = np.array([[0, -axis[2], axis[1]], [axis[2], 0, -axis[0]], [-axis[1], axis[0], 0]])
    assert np.abs(_brush("twist").jacobian(_CENTER[None])[0] - (np.eye(3) + 0.6 * skew)).max() < 1e-15
    assert np.abs(_brush("scale").jacobian(_CENTER[None])[0] - 1.4 * np.eye(3)).max() < 1e-15
    assert np.abs(_brush("pinch").jacobian(_CENTER[None])[0] - (np.eye(3) + _PINCH)).max() < 1e-15


@pytest.mark.parametrize("name", sorted(_BRUSHES))
def test_rig_and_cli_equal_the_class_bit_for_bit(name, cli, tmp_path):
    points = _points()
    falloff = {"grab": "bi", "twist": "tri"}.get(name, "single")
    ours = _brush(name, steps=2, falloff=falloff)(points)
    keys = {k: (as_list(v) if isinstance(v, np.ndarray) else v) for k, v in _BRUSHES[name].items()}
    rig = {"method": "kelvinlet", "brush": name, "center": as_list(_CENTER), "radius": 0.8,
           "poisson": 0.4, "steps": 2, "falloff": falloff, **keys}
    assert np.array_equal(spacewarp.rig(rig)(points), ours)
    assert np.array_equal(cli.deform(rig, points, tmp_path), ours)
    assert not np.array_equal(ours, points)


@pytest.mark.parametrize("name", sorted(_BRUSHES))
def test_jacobian_matches_central_differences(name):
    warp = _brush(name)
    points = _points(40)
    assert np.abs(warp.jacobian(points) - central_jacobian(warp, points)).max() < 1e-7


@pytest.mark.parametrize("kwargs, message", [
    ({"brush": "grab", "radius": 0.0, "displacement": [1, 0, 0]}, "radius must be finite and > 0"),
    ({"brush": "grab", "radius": 1.0, "poisson": 0.6, "displacement": [1, 0, 0]},
     r"poisson must be in \[0, 0.5\]"),
    ({"brush": "smear", "radius": 1.0}, "'smear' is not one of"),
    ({"brush": "grab", "radius": 1.0}, "brush 'grab' needs displacement"),
    ({"brush": "twist", "radius": 1.0, "axis": [0, 0, 0], "angle": 1.0}, "axis must be finite"),
    ({"brush": "scale", "radius": 1.0, "factor": -1.0}, "factor must be finite and > 0"),
    ({"brush": "scale", "radius": 1.0, "factor": 2.0, "angle": 1.0},
     "angle has no effect with brush 'scale'"),
    ({"brush": "pinch", "radius": 1.0, "matrix": np.eye(3)}, "matrix must be traceless"),
    ({"brush": "pinch", "radius": 1.0, "matrix": np.zeros((2, 2))}, r"matrix must have shape \(3, 3\)"),
    ({"brush": "scale", "radius": 1.0, "factor": 2.0, "steps": 0}, "steps must be in 1..10000"),
    ({"brush": "scale", "radius": 1.0, "factor": 2.0, "falloff": "quad"}, "'quad' is not one of"),
])
def test_bad_parameters_name_themselves(kwargs, message):
    with pytest.raises(spacewarp.InvalidInput, match=message):
        spacewarp.Kelvinlet(center=[0, 0, 0], **kwargs)
