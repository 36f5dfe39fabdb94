#!/usr/bin/python3
"""Streaming deform of a large binary PLY point cloud against a plain copy of the same file.

Generates a binary little-endian PLY of POINTS points (float x, y, z; default 200M, about
2.4 GB) in a scratch folder, then, alternating the cases, REPEATS times each (median reported):

- copy: the file read and written in 16 MiB blocks through the page cache, then fsync'd (the
  deform's output is fsync'd too, by the atomic writer), by a child Python process;
- twist, lattice (trilinear ffd, 4x4x4 controls), mvc (mean-value coordinates of a 12-triangle
  box cage): `spacewarp deform --rig RIG IN.ply -o OUT.ply` (streamed: the input is large).

Each case reports wall time, points/s, MB/s of input and the child's peak RSS (its own
maximum resident set size, from GNU time). The scratch folder is removed at the end.

Usage: stream_bench.py [--points N] [--repeats R] [--dir FOLDER] [--spacewarp PATH]
"""

import argparse
import json
import os
import shutil
import statistics
import subprocess
import sys
import tempfile
import time

import numpy as np

COPY = r"""
import os, sys
src, dst = sys.argv[1], sys.argv[2]
with open(src, 'rb', buffering=0) as i, open(dst, 'wb', buffering=0) as o:
    buffer = bytearray(16 << 20)
    view = memoryview(buffer)
    while True:
        n = i.readinto(buffer)
        if not n:
            break
        o.write(view[:n])
    os.fsync(o.fileno())
"""


def generate(path, points, block=1 << 24):
    header = (
        "ply\nformat binary_little_endian 1.0\nelement vertex %d\n"
        "property float x\nproperty float y\nproperty float z\nend_header\n" % points
    )
    rng = np.random.default_rng(17)
    with open(path, "wb") as f:
        f.write(header.encode())
        for begin in range(0, points, block):
            n = min(block, points - begin)
            f.write(rng.uniform(-1.0, 1.0, (n, 3)).astype("<f4").tobytes())


def write_rigs(folder):
    rigs = {}
    twist = {"method": "twist", "origin": [0, 0, 0], "axis": [0, 0, 1], "rate": 0.785398}
    controls = []
    for k in range(4):
        for j in range(4):
            for i in range(4):
                p = [-1.1 + 2.2 * i / 3, -1.1 + 2.2 * j / 3, -1.1 + 2.2 * k / 3]
                controls.append([p[0] + 0.1 * np.sin(3 * p[2]), p[1], p[2] * 1.1])
    lattice = {
        "method": "ffd", "basis": "trilinear", "origin": [-1.1, -1.1, -1.1],
        "size": [2.2, 2.2, 2.2], "resolution": [4, 4, 4], "controlPoints": controls,
    }
    corners = [[x, y, z] for z in (-1.2, 1.2) for y in (-1.2, 1.2) for x in (-1.2, 1.2)]
    # Outward-facing triangles of the box (vertex index = x + 2y + 4z, 1-based in OBJ).
    quads = [(1, 3, 4, 2), (5, 6, 8, 7), (1, 2, 6, 5), (3, 7, 8, 4), (1, 5, 7, 3), (2, 4, 8, 6)]

    def obj(path, vertices):
        with open(path, "w") as f:
            for v in vertices:
                f.write("v %.17g %.17g %.17g\n" % tuple(v))
            for a, b, c, d in quads:
                f.write("f %d %d %d\nf %d %d %d\n" % (a, b, c, a, c, d))

    obj(os.path.join(folder, "cage.obj"), corners)
    posed = [[x * (1.3 if z > 0 else 1.0), y, z + 0.2 * (x > 0)] for x, y, z in corners]
    obj(os.path.join(folder, "pose.obj"), posed)
    mvc = {"method": "mvc", "cage": "cage.obj", "pose": "pose.obj"}
    for name, rig in (("twist", twist), ("lattice", lattice), ("mvc", mvc)):
        path = os.path.join(folder, name + ".json")
        with open(path, "w") as f:
            json.dump(rig, f)
        rigs[name] = path
    return rigs


def run(command, folder):
    """Wall seconds and peak RSS (MB) of one child process; raises if it fails. The RSS comes
    from GNU time: a child forked from this process would inherit its high-water mark."""
    report = os.path.join(folder, "time.txt")
    start = time.perf_counter()
    child = subprocess.run(["/usr/bin/time", "-f", "%M", "-o", report] + command,
                           stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    seconds = time.perf_counter() - start
    if child.returncode != 0:
        raise SystemExit("%s failed (%d): %s" % (command, child.returncode, child.stderr.decode()))
    with open(report) as f:
        return seconds, int(f.read().split()[-1]) / 1024.0


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--points", type=int, default=int(os.environ.get("POINTS", 200_000_000)))
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--dir", default=None, help="scratch folder (default: a new one in /tmp)")
    parser.add_argument("--spacewarp", default=os.path.join("build", "apps", "spacewarp"))
    parser.add_argument("--cases", default="copy,twist,lattice,mvc")
    parser.add_argument("--deform-args", default="",
                        help="extra deform arguments, e.g. '--chunk-points 1000000' to stream a "
                        "file under the automatic threshold")
    args = parser.parse_args()

    folder = tempfile.mkdtemp(prefix="spacewarp-stream-bench-", dir=args.dir)
    try:
        source = os.path.join(folder, "cloud.ply")
        output = os.path.join(folder, "out.ply")
        t = time.perf_counter()
        generate(source, args.points)
        size = os.path.getsize(source)
        print("generated %s: %d points, %.2f GB in %.0f s" % (source, args.points, size / 1e9,
                                                             time.perf_counter() - t), flush=True)
        rigs = write_rigs(folder)
        commands = {"copy": [sys.executable, "-c", COPY, source, output]}
        for name, rig in rigs.items():
            commands[name] = ([args.spacewarp, "deform", "--rig", rig, source, "-o", output] +
                             args.deform_args.split())
        cases = args.cases.split(",")
        results = {case: [] for case in cases}
        for r in range(args.repeats):
            for case in cases:
                seconds, rss = run(commands[case], folder)
                os.remove(output)
                results[case].append((seconds, rss))
                print("  run %d %-8s %8.1f s  peak RSS %7.0f MB" % (r + 1, case, seconds, rss),
                      flush=True)
        copy = statistics.median(s for s, _ in results["copy"]) if "copy" in results else None
        print("\n%d points, %.2f GB input, medians of %d:" % (args.points, size / 1e9, args.repeats))
        print("%-8s %10s %14s %10s %14s %10s" % ("case", "wall s", "points/s", "MB/s", "peak RSS MB",
                                               "vs copy"))
        for case in cases:
            seconds = statistics.median(s for s, _ in results[case])
            rss = max(m for _, m in results[case])
            ratio = "%.0f%%" % (100 * copy / seconds) if copy else "-"
            print("%-8s %10.1f %14.3g %10.0f %14.0f %10s" % (case, seconds, args.points / seconds,
                                                           size / seconds / 1e6, rss, ratio))
    finally:
        shutil.rmtree(folder, ignore_errors=True)


if __name__ == "__main__":
    main()
