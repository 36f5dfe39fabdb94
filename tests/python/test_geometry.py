"""Geometry, files and deform() from Python (python/src/geometry.cpp).

Files round-trip (OBJ, OFF, PLY ascii and binary) with their positions, faces, normals and PLY
attributes with their dtypes; deform() equals `spacewarp deform` bit for bit; in_place and
deform_inverse behave as documented; file errors are spacewarp.IoError naming the file.
"""

from __future__ import annotations

import re
import warnings

import numpy as np
import pytest

spacewarp = pytest.importorskip("spacewarp")

from conftest import write_json  # noqa: E402


def _grid_mesh(n: int = 8):
    """A bumpy (n x n)-vertex height field as quads, with unit vertex normals."""
    u, v = np.meshgrid(np.linspace(-1, 1, n), np.linspace(-1, 1, n), indexing="xy")
    h = 0.2 * np.sin(2.0 * u) * np.cos(1.5 * v)
    positions = np.column_stack([u.ravel(), v.ravel(), h.ravel()])
    quads = [[j * n + i, j * n + i + 1, (j + 1) * n + i + 1, (j + 1) * n + i]
             for j in range(n - 1) for i in range(n - 1)]
    dhdu = 0.4 * np.cos(2.0 * u) * np.cos(1.5 * v)
    dhdv = -0.3 * np.sin(2.0 * u) * np.sin(1.5 * v)
    normals = np.column_stack([-dhdu.ravel(), -dhdv.ravel(), np.ones(n * n)])
    normals /= np.linalg.norm(normals, axis=1, keepdims=True)
    return positions, np.array(quads), normals


@pytest.fixture
def mesh():
    positions, quads, normals = _grid_mesh()
    return spacewarp.Geometry(positions, quads, normals=normals)


def _awkward_points(n: int = 40) -> np.ndarray:
    """Doubles that a short decimal would not round-trip."""
    rng = np.random.default_rng(9)
    return rng.normal(size=(n, 3)) * np.pi * 10.0 ** rng.integers(-5, 6, size=(n, 1))


# ----------------------------------------------------------------------------------------------
# The Geometry class


def test_geometry_properties(mesh):
    positions, quads, normals = _grid_mesh()
    assert len(mesh) == mesh.point_count == 64 and mesh.polygon_count == 49
    assert np.array_equal(mesh.positions, positions)
    assert np.array_equal(mesh.normals, normals)
    assert mesh.faces.shape == (49, 4) and mesh.faces.dtype == np.uint32
    assert np.array_equal(mesh.faces, quads)
    assert "64 points" in repr(mesh) and "normals" in repr(mesh)


def test_geometry_arrays_are_copies(mesh):
    before = mesh.positions
    mesh.positions[0] = 99.0  # changes a copy
    assert np.array_equal(mesh.positions, before)
    moved = before + 1.0
    mesh.positions = moved
    assert np.array_equal(mesh.positions, moved)
    with pytest.raises(spacewarp.InvalidInput, match="64"):
        mesh.positions = moved[:10]
    mesh.normals = None
    assert mesh.normals is None


def test_point_cloud_and_mixed_polygons():
    cloud = spacewarp.Geometry(_awkward_points())
    assert cloud.polygon_count == 0 and cloud.normals is None
    mixed = spacewarp.Geometry(np.eye(3).tolist() + [[1.0, 1.0, 1.0]], [[0, 1, 2], [0, 1, 3, 2]])
    faces = mixed.faces
    assert isinstance(faces, list) and [f.tolist() for f in faces] == [[0, 1, 2], [0, 1, 3, 2]]


def test_geometry_rejects_bad_input():
    with pytest.raises(spacewarp.InvalidInput, match="vertex 5"):
        spacewarp.Geometry(np.zeros((3, 3)), [[0, 1, 5]])
    with pytest.raises(spacewarp.InvalidInput, match=r"\(3, 2\)"):
        spacewarp.Geometry(np.zeros((3, 2)))
    bad = np.zeros((4, 3))
    bad[3, 2] = np.nan
    with pytest.raises(spacewarp.InvalidInput, match="3"):
        spacewarp.Geometry(bad)
    g = spacewarp.Geometry(np.zeros((4, 3)))
    with pytest.raises(spacewarp.InvalidInput, match=r"\(4,\)"):
        g.set_vertex_attribute("a", np.zeros(3))
    with pytest.raises(spacewarp.InvalidInput, match="int64"):
        g.set_vertex_attribute("a", np.zeros(4), dtype="int64")


