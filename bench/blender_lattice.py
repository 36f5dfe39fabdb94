#!/usr/bin/env python3
"""spacewarp's B-spline lattice with "ends": "repeat" against Blender's Lattice modifier.

The same lattice (Blender's new lattice: points one unit apart centred at the origin, resolution
--resolution per axis, B-spline interpolation on all three axes), the same random pose of its control points, and the same
points inside the box: Blender deforms them through a Lattice modifier (headless, run beside the
project, float32), spacewarp through Lattice(basis="bspline", ends="repeat"). Prints the largest
difference relative to the largest displacement (round-off of Blender's float32 is ~1e-7), and
the same figure for the default ends (extrapolate), which Blender does not use. Run inside
Blender; skips, saying so, when Blender is missing:

    python3 bench/blender_lattice.py        # re-runs itself as: blender -b --python <this>
"""

import os
import shutil
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent


def outside_blender():
    blender = shutil.which("blender")
    if blender is None:
        print("Blender is not installed: the peer is skipped (apt-get install blender)")
        return 0
    env = dict(os.environ)
    # spacewarp from the build, NumPy from the system (Debian's Blender runs its Python 3.11).
    env["PYTHONPATH"] = os.pathsep.join(filter(None, [str(ROOT / "build" / "python"),
                                                      "/usr/lib/python3/dist-packages",
                                                      env.get("PYTHONPATH", "")]))
    args = [blender, "-b", "--factory-startup", "--python", __file__, "--"] + sys.argv[1:]
    done = subprocess.run(args, env=env, capture_output=True, text=True)
    lines = [l for l in done.stdout.splitlines() if l.startswith("|")]
    print("\n".join(l[1:] for l in lines) if lines else done.stdout + done.stderr)
    return done.returncode


def inside_blender(argv):
    import argparse

    import bpy
    import numpy as np

    import spacewarp as sw

    parser = argparse.ArgumentParser()
    parser.add_argument("--resolution", type=int, nargs=3, default=[5, 4, 6])
    parser.add_argument("--points", type=int, default=20000)
    parser.add_argument("--amount", type=float, default=0.3, help="pose, in cells")
    args = parser.parse_args(argv)
    l, m, n = args.resolution
    rng = np.random.default_rng(19)

    bpy.ops.wm.read_factory_settings(use_empty=True)
    lattice = bpy.data.lattices.new("lattice")
    lattice.points_u, lattice.points_v, lattice.points_w = l, m, n
    for axis in ("u", "v", "w"):
        setattr(lattice, f"interpolation_type_{axis}", "KEY_BSPLINE")
    lattice_object = bpy.data.objects.new("lattice", lattice)
    bpy.context.scene.collection.objects.link(lattice_object)
    # Points: i fastest, then j, then k, as spacewarp's index i + l (j + m k).
    # Blender spaces a new lattice's points one unit apart, centred at the origin.
    rest = np.array([p.co[:] for p in lattice.points], dtype=np.float64)
    lo, hi = rest.min(axis=0), rest.max(axis=0)
    cell = (hi - lo) / (np.array([l, m, n]) - 1)
    posed = rest + args.amount * cell * rng.uniform(-1, 1, rest.shape)
    posed = posed.astype(np.float32).astype(np.float64)  # what Blender stores
    for p, q in zip(lattice.points, posed):
        p.co_deform = q

    points = rng.uniform(lo, hi, (args.points, 3)).astype(np.float32).astype(np.float64)
    mesh = bpy.data.meshes.new("points")
    mesh.from_pydata(points.tolist(), [], [])
    mesh_object = bpy.data.objects.new("points", mesh)
    bpy.context.scene.collection.objects.link(mesh_object)
    modifier = mesh_object.modifiers.new("lattice", "LATTICE")
    modifier.object = lattice_object
    depsgraph = bpy.context.evaluated_depsgraph_get()
    evaluated = mesh_object.evaluated_get(depsgraph).to_mesh()
    blender = np.array([v.co[:] for v in evaluated.vertices], dtype=np.float64)

    scale = np.abs(blender - points).max()
    print(f"|Blender {bpy.app.version_string} lattice {l} x {m} x {n} (B-spline), pose "
          f"{args.amount} cells, {args.points} points inside; largest displacement {scale:.4f}")
    for ends in ("repeat", "extrapolate"):
        coords = sw.Lattice(origin=lo, extents=hi - lo, resolution=(l, m, n), basis="bspline",
                            ends=ends)
        ours = coords.warp(posed)(points)
        diff = np.abs(ours - blender).max()
        ulps = diff / (np.finfo(np.float32).eps * np.abs(blender).max())
        print(f"|spacewarp ends={ends:<12} max |spacewarp - Blender| = {diff / scale:.2e} of the "
              f"largest displacement ({ulps:.1f} float32 ulps of the largest coordinate)")


if __name__ == "__main__":
    try:
        import bpy  # noqa: F401  (present when Blender runs this file)
    except ImportError:
        sys.exit(outside_blender())
    inside_blender(sys.argv[sys.argv.index("--") + 1:] if "--" in sys.argv else [])
