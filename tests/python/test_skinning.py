"""Skinning from Python (python/src/skinning.cpp): spacewarp.Skinning (a Warp) and the fast
SkinningBinding agree with each other and with `spacewarp deform --rig` bit for bit; LBS
collapses a twisted limb where DQS keeps it; bad input raises InvalidInput naming it.
"""

from __future__ import annotations

import numpy as np
import pytest

spacewarp = pytest.importorskip("spacewarp")

from conftest import as_list, central_jacobian  # noqa: E402


def _turn_x(angle: float, shift=(0.0, 0.0, 0.0)) -> np.ndarray:
    """A row-major 4 x 4 rotation about the x axis, then a shift."""
    c, s = np.cos(angle), np.sin(angle)
    m = np.eye(4)
    m[1:3, 1:3] = [[c, -s], [s, c]]
    m[:3, 3] = shift
    return m


_BONES = np.stack([np.eye(4), _turn_x(0.6, (0.1, 0.0, 0.0)), _turn_x(2.9, (0.0, 0.2, 0.0))])


def _cylinder(rings: int = 21, per_ring: int = 48, radius: float = 0.1) -> np.ndarray:
    x = np.repeat(np.linspace(0.0, 1.0, rings), per_ring)
    a = np.tile(np.linspace(0.0, 2.0 * np.pi, per_ring, endpoint=False), rings)
    return np.column_stack([x, radius * np.cos(a), radius * np.sin(a)])


def _weights(points: np.ndarray) -> np.ndarray:
    """Three bones blended along x in [0, 1]: quadratic Bernstein weights."""
    t = np.clip(points[:, 0], 0.0, 1.0)
    return np.column_stack([(1 - t) ** 2, 2 * t * (1 - t), t ** 2])


def test_binding_and_warp_agree_bit_for_bit_and_with_the_cli(cli, tmp_path):
    model = _cylinder()
    weights = _weights(model)
    np.savetxt(tmp_path / "weights.csv", weights, delimiter=",", fmt="%.17g")
    spacewarp.write(tmp_path / "model.ply", spacewarp.Geometry(model))
    others = np.random.default_rng(3).uniform(-0.2, 1.2, size=(200, 3))
    for mode in ("lbs", "dqs"):
        binding = spacewarp.SkinningBinding(model, weights)
        warp = spacewarp.Skinning(_BONES, weights=weights, model=model, mode=mode)
        posed = binding.deform(_BONES, mode=mode)
        assert posed.shape == model.shape
        assert np.array_equal(posed, warp(model))
        rig = {"method": "skinning", "mode": mode, "bones": as_list(_BONES),
               "weights": str(tmp_path / "weights.csv"), "model": str(tmp_path / "model.ply")}
        assert np.array_equal(cli.deform(rig, others, tmp_path), warp(others))
        assert np.array_equal(spacewarp.rig(rig)(others), warp(others))


def test_dual_quaternions_keep_the_twisted_cylinder_round_linear_blending_does_not():
    points = _cylinder()
    weights = np.column_stack([1 - points[:, 0], points[:, 0]])
    bones = np.stack([np.eye(4), _turn_x(np.radians(170))])
    binding = spacewarp.SkinningBinding(points, weights)
    middle = np.isclose(points[:, 0], 0.5)
    lbs = np.linalg.norm(binding.deform(bones, mode="lbs")[middle, 1:], axis=1)
    dqs = np.linalg.norm(binding.deform(bones, mode="dqs")[:, 1:], axis=1)
    np.testing.assert_allclose(lbs, 0.1 * np.cos(np.radians(85)), rtol=1e-12)
    np.testing.assert_allclose(dqs, 0.1, rtol=1e-12)


