"""Mean-value, Green and harmonic coordinates of one concave cage, and how well each keeps the
properties cage coordinates are expected to have (spacewarp.testing.measure_properties).

    PYTHONPATH=build/python /usr/bin/python3 examples/python/compare_coordinates.py [CAGE.obj]

Without an argument the cage is a box with a pinched waist, made here; with one, it is read
from the file (e.g. ../shared/data/ju2005-armadillo/bounding_mesh.obj).
"""

import sys
import time

import numpy as np

import spacewarp
from spacewarp import testing


def pinched_box(waist=0.4):
    """A 2 x 2 x 2 box whose middle ring of vertices is pulled in to `waist` (concave)."""
    square = np.array([[-1, -1], [1, -1], [1, 1], [-1, 1]], float)
    rings = [np.c_[square * scale, np.full(4, z)] for z, scale in ((-1, 1), (0, waist), (1, 1))]
    vertices = np.vstack(rings)                        # ring r, corner i -> vertex 4 r + i
    faces = [[3, 2, 1, 0], [8, 9, 10, 11]]            # bottom, top (outward)
    for r in range(2):
        for i in range(4):
            j = (i + 1) % 4
            faces.append([4 * r + i, 4 * r + j, 4 * r + 4 + j, 4 * r + 4 + i])
    return spacewarp.Cage(vertices, faces, name="pinched box")


cage = spacewarp.Cage.from_file(sys.argv[1]) if len(sys.argv) > 1 else pinched_box()
points = spacewarp.interior_samples(cage, 2000, seed=1)     # (2000, 3) inside the cage
print(f"cage: {len(cage.vertices)} vertices, {len(cage.triangles)} triangles, "
      f"{len(points)} sample points inside\n")

methods = {
    "mvc": lambda: spacewarp.MeanValue(cage),
    "green": lambda: spacewarp.Green(cage),
    "harmonic": lambda: spacewarp.Harmonic(cage),   # TetGen mesh (~200k tets) + Laplace solve
}
figures = {}
for name, make in methods.items():
    start = time.perf_counter()
    coordinates = make()
    weights = coordinates.weights(points)                  # (n, V) or, for Green, (n, V + F)
    figures[name] = testing.measure_properties(
        weights,
        coordinates.column_controls(cage.vertices),        # rest columns: vertices (+ normals)
        points,
        vertices=cage.vertices,
        faces=cage.triangles,              # Green's face columns are these triangles, in order
        weight_fn=coordinates.weights,     # for Lagrange and face interpolation
    )
    print(f"{name:>8}: weights {weights.shape} in {time.perf_counter() - start:.2f} s")

rows = [
    ("partition of unity", "partition_of_unity", "{:.1e}"),
    ("linear reproduction", "linear_reproduction", "{:.1e}"),
    ("similarity reproduction", "similarity_reproduction", "{:.1e}"),
    ("Lagrange (at vertices)", "lagrange", "{:.1e}"),
    ("face interpolation", "face_interpolation", "{:.1e}"),
    ("min weight", "min_weight", "{:+.3f}"),
    ("points with a negative weight", "samples_with_negative", "{:.0%}"),
]
print(f"\n{'property':<31}" + "".join(f"{name:>10}" for name in figures))
for label, field, form in rows:
    print(f"{label:<31}" + "".join(f"{form.format(getattr(f, field)):>10}"
                                   for f in figures.values()))
print("\nErrors are maxima over the points; lengths are relative to the cage diagonal. Green\n"
      "coordinates interpolate neither vertices nor faces and may be negative; mean-value\n"
      "weights go negative in concave cages; harmonic weights are interpolating and >= 0.")
