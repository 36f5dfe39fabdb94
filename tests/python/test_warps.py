"""spacewarp's Warp classes from Python (python/src/warps.cpp).

Every warp gives the command line's `spacewarp deform --rig` result bit for bit (the rig JSON
describing the same warp), also when built by spacewarp.rig(dict) and load_rig(path); Jacobians
match central differences; inverse() undoes the warp; normals stay unit and perpendicular to the
warped tangents; `out=`, dtypes, layouts and shapes behave as documented.
"""

from __future__ import annotations

import re

import numpy as np
import pytest

spacewarp = pytest.importorskip("spacewarp")

from conftest import as_list, central_jacobian, write_json  # noqa: E402


def _points(n: int = 300, seed: int = 7) -> np.ndarray:
    return np.random.default_rng(seed).uniform(-1.0, 1.0, size=(n, 3))


# A small, smooth deformation graph: explicit nodes on a 4 x 4 x 4 grid over [-1.5, 1.5]^3.
_GRID = np.linspace(-1.5, 1.5, 4)
_NODES = np.array([[x, y, z] for z in _GRID for y in _GRID for x in _GRID])
_HANDLES = np.array([[-1.0, -1.0, -1.0], [1.0, -1.0, -1.0], [-1.0, 1.0, -1.0],
                     [-1.0, -1.0, 1.0], [1.0, 1.0, 1.0], [0.0, 0.0, 0.5]])
_TARGETS = _HANDLES + np.array([[0.0, 0.0, 0.0], [0.05, 0.0, 0.0], [0.0, 0.04, 0.0],
                                [0.0, 0.0, 0.0], [0.1, 0.05, -0.05], [0.02, 0.0, 0.03]])
_AFFINE = np.array([[1.1, 0.2, -0.1, 0.3], [0.05, 0.9, 0.1, -0.2], [0.0, -0.15, 1.2, 0.5],
                    [0.0, 0.0, 0.0, 1.0]])
_MLS_HANDLES = np.array([[-1.2, -1.1, -1.0], [1.3, -1.0, -1.1], [-1.0, 1.2, -1.3],
                         [-1.1, -1.3, 1.2], [1.2, 1.1, 1.3]])
_MLS_TARGETS = _MLS_HANDLES + 0.1 * np.sin(np.arange(15.0).reshape(5, 3))


def _graph_warp():
    graph = spacewarp.DeformationGraph(_NODES, nodes=_NODES, k=4)
    report = graph.solve(_HANDLES, _TARGETS)
    assert report.converged
    return graph.warp()


# name -> (the Python warp, the rig describing it). Limits lie inside the points' range so that
# the clamped branches are exercised too.
CASES = {
    "identity": (lambda: spacewarp.Identity(),
                 {"method": "affine", "matrix": as_list(np.eye(4))}),
    "twist": (lambda: spacewarp.Twist(origin=(0.1, -0.2, 0.05), axis=(0.2, 0.1, 1.0), rate=0.9,
                                      lo=-0.6, hi=0.7),
              {"method": "twist", "origin": [0.1, -0.2, 0.05], "axis": [0.2, 0.1, 1.0],
               "rate": 0.9, "limits": [-0.6, 0.7]}),
    "bend": (lambda: spacewarp.Bend(origin=(0.0, 0.1, -0.3), axis=(0, 0, 1), direction=(1, 0.2, 0),
                                    rate=0.6, lo=-0.8, hi=0.9),
             {"method": "bend", "origin": [0.0, 0.1, -0.3], "axis": [0, 0, 1],
              "direction": [1, 0.2, 0], "rate": 0.6, "limits": [-0.8, 0.9]}),
    "taper": (lambda: spacewarp.Taper(origin=(0, 0, -0.2), axis=(0.1, 1.0, 0.0), rate=0.3,
                                      lo=-0.5, hi=0.6),
              {"method": "taper", "origin": [0, 0, -0.2], "axis": [0.1, 1.0, 0.0], "rate": 0.3,
               "limits": [-0.5, 0.6]}),
    "affine": (lambda: spacewarp.Affine(_AFFINE), {"method": "affine", "matrix": as_list(_AFFINE)}),
    "compose": (lambda: spacewarp.Compose(spacewarp.Twist(rate=0.5),
                                          spacewarp.Affine(_AFFINE),
                                          spacewarp.Taper(axis=(1, 0, 0), rate=0.2)),
                {"method": "compose", "warps": [
                    {"method": "twist", "origin": [0, 0, 0], "axis": [0, 0, 1], "rate": 0.5},
                    {"method": "affine", "matrix": as_list(_AFFINE)},
                    {"method": "taper", "origin": [0, 0, 0], "axis": [1, 0, 0], "rate": 0.2}]}),
    "mls": (lambda: spacewarp.Mls(_MLS_HANDLES, _MLS_TARGETS, mode="rigid", alpha=1.5),
            {"method": "mls", "handles": as_list(_MLS_HANDLES),
             "targets": as_list(_MLS_TARGETS), "mode": "rigid", "alpha": 1.5}),
    "mls_affine": (lambda: spacewarp.Mls(_MLS_HANDLES, _MLS_TARGETS, mode="affine"),
                   {"method": "mls", "handles": as_list(_MLS_HANDLES),
                    "targets": as_list(_MLS_TARGETS), "mode": "affine"}),
    "rbf": (lambda: spacewarp.RbfWarp(_MLS_HANDLES, _MLS_TARGETS, fixed=[[0.0, 0.0, 0.0]]),
            {"method": "rbf", "centers": as_list(_MLS_HANDLES),
             "targets": as_list(_MLS_TARGETS), "fixed": [[0.0, 0.0, 0.0]]}),
    "rbf_gaussian": (lambda: spacewarp.RbfWarp(_MLS_HANDLES, _MLS_TARGETS, kernel="gaussian",
                                               scale=1.5, smoothing=1e-3),
                     {"method": "rbf", "centers": as_list(_MLS_HANDLES),
                      "targets": as_list(_MLS_TARGETS), "kernel": "gaussian", "scale": 1.5,
                      "smoothing": 1e-3}),
    "graph": (_graph_warp,
              {"method": "graph", "handles": as_list(_HANDLES), "targets": as_list(_TARGETS),
               "nodes": as_list(_NODES), "k": 4}),
}

