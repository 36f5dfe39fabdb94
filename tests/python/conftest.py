"""Shared fixtures of the spacewarp Python suite (tests/python/test_<module>.py).

The package is found on PYTHONPATH (build/python); a module that needs it skips when it cannot be
imported. The command-line tool is $SPACEWARP_CLI or build/apps/spacewarp next to this source
tree; the tests that compare with it skip when it is absent. Real models are ../shared/data next
to the repository (or $SPACEWARP_SHARED_DATA); tests that read them skip when it is absent.
Nothing here depends on the current folder: every file goes to pytest's tmp_path.
"""

from __future__ import annotations

import inspect
import json
import os
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path
from typing import Callable, Sequence

import numpy as np
import pytest

REPO = Path(__file__).resolve().parents[2]

# A cube [-1, 1]^3 as a cage of outward quads: corner i + 2 j + 4 k is at (2i-1, 2j-1, 2k-1).
CUBE = np.array([[2.0 * i - 1.0, 2.0 * j - 1.0, 2.0 * k - 1.0]
                 for k in (0, 1) for j in (0, 1) for i in (0, 1)])
CUBE_QUADS = [[0, 2, 3, 1], [4, 5, 7, 6], [0, 1, 5, 4], [2, 6, 7, 3], [0, 4, 6, 2], [1, 3, 7, 5]]

# The octahedron |x| + |y| + |z| <= 2 (around the cube [-0.5, 0.5]^3) as a cage of outward
# triangles, corners +-2 e_x, +-2 e_y, +-2 e_z in that order: a convex cage of triangles, as
# DiscreteHarmonic needs (the cube's quads are refused).
OCTAHEDRON = np.array([[2.0, 0, 0], [-2.0, 0, 0], [0, 2.0, 0], [0, -2.0, 0], [0, 0, 2.0],
                       [0, 0, -2.0]])
# One triangle per octant; its corners x, y, z run counter-clockwise seen from outside when the
# octant has an even number of negative axes (an even index sum), else they are swapped.
OCTAHEDRON_TRIANGLES = [[x, y, z] if (x + y + z) % 2 == 0 else [x, z, y]
                        for x in (0, 1) for y in (2, 3) for z in (4, 5)]


def cli_path() -> Path:
    return Path(os.environ.get("SPACEWARP_CLI", REPO / "build" / "apps" / "spacewarp"))


def shared_data_path() -> Path:
    return Path(os.environ.get("SPACEWARP_SHARED_DATA", REPO.parent / "shared" / "data"))


def as_list(value):
    """JSON-ready: NumPy arrays and scalars as lists and floats (repr round trip is exact)."""
    return np.asarray(value, dtype=float).tolist()


class Cli:
    """Runs the spacewarp command line (quiet) and fails the test with its stderr on error."""

    def __init__(self, path: Path):
        self.path = path

    def __call__(self, *args: object, check: bool = True, timeout: float = 120
                 ) -> subprocess.CompletedProcess:
        command = [str(self.path), "-q", *[str(a) for a in args]]
        result = subprocess.run(command, capture_output=True, text=True, timeout=timeout)
        if check and result.returncode != 0:
            pytest.fail(f"{' '.join(command)} exited {result.returncode}:\n{result.stderr}")
        return result

    def deform(self, rig: dict | Path, points: np.ndarray, tmp: Path, name: str = "cli"
               ) -> np.ndarray:
        """The CLI's `deform --rig` of points (n, 3), through binary PLY point clouds."""
        import spacewarp

        rig_path = rig if isinstance(rig, Path) else write_json(tmp / f"{name}_rig.json", rig)
        source, target = tmp / f"{name}_in.ply", tmp / f"{name}_out.ply"
        spacewarp.write(source, spacewarp.Geometry(points))
        self("deform", "--rig", rig_path, source, "-o", target)
        return spacewarp.read(target).positions


def write_json(path: Path, content: dict) -> Path:
    path.write_text(json.dumps(content))
    return path


@pytest.fixture(scope="session")
def cli() -> Cli:
    path = cli_path()
    if not (path.is_file() and os.access(path, os.X_OK)):
        pytest.skip(f"the spacewarp command line is not built ({path})")
    return Cli(path)


@pytest.fixture(scope="session")
def shared_data() -> Path:
    path = shared_data_path()
    if not path.is_dir():
        pytest.skip(f"no shared data folder ({path})")
    return path


_VOLUME_PROBE = """
import sys
import numpy as np
import spacewarp
if not spacewarp.has_volumes:
    sys.exit(0)
spacewarp.warp_dense(spacewarp.Identity(), np.ones((2, 2, 2)))
try:
    spacewarp.warp_volume(spacewarp.Identity(), sys.argv[1], sys.argv[2])
except spacewarp.IoError:
    pass
print("OK")
"""


@pytest.fixture(scope="session")
def volume_crash(tmp_path_factory) -> str | None:
    """None when warp_dense and warp_volume run in a child interpreter, else how it died.

    The volume functions are probed in a child process first: if they crash the interpreter (as
    a segfault in openvdb::initialize once did), the tests that call them in this process skip
    instead of taking the whole run down, and test_volume_functions_run_in_a_fresh_interpreter
    fails with the crash.
    """
    folder = tmp_path_factory.mktemp("volume_probe")
    result = subprocess.run([sys.executable, "-c", _VOLUME_PROBE, str(folder / "missing.vdb"),
                             str(folder / "out.vdb")], capture_output=True, text=True, timeout=120)
    if result.returncode == 0:
        return None
    how = f"exit code {result.returncode}"
    if result.returncode < 0:
        how = f"killed by {signal.Signals(-result.returncode).name}"
    return f"the volume functions crash the interpreter ({how}) {result.stderr.strip()[-500:]}"


