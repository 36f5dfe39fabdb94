"""The package's surface (python/spacewarp/__init__.py, module.cpp): every public name and member
is documented, the version is a version, and computations release the GIL (two threads run at
once, give the same results as one call, and the main thread keeps running meanwhile).
"""

from __future__ import annotations

import inspect
import re
import threading
import time

import numpy as np
import pytest

spacewarp = pytest.importorskip("spacewarp")

from conftest import main_thread_stall, subdivided_cube  # noqa: E402

CONSTANTS = {"__version__", "has_volumes"}


def _doc_text(doc: str | None, name: str) -> str:
    """A docstring without the signature lines pybind11 writes ("name(self, ...) -> T")."""
    if not doc:
        return ""
    signature = re.compile(r"^\s*(\d+\. )?" + re.escape(name) + r"\(.*\)( -> .*)?$")
    lines = [line for line in doc.strip().splitlines()
             if not signature.match(line) and line.strip() != "Overloaded function."]
    return "\n".join(lines).strip()


def _members(cls) -> dict[str, object]:
    """The public methods and properties a class defines itself."""
    return {name: value for name, value in vars(cls).items() if not name.startswith("_")}


def _undocumented(name: str) -> list[str]:
    """`name` and those of its public members that have no docstring of their own."""
    obj = getattr(spacewarp, name)
    missing = []
    if not _doc_text(getattr(obj, "__doc__", None), name):
        missing.append(name)
    if inspect.isclass(obj):
        for member, value in _members(obj).items():
            if not _doc_text(getattr(value, "__doc__", None), member):
                missing.append(f"{name}.{member}")
    return missing


PUBLIC = [name for name in spacewarp.__all__ if name not in CONSTANTS]


def test_all_lists_the_api():
    expected = {"Warp", "Twist", "Bend", "Taper", "Affine", "Compose", "Identity", "Mls",
                "RbfWarp", "DeformationGraph", "Cage", "Coordinates", "MeanValue", "Green",
                "Harmonic", "Lattice", "Rbf", "MlsAffine", "Binding", "Geometry", "read",
                "write", "deform", "deform_inverse", "load_rig", "rig", "warp_volume",
                "warp_dense", "InvalidInput", "SolverError", "OutOfMemory", "IoError",
                "Cancelled", "testing", "__version__", "has_volumes"}
    if not spacewarp.has_volumes:
        expected -= {"warp_volume", "warp_dense"}
    assert expected <= set(spacewarp.__all__)
    assert len(set(spacewarp.__all__)) == len(spacewarp.__all__)
    for name in spacewarp.__all__:
        assert getattr(spacewarp, name) is not None
    namespace: dict = {}
    exec("from spacewarp import *", namespace)
    assert {n for n in spacewarp.__all__ if n != "__version__"} <= set(namespace)


def test_module_docstrings():
    assert "spacewarp" in spacewarp.__doc__ and len(spacewarp.__doc__) > 200
    assert len(spacewarp.testing.__doc__) > 200


@pytest.mark.parametrize("name", PUBLIC)
def test_public_names_are_documented(name):
    missing = _undocumented(name)
    assert not missing, f"no docstring: {missing}"


def test_warp_classes_derive_from_warp_and_coordinates_from_coordinates():
    for name in ("Twist", "Bend", "Taper", "Affine", "Compose", "Identity", "Mls", "RbfWarp",
                 "DeformationGraphWarp"):
        assert issubclass(getattr(spacewarp, name), spacewarp.Warp), name
    for name in ("MeanValue", "Green", "Harmonic", "Lattice", "Rbf", "MlsAffine"):
        assert issubclass(getattr(spacewarp, name), spacewarp.Coordinates), name


def test_version_is_a_version_string(cli):
    version = spacewarp.__version__
    assert isinstance(version, str)
    assert re.fullmatch(r"\d+\.\d+\.\d+", version), version
    result = cli("--version")
    assert version in result.stdout + result.stderr


def test_version_without_the_cli():
    assert re.fullmatch(r"\d+\.\d+\.\d+", spacewarp.__version__)
    assert spacewarp._spacewarp.__version__ == spacewarp.__version__


# ----------------------------------------------------------------------------------------------
# The GIL


@pytest.fixture(scope="module")
def big_cage():
    vertices, faces = subdivided_cube(6)
    cage = spacewarp.Cage(vertices, faces)
    assert cage.volume == pytest.approx(8.0) and cage.reoriented_count == 0
    return cage