NAMES = list(CASES)


def _warp(name: str):
    return CASES[name][0]()


@pytest.fixture(params=NAMES)
def name(request) -> str:
    return request.param


# ----------------------------------------------------------------------------------------------
# The same warp three ways: Python class, rig(dict) / load_rig(path), and the command line.


def test_warp_equals_cli_bit_for_bit(name, cli, tmp_path):
    points = _points()
    ours = _warp(name)(points)
    theirs = cli.deform(CASES[name][1], points, tmp_path)
    assert theirs.dtype == np.float64 and theirs.shape == points.shape
    assert np.array_equal(ours, theirs), np.abs(ours - theirs).max()
    if name != "identity":
        assert not np.array_equal(ours, points)  # the case deforms something


def test_cli_point_cloud_keeps_float64_positions(cli, tmp_path):
    # Guards the comparisons above: the PLY round trip itself must be exact.
    points = _points(50) * np.pi
    out = cli.deform({"method": "affine", "matrix": as_list(np.eye(4))}, points, tmp_path)
    assert np.array_equal(out, points)


def test_rig_dict_and_file_equal_the_class(name, tmp_path):
    points = _points()
    expected = _warp(name)(points)
    description = CASES[name][1]
    from_dict = spacewarp.rig(description)
    assert isinstance(from_dict, spacewarp.Warp)
    assert np.array_equal(from_dict(points), expected)
    from_file = spacewarp.load_rig(write_json(tmp_path / "rig.json", description))
    assert np.array_equal(from_file(points), expected)


def test_load_rig_resolves_paths_against_its_folder(tmp_path, cube_cage, cube_pose):
    from conftest import CUBE, CUBE_QUADS, write_cage

    folder = tmp_path / "rigs"
    folder.mkdir()
    write_cage(folder / "cage.obj", CUBE, CUBE_QUADS)
    write_cage(folder / "pose.obj", cube_pose, CUBE_QUADS)
    rig = {"method": "mvc", "cage": "cage.obj", "pose": "pose.obj"}
    points = _points(100) * 0.8
    expected = spacewarp.MeanValue(cube_cage).warp(cube_pose)(points)
    assert np.array_equal(spacewarp.load_rig(write_json(folder / "mvc.json", rig))(points),
                          expected)
    assert np.array_equal(spacewarp.rig(rig, base_dir=folder)(points), expected)
    with pytest.raises(spacewarp.IoError):
        spacewarp.rig(rig, base_dir=tmp_path)  # no cage.obj there


def test_malformed_rig_raises_invalid_input_naming_the_key(tmp_path):
    with pytest.raises(spacewarp.InvalidInput, match="rte"):
        spacewarp.rig({"method": "twist", "origin": [0, 0, 0], "axis": [0, 0, 1], "rte": 1.0})
    with pytest.raises(spacewarp.IoError, match="missing.json"):
        spacewarp.load_rig(tmp_path / "missing.json")


