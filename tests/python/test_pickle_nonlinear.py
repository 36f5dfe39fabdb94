"""Pickling the warps and coordinates of nonlinear/ and volume/ (rig/warp_archive.h): every
class, and every rig method of these modules, comes back as its own class with bit-identical
results, also in 'spawn' worker processes; a posed SkinningBinding pickles as its data; a
tampered archive raises InvalidInput.
"""

from __future__ import annotations

import multiprocessing
import pickle

import numpy as np
import pytest

spacewarp = pytest.importorskip("spacewarp")

from conftest import CUBE, CUBE_QUADS, as_list  # noqa: E402

_RNG = np.random.default_rng(17)
_HANDLES = _RNG.uniform(-0.8, 0.8, size=(7, 3))
_TARGETS = _HANDLES + _RNG.uniform(-0.2, 0.2, size=(7, 3))
_POINTS = _RNG.uniform(-1.2, 1.2, size=(400, 3))


def _turn_z(angle: float, shift=(0.0, 0.0, 0.0)) -> np.ndarray:
    c, s = np.cos(angle), np.sin(angle)
    m = np.eye(4)
    m[:2, :2] = [[c, -s], [s, c]]
    m[:3, 3] = shift
    return m


_BONES = np.stack([np.eye(4), _turn_z(2.5, (0.1, 0.0, 0.0))])
_BONE_HANDLES = np.array([[0.0, 0.0, -1.0], [0.0, 0.0, 1.0]])


def _model_weights(points: np.ndarray) -> np.ndarray:
    t = 0.5 + 0.5 * np.tanh(2.0 * points[:, 2])
    return np.column_stack([1.0 - t, t])


def _solved_graph_warp():
    graph = spacewarp.DeformationGraph(_RNG.uniform(-1, 1, size=(1500, 3)), spacing=0.45)
    # One Gauss-Newton step: a state that solving again (to convergence) would not give.
    report = graph.solve(_HANDLES, _TARGETS, max_iterations=1)
    assert not report.converged
    return graph.warp()


def _warps() -> dict:
    inside = spacewarp.InsideDistances(spacewarp.Geometry(CUBE, CUBE_QUADS), _HANDLES,
                                       voxel_size=0.1)
    wire = spacewarp.Wire([[-1, 0, 0], [0, 0.2, 0], [1, 0, 0.1]],
                          [[-1, 0.3, 0], [0, 0.5, 0.2], [1, 0.2, 0.3]], 1.2,
                          inner_radius=0.2, curve="catmull-rom")
    model = _RNG.uniform(-1, 1, size=(300, 3))
    return {
        "mls": spacewarp.Mls(_HANDLES, _TARGETS, mode="similarity", alpha=1.5),
        "mls inside": spacewarp.Mls(_HANDLES, _TARGETS, distances=inside),
        "graph": _solved_graph_warp(),
        "wires": spacewarp.Wires([wire], locality=2.0),
        "shepard": spacewarp.Shepard(_HANDLES, power=3.0).warp(_TARGETS),
        "shepard local": spacewarp.Shepard(_HANDLES, radius=0.9).warp(_TARGETS),
        "kelvinlet": spacewarp.Kelvinlet(brush="twist", center=(0.1, 0, 0), radius=0.8,
                                         axis=(0, 1, 1), angle=0.7, falloff="tri", steps=3),
        "skinning model": spacewarp.Skinning(_BONES, weights=_model_weights(model), model=model,
                                             mode="dqs"),
        "skinning coordinates": spacewarp.Skinning(
            _BONES, coordinates=spacewarp.Shepard(_BONE_HANDLES), mode="lbs"),
    }


def _outcome(warp, points: np.ndarray):
    """The warped points and Jacobians' bytes, or the error's type and message."""
    try:
        return warp(points).tobytes() + warp.jacobian(points[::10]).tobytes()
    except spacewarp.InvalidInput as error:
        return ("InvalidInput", str(error))


def _outcomes(warp, chunks: list[np.ndarray]):
    """What a worker process gives back: the outcome of each chunk (pickled warp in, bytes out)."""
    return [_outcome(warp, c) for c in chunks]


