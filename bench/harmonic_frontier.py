#!/usr/bin/env python3
"""The harmonic set-up's accuracy-versus-time frontier: spacewarp's harmonic coordinates at several
resolutions against Blender's Mesh Deform (a harmonic solve on a grid) at several precisions.

Both deform the Ju et al. armadillo (../shared/data/ju2005-armadillo: armadilloman.obj, 15,002
vertices) by its 110-vertex cage posed as deformed_bounding_mesh5.obj. The error of a run is the
max and RMS distance of its deformed vertices to a converged reference's (spacewarp at a 5M-tet target, 4.2M tets,
computed once and cached under /tmp), relative to the cage's bounding-box diagonal. Its time is
the set-up: tetrahedralise + factorise + solve (with the non-negativity projection) + bind (the
model's weight rows) for spacewarp, the bind (meshdeform_bind and the evaluation that runs it) for
Blender. Runs alternate between the tools, round after round; the table gives medians.

    python3 bench/harmonic_frontier.py --out /tmp/frontier        # needs build/bench/harmonic_frontier

spacewarp levels may be fractional (--precision 1,2,5.5). The verdict lines compare, for each Blender
precision, spacewarp's fastest run at least as accurate in the max error, and in both errors.

Blender (Debian's `blender`) is skipped, with a line saying so, when it is not installed. Writes
frontier.png (log-log, matplotlib) and frontier.json to --out.
"""

import argparse
import json
import math
import os
import shutil
import statistics
import subprocess
import sys

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(HERE)


def read_vertices(path):
    with open(path) as f:
        return np.array([[float(x) for x in line.split()[1:4]] for line in f if line.startswith("v ")])


def run_spacewarp(exe, files, out, key, value):
    result = subprocess.run([exe, *files, out, "--" + key, str(value)], check=True,
                            capture_output=True, text=True)
    return json.loads(result.stdout.strip().splitlines()[-1])


def run_blender(blender, files, out, precision):
    result = subprocess.run([blender, "-b", "--factory-startup", "--python",
                             os.path.join(HERE, "harmonic_frontier_blender.py"), "--", *files, out,
                             str(precision)], check=True, capture_output=True, text=True)
    for line in result.stdout.splitlines():
        if line.startswith("FRONTIER "):
            return json.loads(line[len("FRONTIER "):])
    raise RuntimeError("blender printed no result:\n" + result.stdout + result.stderr)