def test_rig_methods_lists_the_analytic_methods():
    methods = spacewarp.rig_methods()
    assert {"twist", "bend", "taper", "affine", "compose", "mls", "rbf", "graph"} <= set(methods)


# ----------------------------------------------------------------------------------------------
# Closed forms of the analytic warps.


def test_twist_closed_form():
    points = _points()
    rate = 0.7
    moved = spacewarp.Twist(axis=(0, 0, 1), rate=rate)(points)
    angle = rate * points[:, 2]
    c, s = np.cos(angle), np.sin(angle)
    expected = np.column_stack([c * points[:, 0] - s * points[:, 1],
                                s * points[:, 0] + c * points[:, 1], points[:, 2]])
    np.testing.assert_allclose(moved, expected, rtol=0, atol=1e-14)


def test_taper_closed_form():
    points = _points()
    moved = spacewarp.Taper(axis=(0, 0, 1), rate=0.25)(points)
    scale = 1.0 + 0.25 * points[:, 2]
    expected = np.column_stack([points[:, 0] * scale, points[:, 1] * scale, points[:, 2]])
    np.testing.assert_allclose(moved, expected, rtol=0, atol=1e-14)


def test_bend_closed_form():
    # Barr's bend of the z axis towards x with curvature k: the plane y = 0 wraps around the
    # circle of radius 1/k centered at (1/k, 0, 0); y is kept
    k = 0.7
    rng = np.random.default_rng(14)
    x, y, s = rng.uniform(-0.5, 0.5, 100), rng.uniform(-1, 1, 100), rng.uniform(-1.5, 1.5, 100)
    moved = spacewarp.Bend(axis=(0, 0, 1), direction=(1, 0, 0), rate=k)(np.c_[x, y, s])
    radius = 1.0 / k
    expected = np.c_[radius - (radius - x) * np.cos(k * s), y, (radius - x) * np.sin(k * s)]
    np.testing.assert_allclose(moved, expected, rtol=0, atol=1e-14)


def test_limits_move_the_ends_rigidly():
    # beyond `hi` the twist angle stays rate * hi: a rigid rotation of the end
    twist = spacewarp.Twist(axis=(0, 0, 1), rate=0.8, lo=-0.5, hi=0.5)
    points = _points(200, seed=15) * [1, 1, 2]
    moved = twist(points)
    angle = 0.8 * np.clip(points[:, 2], -0.5, 0.5)
    c, s = np.cos(angle), np.sin(angle)
    expected = np.c_[c * points[:, 0] - s * points[:, 1], s * points[:, 0] + c * points[:, 1],
                     points[:, 2]]
    np.testing.assert_allclose(moved, expected, rtol=0, atol=1e-14)


def test_affine_closed_form_and_matrix_shapes():
    points = _points()
    expected = points @ _AFFINE[:3, :3].T + _AFFINE[:3, 3]
    np.testing.assert_allclose(spacewarp.Affine(_AFFINE)(points), expected, atol=1e-14)
    np.testing.assert_allclose(spacewarp.Affine(_AFFINE[:3])(points), expected, atol=1e-14)
    np.testing.assert_allclose(spacewarp.Affine(_AFFINE[:3, :3])(points),
                               points @ _AFFINE[:3, :3].T, atol=1e-14)
    assert np.array_equal(spacewarp.Affine(_AFFINE).matrix, _AFFINE)
    with pytest.raises(spacewarp.InvalidInput, match=r"\(4, 4\)"):
        spacewarp.Affine(np.eye(2))


def test_compose_applies_in_order():
    points = _points()
    a, b = spacewarp.Twist(rate=0.5), spacewarp.Affine(_AFFINE)
    np.testing.assert_allclose(spacewarp.Compose(a, b)(points), b(a(points)), atol=1e-14)
    assert not np.allclose(spacewarp.Compose(b, a)(points), b(a(points)))
    assert np.array_equal(spacewarp.Compose(a)(points), a(points))
    with pytest.raises(spacewarp.InvalidInput):
        spacewarp.Compose()


def test_identity_is_exact():
    points = _points()
    assert np.array_equal(spacewarp.Identity()(points), points)


def test_mls_and_rbf_interpolate_their_handles():
    for warp in (spacewarp.Mls(_MLS_HANDLES, _MLS_TARGETS),
                 spacewarp.Mls(_MLS_HANDLES, _MLS_TARGETS, mode="similarity"),
                 spacewarp.RbfWarp(_MLS_HANDLES, _MLS_TARGETS)):
        np.testing.assert_allclose(warp(_MLS_HANDLES), _MLS_TARGETS, atol=1e-10)


