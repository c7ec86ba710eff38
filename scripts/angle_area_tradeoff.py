"""The area-angle trade-off of sdot-sphere-param's --angle-weight (docs/spherical_parameterization.md).

Runs the command for a list of angle weights λ on shared meshes, reads each report's final-map
metrics (area mean|d|, mean angle error, flips), checks some of them against the independent
evaluator (../shared/tools/eval_sphere_map.py), prints a markdown table and writes a plot of
the mean angle error against the area mean|d|, one curve per mesh, points labelled with λ.

Run from the repository root:

    /usr/bin/python3 scripts/angle_area_tradeoff.py [--build build] [--meshes ../shared/meshes]
        [--names spot elephant david_10k] [--weights 0 0.005 ...] [--plot docs/images/angle_area_tradeoff.png]

Without the shared meshes it prints a message and exits with status 0 (nothing to measure).
"""

import argparse
import json
import os
import pathlib
import subprocess
import sys
import tempfile
import time

ROOT = pathlib.Path(__file__).resolve().parent.parent
DEFAULT_WEIGHTS = [0, 0.005, 0.02, 0.1, 0.5, 2, 10, 50]
# Three characters: a smooth blob (spot), long protrusions (elephant: trunk, legs, ears) and a
# head of near-equilateral triangles (david_10k); each maps in at most a few seconds.
DEFAULT_NAMES = ["spot", "elephant", "david_10k"]
# The report's metrics are computed as the evaluator computes them: they must agree closely.
CROSS_CHECK_TOLERANCE = 1e-6


def run_map(command, mesh, weight, out_dir):
    """Maps `mesh` with --angle-weight `weight`; returns (final_map metrics, optimizer, seconds, output)."""
    stem = f"{mesh.stem}_{weight:g}"
    output, report = out_dir / f"{stem}.off", out_dir / f"{stem}.json"
    start = time.monotonic()
    result = subprocess.run(
        [str(command), str(mesh), "-o", str(output), "--report", str(report), "--quiet", "--angle-weight", repr(weight)],
        capture_output=True, text=True)
    seconds = time.monotonic() - start
    if result.returncode not in (0, 3):  # 3: written, with flipped faces (reported below)
        sys.exit(f"{mesh.name}, λ = {weight:g}: sdot-sphere-param failed ({result.returncode}): {result.stderr.strip()}")
    data = json.loads(report.read_text())
    if data["optimizer"]["angle_weight"] != weight:
        sys.exit(f"{mesh.name}: the report says angle_weight {data['optimizer']['angle_weight']}, asked {weight}")
    return data["final_map"], data["optimizer"], seconds, output


def cross_check(evaluator, mesh, output, metrics):
    """The evaluator's area mean|d|, angle error and flips against the report's."""
    result = subprocess.run(["/usr/bin/python3", str(evaluator), str(mesh), str(output), "--json"],
                            capture_output=True, text=True, check=True)
    independent = json.loads(result.stdout)
    for key in ("area_mean_abs", "angle_mean_abs_deg"):
        if abs(independent[key] - metrics[key]) > CROSS_CHECK_TOLERANCE * max(1.0, abs(independent[key])):
            sys.exit(f"{mesh.name}: {key} is {metrics[key]} in the report but {independent[key]} by the evaluator")
    if independent["flips"] != metrics["flips"]:
        sys.exit(f"{mesh.name}: {metrics['flips']} flips in the report but {independent['flips']} by the evaluator")
    return independent