def test_copy_is_independent(mesh):
    twin = mesh.copy()
    twin.positions = twin.positions * 2.0
    assert not np.array_equal(twin.positions, mesh.positions)


# ----------------------------------------------------------------------------------------------
# Files


@pytest.mark.parametrize("suffix,ascii_", [(".obj", False), (".off", False), (".ply", False),
                                           (".ply", True)])
def test_round_trip_positions_and_faces(tmp_path, suffix, ascii_):
    positions = _awkward_points(12)
    faces = [[0, 1, 2], [2, 3, 4, 5], [6, 7, 8, 9, 10], [11, 0, 5]]
    path = tmp_path / f"soup{suffix}"
    spacewarp.write(path, spacewarp.Geometry(positions, faces), ascii=ascii_)
    back = spacewarp.read(path)
    assert np.array_equal(back.positions, positions)
    assert [f.tolist() for f in back.faces] == faces


@pytest.mark.parametrize("suffix", [".obj", ".ply", ".off"])
def test_round_trip_normals(tmp_path, mesh, suffix):
    path = tmp_path / f"mesh{suffix}"
    spacewarp.write(path, mesh)
    back = spacewarp.read(path)
    assert np.array_equal(back.positions, mesh.positions)
    np.testing.assert_allclose(back.normals, mesh.normals, rtol=0, atol=1e-15)
    assert np.array_equal(back.faces, mesh.faces)


def test_binary_ply_is_exact_and_compact(tmp_path):
    positions = _awkward_points(1000)
    path = tmp_path / "cloud.ply"
    spacewarp.write(path, spacewarp.Geometry(positions))
    assert np.array_equal(spacewarp.read(path).positions, positions)
    assert b"binary_little_endian" in path.read_bytes()[:200]
    assert path.stat().st_size < 1000 * 24 + 400


DTYPES = {"int8": "char", "uint8": "uchar", "int16": "short", "uint16": "ushort",
          "int32": "int", "uint32": "uint", "float32": "float", "float64": "double"}


@pytest.mark.parametrize("ascii_", [False, True])
def test_ply_attributes_keep_values_and_dtypes(tmp_path, ascii_):
    positions = _awkward_points(6)
    g = spacewarp.Geometry(positions, [[0, 1, 2], [3, 4, 5]])
    values = {"int8": [-128, -1, 0, 1, 2, 127], "uint8": [0, 1, 2, 3, 200, 255],
              "int16": [-32768, 0, 1, 2, 3, 32767], "uint16": [0, 1, 2, 3, 4, 65535],
              "int32": [-2**31, 0, 1, 2, 3, 2**31 - 1], "uint32": [0, 1, 2, 3, 4, 2**32 - 1],
              "float32": [0.5, -1.25, 3.0, 1e-3, 2.0**-20, 1e30],
              "float64": [np.pi, -np.e, 1e-300, 1e300, 0.1, 1 / 3]}
    for dtype, v in values.items():
        g.set_vertex_attribute(f"a_{dtype}", v, dtype=dtype)
    g.set_face_attribute("quality", [0.25, 0.75], dtype="float32")
    path = tmp_path / "attrs.ply"
    spacewarp.write(path, g, ascii=ascii_)
    header = path.read_bytes().split(b"end_header")[0].decode()
    for dtype, ply_type in DTYPES.items():
        assert f"property {ply_type} a_{dtype}\n" in header
    assert "property float quality" in header
    back = spacewarp.read(path)
    for dtype, v in values.items():
        expected = np.asarray(v, dtype=dtype).astype(np.float64)
        assert np.array_equal(back.vertex_attributes[f"a_{dtype}"], expected), dtype
    assert np.array_equal(back.face_attributes["quality"], [0.25, 0.75])
    # and written again, the dtypes are still those
    again = tmp_path / "again.ply"
    spacewarp.write(again, back, ascii=ascii_)
    assert again.read_bytes().split(b"end_header")[0].decode() == header


