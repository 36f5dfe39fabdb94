"""Volumes from Python (python/src/volume.cpp): warp_volume() against `spacewarp deform` on the
demo's level set, and warp_dense() on dense NumPy blocks.

Skipped when the package has no volumes (spacewarp.has_volumes). A VDB file holds a random UUID,
so files are compared byte for byte with that UUID blanked out, and through `spacewarp info`.
"""

from __future__ import annotations

import json
import re
import subprocess
import sys

import numpy as np
import pytest

spacewarp = pytest.importorskip("spacewarp")
if not spacewarp.has_volumes:
    pytest.skip("this build has no volumes (SPACEWARP_WITH_OPENVDB off)", allow_module_level=True)

REPORT_KEYS = {"grid", "type", "input_active_voxels", "output_active_voxels", "solved_voxels",
               "inverse_failures", "unmapped_voxels", "max_newton_iterations", "mass_before",
               "mass_after", "redistanced", "cache_error", "vectors", "vector_failures", "points"}

_UUID = re.compile(rb"[0-9a-f]{8}-[0-9a-f]{4}-[0-9a-f]{4}-[0-9a-f]{4}-[0-9a-f]{12}")


@pytest.fixture
def volumes(volume_crash):
    """Skips a test that would call the volume functions in this process when they crash."""
    if volume_crash:
        pytest.skip(volume_crash.splitlines()[0]
                    + " (see test_volume_functions_run_in_a_fresh_interpreter)")


def test_volume_functions_run_in_a_fresh_interpreter(tmp_path):
    # They once crashed the interpreter (SIGSEGV in openvdb::initialize(): the extension's
    # copies of OpenVDB's template statics took libopenvdb's place); in a child process.
    script = ("import numpy as np, spacewarp\n"
              "out, origin = spacewarp.warp_dense(spacewarp.Identity(), np.ones((2, 2, 2)))\n"
              "assert out.shape == (2, 2, 2)\n"
              "try:\n"
              f"    spacewarp.warp_volume(spacewarp.Identity(), {str(tmp_path / 'no.vdb')!r},\n"
              f"                          {str(tmp_path / 'out.vdb')!r})\n"
              "except spacewarp.IoError as e:\n"
              "    print('IoError', e)\n")
    result = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True,
                            timeout=120)
    assert result.returncode == 0, f"exit code {result.returncode}: {result.stderr[-1000:]}"
    assert "IoError" in result.stdout and "no.vdb" in result.stdout


# ----------------------------------------------------------------------------------------------
# warp_volume against the command line


@pytest.fixture(scope="module")
def demo(cli, volume_crash, tmp_path_factory):
    """The CLI demo's folder: bar.vdb (a level set) and the rigs (twist.json, ...)."""
    if volume_crash:  # no use making it (the demo takes seconds)
        pytest.skip(volume_crash.splitlines()[0])
    folder = tmp_path_factory.mktemp("demo")
    cli("demo", folder, timeout=300)
    if not (folder / "bar.vdb").is_file():
        pytest.skip("the demo wrote no bar.vdb")
    return folder


def _masked(path) -> bytes:
    """The file's bytes with the UUID of its header blanked out."""
    data = path.read_bytes()
    match = _UUID.search(data[:512])
    assert match, f"no UUID in the header of {path}"
    return data[:match.start()] + b"-" * 36 + data[match.end():]


def _info(cli, path) -> list[str]:
    """`spacewarp info` of a VDB file, without its file line."""
    lines = cli("info", path).stdout.splitlines()
    return [line for line in lines if not line.startswith("file:")]


def _active_voxels(info_lines: list[str]) -> int:
    for line in info_lines:
        if "active voxels:" in line:
            return int(line.split(":")[1].strip().replace(",", ""))
    raise AssertionError("no active voxel count in: " + "\n".join(info_lines))


def _same_report(a: dict, b: dict) -> bool:
    return a.keys() == b.keys() and all(
        (a[k] == b[k]) or (isinstance(a[k], float) and np.isnan(a[k]) and np.isnan(b[k]))
        for k in a)


