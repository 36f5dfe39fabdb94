"""Exceptions, progress callbacks and Ctrl-C (python/src/common.cpp).

The library's exceptions map to Python types with the C++ message (the one the command line
prints); progress callables see (stage, fraction) with fractions in [0, 1] that never go back
within a stage; returning False cancels (spacewarp.Cancelled), raising propagates; SIGINT
interrupts a long computation within ~2 s and raises KeyboardInterrupt (or runs the program's
own SIGINT handler). Ctrl-C during warp_volume (no file left) is in test_volume.py, next to
the demo volume it needs.
"""

from __future__ import annotations

import threading
from collections import defaultdict

import numpy as np
import pytest

spacewarp = pytest.importorskip("spacewarp")

from conftest import (CAGE_SCRIPT, CUBE, CUBE_QUADS, STARTED_PROGRESS, interrupt_child,  # noqa: E402
                      write_json)

# ----------------------------------------------------------------------------------------------
# Exception types


def test_exception_hierarchy():
    assert issubclass(spacewarp.InvalidInput, ValueError)
    assert issubclass(spacewarp.SolverError, RuntimeError)
    assert issubclass(spacewarp.OutOfMemory, spacewarp.SolverError)
    assert issubclass(spacewarp.OutOfMemory, MemoryError)
    assert issubclass(spacewarp.IoError, OSError)
    assert issubclass(spacewarp.Cancelled, RuntimeError)
    assert not issubclass(spacewarp.Cancelled, spacewarp.SolverError)
    for error in (spacewarp.InvalidInput, spacewarp.SolverError, spacewarp.OutOfMemory,
                  spacewarp.IoError, spacewarp.Cancelled):
        assert error.__module__ == "spacewarp"
        assert error.__doc__ and len(error.__doc__) > 20


def test_each_library_error_maps_to_its_type_with_the_message():
    with pytest.raises(spacewarp.InvalidInput) as invalid:
        spacewarp.Twist(rate=1.0)(np.zeros((4, 2)))
    assert str(invalid.value) == "points must have shape (n, 3) or (3,), not (4, 2)"

    g = spacewarp.Geometry([[0.5, 0.5, -1.0]])
    with pytest.raises(spacewarp.SolverError) as solver:
        spacewarp.deform_inverse(spacewarp.Taper(rate=1.0), g, max_iterations=3)
    assert type(solver.value) is spacewarp.SolverError
    assert str(solver.value).startswith("the inverse of the warp did not converge at 1 of 1")

    with pytest.raises(spacewarp.IoError) as io:
        spacewarp.read("/nonexistent-folder/x.obj")
    assert "/nonexistent-folder/x.obj" in str(io.value)

    with pytest.raises(spacewarp.Cancelled) as cancelled:
        spacewarp.MeanValue(spacewarp.Cage(CUBE, CUBE_QUADS)).weights(
            np.zeros((10, 3)), progress=lambda stage, fraction: False)
    assert str(cancelled.value) == "weights: cancelled"


def test_messages_are_the_command_lines(cli, tmp_path):
    rig = write_json(tmp_path / "bad.json", {"method": "twist", "origin": [0, 0, 0],
                                             "axis": [0, 0, 1], "rte": 1.0})
    malformed = tmp_path / "bad.obj"
    malformed.write_text("v 1 2 3\nv 1 2\n")
    for path, call, error in ((rig, spacewarp.load_rig, spacewarp.InvalidInput),
                              (malformed, spacewarp.read, spacewarp.IoError)):
        result = cli("info", path, check=False)
        assert result.returncode == 3
        with pytest.raises(error) as caught:
            call(path)
        assert f"spacewarp: error: {caught.value}" in result.stderr.splitlines()


def test_memory_estimate_refusal_is_invalid_input():
    # OutOfMemory is memory that ran out inside TetGen or CHOLMOD; a job that its estimate
    # refuses before it starts is InvalidInput, naming what to make smaller
    cage = spacewarp.Cage(CUBE, CUBE_QUADS)
    with pytest.raises(spacewarp.InvalidInput, match="needs about .* of memory") as refused:
        spacewarp.Harmonic(cage, tets=10**12)
    assert not isinstance(refused.value, spacewarp.OutOfMemory)


