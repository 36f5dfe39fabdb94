"""Pickling of every spacewarp.Warp and spacewarp.Coordinates (rig/warp_archive.h), and of Cage:
the loaded object gives bit-identical results, without solving again, also in another process."""

from __future__ import annotations

import concurrent.futures
import copy
import multiprocessing
import pickle

import numpy as np
import pytest

spacewarp = pytest.importorskip("spacewarp")

from conftest import CUBE, CUBE_QUADS, write_cage  # noqa: E402


def points(n=300, lo=-2.0, hi=2.0, seed=17):
    return np.random.default_rng(seed).uniform(lo, hi, (n, 3))


POSE = CUBE + 0.2 * np.sin(np.arange(24.0).reshape(8, 3) * 1.7)


def outcome(f):
    """f()'s bytes, or the type and message of what it raised (the same refusal after loading)."""
    try:
        return np.asarray(f()).tobytes()
    except (spacewarp.InvalidInput, spacewarp.SolverError) as e:
        return (type(e), str(e))


def assert_same_warp(a, b, xs):
    assert type(a) is type(b)
    assert outcome(lambda: a(xs)) == outcome(lambda: b(xs))
    assert outcome(lambda: a.jacobian(xs)) == outcome(lambda: b.jacobian(xs))


def assert_same_coordinates(a, b, xs):
    assert type(a) is type(b)
    assert outcome(lambda: a.weights(xs)) == outcome(lambda: b.weights(xs))
    assert outcome(lambda: a.warp(a.rest_control_points + 0.05)(xs)) == \
        outcome(lambda: b.warp(b.rest_control_points + 0.05)(xs))


def round_trip(obj):
    loaded = pickle.loads(pickle.dumps(obj))
    assert type(loaded) is type(obj)
    assert loaded.to_bytes() == obj.to_bytes()
    return loaded


def twist():
    return spacewarp.Twist(origin=(0.1, -0.2, 0.3), axis=(0.3, 1.0, -0.2), rate=1.7)


@pytest.fixture(scope="module")
def cage():
    return spacewarp.Cage(CUBE, np.array(CUBE_QUADS))


@pytest.fixture(scope="module")
def harmonic(cage):
    if "harmonic" not in spacewarp.cage_methods():
        pytest.skip("built without TetGen")
    return spacewarp.Harmonic(cage, tets=3000, outside="nearest")


def warps(cage):
    matrix = np.array([[1.1, 0.2, 0, 0.5], [0, 0.9, 0.1, 0], [0.3, 0, 1, -1], [0, 0, 0, 1]])
    rbf_centers = CUBE * 0.8
    return {
        "identity": spacewarp.Identity(),
        "affine": spacewarp.Affine(matrix),
        "twist": twist(),
        "bend": spacewarp.Bend(rate=0.5, lo=-0.5, hi=1.0),
        "taper": spacewarp.Taper(rate=0.4),
        "rbf_warp": spacewarp.RbfWarp(rbf_centers, rbf_centers + 0.1 * np.sin(rbf_centers),
                                      kernel="gaussian", scale=1.5),
        "mvc_warp": spacewarp.MeanValue(cage).warp(POSE),
        "green_warp": spacewarp.Green(cage).warp(POSE),
        "lattice_warp": spacewarp.Lattice(origin=(-1, -1, -1), extents=(2, 2, 2), resolution=(4, 4, 4),
                                          basis="bspline", outside="falloff").warp(
            spacewarp.Lattice(origin=(-1, -1, -1), extents=(2, 2, 2), resolution=(4, 4, 4))
            .rest_control_points * 1.1),
        "compose": spacewarp.Compose(twist(), spacewarp.Affine(matrix), spacewarp.MeanValue(cage).warp(POSE)),
    }


def coordinates(cage):
    return {
        "mvc": spacewarp.MeanValue(cage, snap_tolerance=1e-12),
        "green": spacewarp.Green(cage),
        "lattice": spacewarp.Lattice(origin=(-1.2, -1.1, -1), extents=(2.4, 2.2, 2.1),
                                     resolution=(3, 4, 3), basis="bernstein", outside="clamp"),
        "rbf": spacewarp.Rbf(CUBE * 1.1, fixed=CUBE * 2.0, kernel="wendland", radius=5.0),
    }


@pytest.mark.parametrize("name", list(warps(spacewarp.Cage(CUBE, np.array(CUBE_QUADS)))))
def test_every_warp_pickles_bit_identically(cage, name):
    w = warps(cage)[name]
    assert_same_warp(w, round_trip(w), points())