def _rig(demo, name: str):
    """A rig file of the demo, or one written next to it."""
    if name == "translate":
        path = demo / "translate.json"
        if not path.exists():
            path.write_text(json.dumps({"method": "affine", "matrix": [
                [1, 0, 0, 0.3], [0, 1, 0, -0.2], [0, 0, 1, 0.12], [0, 0, 0, 1]]}))
        return path
    return demo / f"{name}.json"


@pytest.mark.parametrize("rig_name", ["twist", "translate", "bend", "mvc", "ffd"])
def test_warp_volume_equals_the_cli(volumes, cli, demo, tmp_path, rig_name):
    rig = _rig(demo, rig_name)
    ours, theirs = tmp_path / "ours.vdb", tmp_path / "theirs.vdb"
    reports = spacewarp.warp_volume(spacewarp.load_rig(rig), demo / "bar.vdb", ours)
    cli("deform", "--rig", rig, demo / "bar.vdb", "-o", theirs)
    assert ours.stat().st_size == theirs.stat().st_size
    assert _masked(ours) == _masked(theirs)
    assert _info(cli, ours) == _info(cli, theirs)
    # the report describes what was read and written
    assert isinstance(reports, list) and len(reports) == 1
    report = reports[0]
    assert set(report) == REPORT_KEYS
    assert report["grid"] == "surface"
    assert "float" in report["type"]
    assert report["input_active_voxels"] == _active_voxels(_info(cli, demo / "bar.vdb"))
    assert report["output_active_voxels"] == _active_voxels(_info(cli, theirs))
    assert report["output_active_voxels"] > 0
    assert report["inverse_failures"] >= 0 and report["unmapped_voxels"] >= 0


def test_warp_volume_options_equal_the_cli_flags(volumes, cli, demo, tmp_path):
    rig = _rig(demo, "twist")
    ours, theirs = tmp_path / "ours.vdb", tmp_path / "theirs.vdb"
    spacewarp.warp_volume(spacewarp.load_rig(rig), demo / "bar.vdb", ours,
                          sampler="triquadratic")
    cli("deform", "--rig", rig, demo / "bar.vdb", "-o", theirs, "--sampler", "triquadratic")
    assert _masked(ours) == _masked(theirs)
    # and the option changes something
    default = tmp_path / "default.vdb"
    spacewarp.warp_volume(spacewarp.load_rig(rig), demo / "bar.vdb", default)
    assert _masked(default) != _masked(ours)


def test_warp_volume_onto_its_input(volumes, demo, tmp_path):
    import shutil

    source = tmp_path / "bar.vdb"
    shutil.copyfile(demo / "bar.vdb", source)
    warp = spacewarp.Twist(rate=0.4)
    spacewarp.warp_volume(warp, source, tmp_path / "separate.vdb")
    spacewarp.warp_volume(warp, source, source)
    assert _masked(source) == _masked(tmp_path / "separate.vdb")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["bar.vdb", "separate.vdb"]


def test_rewarping_the_outputs_gives_the_same_file(volumes, cli, demo, tmp_path):
    rig = _rig(demo, "twist")
    ours, theirs = tmp_path / "ours.vdb", tmp_path / "theirs.vdb"
    spacewarp.warp_volume(spacewarp.load_rig(rig), demo / "bar.vdb", ours)
    cli("deform", "--rig", rig, demo / "bar.vdb", "-o", theirs)
    again_ours, again_theirs = tmp_path / "again_ours.vdb", tmp_path / "again_theirs.vdb"
    warp = spacewarp.Twist(rate=-0.3)
    first = spacewarp.warp_volume(warp, ours, again_ours)
    second = spacewarp.warp_volume(warp, theirs, again_theirs)
    assert len(first) == len(second) == 1 and _same_report(first[0], second[0])
    assert first[0]["input_active_voxels"] == _active_voxels(_info(cli, theirs))
    assert _masked(again_ours) == _masked(again_theirs)


