#!/usr/bin/env python3
"""How much the B-spline lattice's two `ends` differ: for random poses (Gaussian control
displacements), the largest |x'(repeat) - x'(extrapolate)| over 100,000 uniform points in the
box, relative to the largest control displacement; 5 poses per resolution (the README's ffd row).

    PYTHONPATH=build/python python3 bench/lattice_ends_difference.py
"""
import numpy as np

import spacewarp as sw

rng = np.random.default_rng(1)
for res in [(4, 4, 4), (5, 6, 7), (8, 8, 8)]:
    ratios = []
    for _ in range(5):
        kw = dict(origin=[0, 0, 0], extents=[1, 1, 1], resolution=res, basis="bspline")
        extrapolate, repeat = sw.Lattice(**kw), sw.Lattice(**kw, ends="repeat")
        displacement = 0.1 * rng.standard_normal(extrapolate.rest_control_points.shape)
        posed = extrapolate.rest_control_points + displacement
        q = rng.uniform(0, 1, (100000, 3))
        diff = np.linalg.norm(extrapolate.warp(posed)(q) - repeat.warp(posed)(q), axis=1).max()
        ratios.append(diff / np.linalg.norm(displacement, axis=1).max())
    print(f"resolution {res}: largest difference / largest control displacement "
          f"{min(ratios):.2f}-{max(ratios):.2f}")
