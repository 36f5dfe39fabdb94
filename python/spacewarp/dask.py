"""spacewarp past one machine: warps applied by Dask workers, with single-machine results.

Every function here is plain Python over the bindings; the numbers come from the same C++ code
as ``warp(points)``, ``spacewarp deform`` and :func:`spacewarp.warp_volume`, so the results are
the same bits:

* :func:`deform_array` -- a lazy ``dask.array`` ``(n, 3)`` float64 whose chunks are
  ``warp(chunk)``: bit-identical to ``warp(np.asarray(points))``. Sources of such arrays:
  :func:`points_from_npy` (memory-mapped ``.npy``), :func:`points_from_zarr` and
  :func:`points_from_ply` (the vertex rows of a PLY file, read by byte range).
* :func:`deform_ply` -- a PLY file warped in row ranges on the workers, assembled into one file
  byte-identical to ``spacewarp deform`` (or left as a folder of parts with a manifest).
* :func:`warp_volume` -- a VDB file warped brick by brick on the workers and merged on the
  caller, equal to :func:`spacewarp.warp_volume` (same active voxels, the same values bit for
  bit; see its docstring).

What is shipped to the workers: the warp, pickled once per call (``pickle.dumps(warp)``; a
single graph key that each worker fetches once, or ``client.scatter(..., broadcast=True)`` when
a ``client`` is given), and small tuples (row ranges, brick boxes and their seeding cells). Data
is not shipped: workers read the input files themselves, so :func:`deform_ply` and
:func:`warp_volume` assume a file system shared by the caller and every worker (the same paths;
relative paths are made absolute on the caller). Results come back as arrays (deform_array),
files on that file system (deform_ply's parts) or bytes of OpenVDB grids (warp_volume's bricks).

Errors raised on a worker (``spacewarp.InvalidInput`` for NaN coordinates, ...) are raised in the
caller with their type; a failed call leaves no output file and no temporary behind.

Needs ``dask`` (and ``distributed`` for clusters): Debian's python3-dask, python3-distributed.
"""

from __future__ import annotations

import contextlib
import json
import math
import os
import shutil
import signal
import tempfile
import threading
from pathlib import Path
from typing import Any, Sequence

import numpy as np

import dask
import dask.array as da

from . import _spacewarp as _ext

__all__ = ["deform_array", "deform_ply", "warp_volume", "points_from_npy", "points_from_zarr",
           "points_from_ply", "assemble_parts", "shipped_warp", "DEFAULT_CHUNK_ROWS",
           "PARTS_MANIFEST"]

#: Rows per chunk when a function makes the chunks itself: 2^20 points (24 MiB of float64 xyz).
DEFAULT_CHUNK_ROWS = 1 << 20

#: The manifest of a parts folder (deform_ply with parts_dir=): see :func:`deform_ply`.
PARTS_MANIFEST = "manifest.json"


# ----------------------------------------------------------------------------------------------
# The warp on the workers


def shipped_warp(warp, client=None):
    """What the tasks of one call take as the warp: shipped once, not once per task.

    With a ``distributed.Client``, ``client.scatter(warp, broadcast=True)`` (a future: every
    worker holds one copy before any task runs); without one, ``dask.delayed(warp)``: one key of
    the graph, pickled once into it, which a worker fetches once and keeps for all its tasks.
    The warp must pickle (every ``spacewarp.Warp`` does).
    """
    if client is not None:
        return client.scatter(warp, broadcast=True, hash=False)
    return dask.delayed(warp, pure=False, traverse=False)


#: Seconds between the caller's looks at a cluster's futures: how late a Ctrl-C may take effect
#: (a blocking gather would hold it until every task is done).
_WAIT_SLICE = 0.5


def _compute(tasks: Sequence[Any], client=None) -> list:
    if client is None:
        return list(dask.compute(*tasks))
    from distributed import wait

    futures = client.compute(list(tasks))
    try:
        pending = futures
        while pending and not any(f.status == "error" for f in futures):
            try:
                wait(pending, timeout=_WAIT_SLICE, return_when="FIRST_COMPLETED")
            except TimeoutError:
                pass
            pending = [f for f in pending if f.status == "pending"]
        return client.gather(futures)
    except BaseException:
        # Interrupted or failed: the other tasks would go on writing parts and burning workers.
        client.cancel(futures)
        raise


def _raise_system_exit(signum, frame):
    raise SystemExit(128 + signum)


