"""spacewarp.dask (python/spacewarp/dask.py) on a LocalCluster of 2 worker processes, against the
single-machine results: deform_array bit for bit for every rig the demo writes, deform_ply byte
for byte against `spacewarp deform`, warp_volume against spacewarp.warp_volume (the same file
but for its UUID), and errors raised on a worker reaching the caller.

Skipped when dask or distributed is missing. The warps travel to the workers pickled.
"""

from __future__ import annotations

import json
import os
import pickle
import re

import numpy as np
import pytest

spacewarp = pytest.importorskip("spacewarp")
da = pytest.importorskip("dask.array", reason="spacewarp.dask needs dask (python3-dask)")
distributed = pytest.importorskip("distributed",
                                  reason="spacewarp.dask's tests need python3-distributed")
swd = pytest.importorskip("spacewarp.dask")

_UUID = re.compile(rb"[0-9a-f]{8}-[0-9a-f]{4}-[0-9a-f]{4}-[0-9a-f]{4}-[0-9a-f]{12}")


def _masked(path) -> bytes:
    """A VDB file's bytes with the random UUID of its header blanked out."""
    data = path.read_bytes()
    match = _UUID.search(data[:512])
    assert match, f"no UUID in the header of {path}"
    return data[:match.start()] + b"-" * 36 + data[match.end():]


@pytest.fixture(scope="module")
def client():
    cluster = distributed.LocalCluster(n_workers=2, processes=True, threads_per_worker=1,
                                       dashboard_address=None)
    c = distributed.Client(cluster)
    yield c
    c.close()
    cluster.close()


@pytest.fixture(scope="module")
def demo(cli, tmp_path_factory):
    """The CLI demo's folder: its rigs, cloud.ply (a point cloud) and bar.vdb."""
    folder = tmp_path_factory.mktemp("demo")
    cli("demo", folder, timeout=300)
    return folder


def _rigs(demo):
    return sorted(p for p in demo.glob("*.json") if p.name != "edit_handles.json")


def _twist(tmp_path, rate):
    rig = tmp_path / f"twist_{rate}.json"
    rig.write_text(json.dumps({"method": "twist", "origin": [0, 0, 0], "axis": [0, 0, 1],
                               "rate": rate}))
    return spacewarp.load_rig(rig)


# ----------------------------------------------------------------------------------------------
# deform_array


def test_every_demo_warp_gives_a_point_the_same_bits_in_any_batch(demo):
    # What deform_array's equality rests on: applyBatch does not depend on where a point sits.
    points = np.random.default_rng(1).uniform(-0.8, 0.8, (5003, 3))
    points[:, 2] *= 2.5
    for rig in _rigs(demo):
        warp = spacewarp.load_rig(rig)
        whole = warp(points)
        cuts = [0, 1, 2, 17, 1024, 4001, 5003]
        parts = np.concatenate([warp(points[a:b]) for a, b in zip(cuts[:-1], cuts[1:])])
        assert np.array_equal(parts, whole, equal_nan=True), rig.name


def test_deform_array_is_bit_identical_for_every_demo_rig(client, demo):
    points = np.random.default_rng(2).uniform(-0.8, 0.8, (20000, 3))
    points[:, 2] *= 2.5
    x = da.from_array(points, chunks=(3001, 3))
    for rig in _rigs(demo):
        warp = spacewarp.load_rig(rig)
        moved = swd.deform_array(warp, x)
        assert isinstance(moved, da.Array) and moved.dtype == np.float64
        assert moved.chunks == x.chunks
        assert np.array_equal(moved.compute(), warp(points), equal_nan=True), rig.name


def test_deform_array_takes_float32_and_column_chunks(client, tmp_path):
    warp = _twist(tmp_path, 1.5)
    points = np.random.default_rng(3).random((10000, 3)).astype(np.float32)
    x = da.from_array(points, chunks=(999, 1))
    moved = swd.deform_array(warp, x)
    assert moved.chunks[1] == (3,)
    assert np.array_equal(moved.compute(), warp(points))