def test_deformation_graph_solve_report_and_snapshot():
    graph = spacewarp.DeformationGraph(_NODES, nodes=_NODES, k=4)
    assert graph.k == 4
    assert np.array_equal(graph.nodes, _NODES)
    edges = graph.edges
    assert edges.ndim == 2 and edges.shape[1] == 2 and len(edges) > 0
    assert (edges[:, 0] < edges[:, 1]).all() and edges.max() < len(_NODES)
    rest = graph.warp()
    report = graph.solve(_HANDLES, _TARGETS)
    assert report.converged and report.iterations >= 1
    assert report.energies[-1] <= report.energies[0]
    posed = graph.warp()
    # soft constraints: the handles move most of the way to their targets
    before = np.linalg.norm(_HANDLES - _TARGETS)
    assert np.linalg.norm(posed(_HANDLES) - _TARGETS) < 0.5 * before
    points = _points(50)
    assert np.array_equal(rest(points), points)  # a snapshot: the solve did not change it
    graph.reset()
    assert np.allclose(graph.warp()(points), points, atol=1e-14)
    assert not np.allclose(posed(points), points)


def test_deformation_graph_samples_nodes():
    positions = _points(2000)
    graph = spacewarp.DeformationGraph(positions, spacing=0.5)
    assert 8 <= len(graph.nodes) < 2000
    with pytest.raises(spacewarp.InvalidInput, match="sampling"):
        spacewarp.DeformationGraph(positions, spacing=0.5, sampling="grid")


def test_rbf_accepts_the_kernel_names_its_docstring_gives():
    doc = spacewarp.RbfWarp.__doc__
    kernels = doc[doc.index("kernel:"):]
    kernels = kernels[:kernels.index(";")]
    documented = re.findall(r'"([a-z0-9_-]+)"', kernels)
    assert len(documented) == 6, documented
    for kernel in documented:
        spacewarp.RbfWarp(_MLS_HANDLES, _MLS_TARGETS, kernel=kernel)


# ----------------------------------------------------------------------------------------------
# Jacobians, inverse, normals.


def test_jacobian_matches_central_differences(name):
    warp = _warp(name)
    points = _points(100, seed=3) * 0.9
    j = warp.jacobian(points)
    assert j.shape == (100, 3, 3) and j.dtype == np.float64
    fd = central_jacobian(warp, points)
    np.testing.assert_allclose(j, fd, rtol=0, atol=2e-6 * (1.0 + np.abs(fd).max()))


def test_jacobian_of_affine_is_its_matrix():
    j = spacewarp.Affine(_AFFINE).jacobian(_points(10))
    assert np.array_equal(j, np.broadcast_to(_AFFINE[:3, :3], (10, 3, 3)))


def test_inverse_round_trip(name):
    warp = _warp(name)
    x = _points(200, seed=5) * 0.9
    y = warp(x)
    back, converged, residual = warp.inverse(y)
    assert back.shape == (200, 3) and converged.shape == (200,) and residual.shape == (200,)
    assert converged.dtype == np.bool_ and converged.all()
    np.testing.assert_allclose(back, x, rtol=0, atol=1e-9)
    # residual = |warp(x) - y|, within the default relative tolerance 1e-12 of |y|
    np.testing.assert_allclose(residual, np.linalg.norm(warp(back) - y, axis=1), rtol=0,
                               atol=1e-15 * (1 + np.abs(y).max()))
    assert (residual <= 1e-12 * np.maximum(np.linalg.norm(y, axis=1), 1.0)).all()


def test_inverse_of_one_point_and_exact_inverse():
    twist = spacewarp.Twist(rate=0.8)
    x = np.array([0.3, -0.2, 0.7])
    back, converged, residual = twist.inverse(twist(x))
    assert back.shape == (3,) and converged is True and isinstance(residual, float)
    np.testing.assert_allclose(back, x, atol=1e-12)
    exact = twist.exact_inverse(twist(x))
    assert exact.shape == (3,)
    np.testing.assert_allclose(exact, x, atol=1e-12)
    assert _warp("mls").exact_inverse(x) is None  # no closed form


def test_inverse_reports_non_convergence_without_raising():
    # A taper that collapses the plane s = -1: points there have no preimage except the axis.
    warp = spacewarp.Taper(axis=(0, 0, 1), rate=1.0)
    y = np.array([[0.5, 0.5, -1.0], [0.1, 0.2, 0.3]])
    back, converged, _ = warp.inverse(y, max_iterations=5)
    assert not converged[0] and converged[1]