@pytest.fixture(scope="module")
def warps():
    return _warps()


@pytest.mark.parametrize("name", list(_warps().keys()))
def test_every_warp_pickles_bit_identically(warps, name):
    warp = warps[name]
    loaded = pickle.loads(pickle.dumps(warp))
    assert type(loaded) is type(warp)
    assert _outcome(loaded, _POINTS) == _outcome(warp, _POINTS)
    assert loaded.to_bytes() == warp.to_bytes()
    assert spacewarp.warp_from_bytes(warp.to_bytes()).to_bytes() == warp.to_bytes()


def test_points_out_of_reach_are_refused_alike_after_pickling(warps):
    warp = warps["shepard local"]
    far = np.array([[5.0, 5.0, 5.0]])
    with pytest.raises(spacewarp.InvalidInput) as original:
        warp(far)
    with pytest.raises(spacewarp.InvalidInput) as loaded:
        pickle.loads(pickle.dumps(warp))(far)
    assert str(loaded.value) == str(original.value)


def test_coordinates_pickle_bit_identically():
    for coordinates in (spacewarp.MlsAffine(_HANDLES), spacewarp.Shepard(_HANDLES, radius=2.5)):
        loaded = pickle.loads(pickle.dumps(coordinates))
        assert type(loaded) is type(coordinates)
        assert loaded.weights(_POINTS[:50]).tobytes() == coordinates.weights(_POINTS[:50]).tobytes()
    warp = spacewarp.MlsAffine(_HANDLES).warp(_TARGETS)
    assert _outcome(pickle.loads(pickle.dumps(warp)), _POINTS) == _outcome(warp, _POINTS)


def test_inside_distances_pickle_bit_identically():
    inside = spacewarp.InsideDistances(spacewarp.Geometry(CUBE, CUBE_QUADS), _HANDLES,
                                       voxel_size=0.1)
    for loaded in (pickle.loads(pickle.dumps(inside)),
                   spacewarp.distances_from_bytes(bytearray(inside.to_bytes()))):
        assert type(loaded) is spacewarp.InsideDistances
        assert (loaded.voxel_size, loaded.grid_size) == (inside.voxel_size, inside.grid_size)
        # Inside and outside the cube (outside: extrapolated from the nearest inside voxel).
        assert loaded.distances(_POINTS).tobytes() == inside.distances(_POINTS).tobytes()
        assert loaded.to_bytes() == inside.to_bytes()
        on_loaded = spacewarp.Mls(_HANDLES, _TARGETS, distances=loaded)
        on_original = spacewarp.Mls(_HANDLES, _TARGETS, distances=inside)
        assert _outcome(on_loaded, _POINTS) == _outcome(on_original, _POINTS)
    with pytest.raises(spacewarp.InvalidInput, match="is a warp"):
        spacewarp.distances_from_bytes(spacewarp.Mls(_HANDLES, _TARGETS).to_bytes())


def test_the_graph_warp_is_not_solved_again():
    warp = _solved_graph_warp()
    loaded = pickle.loads(pickle.dumps(warp))
    # The archive has no handles or targets to solve with: the state is the one-step solve's,
    # which a converged solve does not reproduce.
    data = warp.to_bytes()
    assert _HANDLES[0].tobytes() not in data
    graph = spacewarp.DeformationGraph(_RNG.uniform(-1, 1, size=(1500, 3)), spacing=0.45)
    graph.solve(_HANDLES, _TARGETS)
    assert _outcome(loaded, _POINTS) == _outcome(warp, _POINTS)
    assert loaded(_HANDLES).tobytes() != graph.warp()(_HANDLES).tobytes()


