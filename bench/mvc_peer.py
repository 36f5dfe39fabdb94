#!/usr/bin/python3
"""Cage deform end to end, spacewarp's CLI against VTK's mean-value coordinates.

POINTS points (default 300,000) uniform inside the armadillo cage of Ju et al. (110 vertices,
216 triangles; ../shared/data/ju2005-armadillo, or $SPACEWARP_SHARED_DATA_DIR) are written once
to a binary little-endian PLY (float x, y, z) in a scratch folder. Then, alternating, REPEATS
times each (medians reported, with their ratio):

- spacewarp: `spacewarp deform --method mvc|green --cage REST --pose POSED IN.ply -o OUT.ply
  --threads THREADS -q`, the child process's wall time (start-up, reading, weights, deformed
  positions, writing);
- vtk (mvc only; VTK 9.1 from Debian's python3-vtk9, skipped with a line saying so if missing):
  a child Python process that reads the same PLY (vtkPLYReader), deforms it with
  vtkDeformPointSet (its weights are vtkMeanValueCoordinatesInterpolator's) from the rest to the
  posed cage and writes a binary PLY (vtkPLYWriter); timed inside the child from the read to the
  written file (Python and VTK's start-up not counted). vtkDeformPointSet is single-threaded,
  so the points are split between THREADS forked worker processes (their start-up counted).

Each run also reports the CPU time of the child and its children (user + system; VTK's then
includes Python's and VTK's start-up), a steadier comparison on a loaded machine.

VTK has no Green coordinates: with --method green only spacewarp is reported.

Usage: mvc_peer.py [--method mvc|green] [--points N] [--repeats R] [--threads T]
                   [--spacewarp PATH] [--dir FOLDER]
"""

import argparse
import os
import resource
import shutil
import statistics
import subprocess
import sys
import tempfile
import time

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))

# The VTK side, run as a child: argv = in.ply rest.obj posed.obj out.ply workers. Prints seconds.
# vtkDeformPointSet runs on one thread (vtkSMPTools does not reach it in VTK 9.1), so the points
# are split between `workers` forked processes, each binding and deforming its share.
VTK = r"""
import multiprocessing, sys, time
import numpy as np
import vtk
from vtk.util.numpy_support import numpy_to_vtk, vtk_to_numpy
src, rest, posed, dst, workers = sys.argv[1:6]
workers = int(workers)

def cage(path):
    v, f = [], []
    for line in open(path):
        w = line.split()
        if w and w[0] == 'v':
            v.append([float(c) for c in w[1:4]])
        elif w and w[0] == 'f':
            f.append([int(c.split('/')[0]) - 1 for c in w[1:]])
    return v, f

rv, faces = cage(rest)
pv, _ = cage(posed)

def polydata(xyz):
    points = vtk.vtkPoints()
    points.SetData(numpy_to_vtk(np.ascontiguousarray(xyz), deep=True))
    data = vtk.vtkPolyData()
    data.SetPoints(points)
    return data

def deform(xyz):
    points = vtk.vtkPoints()
    for p in rv:
        points.InsertNextPoint(p)
    cells = vtk.vtkCellArray()
    for f in faces:
        for k in range(1, len(f) - 1):
            cells.InsertNextCell(3, (f[0], f[k], f[k + 1]))
    mesh = vtk.vtkPolyData()
    mesh.SetPoints(points)
    mesh.SetPolys(cells)
    d = vtk.vtkDeformPointSet()
    d.SetInputData(polydata(xyz))
    d.SetControlMeshData(mesh)
    d.Update()  # binds: the weights of every point for the rest cage
    for i, p in enumerate(pv):
        points.SetPoint(i, p)
    points.Modified()
    mesh.Modified()
    d.Update()  # deforms with the stored weights
    return vtk_to_numpy(d.GetOutput().GetPoints().GetData()).copy()

start = time.perf_counter()
reader = vtk.vtkPLYReader()
reader.SetFileName(src)
reader.Update()
xyz = vtk_to_numpy(reader.GetOutput().GetPoints().GetData())
if workers > 1:
    with multiprocessing.get_context('fork').Pool(workers) as pool:
        moved = np.concatenate(pool.map(deform, np.array_split(xyz, workers)))
else:
    moved = deform(xyz)
writer = vtk.vtkPLYWriter()
writer.SetInputData(polydata(moved))
writer.SetFileName(dst)
writer.SetFileTypeToBinary()
writer.Write()
print(time.perf_counter() - start)
"""