def test_transform_normals_unit_and_perpendicular(name):
    warp = _warp(name)
    rng = np.random.default_rng(11)
    points = _points(100, seed=13) * 0.9
    normals = rng.normal(size=(100, 3))
    normals /= np.linalg.norm(normals, axis=1, keepdims=True)
    out = warp.transform_normals(points, normals)
    assert out.shape == (100, 3)
    np.testing.assert_allclose(np.linalg.norm(out, axis=1), 1.0, atol=1e-12)
    jac = warp.jacobian(points)
    # two tangents of each input normal, carried by J
    helper = np.where(np.abs(normals[:, :1]) < 0.9, [[1.0, 0, 0]], [[0, 1.0, 0]])
    t1 = np.cross(normals, helper)
    t2 = np.cross(normals, t1)
    for t in (t1, t2):
        warped = np.einsum("nrc,nc->nr", jac, t)
        cosine = np.einsum("nr,nr->n", out, warped) / np.linalg.norm(warped, axis=1)
        assert np.abs(cosine).max() < 1e-9
    # and on the same side as the input normal: (J^-T n) . n > 0 for orientation-preserving J
    assert (np.einsum("nr,nrc,nc->n", out, jac, normals) > 0).all()


def test_transform_normals_shape_mismatch_raises():
    with pytest.raises(spacewarp.InvalidInput, match="normals"):
        spacewarp.Twist(rate=1.0).transform_normals(_points(5), _points(4))


# ----------------------------------------------------------------------------------------------
# Arrays: out=, dtypes, layouts, shapes.


def test_out_is_written_and_returned(name):
    warp = _warp(name)
    points = _points()
    expected = warp(points)
    out = np.full_like(points, np.nan)
    result = warp(points, out=out)
    assert result is out
    assert np.array_equal(out, expected)
    in_place = points.copy()
    result = warp(in_place, out=in_place)
    assert result is in_place
    assert np.array_equal(in_place, expected)


def test_out_with_wrong_shape_or_dtype_raises():
    warp = spacewarp.Twist(rate=1.0)
    points = _points(10)
    with pytest.raises(spacewarp.InvalidInput, match=r"\(10, 3\)"):
        warp(points, out=np.empty((9, 3)))
    with pytest.raises(spacewarp.InvalidInput, match="float64"):
        warp(points, out=np.empty((10, 3), dtype=np.float32))
    with pytest.raises(spacewarp.InvalidInput, match="C-contiguous"):
        warp(points, out=np.empty((10, 3), order="F"))
    readonly = np.empty((10, 3))
    readonly.setflags(write=False)
    with pytest.raises(spacewarp.InvalidInput, match="writable"):
        warp(points, out=readonly)


def test_dtypes_and_layouts_give_the_same_result(name):
    warp = _warp(name)
    points = _points()
    expected = warp(points)
    single = points.astype(np.float32)
    assert np.array_equal(warp(single), warp(single.astype(np.float64)))
    wide = np.empty((len(points), 6))
    wide[:, ::2] = points[:, ::-1]  # a strided, reversed view whose values are `points`
    view = wide[:, ::2][:, ::-1]
    assert not view.flags.c_contiguous
    assert np.array_equal(warp(view), expected)
    assert np.array_equal(warp(np.asfortranarray(points)), expected)
    reversed_columns = points[:, ::-1]
    assert np.array_equal(warp(reversed_columns), warp(np.ascontiguousarray(reversed_columns)))
    assert np.array_equal(warp(single[:, ::-1]),
                          warp(np.ascontiguousarray(single[:, ::-1]).astype(np.float64)))
    assert np.array_equal(warp(points.tolist()), expected)
    assert np.array_equal(warp(points[::2]), expected[::2])
    assert np.array_equal(warp.jacobian(np.asfortranarray(points)), warp.jacobian(points))


def test_one_point_gives_one_point(name):
    warp = _warp(name)
    points = _points(5)
    single = warp(points[2])
    assert single.shape == (3,)
    assert np.array_equal(single, warp(points)[2])
    assert warp.jacobian(points[2]).shape == (3, 3)
    out = np.empty(3)
    assert warp(points[2], out=out) is out and np.array_equal(out, single)


@pytest.mark.parametrize("shape", [(4, 2), (5,), (2, 3, 3), (3, 4), (0,)])
def test_wrong_shapes_raise_invalid_input_naming_the_shape(shape):
    warp = spacewarp.Twist(rate=1.0)
    text = "(" + ", ".join(str(s) for s in shape) + ("," if len(shape) == 1 else "") + ")"
    for call in (warp, warp.jacobian, warp.inverse):
        with pytest.raises(spacewarp.InvalidInput, match=re.escape(text)) as error:
            call(np.zeros(shape))
        assert isinstance(error.value, ValueError)