@contextlib.contextmanager
def _sigterm_raises():
    """While a call has temporaries on disk: SIGTERM raises SystemExit(143) so that they are
    removed (Python's default for SIGTERM ends the process at once, with no cleanup). Only in
    the main thread (signal handlers can be set nowhere else) and only where SIGTERM has its
    default action (a handler of the application's stays in charge); restored on return."""
    if (threading.current_thread() is not threading.main_thread()
            or signal.getsignal(signal.SIGTERM) is not signal.SIG_DFL):
        yield
        return
    signal.signal(signal.SIGTERM, _raise_system_exit)
    try:
        yield
    finally:
        signal.signal(signal.SIGTERM, signal.SIG_DFL)


def _cannot_write(path: Path, reason: str) -> _ext.IoError:
    return _ext.IoError(f"cannot write '{path}': {reason}")


def _check_output_folder(path: Path) -> None:
    """An output's folder must exist and be writable: told before any work is done."""
    if not path.parent.is_dir():
        raise _cannot_write(path, f"no folder '{path.parent}' (No such file or directory)")
    if not os.access(path.parent, os.W_OK | os.X_OK):
        raise _cannot_write(path, f"folder '{path.parent}' is not writable (Permission denied)")


# ----------------------------------------------------------------------------------------------
# Arrays of points


def _rows_of(block_info) -> tuple[int, int]:
    return tuple(block_info[0]["array-location"][0]) if block_info else (0, 0)


def _warp_block(block: np.ndarray, warp, block_info=None) -> np.ndarray:
    points = np.ascontiguousarray(block, dtype=np.float64)
    try:
        return warp(points)
    except _ext.InvalidInput as e:
        # Name the row of the whole array, not of the chunk.
        first, last = _rows_of(block_info)
        bad = np.flatnonzero(~np.isfinite(points).all(axis=1))
        if bad.size and (math.isnan(first) or math.isnan(last)):
            # Unknown chunk sizes (e.g. after boolean indexing): the array's row is unknown.
            raise _ext.InvalidInput(f"row {int(bad[0])} of a chunk of {len(points)} points is not "
                                    "finite (the chunk's rows in the array are unknown)") from None
        if bad.size:
            raise _ext.InvalidInput(f"points[{first + int(bad[0])}] is not finite (chunk of rows "
                                    f"{first}..{last - 1})") from None
        raise _ext.InvalidInput(f"rows {first}..{last - 1} of the array: {e}") from None


def deform_array(warp, points, *, client=None):
    """``warp`` applied to a dask array of points, chunk by chunk, lazily.

    points: dask.array ``(n, 3)`` of any float dtype (world units), chunked by rows (column
    chunks are merged into one: ``rechunk({1: 3})``). Returns a lazy dask.array ``(n, 3)``
    float64 with the same row chunks, each ``warp(chunk)`` computed on a worker; it is
    bit-identical to ``warp(np.asarray(points))``, since every warp gives a point the same bits
    wherever it sits in a batch. The warp is shipped once (see :func:`shipped_warp`; with a
    ``distributed.Client`` as ``client``, scattered to every worker). Raises
    spacewarp.InvalidInput (ValueError) for another shape or dtype at once, and when computed,
    for non-finite points, naming the rows of their chunk.
    """
    if not isinstance(points, da.Array):
        raise _ext.InvalidInput("points must be a dask.array (use dask.array.from_array), not "
                                + type(points).__name__)
    if points.ndim != 2 or points.shape[1] != 3:
        raise _ext.InvalidInput(f"points must have shape (n, 3), not {points.shape}")
    if not np.issubdtype(points.dtype, np.floating):
        raise _ext.InvalidInput(f"points must have a float dtype, not {points.dtype}")
    if len(points.chunks[1]) != 1:
        points = points.rechunk({1: 3})
    return da.map_blocks(_warp_block, points, shipped_warp(warp, client), dtype=np.float64,
                         chunks=points.chunks, meta=np.empty((0, 3), np.float64))


def _row_ranges(count: int, chunk_rows: int) -> list[tuple[int, int]]:
    if int(chunk_rows) < 1:
        raise _ext.InvalidInput(f"chunk_rows must be >= 1, not {chunk_rows}")
    chunk_rows = int(chunk_rows)
    return [(s, min(s + chunk_rows, count)) for s in range(0, count, chunk_rows)]