def test_deform_array_refuses_other_shapes_and_dtypes(tmp_path):
    warp = _twist(tmp_path, 1.0)
    with pytest.raises(spacewarp.InvalidInput, match=r"shape \(n, 3\)"):
        swd.deform_array(warp, da.zeros((10, 4), chunks=(5, 4)))
    with pytest.raises(spacewarp.InvalidInput, match="float"):
        swd.deform_array(warp, da.zeros((10, 3), dtype=np.int64, chunks=(5, 3)))
    with pytest.raises(spacewarp.InvalidInput, match="dask.array"):
        swd.deform_array(warp, np.zeros((10, 3)))


def test_the_warp_is_one_key_of_the_graph_not_one_per_chunk(tmp_path):
    warp = _twist(tmp_path, 1.0)
    moved = swd.deform_array(warp, da.zeros((1000, 3), chunks=(10, 3)))
    graph = dict(moved.__dask_graph__())
    holders = [k for k, v in graph.items() if v is warp]
    assert len(holders) == 1 and moved.npartitions == 100


def test_the_warp_is_scattered_once_to_every_worker(client, tmp_path):
    warp = _twist(tmp_path, 1.0)
    future = swd.shipped_warp(warp, client)
    assert len(client.who_has([future])[future.key]) == 2
    x = da.from_array(np.random.default_rng(4).random((3000, 3)), chunks=(100, 3))
    moved = da.map_blocks(swd._warp_block, x, future, dtype=np.float64)
    assert np.array_equal(moved.compute(), warp(x.compute()))


def test_a_nan_in_one_chunk_raises_invalid_input_naming_its_row(client, tmp_path):
    warp = _twist(tmp_path, 1.0)
    points = np.random.default_rng(5).random((10000, 3))
    points[7321, 1] = np.nan
    with pytest.raises(spacewarp.InvalidInput, match=r"points\[7321\] is not finite"):
        swd.deform_array(warp, da.from_array(points, chunks=(1000, 3))).compute()


def test_points_from_npy_and_zarr_are_the_files_rows(client, tmp_path):
    points = np.random.default_rng(6).random((5000, 3))
    np.save(tmp_path / "p.npy", points)
    x = swd.points_from_npy(tmp_path / "p.npy", chunk_rows=777)
    assert x.chunks[0][0] == 777 and np.array_equal(x.compute(), points)
    zarr = pytest.importorskip("zarr")
    zarr.save_array(str(tmp_path / "p.zarr"), points, chunks=(1000, 3))
    z = swd.points_from_zarr(str(tmp_path / "p.zarr"), chunk_rows=1500)
    assert z.chunks[0][0] == 1500 and np.array_equal(z.compute(), points)
    np.save(tmp_path / "bad.npy", points[:, :2])
    with pytest.raises(spacewarp.InvalidInput, match=r"\(n, 3\)"):
        swd.points_from_npy(tmp_path / "bad.npy")


# ----------------------------------------------------------------------------------------------
# deform_ply (on the streaming PLY helpers)

needs_ply_rows = pytest.mark.skipif(
    not all(hasattr(spacewarp, n) for n in ("ply_layout", "deform_ply_rows", "assemble_ply")),
    reason="this build has no streaming PLY helpers (ply_layout, deform_ply_rows, assemble_ply)")


@needs_ply_rows
def test_points_from_ply_reads_the_vertex_rows(client, demo):
    x = swd.points_from_ply(demo / "cloud.ply", chunk_rows=3000)
    assert np.array_equal(x.compute(), spacewarp.read(demo / "cloud.ply").positions)


@needs_ply_rows
def test_deform_ply_equals_the_cli_byte_for_byte(client, cli, demo, tmp_path):
    rig = demo / "mvc.json"
    warp = spacewarp.load_rig(rig)
    cli("deform", "--rig", rig, demo / "cloud.ply", "-o", tmp_path / "cli.ply")
    out = swd.deform_ply(warp, demo / "cloud.ply", tmp_path / "dask.ply", client=client,
                         chunk_rows=3001)
    assert (tmp_path / "dask.ply").read_bytes() == (tmp_path / "cli.ply").read_bytes()
    assert out == str(tmp_path / "dask.ply")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["cli.ply", "dask.ply"]  # no parts left