@pytest.fixture
def cube_cage():
    import spacewarp

    return spacewarp.Cage(CUBE, np.array(CUBE_QUADS))


@pytest.fixture
def cube_pose() -> np.ndarray:
    """The cube's vertices moved by a fixed, non-affine perturbation."""
    return CUBE + 0.2 * np.sin(np.arange(24.0).reshape(8, 3) * 1.7)


def write_cage(path: Path, vertices: np.ndarray, faces: Sequence[Sequence[int]]) -> Path:
    import spacewarp

    spacewarp.write(path, spacewarp.Geometry(np.asarray(vertices, dtype=float), faces))
    return path


def central_jacobian(f: Callable[[np.ndarray], np.ndarray], points: np.ndarray,
                     h: float = 1e-6) -> np.ndarray:
    """(n, 3, 3) central differences J[i, r, c] = d f_r / d x_c."""
    j = np.empty((len(points), 3, 3))
    for c in range(3):
        step = np.zeros(3)
        step[c] = h
        j[:, :, c] = (f(points + step) - f(points - step)) / (2.0 * h)
    return j


def subdivided_cube(n: int) -> tuple[np.ndarray, list[list[int]]]:
    """The cube [-1, 1]^3 with each face cut into n x n quads, oriented outward: (V, 3), faces."""
    index: dict = {}
    vertices: list = []
    faces: list = []

    def vid(key):
        if key not in index:
            index[key] = len(vertices)
            vertices.append([c / n for c in key])
        return index[key]

    for axis in range(3):
        u, v = [a for a in range(3) if a != axis]
        for sign in (-1, 1):
            for i in range(n):
                for j in range(n):
                    quad = []
                    for di, dj in ((0, 0), (1, 0), (1, 1), (0, 1)):
                        key = [0, 0, 0]
                        key[axis] = sign * n
                        key[u] = 2 * (i + di) - n
                        key[v] = 2 * (j + dj) - n
                        quad.append(vid(tuple(key)))
                    a, b, c = (np.array(vertices[q]) for q in quad[:3])
                    if np.cross(b - a, c - a)[axis] * sign < 0:
                        quad.reverse()
                    faces.append(quad)
    return np.array(vertices, float), faces


def main_thread_stall(work: Callable[[], object]) -> tuple[float, float]:
    """(longest pause of the main thread, duration) while `work` runs in another thread: a
    computation that keeps the GIL stalls the main thread for all of it."""
    box: dict = {}
    worker = threading.Thread(target=lambda: box.setdefault("out", work()))
    start = time.perf_counter()
    ticks = [start]
    worker.start()
    while worker.is_alive():
        time.sleep(0.001)
        ticks.append(time.perf_counter())
    worker.join()
    return max(np.diff(ticks)), ticks[-1] - start


# A child script's start: `warp`, a mean-value warp of a 98-vertex cage (subdivided_cube(4), its
# source copied in), and 2M `points` inside it: seconds of work to interrupt.
CAGE_SCRIPT = ("from __future__ import annotations\nimport sys, time\nimport numpy as np\n"
               "import spacewarp\n\n" + inspect.getsource(subdivided_cube) + """
vertices, faces = subdivided_cube(4)
cage = spacewarp.Cage(vertices, faces)
warp = spacewarp.MeanValue(cage).warp(vertices * 1.1)
points = np.random.default_rng(0).uniform(-0.9, 0.9, size=(2_000_000, 3))
""")


# Child-script lines: a progress callable that prints "started" at its first call, which
# interrupt_child waits for before it sends the signal.
STARTED_PROGRESS = """
started = []
def progress(stage, fraction):
    if not started:
        started.append(1)
        print("started", flush=True)
    return True
"""


def _read_line(stream, timeout: float) -> str | None:
    """The next line of a pipe, or None after `timeout` seconds."""
    box: list[str] = []
    reader = threading.Thread(target=lambda: box.append(stream.readline()), daemon=True)
    reader.start()
    reader.join(timeout)
    return box[0].strip() if box else None


def interrupt_child(script: str, pause: float) -> tuple[str | None, float, int]:
    """Runs `script` in a child, sends SIGINT `pause` s after it prints "started"; returns the
    child's next line, the seconds from the signal to that line, and its exit code."""
    child = subprocess.Popen([sys.executable, "-c", script], stdout=subprocess.PIPE,
                             stderr=subprocess.PIPE, text=True, env=dict(os.environ))
    try:
        first = _read_line(child.stdout, 60)
        assert first == "started", (first, child.stderr.read() if child.poll() else "")
        time.sleep(pause)
        sent = time.monotonic()
        child.send_signal(signal.SIGINT)
        line = _read_line(child.stdout, 60)
        elapsed = time.monotonic() - sent
        code = child.wait(30)
        return line, elapsed, code
    finally:
        if child.poll() is None:
            child.kill()
            child.wait()