def test_formats_without_attributes_warn(tmp_path):
    g = spacewarp.Geometry(_awkward_points(3), [[0, 1, 2]])
    g.set_vertex_attribute("q", [1, 2, 3], dtype="uint8")
    with pytest.warns(UserWarning, match="cannot store.*q"):
        spacewarp.write(tmp_path / "a.off", g)
    assert np.array_equal(spacewarp.read(tmp_path / "a.off").positions, g.positions)


def test_writing_to_a_missing_folder_raises_io_error(tmp_path):
    target = tmp_path / "missing" / "out.ply"
    with pytest.raises(spacewarp.IoError) as error:
        spacewarp.write(target, spacewarp.Geometry(_awkward_points(3)))
    assert isinstance(error.value, OSError)
    assert "out.ply" in str(error.value)
    assert not target.exists() and not target.parent.exists()
    assert list(tmp_path.iterdir()) == []


def test_failed_write_leaves_an_existing_file_untouched(tmp_path):
    path = tmp_path / "keep.xyz"
    path.write_bytes(b"original")
    with pytest.raises((spacewarp.IoError, spacewarp.InvalidInput)):
        spacewarp.write(path, spacewarp.Geometry(_awkward_points(3)))  # unknown format
    assert path.read_bytes() == b"original"
    assert [p.name for p in tmp_path.iterdir()] == ["keep.xyz"]


@pytest.mark.parametrize("name,content", [
    ("bad.obj", b"v 1 2 3\nv 1 2\nf 1 2 3\n"),
    ("bad.off", b"OFF\n3 1 0\n0 0 0\n1 0 0\n"),
    ("bad.ply", b"ply\nformat binary_little_endian 1.0\nelement vertex 10\nproperty double x\n"
                b"property double y\nproperty double z\nend_header\n" + b"\0" * 50),
    ("faces.obj", b"v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 7\n"),
])
def test_reading_a_malformed_file_raises_io_error_naming_it(tmp_path, name, content):
    path = tmp_path / name
    path.write_bytes(content)
    with pytest.raises(spacewarp.IoError, match=name.replace(".", r"\.")) as error:
        spacewarp.read(path)
    assert isinstance(error.value, OSError)


def test_reading_a_missing_file_raises_io_error(tmp_path):
    with pytest.raises(spacewarp.IoError, match="nothing.obj"):
        spacewarp.read(tmp_path / "nothing.obj")


def test_read_accepts_str_and_path(tmp_path):
    path = tmp_path / "p.ply"
    spacewarp.write(str(path), spacewarp.Geometry(_awkward_points(4)))
    assert np.array_equal(spacewarp.read(str(path)).positions, spacewarp.read(path).positions)


# ----------------------------------------------------------------------------------------------
# deform() and deform_inverse()

TWIST = {"method": "twist", "origin": [0.1, 0, 0], "axis": [0, 0.3, 1], "rate": 1.1}


def test_deform_equals_the_cli_bit_for_bit(cli, tmp_path, mesh):
    source, target = tmp_path / "mesh.obj", tmp_path / "cli.obj"
    spacewarp.write(source, mesh)
    rig = write_json(tmp_path / "twist.json", TWIST)
    cli("deform", "--rig", rig, source, "-o", target)
    theirs = spacewarp.read(target)
    ours = spacewarp.deform(spacewarp.load_rig(rig), spacewarp.read(source))
    assert np.array_equal(ours.positions, theirs.positions)
    assert np.array_equal(ours.normals, theirs.normals)
    assert np.array_equal(ours.faces, theirs.faces)
    assert not np.allclose(ours.positions, mesh.positions)
    # and the files written are the same bytes
    spacewarp.write(tmp_path / "ours.obj", ours)
    assert (tmp_path / "ours.obj").read_bytes() == target.read_bytes()


