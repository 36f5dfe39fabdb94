"""Blender's Mesh Deform at one precision, for bench/harmonic_frontier.py (run inside Blender:
blender -b --factory-startup --python harmonic_frontier_blender.py -- CAGE POSED MODEL OUT PRECISION).

The OBJ files are parsed here and the meshes built with from_pydata, so the vertex order is the
files' (Blender's importer may split vertices by normals or UVs). Binds the model to the cage
(the bind runs at the depsgraph evaluation after meshdeform_bind; both are timed), moves the
cage's vertices to the posed file's, evaluates the deformed model and writes its vertices as raw
little-endian f64 (x y z per vertex, the model's order). Prints one line: FRONTIER {json}.
"""

import array
import json
import sys
import time

import bpy


def read_obj(path):
    vertices, faces = [], []
    with open(path) as f:
        for line in f:
            parts = line.split()
            if not parts:
                continue
            if parts[0] == "v":
                vertices.append(tuple(float(x) for x in parts[1:4]))
            elif parts[0] == "f":
                idx = [int(p.split("/")[0]) for p in parts[1:]]
                faces.append([i - 1 if i > 0 else len(vertices) + i for i in idx])
    return vertices, faces


def make_object(name, vertices, faces):
    mesh = bpy.data.meshes.new(name)
    mesh.from_pydata(vertices, [], faces)
    mesh.update()
    obj = bpy.data.objects.new(name, mesh)
    bpy.context.scene.collection.objects.link(obj)
    return obj


def main():
    args = sys.argv[sys.argv.index("--") + 1:]
    cage_path, posed_path, model_path, out_path, precision = args[:5]
    for obj in list(bpy.data.objects):
        bpy.data.objects.remove(obj)
    cage = make_object("cage", *read_obj(cage_path))
    posed, _ = read_obj(posed_path)
    model_vertices, model_faces = read_obj(model_path)
    model = make_object("model", model_vertices, model_faces)
    assert len(model.data.vertices) == len(model_vertices)
    modifier = model.modifiers.new("meshdeform", "MESH_DEFORM")
    modifier.object = cage
    modifier.precision = int(precision)
    bpy.context.view_layer.objects.active = model
    model.select_set(True)

    start = time.perf_counter()
    bpy.ops.object.meshdeform_bind(modifier="meshdeform")
    depsgraph = bpy.context.evaluated_depsgraph_get()
    depsgraph.update()
    bind = time.perf_counter() - start
    if not modifier.is_bound:
        raise SystemExit("harmonic_frontier_blender: the bind failed")

    for vertex, p in zip(cage.data.vertices, posed):
        vertex.co = p
    cage.data.update()
    depsgraph = bpy.context.evaluated_depsgraph_get()
    depsgraph.update()
    evaluated = model.evaluated_get(depsgraph)
    mesh = evaluated.to_mesh()
    out = array.array("d")
    for vertex in mesh.vertices:
        out.extend(vertex.co)
    evaluated.to_mesh_clear()
    if len(out) != 3 * len(model_vertices):
        raise SystemExit("harmonic_frontier_blender: the vertex count changed")
    with open(out_path, "wb") as f:
        out.tofile(f)
    print("FRONTIER " + json.dumps({"precision": int(precision), "bind_s": bind}), flush=True)


main()