def test_warp_volume_options_are_checked(volumes, demo, tmp_path):
    with pytest.raises(spacewarp.InvalidInput, match="sampler"):
        spacewarp.warp_volume(spacewarp.Identity(), demo / "bar.vdb", tmp_path / "o.vdb",
                              sampler="cubic")
    with pytest.raises(spacewarp.InvalidInput, match="redistance"):
        spacewarp.warp_volume(spacewarp.Identity(), demo / "bar.vdb", tmp_path / "o.vdb",
                              redistance="never")
    assert list(tmp_path.iterdir()) == []


def test_warp_volume_file_errors_write_nothing(volumes, demo, tmp_path):
    with pytest.raises(spacewarp.IoError, match="missing.vdb"):
        spacewarp.warp_volume(spacewarp.Identity(), tmp_path / "missing.vdb", tmp_path / "o.vdb")
    not_vdb = tmp_path / "bar.obj"
    not_vdb.write_bytes((demo / "bar.obj").read_bytes()[:1000])
    with pytest.raises(spacewarp.IoError, match="bar.obj"):
        spacewarp.warp_volume(spacewarp.Identity(), not_vdb, tmp_path / "o.vdb")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["bar.obj"]


def test_warp_volume_cancelled_writes_nothing(volumes, demo, tmp_path):
    calls = []

    def stop(stage, fraction):
        calls.append((stage, fraction))
        return False

    with pytest.raises(spacewarp.Cancelled):
        spacewarp.warp_volume(spacewarp.Twist(rate=0.5), demo / "bar.vdb", tmp_path / "o.vdb",
                              progress=stop)
    assert calls
    assert list(tmp_path.iterdir()) == []


# ----------------------------------------------------------------------------------------------
# warp_dense

H = 0.1
ORIGIN = np.array([-1.15, -1.05, -0.95])


def _ball(shape=(24, 22, 20), center=(0.05, -0.12, 0.2), radius=0.55, band=0.3):
    """Signed distances to a sphere on the grid origin + H (i, j, k), clipped to +-band."""
    index = np.indices(shape).transpose(1, 2, 3, 0)
    x = ORIGIN + H * index
    return np.clip(np.linalg.norm(x - center, axis=-1) - radius, -band, band)


def _active_min(values: np.ndarray, background: float) -> np.ndarray:
    return np.array([axis.min() for axis in np.nonzero(values != background)])


def test_dense_identity_keeps_a_full_block(volumes):
    values = np.random.default_rng(3).uniform(1.0, 2.0, size=(5, 7, 9))
    out, origin = spacewarp.warp_dense(spacewarp.Identity(), values, voxel_size=0.5,
                                       origin=(1.0, 2.0, 3.0))
    assert out.shape == values.shape and out.dtype == np.float64
    assert np.array_equal(origin, [1.0, 2.0, 3.0])
    np.testing.assert_allclose(out, values, rtol=0, atol=1e-12)


def test_dense_voxel_position(volumes):
    values = np.zeros((4, 5, 6))
    values[1, 2, 3] = 5.0
    out, origin = spacewarp.warp_dense(spacewarp.Identity(), values, voxel_size=0.5,
                                       origin=(10.0, 20.0, 30.0))
    assert out.shape == (1, 1, 1) and out[0, 0, 0] == 5.0
    assert np.array_equal(origin, [10.5, 21.0, 31.5])


def test_dense_identity_keeps_a_ball(volumes):
    band = 0.3
    values = _ball(band=band)
    out, origin = spacewarp.warp_dense(spacewarp.Identity(), values, voxel_size=H, origin=ORIGIN,
                                       background=band)
    start = _active_min(values, band)
    np.testing.assert_allclose(origin, ORIGIN + H * start, rtol=0, atol=1e-14)
    block = values[tuple(slice(s, s + n) for s, n in zip(start, out.shape))]
    active = out != band
    assert active.sum() == (values != band).sum()
    np.testing.assert_allclose(out[active], block[active], rtol=0, atol=1e-12)


def test_dense_values_near_the_background_stay_active(volumes):
    values = np.full((4, 4, 4), 0.5)
    out, origin = spacewarp.warp_dense(spacewarp.Identity(), values, background=0.3)
    assert out.shape == (4, 4, 4)
    np.testing.assert_allclose(out, values, rtol=0, atol=1e-12)