@needs_ply_rows
def test_deform_ply_parts_folder_and_its_manifest(client, cli, demo, tmp_path):
    rig = demo / "twist.json"
    warp = spacewarp.load_rig(rig)
    manifest = swd.deform_ply(warp, demo / "cloud.ply", client=client, chunk_rows=4096,
                              parts_dir=tmp_path / "parts")
    m = json.loads(open(manifest).read())
    assert m["format"] == "spacewarp-ply-parts" and m["version"] == 1
    assert sum(p["row_count"] for p in m["parts"]) == m["vertex_count"]
    assert [p["first_row"] for p in m["parts"]] == list(range(0, m["vertex_count"], 4096))
    for p in m["parts"]:
        assert os.path.getsize(tmp_path / "parts" / p["file"]) == p["bytes"]
    swd.assemble_parts(tmp_path / "parts", tmp_path / "assembled.ply")
    cli("deform", "--rig", rig, demo / "cloud.ply", "-o", tmp_path / "cli.ply")
    assert (tmp_path / "assembled.ply").read_bytes() == (tmp_path / "cli.ply").read_bytes()


@needs_ply_rows
def test_a_failed_ply_task_leaves_no_output_and_no_parts(client, demo, tmp_path):
    layout = swd._ply_layout(str(demo / "cloud.ply"))
    data = bytearray((demo / "cloud.ply").read_bytes())
    row = 5000
    x_at = layout["offset"] + row * layout["stride"] + layout["dtype"].fields["x"][1]
    data[x_at:x_at + layout["dtype"]["x"].itemsize] = np.array(
        np.nan, dtype=layout["dtype"]["x"]).tobytes()
    (tmp_path / "in.ply").write_bytes(bytes(data))
    warp = _twist(tmp_path, 1.0)
    # The reader refuses the file's NaN (an IoError naming the vertex, as `spacewarp deform`).
    with pytest.raises(spacewarp.IoError, match="vertex 5000"):
        swd.deform_ply(warp, tmp_path / "in.ply", tmp_path / "out.ply", client=client,
                       chunk_rows=1000)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["in.ply", "twist_1.0.json"]


# ----------------------------------------------------------------------------------------------
# warp_volume


@pytest.fixture(scope="module")
def spheres(tmp_path_factory):
    """A sphere of radius 1 on voxels of 1/12: a float level set, a double fog volume and a
    vec3s field, in one file."""
    path = tmp_path_factory.mktemp("volumes") / "spheres.vdb"
    spacewarp._spacewarp._write_sphere_volumes(path, radius=1.0, voxel_size=1.0 / 12,
                                               center=(0.1, -0.05, 0.2), half_width=3.0)
    return path


@pytest.mark.parametrize("rate", [0.3, 4.0])  # smooth, and strongly non-rigid
def test_warp_volume_in_bricks_equals_the_single_process_warp(client, spheres, tmp_path, rate):
    warp = _twist(tmp_path, rate)
    plan = spacewarp.plan_volume_bricks(warp, spheres, brick=16)
    assert len(plan.bricks) > 3 * 12  # many bricks per grid
    single = spacewarp.warp_volume(warp, spheres, tmp_path / "single.vdb")
    bricked = swd.warp_volume(warp, spheres, tmp_path / "bricks.vdb", client=client, brick=16)
    assert _masked(tmp_path / "bricks.vdb") == _masked(tmp_path / "single.vdb")
    swd.warp_volume(warp, spheres, tmp_path / "clipped.vdb", client=client, brick=16, clip=True)
    assert _masked(tmp_path / "clipped.vdb") == _masked(tmp_path / "single.vdb")
    assert [r["grid"] for r in bricked] == ["surface", "density", "velocity"]
    for a, b in zip(single, bricked):
        assert a["output_active_voxels"] == b["output_active_voxels"] > 0
        assert b["mass_after"] == pytest.approx(a["mass_after"], rel=1e-12)
        assert {k: v for k, v in a.items() if k != "mass_after"} == \
               {k: v for k, v in b.items() if k != "mass_after"}