def plot(rows, names, path):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(7.5, 5.2))
    for name, marker in zip(names, "osd^v<>"):
        points = [r for r in rows if r["mesh"] == name]
        x = [r["area_mean_abs"] for r in points]
        y = [r["angle_mean_abs_deg"] for r in points]
        ax.plot(x, y, marker=marker, label=name)
        for k, r in enumerate(points):  # labels alternately above and below: close points stay legible
            ax.annotate(f"{r['weight']:g}", (r["area_mean_abs"], r["angle_mean_abs_deg"]), textcoords="offset points",
                        xytext=(3, 5) if k % 2 == 0 else (3, -11), fontsize=7)
    ax.set_xscale("log")  # from 0.01 (area-preserving) to above 1 (conformal-leaning)
    ax.set_xlabel("area distortion: mean |d| over faces, d = log(sphere area share / mesh area share)")
    ax.set_ylabel("mean angle error (degrees)")
    ax.set_title("sdot-sphere-param --angle-weight λ (points labelled with λ)")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend()
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=90, bbox_inches="tight", metadata={"Software": None})
    plt.close(fig)


def main():
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--build", default=str(ROOT / "build"), help="build folder with bin/sdot-sphere-param")
    parser.add_argument("--meshes", default=str(ROOT.parent / "shared" / "meshes"))
    parser.add_argument("--names", nargs="+", default=DEFAULT_NAMES, help="mesh names (NAME.off in --meshes)")
    parser.add_argument("--weights", type=float, nargs="+", default=DEFAULT_WEIGHTS, help="the λ values")
    parser.add_argument("--plot", default=str(ROOT / "docs" / "images" / "angle_area_tradeoff.png"))
    parser.add_argument("--keep", help="keep the maps and reports in this folder (default: a temporary one)")
    args = parser.parse_args()

    meshes = pathlib.Path(args.meshes)
    if not meshes.is_dir():
        print(f"{meshes} not found: no shared meshes, the trade-off is not measured")
        return 0
    command = pathlib.Path(args.build) / "bin" / "sdot-sphere-param"
    if not command.exists():
        sys.exit(f"{command} not found: build the sdot_sphere_param target, or pass --build")
    evaluator = meshes.parent / "tools" / "eval_sphere_map.py"
    missing = [name for name in args.names if not (meshes / f"{name}.off").exists()]
    if missing:
        sys.exit(f"{meshes}: no {', '.join(name + '.off' for name in missing)}")

    with tempfile.TemporaryDirectory() as scratch:
        out_dir = pathlib.Path(args.keep or scratch)
        out_dir.mkdir(parents=True, exist_ok=True)
        rows, checked = [], []
        for name in args.names:
            mesh = meshes / f"{name}.off"
            for k, weight in enumerate(args.weights):
                metrics, optimizer, seconds, output = run_map(command, mesh, weight, out_dir)
                rows.append({"mesh": name, "weight": weight, "seconds": seconds, "sweeps": optimizer["sweeps"],
                             **metrics})
                print(f"{name} λ={weight:g}: area mean|d| {metrics['area_mean_abs']:.4f}, angle "
                      f"{metrics['angle_mean_abs_deg']:.2f}°, flips {metrics['flips']}, {seconds:.2f} s",
                      file=sys.stderr)
                # both ends of the range and the default, by the independent evaluator
                if evaluator.exists() and (k in (0, len(args.weights) - 1) or weight == 0.005):
                    cross_check(evaluator, mesh, output, metrics)
                    checked.append(f"{name} λ={weight:g}")

    print("| mesh | λ (`--angle-weight`) | area mean\\|d\\| | mean angle error (°) | flips | sweeps | time (s) |")
    print("|---|---:|---:|---:|---:|---:|---:|")
    for r in rows:
        print(f"| {r['mesh']} | {r['weight']:g} | {r['area_mean_abs']:.4f} | {r['angle_mean_abs_deg']:.2f} | "
              f"{r['flips']} | {r['sweeps']} | {r['seconds']:.2f} |")
    if checked:
        print(f"\nAgreeing with eval_sphere_map.py (within {CROSS_CHECK_TOLERANCE:g}, same flips): {', '.join(checked)}.")
    else:
        print(f"\n{evaluator} not found: no cross-check.")
    plot(rows, args.names, pathlib.Path(args.plot))
    print(f"\nplot: {os.path.relpath(args.plot, ROOT)}")
    flipped = [r for r in rows if r["flips"] != 0]
    if flipped:
        print(f"flipped faces in {len(flipped)} maps", file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