def test_dense_translation_by_whole_voxels_shifts_the_origin(volumes):
    band = 0.3
    values = _ball(band=band)
    rest, rest_origin = spacewarp.warp_dense(spacewarp.Identity(), values, voxel_size=H,
                                             origin=ORIGIN, background=band)
    steps = np.array([3, -2, 5])
    matrix = np.eye(4)
    matrix[:3, 3] = H * steps
    moved, moved_origin = spacewarp.warp_dense(spacewarp.Affine(matrix), values, voxel_size=H,
                                               origin=ORIGIN, background=band)
    assert moved.shape == rest.shape
    np.testing.assert_allclose(moved, rest, rtol=0, atol=1e-12)
    # the origin moves by the translation, to rounding (the grid's transform computes it)
    np.testing.assert_allclose(moved_origin - rest_origin, H * steps, rtol=0, atol=1e-14)
    # and stays on the input's voxel lattice: ORIGIN + H * an integer index
    index = (moved_origin - ORIGIN) / H
    np.testing.assert_allclose(index, np.rint(index), rtol=0, atol=1e-12)


def test_dense_float32_stays_float32(volumes):
    values = _ball().astype(np.float32)
    out, _ = spacewarp.warp_dense(spacewarp.Identity(), values, voxel_size=H, origin=ORIGIN,
                                  background=0.3)
    assert out.dtype == np.float32
    out64, _ = spacewarp.warp_dense(spacewarp.Identity(), _ball().astype(np.int32) + 1.0)
    assert out64.dtype == np.float64


def test_dense_level_set_identity_keeps_the_surface(volumes):
    values = _ball(shape=(22, 20, 18), center=(-0.1, 0.05, -0.1), radius=0.45, band=0.3)
    out, origin = spacewarp.warp_dense(spacewarp.Identity(), values, voxel_size=H, origin=ORIGIN,
                                       background=0.3, level_set=True)
    # same inside/outside classification where the output is near the surface
    index = np.rint((origin - ORIGIN) / H).astype(int)
    block = values[tuple(slice(s, s + n) for s, n in zip(index, out.shape))]
    near = np.abs(out) < 0.15
    assert near.any()
    np.testing.assert_allclose(out[near], block[near], rtol=0, atol=0.02)


def test_dense_input_is_checked(volumes):
    with pytest.raises(spacewarp.InvalidInput, match="3-dimensional"):
        spacewarp.warp_dense(spacewarp.Identity(), np.ones((4, 4)))
    with pytest.raises(spacewarp.InvalidInput, match="voxel_size"):
        spacewarp.warp_dense(spacewarp.Identity(), np.ones((2, 2, 2)), voxel_size=0.0)
    with pytest.raises(spacewarp.InvalidInput, match="sampler"):
        spacewarp.warp_dense(spacewarp.Identity(), np.ones((2, 2, 2)), sampler="nearest")


def test_dense_progress_and_cancel(volumes):
    seen = []
    spacewarp.warp_dense(spacewarp.Twist(rate=0.3), _ball(), voxel_size=H, origin=ORIGIN,
                         background=0.3, progress=lambda s, f: seen.append((s, f)))
    assert seen and all(isinstance(s, str) and 0.0 <= f <= 1.0 for s, f in seen)
    with pytest.raises(spacewarp.Cancelled):
        spacewarp.warp_dense(spacewarp.Twist(rate=0.3), _ball(), voxel_size=H, origin=ORIGIN,
                             background=0.3, progress=lambda s, f: False)


def _sphere_distance(origin, shape, center, radius):
    index = np.indices(shape).transpose(1, 2, 3, 0)
    return np.linalg.norm(origin + H * index - center, axis=-1) - radius