def test_two_threads_compute_weights_at_once(big_cage):
    points = np.random.default_rng(8).uniform(-0.95, 0.95, size=(12_000, 3))
    other = points[::-1].copy()
    mvc = spacewarp.MeanValue(big_cage)
    expected, expected_other = mvc.weights(points), mvc.weights(other)
    results: dict = {}
    errors: list = []
    barrier = threading.Barrier(2)

    def run(key, p):
        try:
            barrier.wait(10)
            results[key] = mvc.weights(p)
        except BaseException as e:  # noqa: BLE001 - reported below
            errors.append(e)

    threads = [threading.Thread(target=run, args=("a", points)),
               threading.Thread(target=run, args=("b", other))]
    for t in threads:
        t.start()
    for t in threads:
        t.join(60)
    assert not any(t.is_alive() for t in threads), "deadlock: a thread did not finish"
    assert not errors
    assert np.array_equal(results["a"], expected)
    assert np.array_equal(results["b"], expected_other)


def test_the_main_thread_runs_while_a_computation_does(big_cage):
    mvc = spacewarp.MeanValue(big_cage)
    warp = mvc.warp(big_cage.vertices * 1.1)
    points = np.random.default_rng(9).uniform(-0.95, 0.95, size=(60_000, 3))
    start = time.perf_counter()
    expected = warp(points)
    duration = time.perf_counter() - start
    if duration < 0.2:
        pytest.skip(f"the computation is too fast here ({duration:.3f} s) to see the GIL")
    result: dict = {}
    worker = threading.Thread(target=lambda: result.setdefault("out", warp(points)))
    ticks = [time.perf_counter()]
    worker.start()
    while worker.is_alive():
        time.sleep(0.001)
        ticks.append(time.perf_counter())
    worker.join()
    assert np.array_equal(result["out"], expected)
    longest = max(np.diff(ticks))
    # with the GIL held, the main thread would stop for the whole computation
    assert longest < duration / 3, f"main thread stalled {longest:.3f} s of {duration:.3f} s"


def test_threads_share_one_warp_and_one_binding(big_cage):
    mvc = spacewarp.MeanValue(big_cage)
    points = np.random.default_rng(10).uniform(-0.9, 0.9, size=(3000, 3))
    binding = mvc.bind(points)
    pose = big_cage.vertices * 1.2
    expected = binding.deform(pose)
    outputs = [None] * 4

    def run(i):
        outputs[i] = binding.deform(pose)

    threads = [threading.Thread(target=run, args=(i,)) for i in range(4)]
    for t in threads:
        t.start()
    for t in threads:
        t.join(60)
    for out in outputs:
        assert np.array_equal(out, expected)


# ----------------------------------------------------------------------------------------------
# The type stubs (python/tools/make_stubs.py) name what the module has


def _stub(name: str):
    import ast
    from pathlib import Path

    path = Path(spacewarp.__file__).resolve().parent / name
    if not path.is_file():
        pytest.skip(f"no {name} next to the package")
    return ast.parse(path.read_text())


def _stub_all(tree) -> set[str]:
    """The names of a stub's __all__: its literal list, plus `__all__ += _spacewarp.__all__`."""
    import ast

    names: set[str] | None = None
    for node in tree.body:
        if isinstance(node, ast.Assign) and any(getattr(t, "id", None) == "__all__"
                                                for t in node.targets):
            names = set(ast.literal_eval(node.value))
        elif (isinstance(node, ast.AugAssign) and getattr(node.target, "id", None) == "__all__"
              and ast.unparse(node.value) == "_spacewarp.__all__" and names is not None):
            names |= _stub_all(_stub("_spacewarp.pyi"))
    if names is None:
        raise AssertionError("no __all__ in the stub")
    return names


def test_stubs_list_the_packages_names():
    assert _stub_all(_stub("__init__.pyi")) == set(spacewarp.__all__)
    assert _stub_all(_stub("_spacewarp.pyi")) == {
        name for name in dir(spacewarp._spacewarp) if not name.startswith("_")}


def test_stub_classes_have_the_runtime_members():
    import ast

    tree = _stub("_spacewarp.pyi")
    classes = [node for node in tree.body if isinstance(node, ast.ClassDef)]
    assert classes
    for node in classes:
        runtime = getattr(spacewarp._spacewarp, node.name)
        if issubclass(runtime, BaseException):
            continue
        stubbed = {item.name for item in node.body if isinstance(item, ast.FunctionDef)}
        stubbed |= {item.target.id for item in node.body if isinstance(item, ast.AnnAssign)}
        stubbed = {name for name in stubbed if not name.startswith("_")}
        assert stubbed == set(_members(runtime)), node.name
    functions = {node.name for node in tree.body if isinstance(node, ast.FunctionDef)}
    runtime_functions = {name for name in dir(spacewarp._spacewarp)
                         if not name.startswith("_")
                         and inspect.isbuiltin(getattr(spacewarp._spacewarp, name))}
    assert functions == runtime_functions