def read_obj(path):
    vertices, faces = [], []
    with open(path) as f:
        for line in f:
            w = line.split()
            if w and w[0] == "v":
                vertices.append([float(c) for c in w[1:4]])
            elif w and w[0] == "f":
                corners = [int(c.split("/")[0]) - 1 for c in w[1:]]
                faces += [[corners[0], corners[k], corners[k + 1]]
                          for k in range(1, len(corners) - 1)]
    return np.array(vertices), np.array(faces)


def inside_mask(points, vertices, triangles, grid=48):
    """Whether each point is inside the closed triangle mesh: the parity of the triangles above
    it along +z, testing only the triangles whose (x, y) bounds cover the point's grid cell."""
    tri = vertices[triangles]  # T x 3 corners x 3
    lo, hi = vertices[:, :2].min(axis=0), vertices[:, :2].max(axis=0)
    size = (hi - lo) / grid
    cell_lo = np.clip(((tri[:, :, :2].min(axis=1) - lo) / size).astype(int), 0, grid - 1)
    cell_hi = np.clip(((tri[:, :, :2].max(axis=1) - lo) / size).astype(int), 0, grid - 1)
    cells = np.clip(((points[:, :2] - lo) / size).astype(int), 0, grid - 1)
    key = cells[:, 0] * grid + cells[:, 1]
    inside = np.zeros(len(points), dtype=bool)
    for k in np.unique(key):
        cx, cy = divmod(int(k), grid)
        near = np.nonzero((cell_lo[:, 0] <= cx) & (cx <= cell_hi[:, 0]) & (cell_lo[:, 1] <= cy) &
                          (cy <= cell_hi[:, 1]))[0]
        chosen = np.nonzero(key == k)[0]
        x = points[chosen][:, None, :]
        a, b, c = (tri[near, j][None, :, :] for j in range(3))

        def edge(p, q):
            return ((q[..., 0] - p[..., 0]) * (x[..., 1] - p[..., 1]) -
                    (q[..., 1] - p[..., 1]) * (x[..., 0] - p[..., 0]))

        wa, wb, wc = edge(b, c), edge(c, a), edge(a, b)
        hit = ((wa > 0) & (wb > 0) & (wc > 0)) | ((wa < 0) & (wb < 0) & (wc < 0))
        with np.errstate(invalid="ignore", divide="ignore"):
            z = (wa * a[..., 2] + wb * b[..., 2] + wc * c[..., 2]) / (wa + wb + wc)
        inside[chosen] = (hit & (z > x[..., 2])).sum(axis=1) % 2 == 1
    return inside


def points_inside(vertices, triangles, count, seed=19):
    """`count` points uniform inside the cage: rejection in its bounding box."""
    rng = np.random.default_rng(seed)
    lo, hi = vertices.min(axis=0), vertices.max(axis=0)
    kept = []
    have = 0
    while have < count:
        candidates = rng.uniform(lo, hi, (max(count, 100_000), 3))
        inside = candidates[inside_mask(candidates, vertices, triangles)]
        kept.append(inside)
        have += len(inside)
    return np.concatenate(kept)[:count]


def write_ply(path, points):
    header = ("ply\nformat binary_little_endian 1.0\nelement vertex %d\n"
              "property float x\nproperty float y\nproperty float z\nend_header\n" % len(points))
    with open(path, "wb") as f:
        f.write(header.encode())
        f.write(points.astype("<f4").tobytes())


def read_ply_xyz(path):
    """The x, y, z of a binary little-endian PLY whose vertices hold only them (float or double)."""
    with open(path, "rb") as f:
        blob = f.read()
    end = blob.index(b"end_header\n") + len(b"end_header\n")
    header = blob[:end].decode().split("\n")
    count = next(int(l.split()[2]) for l in header if l.startswith("element vertex"))
    kinds = [l.split()[1] for l in header if l.startswith("property")][:3]
    dtype = "<f4" if kinds[0] == "float" else "<f8"
    return np.frombuffer(blob, dtype=dtype, count=3 * count, offset=end).reshape(count, 3)


def have_vtk():
    return subprocess.run([sys.executable, "-c", "import vtk"], stdout=subprocess.DEVNULL,
                          stderr=subprocess.DEVNULL).returncode == 0


