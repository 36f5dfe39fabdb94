"""Deform a scanned point cloud two ways: with a rig given as a dict (a twist), and with a cage
bound to the points once (mean-value coordinates) and then posed.

    PYTHONPATH=build/python /usr/bin/python3 examples/python/deform_scan.py [OUT_DIR]

The "scan" is made here: 20,000 random points on a unit sphere with their normals, written as
a binary PLY. Results go to OUT_DIR (default out/examples).
"""

import sys
from pathlib import Path

import numpy as np

import spacewarp

out = Path(sys.argv[1] if len(sys.argv) > 1 else "out/examples")
out.mkdir(parents=True, exist_ok=True)

# A scan: points on the unit sphere, normals pointing out, a per-point attribute.
rng = np.random.default_rng(7)
p = rng.normal(size=(20_000, 3))
p /= np.linalg.norm(p, axis=1, keepdims=True)
scan = spacewarp.Geometry(p, normals=p)
scan.set_vertex_attribute("intensity", rng.random(len(p)), dtype="float32")
spacewarp.write(out / "scan.ply", scan)

cloud = spacewarp.read(out / "scan.ply")       # a Geometry: positions, normals, attributes
print(f"read {cloud}, attributes {sorted(cloud.vertex_attributes)}")

# 1. A rig dict: the JSON of a rig file, as `spacewarp deform --rig` reads it.
twist = spacewarp.rig({"method": "twist", "origin": [0, 0, 0], "axis": [0, 0, 1],
                       "rate": 0.785398})     # 45 degrees per unit along z
twisted = spacewarp.deform(twist, cloud)      # positions warped, normals carried by J^-T
spacewarp.write(out / "scan_twist.ply", twisted)
moved = np.linalg.norm(twisted.positions - cloud.positions, axis=1)
print(f"twist: points moved by up to {moved.max():.3f} (45 degrees about z per unit of z)")

# 2. A cage: a box around the sphere, bound to the points once; each pose is then one product.
corners = np.array([[x, y, z] for z in (-1.2, 1.2) for y in (-1.2, 1.2) for x in (-1.2, 1.2)])
box = [[0, 2, 3, 1], [4, 5, 7, 6], [0, 1, 5, 4], [2, 6, 7, 3], [0, 4, 6, 2], [1, 3, 7, 5]]
cage = spacewarp.Cage(corners, box)
mvc = spacewarp.MeanValue(cage)
binding = mvc.bind(cloud.positions)            # (n, 8) weights, computed once in parallel

for frame, lean in enumerate((0.0, 0.3, 0.6)):
    posed = cage.vertices.copy()
    posed[posed[:, 2] > 0, 0] += lean          # slide the top face along x
    moved = cloud.copy()
    moved.positions = binding.deform(posed)    # (n, 3); normals are not updated this way
    spacewarp.write(out / f"scan_cage_{frame}.ply", moved)

# The same pose as a Warp carries the normals too (and works on meshes and volumes).
leaned = spacewarp.deform(mvc.warp(posed), cloud)
assert np.allclose(leaned.positions, binding.deform(posed))
spacewarp.write(out / "scan_cage_normals.ply", leaned)
print(f"wrote {len(list(out.glob('scan*.ply')))} PLY files to {out}/")