def test_warp_volume_with_a_cage_and_options(client, demo, tmp_path):
    rig = demo / "mvc.json"
    warp = spacewarp.load_rig(rig)
    options = dict(sampler="triquadratic", seed_spacing=2)
    spacewarp.warp_volume(warp, demo / "bar.vdb", tmp_path / "single.vdb", **options)
    swd.warp_volume(warp, demo / "bar.vdb", tmp_path / "bricks.vdb", client=client, brick=16,
                    **options)
    assert _masked(tmp_path / "bricks.vdb") == _masked(tmp_path / "single.vdb")


def test_bricks_whose_preimages_leave_their_input_box_are_redone_whole(tmp_path):
    # Input boxes cut 5 voxels short (past the 4-voxel margin): stencils near their faces leave
    # the clipped read, those bricks are warped again from the whole grid, and the result is
    # still the single-process one.
    small = tmp_path / "small.vdb"
    spacewarp._spacewarp._write_sphere_volumes(small, radius=0.5, voxel_size=1.0 / 16)
    warp = spacewarp.Twist(rate=3.0)
    plan = spacewarp.plan_volume_bricks(warp, small, brick=16)
    cut = [b[:6] + (tuple(c + 5 for c in b[6]), tuple(c - 5 for c in b[7])) + b[8:]
           for b in plan.bricks]
    results = [spacewarp.warp_volume_brick(warp, small, b, clip=True) for b in cut]
    assert any(r.halo_misses > 0 for r in results)
    plan.merge(warp, [pickle.loads(pickle.dumps(r)) for r in results], tmp_path / "bricks.vdb")
    spacewarp.warp_volume(warp, small, tmp_path / "single.vdb")
    assert _masked(tmp_path / "bricks.vdb") == _masked(tmp_path / "single.vdb")


def test_warp_volume_refuses_the_cache_and_writes_nothing_on_errors(client, spheres, tmp_path):
    warp = _twist(tmp_path, 1.0)
    with pytest.raises(spacewarp.InvalidInput, match="cache_spacing"):
        swd.warp_volume(warp, spheres, tmp_path / "out.vdb", cache_spacing=2.0)
    with pytest.raises(spacewarp.IoError, match="missing.vdb"):
        swd.warp_volume(warp, tmp_path / "missing.vdb", tmp_path / "out.vdb", client=client)
    plan = spacewarp.plan_volume_bricks(warp, spheres, brick=32)
    with pytest.raises(spacewarp.InvalidInput, match="results"):
        plan.merge(warp, [], tmp_path / "out.vdb")
    assert not (tmp_path / "out.vdb").exists()


def test_a_failed_brick_raises_in_the_caller_and_writes_nothing(client, spheres, tmp_path,
                                                                monkeypatch):
    # The input vanishes after the plan: every worker's read fails with IoError.
    source = tmp_path / "in.vdb"
    source.write_bytes(spheres.read_bytes())
    plan = swd._ext.plan_volume_bricks

    def plan_then_remove(*args, **kwargs):
        p = plan(*args, **kwargs)
        source.unlink()
        return p

    monkeypatch.setattr(swd._ext, "plan_volume_bricks", plan_then_remove)
    for clip in (False, True):
        with pytest.raises(spacewarp.IoError, match="in.vdb"):
            swd.warp_volume(_twist(tmp_path, 1.0), source, tmp_path / "out.vdb", client=client,
                            clip=clip)
        source.write_bytes(spheres.read_bytes())
    source.unlink()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["twist_1.0.json"]


# ----------------------------------------------------------------------------------------------
# Interruptions and error messages


def test_ctrl_c_while_waiting_on_a_cluster_raises_at_once_and_cancels(client):
    import _thread
    import threading
    import time

    delayed = pytest.importorskip("dask").delayed
    tasks = [delayed(time.sleep, pure=False)(3.0) for _ in range(4)]
    threading.Timer(0.3, _thread.interrupt_main).start()
    start = time.monotonic()
    with pytest.raises(KeyboardInterrupt):
        swd._compute(tasks, client)
    # A blocking gather would hold the interrupt until the 2 x 3 s of sleeps are done.
    assert time.monotonic() - start < 2.0
    # The futures were cancelled: the scheduler forgets their tasks.
    def sleeps(dask_scheduler):
        return sum(str(key).startswith("sleep-") for key in dask_scheduler.tasks)

    deadline = time.monotonic() + 10
    while client.run_on_scheduler(sleeps) and time.monotonic() < deadline:
        time.sleep(0.1)
    assert client.run_on_scheduler(sleeps) == 0