def test_non_numeric_input_raises_invalid_input():
    with pytest.raises(spacewarp.InvalidInput, match="points"):
        spacewarp.Twist(rate=1.0)("abc")


def test_non_finite_point_raises_naming_it():
    points = _points(10)
    points[6, 1] = np.nan
    with pytest.raises(spacewarp.InvalidInput, match="point 6 is not finite"):
        spacewarp.Twist(rate=1.0)(points)
    with pytest.raises(spacewarp.InvalidInput, match="point 6"):
        spacewarp.Twist(rate=1.0)(points, out=points)
    points[6, 1] = np.inf
    with pytest.raises(spacewarp.InvalidInput, match="point 6"):
        spacewarp.Affine(np.eye(4))(points, progress=lambda stage, fraction: True)


def test_empty_input_gives_empty_output():
    out = spacewarp.Twist(rate=1.0)(np.zeros((0, 3)))
    assert out.shape == (0, 3)


def test_rig_warnings_are_python_warnings():
    corners = np.array([[x, y, z] for z in (-1, 1) for y in (-1, 1) for x in (-1, 1)], float)
    rig = {"method": "graph", "handles": corners.tolist(),
           "targets": (corners * 1.3 + np.sin(corners)).tolist(), "spacing": 0.5,
           "maxIterations": 1}
    with pytest.warns(UserWarning, match="did not converge in 1 iterations"):
        warp = spacewarp.rig(rig)
    assert isinstance(warp, spacewarp.Warp)


def test_compose_of_a_non_warp_raises_type_error():
    with pytest.raises(TypeError):
        spacewarp.Compose(spacewarp.Twist(rate=1.0), 3)


def test_results_do_not_depend_on_progress_or_thread(name):
    # with or without a progress callable, in the main thread (Ctrl-C watched) or another one:
    # the same bits
    import threading

    warp = _warp(name)
    points = _points(70_000, seed=21)
    plain = warp(points)
    assert np.array_equal(warp(points, progress=lambda stage, fraction: True), plain)
    box = {}
    worker = threading.Thread(target=lambda: box.setdefault("out", warp(points)))
    worker.start()
    worker.join(60)
    assert np.array_equal(box["out"], plain)


# ----------------------------------------------------------------------------------------------
# Rigs with coordinates: the class-built warp, the rig and the command line agree bit for bit.

_LATTICE = dict(origin=[-1.1, -1.2, -1.0], axes=[[1, 0, 0], [0, 1, 0], [0, 0, 1]],
                size=[2.2, 2.4, 2.1], resolution=[3, 4, 3])


def _lattice_pose(resolution) -> np.ndarray:
    count = int(np.prod(resolution))
    lattice = spacewarp.Lattice(origin=_LATTICE["origin"], extents=_LATTICE["size"],
                                resolution=resolution)
    rest = lattice.rest_control_points
    assert rest.shape == (count, 3)
    return rest + 0.1 * np.sin(np.arange(3.0 * count).reshape(count, 3))


def _coordinate_case(kind: str, folder):
    """(the warp built from classes, the rig dict) for a rig method with coordinates."""
    from conftest import CUBE, CUBE_QUADS, write_cage

    cage_path = write_cage(folder / "cage.obj", CUBE * 1.3, CUBE_QUADS)
    pose = CUBE * 1.3 + 0.15 * np.cos(np.arange(24.0).reshape(8, 3))
    pose_path = write_cage(folder / "pose.obj", pose, CUBE_QUADS)
    cage = spacewarp.Cage(CUBE * 1.3, CUBE_QUADS)
    if kind in ("mvc", "green"):
        coords = spacewarp.MeanValue(cage) if kind == "mvc" else spacewarp.Green(cage)
        return coords.warp(pose), {"method": kind, "cage": str(cage_path),
                                   "pose": str(pose_path)}
    if kind == "harmonic":
        coords = spacewarp.Harmonic(cage, tets=3000)
        return coords.warp(pose), {"method": "harmonic", "cage": str(cage_path),
                                   "pose": str(pose_path), "tets": 3000}
    basis = {"ffd_trilinear": "trilinear", "ffd_bernstein": "bernstein",
             "ffd_bspline": "bspline"}[kind]
    resolution = [4, 5, 4] if basis == "bspline" else _LATTICE["resolution"]
    lattice = spacewarp.Lattice(origin=_LATTICE["origin"], axes=_LATTICE["axes"],
                                extents=_LATTICE["size"], resolution=resolution, basis=basis)
    posed = _lattice_pose(resolution)
    return lattice.warp(posed), {"method": "ffd", "basis": basis,
                                 "origin": _LATTICE["origin"], "size": _LATTICE["size"],
                                 "resolution": resolution, "controlPoints": as_list(posed)}