@pytest.mark.parametrize("name", ["mvc", "green", "lattice", "rbf"])
def test_every_coordinates_pickle_bit_identically(cage, name):
    c = coordinates(cage)[name]
    assert_same_coordinates(c, round_trip(c), points())


def test_harmonic_coordinates_and_warp_pickle_without_solving(harmonic):
    loaded = round_trip(harmonic)
    assert loaded.tet_count == harmonic.tet_count
    assert_same_coordinates(harmonic, loaded, points())
    warp = harmonic.warp(POSE)
    assert_same_warp(warp, round_trip(warp), points())


def test_harmonic_raise_outside_is_the_same_refusal(cage):
    if "harmonic" not in spacewarp.cage_methods():
        pytest.skip("built without TetGen")
    h = spacewarp.Harmonic(cage, tets=2000)
    xs = points()  # many outside the cube: both refuse them alike
    assert isinstance(outcome(lambda: h.weights(xs)), tuple)
    assert_same_coordinates(h, round_trip(h), xs)


def test_a_cage_pickles(cage):
    loaded = pickle.loads(pickle.dumps(cage))
    assert isinstance(loaded, spacewarp.Cage)
    assert loaded.to_bytes() == cage.to_bytes()
    assert_same_coordinates(spacewarp.MeanValue(cage), spacewarp.MeanValue(loaded), points())


def test_rig_and_load_rig_results_pickle(cage, tmp_path):
    write_cage(tmp_path / "rest.obj", CUBE, CUBE_QUADS)
    write_cage(tmp_path / "pose.obj", POSE, CUBE_QUADS)
    rigs = [
        {"method": "twist", "origin": [0, 0, 0], "axis": [0, 1, 0], "rate": 0.7},
        {"method": "bend", "origin": [0, 0, 0], "axis": [0, 0, 1], "direction": [1, 0, 0], "rate": 0.4},
        {"method": "taper", "origin": [0, 0, 0], "axis": [0, 0, 1], "rate": 0.2},
        {"method": "affine", "matrix": [[1, 0.1, 0, 0.5], [0, 1, 0, 0], [0, 0, 2, 0], [0, 0, 0, 1]]},
        {"method": "mvc", "cage": "rest.obj", "pose": "pose.obj"},
        {"method": "green", "cage": "rest.obj", "pose": "pose.obj"},
        {"method": "ffd", "basis": "trilinear", "origin": [-1, -1, -1], "size": [2, 2, 2],
         "resolution": [3, 3, 3],
         "constraints": {"from": [[0, 0, 0], [0.5, 0, 0]], "to": [[0.1, 0, 0], [0.5, 0.2, 0]]}},
        {"method": "rbf", "centers": [[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]],
         "targets": [[0, 0, 0.1], [1, 0, 0], [0, 1.2, 0], [0, 0, 1]]},
    ]
    if "harmonic" in spacewarp.cage_methods():
        rigs.append({"method": "harmonic", "cage": "rest.obj", "pose": "pose.obj", "tets": 2000})
    rigs.append({"method": "compose", "warps": rigs[:3] + rigs[-1:]})
    for description in rigs:
        w = spacewarp.rig(description, base_dir=tmp_path)
        assert_same_warp(w, round_trip(w), points())
    (tmp_path / "rig.json").write_text(__import__("json").dumps(rigs[-1]))
    w = spacewarp.load_rig(tmp_path / "rig.json")
    assert_same_warp(w, round_trip(w), points())


def test_to_bytes_and_from_bytes_agree_with_pickle(cage):
    w = twist()
    data = w.to_bytes()
    assert isinstance(data, bytes) and data.startswith(b"\x11\0\0\0\0\0\0\0spacewarp-archive")
    assert_same_warp(w, spacewarp.warp_from_bytes(data), points())
    c = spacewarp.MeanValue(cage)
    assert_same_coordinates(c, spacewarp.coordinates_from_bytes(c.to_bytes()), points())
    with pytest.raises(spacewarp.InvalidInput,
                       match="'mean-value' is coordinates .*coordinates_from_bytes.*not a warp"):
        spacewarp.warp_from_bytes(c.to_bytes())