def test_sigterm_during_deform_ply_removes_the_hidden_parts_folder(client, demo, tmp_path,
                                                                   monkeypatch):
    import signal
    import time

    if signal.getsignal(signal.SIGTERM) is not signal.SIG_DFL:
        pytest.skip("SIGTERM has a handler here already (deform_ply leaves it alone)")
    here = os.getpid()
    marker = str(tmp_path / "sent")

    def terminated(warp, input_path, part, first, count):
        try:  # once, whichever worker comes first: a late one would find the default restored
            os.close(os.open(marker, os.O_CREAT | os.O_EXCL))
            os.kill(here, signal.SIGTERM)
        except FileExistsError:
            pass
        time.sleep(0.5)
        return part

    # The tasks (pickled by value, closure and all) signal the caller, whose main thread waits.
    monkeypatch.setattr(swd, "_deform_rows", terminated)
    with pytest.raises(SystemExit) as raised:
        swd.deform_ply(_twist(tmp_path, 1.0), demo / "cloud.ply", tmp_path / "out.ply",
                       client=client, chunk_rows=1000)
    assert raised.value.code == 128 + signal.SIGTERM
    assert sorted(p.name for p in tmp_path.iterdir()) == ["sent", "twist_1.0.json"]
    assert signal.getsignal(signal.SIGTERM) is signal.SIG_DFL


@needs_ply_rows
def test_a_missing_output_folder_is_an_io_error_naming_the_output(demo, spheres, tmp_path,
                                                                 monkeypatch):
    warp = _twist(tmp_path, 1.0)
    out = tmp_path / "nodir" / "x.ply"
    with pytest.raises(spacewarp.IoError, match=f"cannot write '{re.escape(str(out))}'.*No such"):
        swd.deform_ply(warp, demo / "cloud.ply", out)

    def no_plan(*args, **kwargs):
        raise AssertionError("the bricks were planned before the output was checked")

    monkeypatch.setattr(swd._ext, "plan_volume_bricks", no_plan)
    out = tmp_path / "nodir" / "x.vdb"
    with pytest.raises(spacewarp.IoError, match=f"cannot write '{re.escape(str(out))}'.*No such"):
        swd.warp_volume(warp, spheres, out)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["twist_1.0.json"]


def test_a_truncated_npy_and_a_missing_zarr_are_io_errors_naming_them(tmp_path):
    np.save(tmp_path / "p.npy", np.zeros((100, 3)))
    data = (tmp_path / "p.npy").read_bytes()
    (tmp_path / "short.npy").write_bytes(data[:-8])
    with pytest.raises(spacewarp.IoError, match="short.npy: truncated"):
        swd.points_from_npy(tmp_path / "short.npy")
    assert swd.points_from_npy(tmp_path / "p.npy").shape == (100, 3)
    pytest.importorskip("zarr")
    with pytest.raises(spacewarp.IoError, match="nothing.zarr"):
        swd.points_from_zarr(str(tmp_path / "nothing.zarr"))


def test_a_nan_message_is_short_and_names_no_unknown_rows(client, tmp_path):
    warp = _twist(tmp_path, 1.0)
    points = np.random.default_rng(8).random((100, 3))
    points[42, 0] = np.nan
    x = da.from_array(points, chunks=(10, 3))
    # Boolean indexing: the chunk sizes become unknown (nan).
    kept = x[da.from_array(np.arange(100) % 2 == 0, chunks=10)]
    assert np.isnan(kept.shape[0])
    with pytest.raises(spacewarp.InvalidInput, match="not finite") as raised:
        swd.deform_array(warp, kept).compute()
    assert "nan" not in str(raised.value)
    with pytest.raises(spacewarp.InvalidInput) as raised:
        swd.deform_array(warp, x, client=client).compute()
    # The worker logs the exception's repr: the message alone, no chunk, no chained traceback.
    assert repr(raised.value) == "InvalidInput('points[42] is not finite (chunk of rows 40..49)')"
    assert raised.value.__cause__ is None and raised.value.__suppress_context__