_H = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1.0]])
_BAD_ARGUMENTS = {
    "lattice_axes": (lambda: spacewarp.Lattice(axes=[[1, 0, 0], [1, 1, 0], [0, 0, 1]]),
                     "not a unit vector"),
    "lattice_extent": (lambda: spacewarp.Lattice(extents=(0, 1, 1)), "must be positive"),
    "lattice_basis": (lambda: spacewarp.Lattice(basis="nurbs"), "basis"),
    "mls_coincident": (lambda: spacewarp.Mls(np.vstack([_H, _H[:1]]), np.vstack([_H, _H[:1]])),
                       "coincide"),
    "mls_alpha": (lambda: spacewarp.Mls(_H, _H, alpha=0.0), "alpha"),
    "mls_mode": (lambda: spacewarp.Mls(_H, _H, mode="projective"), "projective"),
    "rbf_coplanar": (lambda: spacewarp.RbfWarp(_H[:3], _H[:3]), "affinely independent"),
    "rbf_scale": (lambda: spacewarp.RbfWarp(_H, _H, kernel="gaussian", scale=1e-200),
                  "scale"),
    "rbf_smoothing": (lambda: spacewarp.RbfWarp(_H, _H, smoothing=-1.0), "smoothing"),
    "rbf_kernel": (lambda: spacewarp.Rbf(_H, kernel="cubic"), "cubic"),
    "graph_spacing": (lambda: spacewarp.DeformationGraph(_H), "spacing"),
    "graph_k": (lambda: spacewarp.DeformationGraph(_H, nodes=_H, k=4), "k = 4"),
    "twist_rate": (lambda: spacewarp.Twist(rate=float("inf")), "rate"),
    "harmonic_outside": (lambda: spacewarp.Harmonic(spacewarp.Cage(CUBE, CUBE_QUADS),
                                                    tets=3000, outside="ignore"), "ignore"),
}


@pytest.mark.parametrize("case", list(_BAD_ARGUMENTS))
def test_bad_arguments_raise_invalid_input_naming_them(case):
    make, fragment = _BAD_ARGUMENTS[case]
    with pytest.raises(spacewarp.InvalidInput, match=fragment):
        make()


# ----------------------------------------------------------------------------------------------
# Progress callables


class Recorder:
    """A progress callable that records its calls and checks their types."""

    def __init__(self, answer=True):
        self.calls: list[tuple[str, float]] = []
        self.answer = answer

    def __call__(self, stage, fraction):
        assert isinstance(stage, str) and stage
        assert isinstance(fraction, float)
        self.calls.append((stage, fraction))
        return self.answer

    def check(self):
        assert self.calls, "the progress callable was never called"
        by_stage = defaultdict(list)
        for stage, fraction in self.calls:
            assert 0.0 <= fraction <= 1.0, (stage, fraction)
            by_stage[stage].append(fraction)
        for stage, fractions in by_stage.items():
            assert all(a <= b for a, b in zip(fractions, fractions[1:])), (stage, fractions)
        return set(by_stage)


def _progress_jobs():
    cage = spacewarp.Cage(CUBE, CUBE_QUADS)
    points = np.random.default_rng(1).uniform(-0.9, 0.9, size=(20_000, 3))
    many = np.random.default_rng(2).uniform(-0.9, 0.9, size=(140_000, 3))
    handles = CUBE * 1.2
    grid = np.linspace(-1.5, 1.5, 4)
    nodes = np.array([[x, y, z] for z in grid for y in grid for x in grid])
    lattice = spacewarp.Lattice(origin=(-1, -1, -1), extents=(2, 2, 2), resolution=(4, 4, 4))
    return {
        "weights": lambda p: spacewarp.MeanValue(cage).weights(points, progress=p),
        "bind": lambda p: spacewarp.MeanValue(cage).bind(points, progress=p),
        "warp": lambda p: spacewarp.Twist(rate=1.0)(many, progress=p),
        "inverse": lambda p: spacewarp.Bend(rate=0.5).inverse(points, progress=p),
        "harmonic": lambda p: spacewarp.Harmonic(cage, tets=3000, progress=p),
        "rbf": lambda p: spacewarp.RbfWarp(handles, handles * 1.1, progress=p),
        "graph": lambda p: spacewarp.DeformationGraph(nodes, nodes=nodes).solve(
            handles[:4], handles[:4] * 1.1, progress=p),
        "lattice_fit": lambda p: lattice.fit(points[:10], points[:10] * 1.05, progress=p),
        "deform": lambda p: spacewarp.deform(spacewarp.Twist(rate=1.0),
                                             spacewarp.Geometry(many), progress=p),
        "rig": lambda p: spacewarp.rig({"method": "graph", "handles": handles[:4].tolist(),
                                        "targets": (handles[:4] * 1.1).tolist(),
                                        "nodes": nodes.tolist()}, progress=p),
    }


JOBS = list(_progress_jobs())


