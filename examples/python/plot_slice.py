"""Plot one cage vertex's mean-value and harmonic weight on a slice through a concave cage.

    PYTHONPATH=build/python /usr/bin/python3 examples/python/plot_slice.py OUT.png

Needs matplotlib (Debian: python3-matplotlib); without it, says so and exits 0. The cage is a
box with a pinched waist; the slice is the plane y = -0.5, inside the cage. Mean-value weights
(defined everywhere) go slightly negative where the cage is concave (magenta: the zero line);
harmonic weights (defined inside the cage only) are never negative.
"""

import sys

import numpy as np

try:
    import matplotlib
    matplotlib.use("Agg")                      # no display needed
    import matplotlib.pyplot as plt
except ImportError:
    print("matplotlib is missing (Debian: apt-get install python3-matplotlib); no plot made")
    sys.exit(0)

import spacewarp

if len(sys.argv) != 2:
    sys.exit(f"usage: {sys.argv[0]} OUT.png")

# The cage: rings of 4 vertices at z = -1, 0, 1; the middle one pinched to 0.4 of the box.
square = np.array([[-1, -1], [1, -1], [1, 1], [-1, 1]], float)
vertices = np.vstack([np.c_[square * s, np.full(4, z)] for z, s in ((-1, 1), (0, 0.4), (1, 1))])
faces = [[3, 2, 1, 0], [8, 9, 10, 11]] + [
    [4 * r + i, 4 * r + (i + 1) % 4, 4 * r + 4 + (i + 1) % 4, 4 * r + 4 + i]
    for r in range(2) for i in range(4)]
cage = spacewarp.Cage(vertices, faces)
vertex = 9                                     # the top ring's corner (1, -1, 1)

# The slice: a 200 x 200 grid of the plane y = -0.5 around the cage; only points inside count.
u = np.linspace(-1.2, 1.2, 200)
x, z = np.meshgrid(u, u)
points = np.c_[x.ravel(), np.full(x.size, -0.5), z.ravel()]
inside = cage.contains(points)                 # (n,) bool

mvc = np.full(len(points), np.nan)
mvc[inside] = spacewarp.MeanValue(cage).weights(points[inside])[:, vertex]
harmonic = np.full(len(points), np.nan)        # undefined outside the cage (outside="raise")
harmonic[inside] = spacewarp.Harmonic(cage).weights(points[inside])[:, vertex]

fig, axes = plt.subplots(1, 2, figsize=(10, 4.6), constrained_layout=True)
limit = np.nanmax(np.abs(mvc))                 # one colour scale for both
for ax, (title, w) in zip(axes, [("mean-value", mvc), ("harmonic", harmonic)]):
    image = ax.imshow(w.reshape(x.shape), origin="lower", extent=(u[0], u[-1], u[0], u[-1]),
                      cmap="RdBu_r", vmin=-limit, vmax=limit)
    ax.contour(x, z, inside.reshape(x.shape), levels=[0.5], colors="k", linewidths=1)
    if np.nanmin(w) < 0:
        ax.contour(x, z, w.reshape(x.shape), levels=[0.0], colors="m", linewidths=0.8)
    ax.set(title=f"{title} weight of vertex {vertex}, min {np.nanmin(w):.1e}", xlabel="x",
           ylabel="z", xlim=(u[0], u[-1]))
fig.colorbar(image, ax=axes, shrink=0.8, label="weight (magenta: 0, black: the cage)")
fig.savefig(sys.argv[1], dpi=100)
print(f"wrote {sys.argv[1]}: inside the cage, the mean-value weight of vertex {vertex} is "
      f"negative at {(mvc[inside] < 0).mean():.0%} of the slice (min {np.nanmin(mvc):.2e}); "
      f"the harmonic weight's min is {np.nanmin(harmonic):.2e}")