def errors(path, reference, diagonal):
    d = np.linalg.norm(np.fromfile(path).reshape(-1, 3) - reference, axis=1) / diagonal
    return float(d.max()), float(math.sqrt(np.mean(d * d)))


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--out", required=True, help="folder for frontier.png and frontier.json")
    parser.add_argument("--build", default=os.path.join(ROOT, "build"))
    parser.add_argument("--data", default=os.path.join(ROOT, "..", "shared", "data", "ju2005-armadillo"))
    parser.add_argument("--pose", default="deformed_bounding_mesh5.obj")
    parser.add_argument("--precision", default="1,2,3,4,5,5.5,6",
                        help="spacewarp precision levels (comma-separated; fractional levels allowed)")
    parser.add_argument("--tets", default="", help="spacewarp target tet counts besides (comma-separated)")
    parser.add_argument("--blender-precision", default="4,5,6")
    parser.add_argument("--repeat", type=int, default=3, help="rounds; the table gives medians")
    parser.add_argument("--reference-tets", type=int, default=5000000)
    parser.add_argument("--cache", default="/tmp/spacewarp-harmonic-frontier-reference",
                        help="where the reference's vertices are kept (computed once)")
    args = parser.parse_args()

    exe = os.path.join(args.build, "bench", "harmonic_frontier")
    if not os.path.exists(exe):
        sys.exit(f"harmonic_frontier.py: {exe} is missing: build the target harmonic_frontier")
    files = [os.path.join(args.data, name) for name in ("bounding_mesh.obj", args.pose, "armadilloman.obj")]
    if not all(os.path.exists(f) for f in files):
        print(f"harmonic_frontier.py: the armadillo data is missing in {args.data}: skipped")
        return
    os.makedirs(args.out, exist_ok=True)
    cage = read_vertices(files[0])
    diagonal = float(np.linalg.norm(cage.max(0) - cage.min(0)))

    reference = f"{args.cache}-{args.reference_tets}-{os.path.splitext(args.pose)[0]}.f64"
    if not os.path.exists(reference):
        print(f"reference: spacewarp at {args.reference_tets} tets (once; cached in {reference})",
              flush=True)
        info = run_spacewarp(exe, files, reference + ".part", "tets", args.reference_tets)
        os.replace(reference + ".part", reference)
        print(f"reference: {info}", flush=True)
    ref = np.fromfile(reference).reshape(-1, 3)

    blender = shutil.which("blender")
    if blender is None:
        print("Blender is not installed (apt-get install blender): its Mesh Deform is skipped")
    runs = [("spacewarp", "precision", float(p)) for p in args.precision.split(",") if p]
    runs += [("spacewarp", "tets", int(t)) for t in args.tets.split(",") if t]
    if blender:
        runs += [("blender", "precision", int(p)) for p in args.blender_precision.split(",") if p]
    # Round-robin over configurations, alternating the tools within every round.
    order = sorted(runs, key=lambda r: (r[2], r[0]))
    times = {r: [] for r in runs}
    info = {}
    out = os.path.join(args.out, "deformed.f64")
    for _ in range(args.repeat):
        for run in order:
            tool, key, value = run
            if tool == "spacewarp":
                result = run_spacewarp(exe, files, out, key, value)
                times[run].append(result["setup_s"])
            else:
                result = run_blender(blender, files, out, value)
                times[run].append(result["bind_s"])
            info[run] = (result, errors(out, ref, diagonal))

    rows = []
    for run in runs:
        result, (emax, erms) = info[run]
        # The setting apart from the result's keys (its "tets" is the mesh's count, not the target).
        rows.append({"tool": run[0], "setting": f"{run[1]} {run[2]:g}", run[1] + "_setting": run[2],
                     "time_s": statistics.median(times[run]), "max_error": emax, "rms_error": erms,
                     **{k: v for k, v in result.items() if k not in ("setup_s", "bind_s", "precision")}})
    load = os.getloadavg()
    print(f"harmonic set-up vs Blender Mesh Deform, armadillo (15,002 vertices, 110-vertex cage, "
          f"pose {args.pose}); errors relative to the cage diagonal vs spacewarp at "
          f"{args.reference_tets} tets; medians of {args.repeat}; load average {load[0]:.1f}")
    print(f"{'tool':10} {'setting':>16} {'time s':>8} {'max err':>9} {'rms err':>9} {'tets':>8} "
          f"{'projected':>9}")
    for r in sorted(rows, key=lambda r: (r["tool"], r["time_s"])):
        tets = r.get("tets", "") if r["tool"] == "spacewarp" else ""
        projected = f"{r['projected_rows']}/{r['mesh_vertices']}" if "projected_rows" in r else ""
        print(f"{r['tool']:10} {r['setting']:>16} {r['time_s']:8.3f} {r['max_error']:9.2e} "
              f"{r['rms_error']:9.2e} {tets!s:>8} {projected:>9}")
    # Where Blender's error is reached, spacewarp's fastest run at least as accurate: in the max
    # error (the measure), and in both the max and the RMS error.
    sw = [r for r in rows if r["tool"] == "spacewarp"]
    for b in sorted((r for r in rows if r["tool"] == "blender"), key=lambda r: r["precision_setting"]):
        for measure, keys in (("max", ("max_error",)), ("max and RMS", ("max_error", "rms_error"))):
            better = [r for r in sw if all(r[k] <= b[k] for k in keys)]
            if better:
                best = min(better, key=lambda r: r["time_s"])
                print(f"Blender {b['setting']} ({b['time_s']:.3f} s): spacewarp as accurate in "
                      f"{measure} at {best['setting']}, {best['time_s']:.3f} s: Blender's time / "
                      f"spacewarp's {b['time_s'] / best['time_s']:.2f}")
            else:
                print(f"Blender {b['setting']}: no spacewarp run here is as accurate in {measure}")
    with open(os.path.join(args.out, "frontier.json"), "w") as f:
        json.dump({"load_average": load, "rows": rows}, f, indent=1)
    os.remove(out)

    try:
        import matplotlib
        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:
        print("matplotlib is missing (apt-get install python3-matplotlib): no plot")
        return
    fig, ax = plt.subplots(figsize=(7, 5))
    for tool, marker in (("spacewarp", "o"), ("blender", "s")):
        pts = sorted((r["time_s"], r["max_error"], r["rms_error"]) for r in rows if r["tool"] == tool)
        if not pts:
            continue
        t, emax, erms = zip(*pts)
        label = "spacewarp harmonic" if tool == "spacewarp" else "Blender Mesh Deform"
        ax.plot(t, emax, marker + "-", label=label + " (max)")
        ax.plot(t, erms, marker + "--", label=label + " (RMS)")
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_xlabel("set-up time (s)")
    ax.set_ylabel("error / cage diagonal")
    ax.set_title("Harmonic set-up, armadillo: accuracy vs time")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend()
    png = os.path.join(args.out, "frontier.png")
    fig.savefig(png, dpi=120, bbox_inches="tight")
    print(f"plot: {png}")


if __name__ == "__main__":
    main()