def timed(command):
    """Wall seconds, CPU seconds (user + system, the child's and its children's) and stdout."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    start = time.perf_counter()
    child = subprocess.run(command, stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    seconds = time.perf_counter() - start
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    if child.returncode != 0:
        raise SystemExit("%s failed (%d): %s" % (command[0], child.returncode,
                                                 child.stderr.decode()))
    return seconds, cpu, child.stdout.decode()


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--method", choices=["mvc", "green"], default="mvc")
    parser.add_argument("--points", type=int, default=300_000)
    parser.add_argument("--repeats", type=int, default=5)
    parser.add_argument("--threads", type=int, default=2)
    parser.add_argument("--spacewarp",
                        default=os.path.join(HERE, "..", "build", "apps", "spacewarp"))
    parser.add_argument("--dir", default=None, help="scratch folder (default: a new one in /tmp)")
    args = parser.parse_args()

    data = os.environ.get("SPACEWARP_SHARED_DATA_DIR",
                          os.path.join(HERE, "..", "..", "shared", "data"))
    rest = os.path.join(data, "ju2005-armadillo", "bounding_mesh.obj")
    posed = os.path.join(data, "ju2005-armadillo", "deformed_fixed_1.obj")
    if not os.path.exists(rest):
        raise SystemExit("skipped: %s not found (set SPACEWARP_SHARED_DATA_DIR)" % rest)
    vtk = args.method == "mvc" and have_vtk()
    if args.method != "mvc":
        print("vtk: skipped (VTK has no %s coordinates)" % args.method)
    elif not vtk:
        print("vtk: skipped (python3 cannot import vtk; apt-get install python3-vtk9)")

    folder = tempfile.mkdtemp(prefix="spacewarp-mvc-peer-", dir=args.dir)
    try:
        source = os.path.join(folder, "cloud.ply")
        vertices, triangles = read_obj(rest)
        start = time.perf_counter()
        write_ply(source, points_inside(vertices, triangles, args.points))
        print("%d points inside the armadillo cage (%d vertices, %d triangles) in %.1f s" %
              (args.points, len(vertices), len(triangles), time.perf_counter() - start))
        commands = {
            "spacewarp": [args.spacewarp, "deform", "--method", args.method, "--cage", rest,
                          "--pose", posed, source, "-o", os.path.join(folder, "ours.ply"),
                          "--threads", str(args.threads), "-q"],
        }
        if vtk:
            commands["vtk"] = [sys.executable, "-c", VTK, source, rest, posed,
                               os.path.join(folder, "vtk.ply"), str(args.threads)]
        times = {name: [] for name in commands}
        cpus = {name: [] for name in commands}
        for r in range(args.repeats):
            for name, command in commands.items():
                wall, cpu, out = timed(command)
                times[name].append(float(out.split()[-1]) if name == "vtk" else wall)
                cpus[name].append(cpu)
                print("  run %d %-9s %7.3f s  (CPU %.3f s)" % (r + 1, name, times[name][-1], cpu),
                      flush=True)
        if vtk:  # the same computation: both outputs agree to the files' float precision
            gap = np.abs(read_ply_xyz(os.path.join(folder, "ours.ply")) -
                         read_ply_xyz(os.path.join(folder, "vtk.ply"))).max()
            diagonal = np.linalg.norm(vertices.max(axis=0) - vertices.min(axis=0))
            print("  largest difference between the outputs: %.2g cage diagonals" %
                  (gap / diagonal))
        medians = {name: statistics.median(t) for name, t in times.items()}
        cpu = {name: statistics.median(t) for name, t in cpus.items()}
        print("\n%s, %d points, %d threads, medians of %d (load average %.1f):" %
              (args.method, args.points, args.threads, args.repeats, os.getloadavg()[0]))
        for name, seconds in medians.items():
            print("  %-9s %7.3f s  (CPU %.3f s)" % (name, seconds, cpu[name]))
        if "vtk" in medians:
            print("  spacewarp is %.1fx VTK (CPU time: %.1fx, VTK's including Python's start-up)" %
                  (medians["vtk"] / medians["spacewarp"], cpu["vtk"] / cpu["spacewarp"]))
    finally:
        shutil.rmtree(folder, ignore_errors=True)


if __name__ == "__main__":
    main()