def test_deform_moves_positions_and_carries_normals(mesh):
    warp = spacewarp.rig(TWIST)
    out = spacewarp.deform(warp, mesh)
    assert np.array_equal(out.positions, warp(mesh.positions))
    assert np.array_equal(out.normals, warp.transform_normals(mesh.positions, mesh.normals))
    assert np.array_equal(out.faces, mesh.faces)


def test_deform_in_place(mesh):
    warp = spacewarp.Twist(rate=0.8)
    rest = mesh.positions
    copy = spacewarp.deform(warp, mesh)
    assert copy is not mesh
    assert np.array_equal(mesh.positions, rest)  # untouched
    same = spacewarp.deform(warp, mesh, in_place=True)
    assert same is mesh
    assert np.array_equal(mesh.positions, copy.positions)
    assert np.array_equal(mesh.normals, copy.normals)


def test_a_geometry_in_use_by_a_call_refuses_changes(mesh):
    # The progress callable runs while deform works on the geometry with the GIL released: a
    # change from there (or from another thread) would reallocate what the call reads.
    refused = []

    def change(stage, fraction):
        try:
            mesh.positions = mesh.positions
        except ValueError as error:
            refused.append(str(error))

    spacewarp.deform(spacewarp.Twist(rate=0.8), mesh, in_place=True, progress=change)
    assert refused and "being read or changed" in refused[0]
    mesh.positions = mesh.positions  # free again afterwards


def test_deform_is_all_or_nothing(mesh):
    positions = mesh.positions
    positions[17, 0] = np.nan
    mesh.positions = positions  # the setter does not check values
    with pytest.raises(spacewarp.InvalidInput, match="17"):
        spacewarp.deform(spacewarp.Twist(rate=0.8), mesh, in_place=True)
    assert np.array_equal(mesh.positions, positions, equal_nan=True)


def test_deform_inverse_round_trip(mesh):
    for warp in (spacewarp.rig(TWIST), spacewarp.Bend(rate=0.5),
                 spacewarp.Mls([[-1, -1, -1], [1, -1, 0], [-1, 1, 0.5], [1, 1, 1.0]],
                               [[-1, -1, -1], [1.1, -1, 0], [-1, 1.05, 0.5], [1, 1, 1.1]])):
        posed = spacewarp.deform(warp, mesh)
        back = spacewarp.deform_inverse(warp, posed)
        assert back is not posed
        np.testing.assert_allclose(back.positions, mesh.positions, rtol=0, atol=1e-10)
        np.testing.assert_allclose(back.normals, mesh.normals, rtol=0, atol=1e-8)
        same = spacewarp.deform_inverse(warp, posed, in_place=True)
        assert same is posed
        np.testing.assert_allclose(posed.positions, mesh.positions, rtol=0, atol=1e-10)


def test_deform_inverse_raises_when_a_vertex_has_no_preimage():
    # the taper collapses the plane z = -1 onto the axis: (0.5, 0.5, -1) has no preimage
    g = spacewarp.Geometry([[0.1, 0.2, 0.3], [0.5, 0.5, -1.0]])
    with pytest.raises(spacewarp.SolverError, match="vertex 1 "):
        spacewarp.deform_inverse(spacewarp.Taper(rate=1.0), g, in_place=True, max_iterations=5)
    assert np.array_equal(g.positions, [[0.1, 0.2, 0.3], [0.5, 0.5, -1.0]])


def test_singular_normals_warn():
    g = spacewarp.Geometry([[0.5, 0.5, -1.0], [0.2, 0.1, 0.5]], normals=[[0, 0, 1.0], [1.0, 0, 0]])
    with pytest.warns(UserWarning, match="singular at 1 of 2"):
        spacewarp.deform(spacewarp.Taper(rate=1.0), g)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        spacewarp.deform(spacewarp.Twist(rate=1.0), g)


