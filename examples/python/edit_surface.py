"""Edit a mesh by its surface: bend a bar by turning one end, three ways.

    PYTHONPATH=build/python /usr/bin/python3 examples/python/edit_surface.py [OUT_DIR]

1. spacewarp.edit() with a handles file, as `spacewarp edit --handles` reads it;
2. an ArapEditor built once and solved for several poses (an animation: each frame starts from
   the previous one);
3. ARAP in a cage's subspace (CageArapEditor): the result is a posed cage, which then carries
   any other geometry (here a point cloud around the bar) the same way.

The bar is made here: [-3, 3] x [-0.5, 0.5]^2 as quads, written as OBJ. Results go to OUT_DIR
(default out/examples).
"""

import json
import sys
from pathlib import Path

import numpy as np

import spacewarp

out = Path(sys.argv[1] if len(sys.argv) > 1 else "out/examples")
out.mkdir(parents=True, exist_ok=True)

def box(n, half):
    """A box [-half, half] (3 half-widths) of outward quads, n[a] along axis a: (V, 3), quads."""
    index, quads = {}, []
    for axis in range(3):
        u, v = [a for a in range(3) if a != axis]
        for side in (0, n[axis]):
            for i in range(n[u]):
                for j in range(n[v]):
                    quad = []
                    for di, dj in ((0, 0), (1, 0), (1, 1), (0, 1)):
                        key = [0, 0, 0]
                        key[axis], key[u], key[v] = side, i + di, j + dj
                        quad.append(index.setdefault(tuple(key), len(index)))
                    quads.append(quad)
    vertices = np.array([[2.0 * k / m - 1.0 for k, m in zip(key, n)]
                         for key in sorted(index, key=index.get)]) * half
    # Outward: each quad's normal points away from the centre.
    return vertices, [q if np.cross(vertices[q[1]] - vertices[q[0]],
                                    vertices[q[2]] - vertices[q[0]]) @ vertices[q].mean(axis=0) > 0
                      else q[::-1] for q in quads]


# The bar: 24 x 4 x 4 quads per side over [-3, 3] x [-0.5, 0.5]^2.
rest, quads = box((24, 4, 4), [3.0, 0.5, 0.5])
bar = spacewarp.Geometry(rest, quads)
spacewarp.write(out / "bar.obj", bar)

# The handles: the left end pinned (the identity), the right end turned about z and moved to
# where bending the bar's axis into a circular arc of its own length takes it: a 4 x 4 matrix
# given by rows.
left = np.flatnonzero(rest[:, 0] < -2.99)
right = np.flatnonzero(rest[:, 0] > 2.99)


def turn(degrees: float) -> np.ndarray:
    t = np.radians(degrees)
    radius = 6.0 / t
    m = np.eye(4)
    m[:2, :2] = [[np.cos(t), -np.sin(t)], [np.sin(t), np.cos(t)]]
    end = [-3.0 + radius * np.sin(t), radius * (1 - np.cos(t)), 0.0]
    m[:3, 3] = end - m[:3, :3] @ [3.0, 0, 0]
    return m


(out / "bar_handles.json").write_text(json.dumps({"handles": [
    {"vertices": left.tolist(), "matrix": np.eye(4).tolist()},
    {"vertices": right.tolist(), "matrix": turn(90).tolist()}]}))

# 1. One call: weld, resolve the handles, solve, write.
handles = spacewarp.load_handles(out / "bar_handles.json")
edges = np.array([(q[i], q[(i + 1) % 4]) for q in quads for i in range(4)])


def stretch(positions: np.ndarray) -> np.ndarray:
    """The relative change of each edge's length from the rest bar."""
    length = np.linalg.norm(positions[edges[:, 0]] - positions[edges[:, 1]], axis=1)
    return np.abs(length / np.linalg.norm(rest[edges[:, 0]] - rest[edges[:, 1]], axis=1) - 1)


for method in ("laplacian", "arap"):
    options = {"max_iterations": 200} if method == "arap" else {}
    edited = spacewarp.edit(bar, handles, method=method, **options)
    spacewarp.write(out / f"bar_{method}.obj", edited)
    change = stretch(edited.positions)
    print(f"{method}: edge lengths change by {change.mean():.1%} on average, "
          f"{change.max():.1%} at most")

# 2. The editor, built once: each pose is one solve (ARAP's factor is kept).
mesh = spacewarp.weld_soup(bar)
print(f"mesh: {mesh}, {mesh.report}")
constrained = np.concatenate([mesh.soup_to_mesh[left], mesh.soup_to_mesh[right]])
editor = spacewarp.ArapEditor(mesh.positions, mesh.triangles, constrained, max_iterations=200)


def targets_for(degrees: float) -> np.ndarray:
    """The constrained vertices' targets: the left end at rest, the right one turned."""
    targets = mesh.positions[constrained].copy()
    m = turn(degrees)
    targets[len(left):] = targets[len(left):] @ m[:3, :3].T + m[:3, 3]
    return targets


positions = mesh.positions
for frame, degrees in enumerate((30, 60, 90)):
    targets = targets_for(degrees)
    result = editor.solve_from(positions, targets)
    positions = result.positions
    energies = result.report.energies
    print(f"frame {frame}: {degrees} degrees, {result.report.iterations} iterations, "
          f"energy {energies[0]:.4g} -> {energies[-1]:.4g}")
    frame_soup = bar.copy()
    frame_soup.positions = mesh.to_soup_positions(positions)
    spacewarp.write(out / f"bar_arap_{frame}.obj", frame_soup)

# 3. ARAP in a cage's subspace: the unknowns are the 26 vertices of a box cage of 6 x 1 x 1
# quads per side around the bar.
cage = spacewarp.Cage(*box((6, 1, 1), [3.5, 1.0, 1.0]))
mvc = spacewarp.MeanValue(cage)
cage_editor = spacewarp.CageArapEditor(mesh.positions, mesh.triangles, mvc, constrained)
posed = cage_editor.solve(targets)
report = posed.report
print(f"cage-arap: {cage_editor.cluster_count} rotation clusters, {report.iterations} iterations, "
      f"max handle residual {report.max_residual:.3g}, {len(report.unreached)} unreached")
# The posed cage moves anything inside it the same way: here a cloud of points.
cloud = spacewarp.Geometry(np.random.default_rng(1).uniform(-1, 1, (5000, 3)) * [3, 0.5, 0.5])
spacewarp.write(out / "bar_cloud_cage_arap.ply", spacewarp.deform(mvc.warp(posed.control_points),
                                                                   cloud))
print(f"wrote the bar, its edits and a point cloud moved by the posed cage to {out}/")