def test_weights_from_coordinates_move_each_handle_with_its_bone():
    handles = np.array([[-1.0, 0, 0], [1, 0.2, 0], [0, 1, 0.3], [0.2, -0.4, 1]])
    coordinates = spacewarp.MlsAffine(handles)
    bones = np.stack([np.eye(4)] * 4)
    bones[2] = _turn_x(0.4, (0.0, 0.0, 0.5))
    for mode in ("lbs", "dqs"):
        warp = spacewarp.Skinning(bones, coordinates=coordinates, mode=mode)
        expected = handles.copy()
        expected[2] = (bones[2] @ np.append(handles[2], 1.0))[:3]
        np.testing.assert_allclose(warp(handles), expected, atol=1e-12)
        points = np.random.default_rng(5).uniform(-1, 1, size=(100, 3))
        bound = spacewarp.SkinningBinding(points, coordinates).deform(bones, mode=mode)
        assert np.array_equal(bound, warp(points))
        np.testing.assert_allclose(warp.jacobian(points[:10]), central_jacobian(warp, points[:10]),
                                   atol=1e-6)


def test_the_kept_influences_are_normalised_largest_first():
    weights = np.array([[0.1, 0.5, 0.3, 0.05, 0.2]])
    binding = spacewarp.SkinningBinding(np.zeros((1, 3)), weights, influences=3)
    bones, kept = binding.influences
    assert bones.tolist() == [[1, 2, 4]]
    np.testing.assert_allclose(kept, [[0.5, 0.3, 0.2]])
    assert binding.point_count == 1 and binding.bone_count == 5


def test_bad_input_is_named():
    points = np.zeros((2, 3))
    with pytest.raises(spacewarp.InvalidInput, match="weights must have shape"):
        spacewarp.Skinning(_BONES, weights=np.ones((3, 3)), model=points)
    with pytest.raises(spacewarp.InvalidInput, match="point 1 has a non-finite weight"):
        spacewarp.SkinningBinding(points, np.array([[1.0, 0, 0], [np.nan, 1, 0]]))
    with pytest.raises(spacewarp.InvalidInput, match="weights of point 0 sum to 0"):
        spacewarp.SkinningBinding(points, np.array([[1.0, -1, 0], [1, 0, 0]]))
    binding = spacewarp.SkinningBinding(points, np.ones((2, 3)))
    with pytest.raises(spacewarp.InvalidInput, match="skinning mode 'slerp' is not one of: lbs, dqs"):
        binding.deform(_BONES, mode="slerp")
    scaled = _BONES.copy()
    scaled[1, 0, 0] = 2.0
    with pytest.raises(spacewarp.InvalidInput, match="bone 1: dual-quaternion skinning needs"):
        binding.deform(scaled, mode="dqs")
    with pytest.raises(spacewarp.InvalidInput, match=r"bones must have shape \(b, 4, 4\)"):
        binding.deform(np.eye(3))
    with pytest.raises(spacewarp.InvalidInput, match="give weights"):
        spacewarp.Skinning(_BONES, weights=np.ones((2, 3)))


def test_weights_from_coordinates_have_no_pole():
    """The adversarial tester's reproducer: 16 random handles, signed RBF weights. Truncated to 4
    (negatives dropped, faded) and by default (all weights), two points 1e-5 apart stay together
    and within the bones' reach (they were thrown 50 units apart)."""
    rng = np.random.default_rng(3)
    handles = rng.random((16, 3))
    bones = np.stack([_turn_x(np.radians(rng.uniform(-60, 60)), rng.random(3) * 0.5)
                      for _ in range(16)])
    points = np.array([[0.14468] * 3, [0.14469] * 3])
    coordinates = spacewarp.Rbf(handles)
    for influences in (4, None):
        for mode in ("lbs", "dqs"):
            warp = spacewarp.Skinning(bones, coordinates=coordinates, mode=mode,
                                      influences=influences)
            moved = warp(points)
            assert np.linalg.norm(moved[1] - moved[0]) < 1e-3, (influences, mode)
            assert np.all(np.linalg.norm(moved - points, axis=1) < 2.0), (influences, mode)
    # Truncated: non-negative weights summing to 1.
    _, kept = spacewarp.SkinningBinding(points, coordinates, influences=4).influences
    assert np.all(kept >= 0.0)
    np.testing.assert_allclose(kept.sum(axis=1), 1.0, rtol=1e-14)
    # Default: all 16 bones kept.
    assert spacewarp.SkinningBinding(points, coordinates).influences[0].shape == (2, 16)