def _rigs(tmp_path) -> dict:
    handles, targets = as_list(_HANDLES), as_list(_TARGETS)
    spacewarp.write(tmp_path / "cube.obj", spacewarp.Geometry(CUBE, CUBE_QUADS))
    rigs = {
        "mls": {"method": "mls", "handles": handles, "targets": targets},
        "mls inside": {"method": "mls", "distance": "inside", "model": "cube.obj",
                       "voxelSize": 0.1, "handles": handles, "targets": targets},
        "graph": {"method": "graph", "spacing": 0.5, "handles": handles, "targets": targets},
        "idw": {"method": "idw", "radius": 1.5, "handles": handles, "targets": targets},
        "wires": {"method": "wires",
                  "wires": [{"rest": [[0, 0, -1], [0, 0, 0], [0, 0, 1]],
                             "deformed": [[0, 0, -1], [0.3, 0, 0], [0.2, 0.2, 1]],
                             "radius": 1.5}]},
        "kelvinlet": {"method": "kelvinlet", "brush": "grab", "center": [0, 0, 0.5],
                      "radius": 1.0, "displacement": [0.3, 0, 0]},
    }
    for coordinates in ("idw", "mls-affine", "rbf"):
        handles4 = [[-1, 0, -1], [1, 0, -1], [0, -1, 1], [0, 1, 1]]
        rigs["skinning " + coordinates] = {
            "method": "skinning", "mode": "dqs", "coordinates": coordinates,
            "bones": as_list(np.stack([np.eye(4), np.eye(4), _turn_z(1.0), _turn_z(1.0)])),
            "handles": handles4}
    return rigs


def test_every_rig_method_pickles_bit_identically(tmp_path):
    for name, description in _rigs(tmp_path).items():
        warp = spacewarp.rig(description, base_dir=tmp_path)
        loaded = pickle.loads(pickle.dumps(warp))
        assert type(loaded) is type(warp), name
        assert _outcome(loaded, _POINTS) == _outcome(warp, _POINTS), name
    path = tmp_path / "mls.json"
    path.write_text(__import__("json").dumps(_rigs(tmp_path)["mls inside"]))
    warp = spacewarp.load_rig(path)
    assert _outcome(pickle.loads(pickle.dumps(warp)), _POINTS) == _outcome(warp, _POINTS)


def test_a_spawn_pool_gives_the_same_bits(warps):
    chunks = np.array_split(_POINTS, 4)
    context = multiprocessing.get_context("spawn")
    with context.Pool(2) as pool:
        results = pool.starmap(_outcomes, [(warp, chunks) for warp in warps.values()])
    for (name, warp), result in zip(warps.items(), results):
        assert result == _outcomes(warp, chunks), name


def test_skinning_binding_pickles_as_its_data():
    points = _RNG.uniform(-1, 1, size=(500, 3))
    binding = spacewarp.SkinningBinding(points, spacewarp.Shepard(_BONE_HANDLES))
    loaded = pickle.loads(pickle.dumps(binding))
    for mode in ("lbs", "dqs"):
        assert loaded.deform(_BONES, mode=mode).tobytes() == \
            binding.deform(_BONES, mode=mode).tobytes()
    assert loaded.rest_points.tobytes() == binding.rest_points.tobytes()
    # A state whose bones name a bone the binding does not have is refused by the constructor.
    state = binding.__getstate__()
    bones, weights = state[1]
    bad = (state[0], (bones + 5, weights), state[2])
    fresh = spacewarp.SkinningBinding.__new__(spacewarp.SkinningBinding)
    with pytest.raises(spacewarp.InvalidInput, match="names bone"):
        fresh.__setstate__(bad)


def test_a_tampered_archive_raises_invalid_input(warps):
    data = bytearray(warps["mls"].to_bytes())
    # The MLS mode is the u32 after the handles and targets: made 9, it is no mode at all.
    tag = data.find(b"mls") + 3
    handles_end = tag + 8 + 7 * 24
    mode_at = handles_end + 8 + 7 * 24
    assert data[mode_at:mode_at + 4] == (1).to_bytes(4, "little")  # similarity
    data[mode_at] = 9
    with pytest.raises(spacewarp.InvalidInput, match="warp archive"):
        pickle.loads(pickle.dumps(warps["mls"]).replace(warps["mls"].to_bytes(), bytes(data)))
    with pytest.raises(spacewarp.InvalidInput, match="warp archive"):
        spacewarp.warp_from_bytes(warps["graph"].to_bytes()[:-5])