@pytest.mark.parametrize("case", ["twist_about_the_center", "translate"])
def test_dense_level_set_follows_the_warp(volumes, case):
    center, radius = np.array([0.05, -0.05, 0.1]), 0.5
    values = _ball(shape=(22, 22, 22), center=center, radius=radius, band=0.3)
    if case == "twist_about_the_center":
        # a twist about an axis through the center maps the sphere onto itself
        warp, moved_center = spacewarp.Twist(origin=center, axis=(0, 0, 1), rate=1.2), center
    else:
        shift = np.array([0.13, -0.07, 0.21])
        matrix = np.eye(4)
        matrix[:3, 3] = shift
        warp, moved_center = spacewarp.Affine(matrix), center + shift
    out, origin = spacewarp.warp_dense(warp, values, voxel_size=H, origin=ORIGIN,
                                       background=0.3, level_set=True)
    exact = _sphere_distance(origin, out.shape, moved_center, radius)
    near = np.abs(exact) < 0.12
    assert near.sum() > 100
    np.testing.assert_allclose(out[near], exact[near], rtol=0, atol=0.02)


def test_dense_fog_mass(volumes):
    index = np.indices((22, 22, 22)).transpose(1, 2, 3, 0)
    distance = np.linalg.norm(ORIGIN + H * index - [0.05, -0.05, 0.1], axis=-1)
    fog = np.clip(1.0 - (distance - 0.4) / 0.2, 0.0, 1.0)  # a soft ball of density 1
    matrix = np.diag([1.5, 1.2, 0.8, 1.0])  # det 1.44
    kept, _ = spacewarp.warp_dense(spacewarp.Affine(matrix), fog, voxel_size=H, origin=ORIGIN,
                                   conserve_mass=True)
    scaled, _ = spacewarp.warp_dense(spacewarp.Affine(matrix), fog, voxel_size=H, origin=ORIGIN)
    # resampling a coarse soft ball costs a few percent either way
    assert kept.sum() == pytest.approx(fog.sum(), rel=0.05)
    assert scaled.sum() == pytest.approx(1.44 * fog.sum(), rel=0.05)


# ----------------------------------------------------------------------------------------------
# Ctrl-C while warp_volume writes (the demo's bar.vdb is already here)


def test_sigint_during_warp_volume_leaves_no_file(volumes, demo, tmp_path):
    from conftest import CAGE_SCRIPT, STARTED_PROGRESS, interrupt_child

    out = tmp_path / "out"
    out.mkdir()
    script = CAGE_SCRIPT.replace("size=(2_000_000, 3)", "size=(10, 3)") + f"""
vertices, faces = subdivided_cube(8)  # a slower warp: seconds for the demo's 72k voxels
warp = spacewarp.MeanValue(spacewarp.Cage(vertices, faces)).warp(vertices * 1.1)
""" + STARTED_PROGRESS + f"""
try:
    spacewarp.warp_volume(warp, {str(demo / 'bar.vdb')!r}, {str(out / 'out.vdb')!r},
                          progress=progress)
    print("finished", flush=True)
except KeyboardInterrupt:
    print("KeyboardInterrupt", flush=True)
"""
    line, elapsed, code = interrupt_child(script, pause=0.3)
    assert line == "KeyboardInterrupt", f"child said {line!r} after the signal"
    assert elapsed < 2.5 and code == 0
    assert list(out.iterdir()) == []  # neither out.vdb nor a temporary file


# ----------------------------------------------------------------------------------------------
# A fog volume and a velocity field (written by pyopenvdb in a child process, so that this one
# never imports it: spacewarp must be imported first)

