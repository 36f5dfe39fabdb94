"""spacewarp.deform_file, ply_layout, deform_ply_rows and assemble_ply: files warped in pieces
give the bytes of the whole-file path (and of the CLI)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

spacewarp = pytest.importorskip("spacewarp")

TWIST = {"method": "twist", "origin": [0, 0, 0], "axis": [0, 0, 1], "rate": 0.7}


def write_cloud(path: Path, n: int, byte_order: str = "<", faces: bool = False) -> np.ndarray:
    """A binary PLY of n points (float xyz, float normals, uchar red) with a few polygons."""
    rng = np.random.default_rng(n)
    dtype = np.dtype([("x", byte_order + "f4"), ("y", byte_order + "f4"), ("z", byte_order + "f4"),
                      ("nx", byte_order + "f4"), ("ny", byte_order + "f4"),
                      ("nz", byte_order + "f4"), ("red", "u1")])
    rows = np.zeros(n, dtype)
    for axis in "xyz":
        rows[axis] = rng.uniform(-1, 1, n)
    normals = rng.normal(size=(n, 3))
    normals /= np.linalg.norm(normals, axis=1)[:, None]
    rows["nx"], rows["ny"], rows["nz"] = normals.T
    rows["red"] = np.arange(n) % 256
    encoding = "binary_little_endian" if byte_order == "<" else "binary_big_endian"
    header = (f"ply\nformat {encoding} 1.0\nelement vertex {n}\n"
              + "".join(f"property float {a}\n" for a in ("x", "y", "z", "nx", "ny", "nz"))
              + "property uchar red\n")
    polygons = [[0, 1, 2], [3, 4, 5, 6], [n - 1, 0, 1, 2, 3]] if faces else []
    if faces:
        header += f"element face {len(polygons)}\nproperty list uchar int vertex_indices\n"
    header += "end_header\n"
    with open(path, "wb") as f:
        f.write(header.encode())
        f.write(rows.tobytes())
        for polygon in polygons:
            f.write(np.array([len(polygon)], "u1").tobytes())
            f.write(np.array(polygon, byte_order + "i4").tobytes())
    return rows


@pytest.fixture
def twist():
    return spacewarp.rig(TWIST)


@pytest.mark.parametrize("byte_order", ["<", ">"])
@pytest.mark.parametrize("ascii", [False, True])
def test_streamed_file_is_byte_identical_to_the_whole_file_path(tmp_path, twist, byte_order, ascii):
    source = tmp_path / "in.ply"
    write_cloud(source, 300, byte_order, faces=True)
    whole = spacewarp.deform_file(twist, source, tmp_path / "whole.ply", chunk_points=0,
                                  ascii=ascii)
    assert not whole["streamed"]
    for chunk in (1, 7, 1000):
        report = spacewarp.deform_file(twist, source, tmp_path / "s.ply", chunk_points=chunk,
                                       ascii=ascii)
        assert report["streamed"] and report["points"] == 300 and report["faces"] == 3
        assert report["chunks"] == -(-300 // chunk)
        assert (tmp_path / "s.ply").read_bytes() == (tmp_path / "whole.ply").read_bytes()


def test_deform_file_matches_the_cli(tmp_path, twist, cli):
    source = tmp_path / "in.ply"
    write_cloud(source, 100)
    (tmp_path / "twist.json").write_text(__import__("json").dumps(TWIST))
    cli("deform", "--chunk-points", "9", "--rig", tmp_path / "twist.json", source, "-o",
        tmp_path / "cli.ply")
    spacewarp.deform_file(twist, source, tmp_path / "py.ply")
    assert (tmp_path / "py.ply").read_bytes() == (tmp_path / "cli.ply").read_bytes()


def test_ply_layout_memmaps_the_vertex_rows(tmp_path):
    source = tmp_path / "in.ply"
    rows = write_cloud(source, 50, ">", faces=True)
    layout = spacewarp.ply_layout(source)
    assert layout["vertex_count"] == 50
    assert layout["vertex_row_bytes"] == rows.dtype.itemsize == layout["dtype"].itemsize
    assert layout["encoding"] == "binary_big_endian"
    assert [e["name"] for e in layout["elements"]] == ["vertex", "face"]
    assert layout["elements"][1]["offset"] + layout["elements"][1]["bytes"] == layout["file_bytes"]
    assert layout["face_count"] == 3 and layout["largest_polygon"] == 5
    assert layout["output_row_bytes"] == 6 * 8 + 1
    view = np.memmap(source, layout["dtype"], "r", layout["vertex_offset"], (50,))
    assert np.array_equal(view, rows)  # every field, bit for bit


def test_row_parts_assemble_into_the_whole_output(tmp_path, twist):
    source = tmp_path / "in.ply"
    write_cloud(source, 101, faces=True)
    spacewarp.deform_file(twist, source, tmp_path / "whole.ply", chunk_points=0)
    layout = spacewarp.ply_layout(source)
    cuts = [0, 40, 40, 77, 101]
    parts = []
    for k, (begin, end) in enumerate(zip(cuts, cuts[1:])):
        part = tmp_path / f"part{k}"
        spacewarp.deform_ply_rows(twist, source, part, begin, end - begin, chunk_points=6)
        assert part.stat().st_size == (end - begin) * layout["output_row_bytes"]
        parts.append(part)
    spacewarp.assemble_ply(source, parts, tmp_path / "joined.ply")
    assert (tmp_path / "joined.ply").read_bytes() == (tmp_path / "whole.ply").read_bytes()
    with pytest.raises(spacewarp.InvalidInput, match="hold 61 vertex rows"):
        spacewarp.assemble_ply(source, parts[1:], tmp_path / "bad.ply")
    assert not (tmp_path / "bad.ply").exists()


def test_refusals_name_the_file_and_vertex_and_leave_no_output(tmp_path, twist):
    source = tmp_path / "in.ply"
    write_cloud(source, 40)
    data = bytearray(source.read_bytes())
    row = 25
    start = len(data) - (40 - 33) * row + 8  # vertex 33, z
    data[start:start + 4] = np.array([np.nan], "<f4").tobytes()
    source.write_bytes(bytes(data))
    with pytest.raises(spacewarp.IoError, match="vertex 33: non-finite coordinate"):
        spacewarp.deform_file(twist, source, tmp_path / "out.ply", chunk_points=4)
    with pytest.raises(spacewarp.InvalidInput, match="past the 40 vertices"):
        spacewarp.deform_ply_rows(twist, source, tmp_path / "p", 30, 11)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["in.ply"]


def test_progress_cancels_without_output(tmp_path, twist):
    source = tmp_path / "in.ply"
    write_cloud(source, 100)
    stages = []

    def progress(stage, fraction):
        stages.append(stage)
        return len(stages) < 3

    with pytest.raises(spacewarp.Cancelled):
        spacewarp.deform_file(twist, source, tmp_path / "out.ply", chunk_points=10,
                              progress=progress)
    assert stages[0] == "deform"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["in.ply"]


def test_a_part_that_is_the_input_is_refused_and_the_input_kept(tmp_path, twist):
    source = tmp_path / "in.ply"
    write_cloud(source, 30, faces=True)
    original = source.read_bytes()
    (tmp_path / "link.ply").symlink_to(source)
    for part in (source, tmp_path / "link.ply"):
        with pytest.raises(spacewarp.InvalidInput, match="is the input"):
            spacewarp.deform_ply_rows(twist, source, part, 0, 10)
        with pytest.raises(spacewarp.InvalidInput, match="is the input"):
            spacewarp.assemble_ply(source, [part], tmp_path / "out.ply")
    assert source.read_bytes() == original
    assert not (tmp_path / "out.ply").exists()


def test_a_warp_domain_error_names_the_file_and_the_vertex_in_it(tmp_path):
    source = tmp_path / "in.ply"
    rows = write_cloud(source, 50)
    # Points farther than the radius from the one handle are refused.
    warp = spacewarp.rig({"method": "idw", "handles": [[0, 0, 0]], "targets": [[0, 0, 0]],
                          "radius": 1.0})
    points = np.stack([rows["x"], rows["y"], rows["z"]], axis=1).astype(np.float64)
    far = np.linalg.norm(points, axis=1) >= 1.0
    first = int(np.argmax(far))
    assert far.any() and not far.all()

    def message(chunk):
        with pytest.raises(spacewarp.InvalidInput) as error:
            spacewarp.deform_file(warp, source, tmp_path / "out.ply", chunk_points=chunk)
        return str(error.value)

    whole = message(0)
    assert whole.startswith(str(source) + ": ")
    assert f"{int(far.sum())} of 50 points" in whole and f"the first is point {first} " in whole
    assert message(50) == message(1000) == whole  # one chunk: the same message
    chunk = 4
    in_chunk = int(far[first // chunk * chunk:first // chunk * chunk + chunk].sum())
    assert message(chunk) == whole.replace(f"{int(far.sum())} of 50",
                                           f"at least {in_chunk} of 50")
    with pytest.raises(spacewarp.InvalidInput, match=f"the first is point {first} "):
        spacewarp.deform_ply_rows(warp, source, tmp_path / "part", first, 50 - first)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["in.ply"]


def test_a_pipe_is_read_whole_with_the_same_bytes(tmp_path, twist):
    import os
    import threading

    source = tmp_path / "in.ply"
    write_cloud(source, 60, faces=True)
    spacewarp.deform_file(twist, source, tmp_path / "whole.ply", chunk_points=0)
    fifo = tmp_path / "pipe.ply"
    os.mkfifo(fifo)
    writer = threading.Thread(target=lambda: fifo.write_bytes(source.read_bytes()))
    writer.start()
    try:
        # Streaming would read the pipe twice (layout, then rows): it is read whole instead.
        report = spacewarp.deform_file(twist, fifo, tmp_path / "out.ply", chunk_points=7)
    finally:
        writer.join(timeout=30)
    assert not report["streamed"] and report["points"] == 60
    assert (tmp_path / "out.ply").read_bytes() == (tmp_path / "whole.ply").read_bytes()
    with pytest.raises(spacewarp.InvalidInput, match="cannot stream a pipe"):
        spacewarp.ply_layout(fifo)