@pytest.mark.parametrize("job", JOBS)
def test_progress_fractions_are_in_range_and_never_decrease(job):
    recorder = Recorder()
    _progress_jobs()[job](recorder)
    recorder.check()


def test_progress_of_harmonic_names_its_stages():
    recorder = Recorder()
    spacewarp.Harmonic(spacewarp.Cage(CUBE, CUBE_QUADS), tets=3000, progress=recorder)
    stages = recorder.check()
    assert len(stages) >= 2, stages


def test_progress_of_a_large_job_is_called_several_times():
    recorder = Recorder()
    spacewarp.MeanValue(spacewarp.Cage(CUBE, CUBE_QUADS)).weights(
        np.zeros((50_000, 3)), progress=recorder)
    recorder.check()
    assert len(recorder.calls) >= 5
    assert recorder.calls[-1][1] == 1.0


@pytest.mark.parametrize("job", JOBS)
def test_returning_false_cancels(job):
    recorder = Recorder(answer=False)
    with pytest.raises(spacewarp.Cancelled):
        _progress_jobs()[job](recorder)
    # stopped before the end (blocks already running may still report once)
    assert max(fraction for _, fraction in recorder.calls) < 1.0


def test_returning_none_or_true_continues():
    cage = spacewarp.Cage(CUBE, CUBE_QUADS)
    points = np.zeros((9000, 3))
    expected = spacewarp.MeanValue(cage).weights(points)
    for answer in (None, True, 1):
        got = spacewarp.MeanValue(cage).weights(points, progress=lambda s, f, a=answer: a)
        assert np.array_equal(got, expected)


def test_numpy_false_cancels_too():
    limit = np.float64(0.5)
    with pytest.raises(spacewarp.Cancelled):
        spacewarp.MeanValue(spacewarp.Cage(CUBE, CUBE_QUADS)).weights(
            np.zeros((20_000, 3)), progress=lambda stage, fraction: fraction < limit)


class _Mine(Exception):
    pass


@pytest.mark.parametrize("job", JOBS)
def test_a_raising_callable_propagates_its_exception(job):
    def boom(stage, fraction):
        raise _Mine(f"stop at {stage}")

    with pytest.raises(_Mine, match="stop at"):
        _progress_jobs()[job](boom)


def test_cancelled_in_place_deform_changes_nothing():
    g = spacewarp.Geometry(np.random.default_rng(5).uniform(size=(140_000, 3)))
    before = g.positions
    calls = []

    def second_call_stops(stage, fraction):
        calls.append(fraction)
        return len(calls) < 2

    with pytest.raises(spacewarp.Cancelled):
        spacewarp.deform(spacewarp.Twist(rate=1.0), g, in_place=True, progress=second_call_stops)
    assert np.array_equal(g.positions, before)


def test_progress_from_another_thread():
    recorder = Recorder()
    errors = []

    def run():
        try:
            spacewarp.MeanValue(spacewarp.Cage(CUBE, CUBE_QUADS)).weights(
                np.zeros((20_000, 3)), progress=recorder)
        except BaseException as e:  # noqa: BLE001 - reported below
            errors.append(e)

    thread = threading.Thread(target=run)
    thread.start()
    thread.join(60)
    assert not thread.is_alive() and not errors
    recorder.check()


# ----------------------------------------------------------------------------------------------
# Ctrl-C

_WITH_PROGRESS = CAGE_SCRIPT + STARTED_PROGRESS + """
try:
    warp(points, progress=progress)
    print("finished", flush=True)
except KeyboardInterrupt:
    print("KeyboardInterrupt", flush=True)
"""

_WITHOUT_PROGRESS = CAGE_SCRIPT + """
print("started", flush=True)
try:
    warp(points)
    print("finished", flush=True)
except KeyboardInterrupt:
    print("KeyboardInterrupt", flush=True)
"""


@pytest.mark.parametrize("script", [_WITH_PROGRESS, _WITHOUT_PROGRESS],
                         ids=["with_progress", "without_progress"])
def test_sigint_raises_keyboard_interrupt_quickly(script):
    line, elapsed, code = interrupt_child(script, pause=0.5)
    assert line == "KeyboardInterrupt", f"child said {line!r} after the signal"
    assert elapsed < 2.5, f"{elapsed:.2f} s from SIGINT to KeyboardInterrupt"
    assert code == 0