_FIELDS_SCRIPT = """
import sys
import numpy as np
import pyopenvdb as vdb
n, h = 24, 0.05
x = (np.indices((n, n, n)).transpose(1, 2, 3, 0) - n / 2) * h
r = np.linalg.norm(x, axis=-1)
fog = vdb.FloatGrid()
fog.copyFromArray(np.clip(1.0 - (r - 0.3) / 0.2, 0.0, 1.0).astype(np.float32),
                  ijk=(-12, -12, -12))
fog.transform = vdb.createLinearTransform(voxelSize=h)
fog.name = "density"
fog.gridClass = vdb.GridClass.FOG_VOLUME
field = np.zeros((n, n, n, 3), np.float32)
field[..., 0], field[..., 1], field[..., 2] = -x[..., 1], x[..., 0], 0.5
field[r > 0.5] = 0
velocity = vdb.Vec3SGrid()
velocity.copyFromArray(field, ijk=(-12, -12, -12))
velocity.transform = vdb.createLinearTransform(voxelSize=h)
velocity.name = "velocity"
velocity.vectorType = vdb.VectorType.CONTRAVARIANT_RELATIVE
vdb.write(sys.argv[1], grids=[fog, velocity])
mask = vdb.BoolGrid()
mask.copyFromArray(np.ones((4, 4, 4), bool))
mask.name = "mask"
vdb.write(sys.argv[1].replace("fields.vdb", "mask.vdb"), grids=[mask])
vdb.write(sys.argv[1].replace("fields.vdb", "mixed.vdb"), grids=[mask, fog])
"""

_AFFINE_RIG = {"method": "affine", "matrix": [[1.3, 0.2, 0, 0.1], [0, 0.9, 0.1, 0],
                                              [0, 0, 1.1, -0.05], [0, 0, 0, 1]]}  # det 1.287


@pytest.fixture(scope="module")
def fields(volume_crash, tmp_path_factory):
    """fields.vdb: a fog volume 'density' and a vec3s grid 'velocity'; next to it mask.vdb (a
    bool grid 'mask') and mixed.vdb ('mask' and 'density')."""
    if volume_crash:
        pytest.skip(volume_crash.splitlines()[0])
    path = tmp_path_factory.mktemp("fields") / "fields.vdb"
    result = subprocess.run([sys.executable, "-c", _FIELDS_SCRIPT, str(path)],
                            capture_output=True, text=True, timeout=120)
    if result.returncode != 0:
        pytest.skip("pyopenvdb could not write a test volume: "
                    + (result.stderr.strip().splitlines() or ["?"])[-1])
    return path


@pytest.mark.parametrize("options,flags,vectors", [
    ({}, [], "J v"),
    ({"conserve_mass": True}, ["--conserve-mass"], "J v"),
    ({"vectors": "normal"}, ["--vectors", "normal"], "J^-T v, length kept"),
    ({"vectors": "keep"}, ["--vectors", "keep"], "unchanged"),
    ({"sampler": "triquadratic"}, ["--sampler", "triquadratic"], "J v"),
], ids=["default", "conserve_mass", "normal", "keep", "triquadratic"])
def test_fog_and_vector_grids_equal_the_cli(cli, fields, tmp_path, options, flags, vectors):
    rig = tmp_path / "affine.json"
    rig.write_text(json.dumps(_AFFINE_RIG))
    ours, theirs = tmp_path / "ours.vdb", tmp_path / "theirs.vdb"
    reports = spacewarp.warp_volume(spacewarp.load_rig(rig), fields, ours, **options)
    cli("deform", "--rig", rig, fields, "-o", theirs, *flags)
    assert _masked(ours) == _masked(theirs)
    density, velocity = reports
    assert (density["grid"], velocity["grid"]) == ("density", "velocity")
    assert "vec3s" in velocity["type"] and velocity["vectors"] == vectors
    assert velocity["vector_failures"] == 0
    # the fog's total follows det J = 1.287, or is kept
    expected = density["mass_before"] * (1.0 if options.get("conserve_mass") else 1.287)
    assert density["mass_after"] == pytest.approx(expected, rel=0.02)


def test_unsupported_grids_are_left_out_with_a_warning(fields, tmp_path):
    with pytest.warns(UserWarning, match="grid 'mask' of type .* is not supported and is left out"):
        reports = spacewarp.warp_volume(spacewarp.Identity(), fields.parent / "mixed.vdb",
                                        tmp_path / "out.vdb")
    assert [r["grid"] for r in reports] == ["density"]
    with pytest.raises(spacewarp.InvalidInput, match="no supported grid"):
        spacewarp.warp_volume(spacewarp.Identity(), fields.parent / "mask.vdb",
                              tmp_path / "none.vdb")
    assert [p.name for p in tmp_path.iterdir()] == ["out.vdb"]