@pytest.mark.parametrize("kind", ["mvc", "green", "harmonic", "ffd_trilinear", "ffd_bernstein",
                                  "ffd_bspline"])
def test_coordinate_rigs_equal_the_classes_and_the_cli(kind, cli, tmp_path):
    warp, rig = _coordinate_case(kind, tmp_path)
    points = _points(300, seed=17) * 0.95
    ours = warp(points)
    assert not np.allclose(ours, points)
    assert np.array_equal(spacewarp.rig(rig)(points), ours)
    rig_path = write_json(tmp_path / "rig.json", rig)
    assert np.array_equal(spacewarp.load_rig(rig_path)(points), ours)
    assert np.array_equal(cli.deform(rig_path, points, tmp_path), ours)


@pytest.mark.parametrize("kernel", ["biharmonic", "thin-plate", "inverse-multiquadric",
                                    "wendland"])
def test_rbf_kernels_equal_the_cli(kernel, cli, tmp_path):
    options = {"scale": 0.8} if kernel == "inverse-multiquadric" else (
        {"radius": 4.0} if kernel == "wendland" else {})
    warp = spacewarp.RbfWarp(_MLS_HANDLES, _MLS_TARGETS, kernel=kernel, **options)
    rig = {"method": "rbf", "centers": as_list(_MLS_HANDLES), "targets": as_list(_MLS_TARGETS),
           "kernel": kernel, **options}
    points = _points(200, seed=19)
    ours = warp(points)
    np.testing.assert_allclose(warp(_MLS_HANDLES), _MLS_TARGETS, atol=1e-9)
    assert np.array_equal(spacewarp.rig(rig)(points), ours)
    assert np.array_equal(cli.deform(rig, points, tmp_path), ours)


def test_mls_similarity_equals_the_cli(cli, tmp_path):
    warp = spacewarp.Mls(_MLS_HANDLES, _MLS_TARGETS * 1.2, mode="similarity", alpha=0.8)
    rig = {"method": "mls", "handles": as_list(_MLS_HANDLES),
           "targets": as_list(_MLS_TARGETS * 1.2), "mode": "similarity", "alpha": 0.8}
    points = _points(200, seed=23)
    assert np.array_equal(cli.deform(rig, points, tmp_path), warp(points))


def test_a_warp_that_overflows_raises_naming_the_point():
    points = np.array([[0.5, 0.0, 0.0], [10.0, 0.0, 0.0], [0.1, 0.2, 0.3]])
    huge = spacewarp.Affine(np.diag([1e308, 1.0, 1.0]))
    with pytest.raises(spacewarp.InvalidInput, match="point 1 to a non-finite position"):
        huge(points)
    with pytest.raises(spacewarp.InvalidInput, match="point 1"):
        huge(points.copy(), out=np.empty((3, 3)))


def test_out_partly_overlapping_points_reads_a_copy():
    # two shifted views of one buffer: the warp must not read points it already overwrote
    # (it once did: errors of 2.2 on a twist of 200k points)
    warp = spacewarp.Twist(rate=1.0)
    buffer = _points(200_001, seed=31)
    expected = warp(buffer[:-1].copy())
    result = warp(buffer[:-1], out=buffer[1:])
    assert np.shares_memory(result, buffer)
    assert np.array_equal(result, expected)
    buffer = _points(200_001, seed=31)
    expected = warp(buffer[1:].copy())
    assert np.array_equal(warp(buffer[1:], out=buffer[:-1]), expected)


def test_inverse_convergence_follows_the_tolerance_rule():
    # converged <=> |warp(x) - y| <= tolerance * scale, scale = length_scale if > 0, else
    # max(|y|_inf, |warp(y) - y|_inf) (core/inverse.h); one Newton step leaves some unconverged
    warp = _warp("mls")
    y = warp(_points(500, seed=3) * 1.5)
    for length_scale in (0.0, 2.0):
        x, converged, residual = warp.inverse(y, tolerance=1e-6, max_iterations=1,
                                              length_scale=length_scale, continuation=False,
                                              closed_form=False)
        np.testing.assert_allclose(residual, np.linalg.norm(warp(x) - y, axis=1), rtol=0,
                                   atol=1e-14)
        scale = length_scale if length_scale > 0 else np.maximum(
            np.abs(y).max(axis=1), np.abs(warp(y) - y).max(axis=1))
        assert np.array_equal(converged, residual <= 1e-6 * scale)
        assert 0 < converged.sum() < len(y)  # the rule is exercised both ways