def test_deform_the_armadillo_like_the_cli(cli, shared_data, tmp_path):
    folder = shared_data / "ju2005-armadillo"
    rig = write_json(tmp_path / "mvc.json", {
        "method": "mvc", "cage": str(folder / "bounding_mesh.obj"),
        "pose": str(folder / "deformed_bounding_mesh3.obj")})
    model = spacewarp.read(folder / "armadilloman.obj")
    small = spacewarp.Geometry(model.positions[::10])
    spacewarp.write(tmp_path / "small.ply", small)
    cli("deform", "--rig", rig, tmp_path / "small.ply", "-o", tmp_path / "cli.ply")
    ours = spacewarp.deform(spacewarp.load_rig(rig), small)
    assert np.array_equal(ours.positions, spacewarp.read(tmp_path / "cli.ply").positions)


def test_read_warns_about_what_it_does_not_keep(tmp_path):
    path = tmp_path / "lines.obj"
    path.write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\nl 1 2\n")
    with pytest.warns(UserWarning, match="lines.obj: not kept"):
        g = spacewarp.read(path)
    assert g.polygon_count == 1


_CUBE = np.array([[2.0 * i - 1, 2.0 * j - 1, 2.0 * k - 1]
                  for k in (0, 1) for j in (0, 1) for i in (0, 1)])
_QUADS = [[0, 2, 3, 1], [4, 5, 7, 6], [0, 1, 5, 4], [2, 6, 7, 3], [0, 4, 6, 2], [1, 3, 7, 5]]
_BAD_FACES = {
    "geometry_float_array": (lambda: spacewarp.Geometry(_CUBE, np.array(_QUADS, dtype=float)),
                             "integer array"),
    "geometry_float_lists": (lambda: spacewarp.Geometry(_CUBE, [[0.0, 1.0, 2.0]]),
                             "face 0: index 0.0 is not an integer"),
    "cage_float_array": (lambda: spacewarp.Cage(_CUBE, np.array(_QUADS, dtype=float)),
                         "integer array"),
    "cage_float_lists": (lambda: spacewarp.Cage(_CUBE, [[float(i) for i in q] for q in _QUADS]),
                         "face 0: index 0.0 is not an integer"),
    "cage_string": (lambda: spacewarp.Cage(_CUBE, "abc"), "faces must be"),
    "geometry_out_of_range": (lambda: spacewarp.Geometry(_CUBE, [[0, 1, 2], [0, 1, 8]]),
                              "face 1 refers to vertex 8"),
}


@pytest.mark.parametrize("case", list(_BAD_FACES))
def test_bad_faces_raise_invalid_input_naming_the_face(case):
    # (they once raised a bare RuntimeError "Unable to cast Python instance to C++ type")
    make, message = _BAD_FACES[case]
    with pytest.raises(spacewarp.InvalidInput, match=re.escape(message)):
        make()


def test_out_of_range_attribute_is_refused_and_nothing_written(tmp_path):
    g = spacewarp.Geometry(_awkward_points(3))
    g.set_vertex_attribute("q", [300, 1, 2], dtype="uint8")
    path = tmp_path / "q.ply"
    with pytest.raises(spacewarp.InvalidInput, match="300"):
        spacewarp.write(path, g)
    assert list(tmp_path.iterdir()) == []
    path.write_bytes(b"before")
    with pytest.raises(spacewarp.InvalidInput):
        spacewarp.write(path, g)
    assert path.read_bytes() == b"before"
    assert [p.name for p in tmp_path.iterdir()] == ["q.ply"]


@pytest.mark.parametrize("rig", [TWIST, {"method": "mls", "mode": "rigid",
                                         "handles": [[-1, -1, -1], [1, -1, 0], [-1, 1, 0.5],
                                                     [1, 1, 1.0]],
                                         "targets": [[-1, -1, -1], [1.1, -1, 0],
                                                     [-1, 1.05, 0.5], [1, 1, 1.1]]}],
                         ids=["twist", "mls"])
