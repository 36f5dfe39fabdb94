#!/usr/bin/env python3
"""spacewarp.dask against the single process, on a LocalCluster of 2 worker processes (1 thread
each) in the same run; medians of --repeats runs. Run by hand (not part of `make bench`):

    PYTHONPATH=build/python /usr/bin/python3 bench/dask_bench.py [--points N] [--voxel-size H]

1. deform_array: a twist on N points (default 50M, 1.2 GB of float64) generated on the workers
   (dask.array.random, 2^21-row chunks) and kept there (persist). "on the workers" is
   deform_array(...).sum() computed on the workers (and, for reference, the same sum of the
   unwarped points); "gathered" brings the warped array back to the caller. Against
   warp(points) on the caller's copy of the same array (every core).
2. warp_volume: a twist on the level set of a sphere of radius 1 on voxels of H (default 1/170:
   about 2M active voxels), bricks of 64 voxels, against spacewarp.warp_volume. The outputs
   are checked to be the same file but for its UUID.
"""

import argparse
import re
import statistics
import tempfile
import time
from pathlib import Path

import numpy as np

import dask.array as da
import spacewarp
import spacewarp.dask as swd
from distributed import Client, LocalCluster

_UUID = re.compile(rb"[0-9a-f]{8}-[0-9a-f]{4}-[0-9a-f]{4}-[0-9a-f]{4}-[0-9a-f]{12}")


def masked(path: Path) -> bytes:
    data = path.read_bytes()
    return _UUID.sub(b"-" * 36, data[:512], count=1) + data[512:]


def median_time(f, repeats: int) -> float:
    times = []
    for _ in range(repeats):
        t = time.perf_counter()
        f()
        times.append(time.perf_counter() - t)
    return statistics.median(times)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--points", type=int, default=50_000_000)
    parser.add_argument("--voxel-size", type=float, default=1.0 / 170)
    parser.add_argument("--brick", type=int, default=64)
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--no-volume", action="store_true", help="only deform_array")
    args = parser.parse_args()

    client = Client(LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                                 dashboard_address=None))
    twist = spacewarp.Twist(axis=(0, 0, 1), rate=0.5)
    import pickle

    try:
        print(f"pickled twist: {len(pickle.dumps(twist))} bytes")
    except TypeError as e:
        print(f"this build's warps do not pickle ({e}); the benchmark needs them to")
        return

    n = args.points
    points = client.persist(da.random.RandomState(0).random_sample((n, 3), chunks=(1 << 21, 3)))
    local = points.compute()
    single = median_time(lambda: twist(local), args.repeats)
    moved = swd.deform_array(twist, points, client=client)
    base = median_time(lambda: points.sum().compute(), args.repeats)
    on_workers = median_time(lambda: moved.sum().compute(), args.repeats)
    gathered = median_time(lambda: moved.compute(), args.repeats)
    print(f"deform_array, twist, {n:,} points, 2 workers x 1 thread (medians of {args.repeats}):")
    print(f"  single process warp(points): {single:8.3f} s  {n / single / 1e6:7.1f} M points/s")
    print(f"  dask, on the workers:        {on_workers:8.3f} s  {n / on_workers / 1e6:7.1f} M points/s"
          f"  ({on_workers / single:.2f}x)")
    print(f"  (sum of the unwarped points on the workers: {base:.3f} s)")
    print(f"  dask, gathered to the caller:{gathered:8.3f} s  {n / gathered / 1e6:7.1f} M points/s"
          f"  ({gathered / single:.2f}x)")
    del local
    if args.no_volume:
        client.close()
        return

    with tempfile.TemporaryDirectory() as folder:
        folder = Path(folder)
        source = folder / "sphere.vdb"
        spacewarp._spacewarp._write_sphere_volumes(source, radius=1.0, voxel_size=args.voxel_size)
        report = []

        def one():
            report[:] = spacewarp.warp_volume(twist, source, folder / "single.vdb")

        single = median_time(one, args.repeats)
        plan = spacewarp.plan_volume_bricks(twist, source, brick=args.brick)
        bricked = median_time(lambda: swd.warp_volume(twist, source, folder / "bricks.vdb",
                                                      client=client, brick=args.brick),
                              args.repeats)
        same = masked(folder / "single.vdb") == masked(folder / "bricks.vdb")
        active = report[0]["output_active_voxels"]
        print(f"warp_volume, twist, level set of {report[0]['input_active_voxels']:,} active "
              f"voxels ({active:,} out; 3 grids), {len(plan.bricks)} bricks of {args.brick}:")
        print(f"  single process: {single:8.3f} s")
        print(f"  dask bricks:    {bricked:8.3f} s  ({bricked / single:.2f}x); same file: {same}")
    client.close()


if __name__ == "__main__":
    main()