def _memmap_rows(path: str, offset: int, dtype, shape: tuple, first: int, last: int,
                 columns) -> np.ndarray:
    rows = np.memmap(path, dtype=dtype, mode="r", offset=offset, shape=shape)[first:last]
    if columns is not None:
        rows = np.stack([rows[c] for c in columns], axis=1)
    return np.array(rows, dtype=np.float64 if columns is not None else rows.dtype)


def _from_ranges(path: str, offset: int, dtype, shape: tuple, ranges, columns, out_dtype):
    parts = [da.from_delayed(dask.delayed(_memmap_rows, pure=True)(path, offset, dtype, shape,
                                                                   a, b, columns),
                             shape=(b - a, 3), dtype=out_dtype) for a, b in ranges]
    if not parts:
        return da.zeros((0, 3), dtype=out_dtype, chunks=(0, 3))
    return da.concatenate(parts, axis=0)


def points_from_npy(path, *, chunk_rows: int = DEFAULT_CHUNK_ROWS):
    """An ``(n, 3)`` ``.npy`` file as a dask array, memory-mapped by each task (no full read).

    The file must hold a C-ordered float array of shape (n, 3); its dtype is kept. Raises
    spacewarp.InvalidInput for another shape or layout, spacewarp.IoError if unreadable.
    """
    path = os.path.abspath(path)
    try:
        with open(path, "rb") as f:
            version = np.lib.format.read_magic(f)
            shape, fortran, dtype = np.lib.format._read_array_header(f, version)
            offset = f.tell()
    except (OSError, ValueError) as e:
        raise _ext.IoError(f"{path}: not a readable .npy file ({e})") from None
    if len(shape) != 2 or shape[1] != 3 or fortran or not np.issubdtype(dtype, np.floating):
        raise _ext.InvalidInput(f"{path}: expected a C-ordered float (n, 3) array, found "
                                f"{dtype} {shape}{' (Fortran order)' if fortran else ''}")
    needed = offset + shape[0] * 3 * dtype.itemsize
    size = os.path.getsize(path)
    if size < needed:
        # Told here, not as a memmap's ValueError when a task reads past the end.
        raise _ext.IoError(f"{path}: truncated .npy file: {size} bytes, its header's {dtype} "
                           f"{shape} needs {needed}")
    return _from_ranges(path, offset, dtype, tuple(shape), _row_ranges(shape[0], chunk_rows),
                        None, dtype)


def points_from_zarr(url, component: str | None = None, *, chunk_rows: int | None = None,
                     **kwargs):
    """A zarr array ``(n, 3)`` as a dask array (``dask.array.from_zarr``), rechunked to
    ``chunk_rows`` rows (default: the zarr chunks) and whole rows."""
    try:
        points = da.from_zarr(url, component=component, **kwargs)
    except (OSError, KeyError, ValueError) as e:
        # zarr's own errors (ArrayNotFoundError, ...) are ValueErrors with terse messages.
        where = f"{url}" + (f" (component {component!r})" if component else "")
        raise _ext.IoError(f"{where}: no readable zarr array ({type(e).__name__}: {e})") from None
    if points.ndim != 2 or points.shape[1] != 3:
        raise _ext.InvalidInput(f"{url}: expected an (n, 3) array, found {points.shape}")
    return points.rechunk({0: chunk_rows or points.chunks[0], 1: 3})


def points_from_ply(path, *, chunk_rows: int = DEFAULT_CHUNK_ROWS):
    """The x, y, z of a binary PLY file's vertex rows as a lazy ``(n, 3)`` float64 dask array.

    The layout comes from ``spacewarp.ply_layout(path)`` (vertex count, byte offset of the
    vertex rows, row stride, a NumPy structured dtype of one row); each task memory-maps its
    rows, so the file is never read whole.
    """
    path = os.path.abspath(path)
    layout = _ply_layout(path)
    count, offset, dtype = layout["count"], layout["offset"], layout["dtype"]
    return _from_ranges(path, offset, dtype, (count,), _row_ranges(count, chunk_rows),
                        ("x", "y", "z"), np.float64)


def _ply_layout(path: str) -> dict:
    """spacewarp.ply_layout as count, offset, stride and dtype (one vertex row)."""
    layout = _ext.ply_layout(path)
    return {"count": layout["vertex_count"], "offset": layout["vertex_offset"],
            "stride": layout["vertex_row_bytes"], "dtype": np.dtype(layout["dtype"])}


# ----------------------------------------------------------------------------------------------
# PLY files