_HARMONIC_INTERRUPT = """
import numpy as np, spacewarp
cube = np.array([[2.0*i-1, 2.0*j-1, 2.0*k-1] for k in (0,1) for j in (0,1) for i in (0,1)])
quads = [[0, 2, 3, 1], [4, 5, 7, 6], [0, 1, 5, 4], [2, 6, 7, 3], [0, 4, 6, 2], [1, 3, 7, 5]]
cage = spacewarp.Cage(cube, quads)
started = []
def progress(stage, fraction):
    # the parent interrupts half a second into the tetrahedralisation (about 5 s here)
    if stage == "tetrahedralise" and not started:
        started.append(1)
        print("started", flush=True)
    return True
try:
    spacewarp.Harmonic(cage, tets=1_500_000, progress=progress)
    print("finished", flush=True)
except KeyboardInterrupt:
    print("KeyboardInterrupt", flush=True)
"""


def test_sigint_stops_harmonic_during_its_tetrahedralisation():
    line, elapsed, code = interrupt_child(_HARMONIC_INTERRUPT, pause=0.5)
    assert line == "KeyboardInterrupt", f"child said {line!r} after the signal"
    assert elapsed < 2.5, f"{elapsed:.2f} s from SIGINT to KeyboardInterrupt"


@pytest.mark.xfail(strict=False, reason="LIMITATION (README): Ctrl-C does not stop Harmonic(...) during its sparse "
                   "factorisation and solve (CHOLMOD is not polled): SIGINT 1 s into the "
                   "'factorise' stage at tets=1_000_000 gives KeyboardInterrupt only when the "
                   "whole solve has ended, about 4.4 s later on 2 cores (the tetrahedralisation "
                   "is interrupted within ~1 s since 7c1d408). Not strict: on a loaded machine "
                   "the solve can end before the 2.5 s bound, and a limitation must not flake")
def test_sigint_stops_harmonic_during_its_factorisation():
    script = (_HARMONIC_INTERRUPT.replace('stage == "tetrahedralise"', 'stage == "factorise"')
              .replace("tets=1_500_000", "tets=1_000_000"))
    assert 'stage == "factorise"' in script and "1_000_000" in script
    line, elapsed, code = interrupt_child(script, pause=1.0)
    assert line == "KeyboardInterrupt", f"child said {line!r} after the signal"
    assert elapsed < 2.5, f"{elapsed:.2f} s from SIGINT to KeyboardInterrupt"


_CUSTOM_HANDLER = CAGE_SCRIPT + """
import signal
class Mine(Exception):
    pass
def handler(signum, frame):
    raise Mine("from the handler")
signal.signal(signal.SIGINT, handler)
print("started", flush=True)
try:
    warp(points)
    print("finished", flush=True)
except Mine:
    print("Mine", flush=True)
"""

_QUIET_HANDLER = CAGE_SCRIPT + """
import signal
hits = []
signal.signal(signal.SIGINT, lambda signum, frame: hits.append(signum))
print("started", flush=True)
try:
    out = warp(points[:1_000_000])
    print("finished", len(hits), bool(np.isfinite(out).all()), flush=True)
except BaseException as e:
    print(type(e).__name__, len(hits), flush=True)
"""


def test_sigint_runs_the_programs_own_handler():
    line, elapsed, code = interrupt_child(_CUSTOM_HANDLER, pause=0.5)
    assert line == "Mine" and elapsed < 2.5 and code == 0


def test_a_sigint_handler_that_does_not_raise_lets_the_work_finish():
    line, _, code = interrupt_child(_QUIET_HANDLER, pause=0.5)
    assert line == "finished 1 True", f"child said {line!r}"
    assert code == 0


_JACOBIAN_INTERRUPT = CAGE_SCRIPT + """
print("started", flush=True)
try:
    warp.jacobian(points[:1_000_000])  # about a minute on 2 cores
    print("finished", flush=True)
except KeyboardInterrupt:
    print("KeyboardInterrupt", flush=True)
"""


def test_sigint_stops_a_long_jacobian():
    # The bound is a sixth of the whole job, so the test shows the job was cut short without
    # timing the cancellation itself (2.5 s flaked at load 9).
    line, elapsed, code = interrupt_child(_JACOBIAN_INTERRUPT, pause=0.5)
    assert line == "KeyboardInterrupt", f"child said {line!r} after the signal"
    assert elapsed < 10, f"{elapsed:.2f} s from SIGINT to KeyboardInterrupt"


def test_sigint_outside_library_work_still_works():
    script = ("import time, spacewarp\n"
              "print('started', flush=True)\n"
              "try:\n"
              "    time.sleep(30)\n"
              "except KeyboardInterrupt:\n"
              "    print('KeyboardInterrupt', flush=True)\n")
    line, elapsed, code = interrupt_child(script, pause=0.2)
    assert line == "KeyboardInterrupt" and elapsed < 2.0 and code == 0