def test_tampered_bytes_raise_invalid_input(cage):
    data = bytearray(twist().to_bytes())
    with pytest.raises(spacewarp.InvalidInput, match="not a spacewarp archive"):
        spacewarp.warp_from_bytes(b"hello")
    with pytest.raises(spacewarp.InvalidInput, match="truncated"):
        spacewarp.warp_from_bytes(bytes(data[:-1]))
    data[-8:] = np.float64("nan").tobytes()  # hi, the last field: refused by the constructor
    pickled = pickle.dumps(twist()).replace(twist().to_bytes(), bytes(data))
    with pytest.raises(spacewarp.InvalidInput):
        pickle.loads(pickled)
    # No flipped byte crashes, in a warp or in coordinates holding a cage.
    for original in (twist().to_bytes(), spacewarp.Green(cage).to_bytes()):
        for i in range(len(original)):
            flipped = bytearray(original)
            flipped[i] ^= 0x5A
            try:
                spacewarp.coordinates_from_bytes(bytes(flipped))
                spacewarp.warp_from_bytes(bytes(flipped))
            except spacewarp.InvalidInput:
                pass


def _apply(warp, xs):
    return warp(xs)


def test_a_spawned_process_applies_warps_bit_identically(cage):
    ws = [twist(), spacewarp.Compose(twist(), spacewarp.MeanValue(cage).warp(POSE)),
          spacewarp.RbfWarp(CUBE, CUBE * 1.1)]
    xs = points()
    context = multiprocessing.get_context("spawn")
    with concurrent.futures.ProcessPoolExecutor(max_workers=1, mp_context=context) as pool:
        remote = [pool.submit(_apply, w, xs).result(timeout=120) for w in ws]
    for w, r in zip(ws, remote):
        assert r.tobytes() == w(xs).tobytes()


def test_a_composition_of_any_depth_pickles_and_loads():
    # Nested two by two, 65 levels used to save but not load (the archive's nesting limit), and
    # 100,000 levels overflowed the stack when applied: compositions are now a flat list.
    t = spacewarp.Twist(rate=0.1)
    xs = points(20)
    for depth in (64, 65, 200, 20000):
        w = t
        for _ in range(depth):
            w = spacewarp.Compose(w, t)
        loaded = round_trip(w)
        assert loaded(xs).tobytes() == w(xs).tobytes()
    assert spacewarp.Compose(*([t] * 100001))(xs).shape == xs.shape


@pytest.mark.parametrize("cls", [spacewarp.Twist, spacewarp.MeanValue, spacewarp.Cage])
def test_an_uninitialised_instance_is_a_type_error_not_a_crash(cls):
    # cls.__new__ without __init__ holds no C++ object: these used to dereference a null pointer.
    obj = cls.__new__(cls)
    calls = [lambda: pickle.dumps(obj), obj.to_bytes, lambda: copy.deepcopy(obj)]
    if isinstance(obj, spacewarp.Warp):
        calls += [lambda: obj(points(3)), lambda: obj.jacobian(points(3))]
    for call in calls:
        with pytest.raises(TypeError, match=f"{cls.__name__} instance is not initialised"):
            call()


class ReducedTwist(spacewarp.Twist):
    def __reduce__(self):
        return (ReducedTwist, ())


def test_a_python_subclass_is_refused_not_pickled_as_its_base():
    class MyTwist(spacewarp.Twist):
        pass

    w = MyTwist(rate=0.5)
    w.note = "kept?"
    for call in (lambda: pickle.dumps(w), w.to_bytes):
        with pytest.raises(TypeError, match="MyTwist is a Python subclass of spacewarp.Twist.*"
                                            "define __reduce__ in .*MyTwist"):
            call()
    # A subclass that says how to pickle itself pickles.
    assert type(pickle.loads(pickle.dumps(ReducedTwist()))) is ReducedTwist


def test_warps_sharing_coordinates_store_them_once(cage):
    mv = spacewarp.MeanValue(cage)
    a, b = mv.warp(POSE), mv.warp(POSE * 1.1)
    both = spacewarp.Compose(a, b)
    assert len(both.to_bytes()) < len(a.to_bytes()) + len(b.to_bytes()) - len(mv.to_bytes()) // 2
    loaded = round_trip(both)
    xs = points()
    assert loaded(xs).tobytes() == both(xs).tobytes()


def test_loaders_accept_any_bytes_like_object(cage):
    w, c = twist(), spacewarp.MeanValue(cage)
    xs = points(50)
    for wrap in (bytearray, memoryview, lambda b: np.frombuffer(b, np.uint8)):
        assert spacewarp.warp_from_bytes(wrap(w.to_bytes()))(xs).tobytes() == w(xs).tobytes()
        assert type(spacewarp.coordinates_from_bytes(wrap(c.to_bytes()))) is type(c)
        assert spacewarp.cage_from_bytes(wrap(cage.to_bytes())).to_bytes() == cage.to_bytes()
    with pytest.raises(TypeError, match="expected a bytes-like object.*not int"):
        spacewarp.warp_from_bytes(3)