def test_interior_samples_releases_the_gil(big_cage):
    longest, duration = main_thread_stall(
        lambda: spacewarp.interior_samples(big_cage, 150_000, seed=2))
    assert duration > 0.3, "too fast to tell"
    assert longest < duration / 3, f"main thread stalled {longest:.3f} s of {duration:.3f} s"


@pytest.mark.parametrize("what", ["winding_number", "contains"])
def test_cage_queries_release_the_gil(big_cage, what):
    samples = np.random.default_rng(4).uniform(-1.5, 1.5, size=(200_000, 3))
    longest, duration = main_thread_stall(lambda: getattr(big_cage, what)(samples))
    if duration < 0.2:
        pytest.skip(f"too fast here ({duration:.3f} s) to see the GIL")
    assert longest < duration / 3, f"main thread stalled {longest:.3f} s of {duration:.3f} s"


_GRAPH_WARP_DURING_SOLVE = """
import threading, time
import numpy as np
import spacewarp
grid = np.linspace(-1.5, 1.5, 8)
nodes = np.array([[x, y, z] for z in grid for y in grid for x in grid])
graph = spacewarp.DeformationGraph(nodes, nodes=nodes)
handles = np.array([[-1, -1, -1], [1, -1, -1], [-1, 1, -1], [-1, -1, 1], [1, 1, 1.0]])
calls = []
def progress(stage, fraction):
    calls.append(fraction)
    time.sleep(0.05)
    return True
solver = threading.Thread(
    target=lambda: graph.solve(handles, handles * 1.2 + np.sin(handles), progress=progress))
solver.start()
while not calls:
    time.sleep(0.001)
snapshot = graph.warp()  # while the other thread solves
solver.join()
print("done", len(calls), flush=True)
"""


def test_graph_warp_during_a_solve_in_another_thread_does_not_deadlock():
    import subprocess
    import sys

    try:
        result = subprocess.run([sys.executable, "-c", _GRAPH_WARP_DURING_SOLVE],
                                capture_output=True, text=True, timeout=6)
    except subprocess.TimeoutExpired:
        pytest.fail("deadlock: no result after 6 s (a solve alone takes 0.1 s)")
    assert result.returncode == 0 and result.stdout.startswith("done"), result.stderr[-1000:]


@pytest.mark.parametrize("kind", ["mls", "rbf", "graph", "harmonic"])
def test_one_warp_called_from_several_threads_at_once(big_cage, kind):
    handles = big_cage.vertices[::20]
    targets = handles * 1.1 + 0.05 * np.sin(handles)
    if kind == "mls":
        warp = spacewarp.Mls(handles, targets)
    elif kind == "rbf":
        warp = spacewarp.RbfWarp(handles, targets)
    elif kind == "graph":
        graph = spacewarp.DeformationGraph(big_cage.vertices, spacing=0.5)
        graph.solve(handles, targets)
        warp = graph.warp()
    else:
        harmonic = spacewarp.Harmonic(big_cage, tets=3000)
        warp = harmonic.warp(big_cage.vertices * 1.1)
    points = np.random.default_rng(11).uniform(-0.9, 0.9, size=(40_000, 3))
    expected, expected_jacobian = warp(points), warp.jacobian(points[:2000])
    outputs: list = [None] * 4

    def run(i):
        outputs[i] = (warp(points), warp.jacobian(points[:2000]), warp.inverse(expected[:500]))

    threads = [threading.Thread(target=run, args=(i,)) for i in range(4)]
    for t in threads:
        t.start()
    for t in threads:
        t.join(120)
    for moved, jacobian, (back, converged, _) in outputs:
        assert np.array_equal(moved, expected)
        assert np.array_equal(jacobian, expected_jacobian)
        assert converged.all()
        np.testing.assert_allclose(back, points[:500], rtol=0, atol=1e-9)


def test_a_daemon_thread_inside_a_call_does_not_abort_the_exit():
    # Python ends daemon threads when they take the GIL back after the interpreter exited; from
    # a destructor (pybind11's gil_scoped_release) that aborted the process.
    import subprocess
    import sys

    script = ("import threading, time\nimport numpy as np\nimport spacewarp\n"
              "points = np.random.default_rng(0).uniform(-1, 1, (300_000, 3))\n"
              "twist = spacewarp.Twist(rate=1.0)\n"
              "def forever():\n"
              "    while True:\n"
              "        twist(points)\n"
              "threading.Thread(target=forever, daemon=True).start()\n"
              "time.sleep(0.3)\n"
              "print('main thread exits', flush=True)\n")
    for _ in range(3):
        result = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True,
                                timeout=60)
        assert result.returncode == 0, (result.returncode, result.stderr[-500:])
        assert "main thread exits" in result.stdout