def test_deform_inverse_equals_the_cli_inverse(cli, tmp_path, mesh, rig):
    rig_path = write_json(tmp_path / "rig.json", rig)
    warp = spacewarp.load_rig(rig_path)
    posed = spacewarp.deform(warp, mesh)
    spacewarp.write(tmp_path / "posed.obj", posed)
    cli("inverse", "--rig", rig_path, tmp_path / "posed.obj", "-o", tmp_path / "rest.obj")
    theirs = spacewarp.read(tmp_path / "rest.obj")
    ours = spacewarp.deform_inverse(warp, spacewarp.read(tmp_path / "posed.obj"))
    assert np.array_equal(ours.positions, theirs.positions)
    assert np.array_equal(ours.normals, theirs.normals)
    np.testing.assert_allclose(ours.positions, mesh.positions, rtol=0, atol=1e-10)


def test_failed_faces_assignment_changes_nothing():
    g = spacewarp.Geometry(_awkward_points(4), [[0, 1, 2], [1, 2, 3]])
    with pytest.raises(spacewarp.InvalidInput, match="vertex 99"):
        g.faces = [[0, 1, 3], [0, 1, 99]]
    assert np.array_equal(g.faces, [[0, 1, 2], [1, 2, 3]])


def test_faces_assignment_keeps_the_geometry_writable(tmp_path):
    # polygons of other sizes drop the per-face data (it described the old polygons); the
    # same sizes keep it
    g = spacewarp.Geometry(_awkward_points(4), [[0, 1, 2], [1, 2, 3]])
    g.set_face_attribute("q", [1.0, 2.0])
    g.faces = [[0, 2, 1], [1, 3, 2]]
    assert np.array_equal(g.face_attributes["q"], [1.0, 2.0])
    g.faces = [[0, 1, 3]]
    assert g.face_attributes == {}
    spacewarp.write(tmp_path / "g.ply", g)
    assert spacewarp.read(tmp_path / "g.ply").polygon_count == 1


def test_deform_keeps_ply_attributes_like_the_cli(cli, tmp_path, mesh):
    mesh.set_vertex_attribute("quality", np.arange(64) % 200, dtype="uint8")
    mesh.set_vertex_attribute("weight", np.linspace(0, 1, 64), dtype="float32")
    mesh.set_face_attribute("label", np.arange(49), dtype="int16")
    source = tmp_path / "mesh.ply"
    spacewarp.write(source, mesh)
    rig = write_json(tmp_path / "twist.json", TWIST)
    cli("deform", "--rig", rig, source, "-o", tmp_path / "cli.ply")
    ours = spacewarp.deform(spacewarp.load_rig(rig), spacewarp.read(source))
    assert set(ours.vertex_attributes) == {"quality", "weight"}
    assert np.array_equal(ours.vertex_attributes["quality"], np.arange(64) % 200)
    spacewarp.write(tmp_path / "ours.ply", ours)
    assert (tmp_path / "ours.ply").read_bytes() == (tmp_path / "cli.ply").read_bytes()


_TEXTURED_OBJ = """v 0 0 0
v 1 0 0
v 1 1 0
v 0 1 0
v 2 0 0.5
v 2 1 0.5
vt 0 0
vt 1 0
vt 1 1
vt 0 1
vn 0 0 1
vn 0.3 0 0.95
g left
f 1/1/1 2/2/1 3/3/1 4/4/1
g right
f 2/1/2 5/2/2 6/3/2 3/4/2
"""


def test_obj_texture_coordinates_groups_and_corner_normals_travel(cli, tmp_path):
    source = tmp_path / "textured.obj"
    source.write_text(_TEXTURED_OBJ)
    g = spacewarp.read(source)
    assert g.point_count == 6 and g.polygon_count == 2
    spacewarp.write(tmp_path / "copy.obj", g)
    assert (tmp_path / "copy.obj").read_text() == _TEXTURED_OBJ
    rig = write_json(tmp_path / "twist.json", TWIST)
    cli("deform", "--rig", rig, source, "-o", tmp_path / "cli.obj")
    spacewarp.write(tmp_path / "ours.obj", spacewarp.deform(spacewarp.load_rig(rig), g))
    ours = (tmp_path / "ours.obj").read_text()
    assert ours == (tmp_path / "cli.obj").read_text()
    assert "vt 1 1" in ours and "g right" in ours