def _deform_rows(warp, input_path: str, part: str, first: int, count: int) -> str:
    _ext.deform_ply_rows(warp, input_path, part, first, count)
    return part


def deform_ply(warp, input, output=None, *, client=None, chunk_rows: int = DEFAULT_CHUNK_ROWS,
               parts_dir=None):
    """A binary PLY file's vertices warped on the workers, row range by row range.

    Each range of ``chunk_rows`` vertex rows is warped on a worker by
    ``spacewarp.deform_ply_rows`` into a part file (the output bytes of those rows, written
    atomically). The caller and every worker must see ``input``, ``output`` and the parts under
    the same paths (a shared file system).

    One file (``output``, the default): ``spacewarp.assemble_ply`` writes header, parts and the
    input's other elements atomically: byte-identical to ``spacewarp deform --rig RIG input -o
    output`` on one machine. The parts live in a hidden temporary folder beside ``output`` and
    are removed on success and on failure; a failed task leaves no output file.

    A folder of parts (``parts_dir=``, with ``output`` None): the parts stay in ``parts_dir``
    (created; it must not exist or be empty) as ``part-NNNNNN.bin`` with a manifest
    ``manifest.json``: ``{"format": "spacewarp-ply-parts", "version": 1, "input": absolute
    input path, "vertex_count": n, "parts": [{"file": name, "first_row": i, "row_count": k,
    "bytes": size}, ...]}`` in row order; :func:`assemble_parts` turns it into one file later.
    On failure the folder is removed again (or emptied, if it existed).

    Returns the output path (or the manifest's). Raises what the workers raise
    (spacewarp.InvalidInput for a non-finite vertex, spacewarp.IoError for unreadable files),
    and spacewarp.IoError naming ``output`` if its folder is missing or not writable.

    Interrupts: a KeyboardInterrupt while waiting on a cluster raises within half a second and
    cancels the outstanding tasks. From the main thread, SIGTERM (if it has its default action)
    raises SystemExit(143) while this runs, so the temporaries are removed. After SIGKILL (or a
    SIGTERM handled elsewhere) the hidden folder ``.NAME.parts-XXXXXXXX/`` beside ``output`` may
    be left; it holds only part files and is safe to delete.
    """
    if (output is None) == (parts_dir is None):
        raise _ext.InvalidInput("deform_ply: give exactly one of output and parts_dir")
    input_path = os.path.abspath(input)
    count = _ply_layout(input_path)["count"]
    ranges = _row_ranges(count, chunk_rows)
    with _sigterm_raises():
        if parts_dir is not None:
            folder = Path(os.path.abspath(parts_dir))
            existed = folder.exists()
            if existed and any(folder.iterdir()):
                raise _ext.InvalidInput(f"deform_ply: parts_dir {folder} is not empty")
            folder.mkdir(parents=True, exist_ok=True)
        else:
            out = Path(os.path.abspath(output))
            _check_output_folder(out)
            try:
                folder = Path(tempfile.mkdtemp(prefix=f".{out.name}.parts-", dir=out.parent))
            except OSError as e:
                raise _cannot_write(out, e.strerror or str(e)) from None
        parts = [str(folder / f"part-{i:06d}.bin") for i in range(len(ranges))]
        try:
            w = shipped_warp(warp, client)
            tasks = [dask.delayed(_deform_rows, pure=False)(w, input_path, part, a, b - a)
                     for part, (a, b) in zip(parts, ranges)]
            _compute(tasks, client)
            if parts_dir is None:
                _ext.assemble_ply(input_path, parts, str(out))
                return str(out)
            manifest = {"format": "spacewarp-ply-parts", "version": 1, "input": input_path,
                        "vertex_count": count,
                        "parts": [{"file": Path(p).name, "first_row": a, "row_count": b - a,
                                   "bytes": os.path.getsize(p)}
                                  for p, (a, b) in zip(parts, ranges)]}
            tmp = folder / (PARTS_MANIFEST + ".tmp")
            tmp.write_text(json.dumps(manifest, indent=1))
            os.replace(tmp, folder / PARTS_MANIFEST)
            return str(folder / PARTS_MANIFEST)
        except BaseException:
            if parts_dir is not None and existed:
                for child in folder.iterdir():
                    child.unlink()
            else:
                shutil.rmtree(folder, ignore_errors=True)
            raise
        finally:
            if parts_dir is None:
                shutil.rmtree(folder, ignore_errors=True)


