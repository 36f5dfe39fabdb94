"""Warp volumes: a dense NumPy block of signed distances (a ball) with warp_dense, and, when a
path is given, every grid of an OpenVDB file with warp_volume.

    PYTHONPATH=build/python /usr/bin/python3 examples/python/warp_volume.py [IN.vdb [OUT.vdb]]

IN.vdb can be out/demo/bar.vdb from `build/apps/spacewarp demo`; OUT.vdb defaults to
IN_twisted.vdb next to it.
"""

import sys
import warnings
from pathlib import Path

import numpy as np

import spacewarp

if not spacewarp.has_volumes:
    sys.exit("this spacewarp was built without OpenVDB (SPACEWARP_WITH_OPENVDB=OFF)")

# A taper then a twist about z: a closed form exists, so warp.inverse is exact below.
warp = spacewarp.Compose(spacewarp.Taper(axis=(0, 0, 1), rate=0.3),
                         spacewarp.Twist(axis=(0, 0, 1), rate=1.0))

# 1. A dense block: a ball of radius 0.8 as a narrow-band level set, voxels of 0.04.
voxel, radius = 0.04, 0.8
band = 3 * voxel                                   # half-width of the narrow band, world units
n = 50
origin = np.full(3, -(n - 1) / 2 * voxel)         # world position of voxel (0, 0, 0)
centers = origin + voxel * np.indices((n, n, n)).transpose(1, 2, 3, 0)   # (n, n, n, 3)
# float32 stays float32 (other dtypes are float64); voxels equal to `background` are inactive.
sdf = np.clip(np.linalg.norm(centers, axis=-1) - radius, -band, band).astype(np.float32)

out, out_origin = spacewarp.warp_dense(warp, sdf, voxel_size=voxel, origin=origin,
                                       background=band, level_set=True)
print(f"warp_dense: {sdf.shape} {sdf.dtype} block -> {out.shape} {out.dtype} at {out_origin}")

# Check: output voxels on the surface (|distance| < half a voxel) map back onto the sphere.
surface = out_origin + voxel * np.argwhere(np.abs(out) < 0.5 * voxel)
rest, converged, _ = warp.inverse(surface)
error = np.abs(np.linalg.norm(rest[converged], axis=1) - radius).max()
print(f"  {len(surface)} surface voxels; their preimages lie {error / voxel:.2f} voxels "
      "or less from the ball's sphere")

# 2. A VDB file: every grid (level sets, fog volumes, vector fields, points) in one call.
if len(sys.argv) > 1:
    source = Path(sys.argv[1])
    target = Path(sys.argv[2]) if len(sys.argv) > 2 else source.with_name(
        source.stem + "_twisted.vdb")
    with warnings.catch_warnings(record=True) as lost:   # voxels lost are warnings
        warnings.simplefilter("always")
        reports = spacewarp.warp_volume(warp, source, target)
    for report in reports:
        print(f"warp_volume: grid '{report['grid']}' ({report['type']}): "
              f"{report['input_active_voxels']} -> {report['output_active_voxels']} active "
              f"voxels, {report['inverse_failures']} inverse failures")
    for warning in lost:
        print(f"  warning: {warning.message}")
    print(f"wrote {target}")