def _rotation(angle: float, axis) -> np.ndarray:
    axis = np.asarray(axis, float) / np.linalg.norm(axis)
    k = np.array([[0, -axis[2], axis[1]], [axis[2], 0, -axis[0]], [-axis[1], axis[0], 0]])
    return np.eye(3) + np.sin(angle) * k + (1 - np.cos(angle)) * k @ k


_ROTATION = _rotation(0.6, (1.0, 2.0, -0.5))
_SHIFT = np.array([0.3, -0.1, 0.25])
_GENERAL = np.array([[1.1, 0.2, -0.1], [0.05, 0.9, 0.1], [0.0, -0.15, 1.2]])


@pytest.mark.parametrize("case", ["mls_rigid", "mls_similarity", "mls_affine", "rbf_affine",
                                  "graph_rigid"])
def test_handle_warps_reproduce_their_handles_motion(case):
    # handles moved by a map of the warp's class: every point follows that map
    matrix = {"mls_rigid": _ROTATION, "mls_similarity": 1.3 * _ROTATION,
              "mls_affine": _GENERAL, "rbf_affine": _GENERAL, "graph_rigid": _ROTATION}[case]
    handles = _MLS_HANDLES if case != "graph_rigid" else _HANDLES
    targets = handles @ matrix.T + _SHIFT
    if case.startswith("mls"):
        warp = spacewarp.Mls(handles, targets, mode=case.split("_")[1])
    elif case == "rbf_affine":
        warp = spacewarp.RbfWarp(handles, targets)
    else:
        graph = spacewarp.DeformationGraph(_NODES, nodes=_NODES)
        assert graph.solve(handles, targets).converged
        warp = graph.warp()
    points = _points(300, seed=27)
    np.testing.assert_allclose(warp(points), points @ matrix.T + _SHIFT, rtol=0, atol=1e-10)


def test_inverse_does_not_depend_on_progress_or_thread(name):
    import threading

    warp = _warp(name)
    y = warp(_points(5000, seed=33) * 0.9)
    plain = warp.inverse(y)
    with_progress = warp.inverse(y, progress=lambda stage, fraction: True)
    box = {}
    worker = threading.Thread(target=lambda: box.setdefault("out", warp.inverse(y)))
    worker.start()
    worker.join(60)
    for other in (with_progress, box["out"]):
        for a, b in zip(plain, other):
            assert np.array_equal(a, b)


def test_graph_solve_report():
    graph = spacewarp.DeformationGraph(_NODES, nodes=_NODES)
    report = graph.solve(_HANDLES, _TARGETS, rotation_weight=1.0, regularization_weight=10.0,
                         constraint_weight=100.0)
    assert report.converged and report.iterations == len(report.energies) - 1 >= 1
    assert all(a > b for a, b in zip(report.energies, report.energies[1:]))  # strictly lower
    # the final energy is the weighted sum of its terms
    total = (1.0 * report.rotation_energy + 10.0 * report.regularization_energy
             + 100.0 * report.constraint_energy)
    assert report.energies[-1] == pytest.approx(total, rel=1e-12)
    assert report.component_count == 1 and list(report.unconstrained_nodes) == []
    # a second cluster of nodes that no handle reaches stays in place
    far = np.vstack([_NODES, _NODES[:8] + 100.0])
    split = spacewarp.DeformationGraph(far, nodes=far)
    report = split.solve(_HANDLES, _TARGETS)
    assert report.component_count == 2
    assert sorted(report.unconstrained_nodes) == list(range(64, 72))
    assert np.array_equal(split.warp()(far[64:]), far[64:])
    assert isinstance(report, spacewarp.GraphSolveReport)


def test_rig_cache_paths_are_relative_to_the_rig(tmp_path, cube_cage, cube_pose):
    from conftest import CUBE, CUBE_QUADS, write_cage

    folder = tmp_path / "rig"
    folder.mkdir()
    write_cage(folder / "cage.obj", CUBE, CUBE_QUADS)
    write_cage(folder / "pose.obj", cube_pose, CUBE_QUADS)
    rig = write_json(folder / "harmonic.json", {
        "method": "harmonic", "cage": "cage.obj", "pose": "pose.obj", "tets": 3000,
        "cache": "harmonic.cache"})
    points = _points(100, seed=37) * 0.8
    first = spacewarp.load_rig(rig)(points)
    assert (folder / "harmonic.cache").is_file()
    stamp = (folder / "harmonic.cache").stat().st_mtime_ns
    assert np.array_equal(spacewarp.load_rig(rig)(points), first)
    assert (folder / "harmonic.cache").stat().st_mtime_ns == stamp
    expected = spacewarp.Harmonic(cube_cage, tets=3000).warp(cube_pose)(points)
    assert np.array_equal(first, expected)