def assemble_parts(parts_dir, output) -> str:
    """One PLY file from a parts folder of :func:`deform_ply` (its manifest names the input,
    which must still be there): byte-identical to the single-file mode. Atomic."""
    folder = Path(parts_dir)
    manifest = json.loads((folder / PARTS_MANIFEST).read_text())
    if manifest.get("format") != "spacewarp-ply-parts" or manifest.get("version") != 1:
        raise _ext.InvalidInput(f"{folder / PARTS_MANIFEST}: not a spacewarp PLY parts manifest")
    parts = [str(folder / p["file"]) for p in manifest["parts"]]
    _ext.assemble_ply(manifest["input"], parts, str(output))
    return str(output)


# ----------------------------------------------------------------------------------------------
# Volumes

_VOLUME_OPTIONS = ("sampler", "conserve_mass", "vectors", "redistance", "seed_spacing")


def _warp_brick(warp, input_path: str, brick: tuple, clip: bool, options: dict):
    return _ext.warp_volume_brick(warp, input_path, brick, clip=clip, **options)


def warp_volume(warp, input_vdb, output_vdb, *, client=None, brick: int = 64, halo: int = 4,
                clip: bool = False, **options) -> list:
    """A VDB file warped brick by brick on the workers: :func:`spacewarp.warp_volume`'s result.

    1. Here (cheap): the file is read and the warp evaluated at the seeding cells of each grid
       (``seed_spacing`` voxels); the images of the cells give the output's region, which is cut
       into bricks of ``brick`` output voxels per edge (rounded up to a multiple of 8), each with
       the cells whose images reach it (``spacewarp.plan_volume_bricks``).
    2. On the workers (the expensive part, an inverse solve per output voxel): each brick
       resamples its voxels from those cells (``spacewarp.warp_volume_brick``). Each worker
       reads the input file whole once and keeps it for its next bricks (the default), or, with
       ``clip=True``, each brick reads only its cells' part of the input (OpenVDB's clipped read:
       the cells plus ``halo`` + 4 voxels; where a voxel's preimage leaves that part, the
       worker reads the whole grid and does its brick again). A clipped read costs about as
       much time as a whole one (OpenVDB passes every compressed leaf buffer), so clip only
       saves the workers' memory, at the price of one read per brick.
    3. Here: the bricks' leaves are merged into one grid per grid, level sets are re-distanced
       once over the merged grid (OpenVDB's LevelSetTracker is not brick-local), point data
       grids are warped here whole, and every grid is written atomically to ``output_vdb``.

    Equality with the single process: every output voxel is seeded from the same cells in the
    same order and samples the same input, so the grids have the same active voxels and the
    same values bit for bit (the files differ only in their random UUID); of the reports,
    ``mass_after`` is the same sum in another order (equal within rounding), the rest equal.
    Grids: float and double level sets and fog volumes, vec3s grids (bricked), point data grids
    (warped on the caller), several per file. ``options`` are spacewarp.warp_volume's
    (``sampler``, ``conserve_mass``, ``vectors``, ``redistance``, ``seed_spacing``);
    ``cache_spacing`` is refused (its lattice depends on every cell). The input must be on a
    file system the workers share. Returns one report dict per grid, as spacewarp.warp_volume.
    A failed brick raises its error here and nothing is written. A missing output folder is a
    spacewarp.IoError raised before any work. Interrupts (Ctrl-C, SIGTERM) as :func:`deform_ply`.
    """
    unknown = set(options) - set(_VOLUME_OPTIONS)
    if "cache_spacing" in unknown and not options.get("cache_spacing"):
        unknown.discard("cache_spacing")
        options.pop("cache_spacing")
    if unknown:
        raise _ext.InvalidInput("warp_volume: unsupported option(s) " + ", ".join(sorted(unknown))
                                + " (spacewarp.dask takes " + ", ".join(_VOLUME_OPTIONS) + ")")
    input_path = os.path.abspath(input_vdb)
    output_path = Path(os.path.abspath(output_vdb))
    _check_output_folder(output_path)
    plan = _ext.plan_volume_bricks(warp, input_path, brick=brick, halo=halo, **options)
    with _sigterm_raises():
        w = shipped_warp(warp, client)
        tasks = [dask.delayed(_warp_brick, pure=False)(w, input_path, b, clip, options)
                 for b in plan.bricks]
        results = _compute(tasks, client) if tasks else []
        return plan.merge(warp, results, str(output_path))
