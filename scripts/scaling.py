#!/usr/bin/python3
"""Time against N for every geometry with `sdot bench`: a log-log plot with an N log N reference,
the raw figures as JSON, and the markdown table of docs/benchmarks.md.

    /usr/bin/python3 scripts/scaling.py [--sdot build/bin/sdot] [--sizes 1000 10000 100000 1000000]
                                        [--geometries plane sphere hyperbolic]
                                        [--plot docs/images/scaling.png] [--json scaling.json]

Each (geometry, N) is one run of `sdot bench --geometry G --n N --tolerance 1e-6 --quiet`
(uniform random sites, seed 1, equal masses). The table goes to standard output.
"""
import argparse
import json
import math
import subprocess
import sys


def bench(sdot, geometry, n):
    command = [sdot, "bench", "--geometry", geometry, "--n", str(n), "--tolerance", "1e-6", "--quiet"]
    output = subprocess.run(command, check=True, capture_output=True, text=True).stdout
    lines = [line for line in output.splitlines() if line.startswith("{")]
    if not lines:
        raise RuntimeError(f"no JSON line from {' '.join(command)}")
    return json.loads(lines[-1])


def table(rows):
    header = ("| geometry | N | time (s) | diagram (s) | assembly (s) | linear solve (s) | iterations "
              "| peak RSS (MB) | max rel. mass error |\n|---|---|---|---|---|---|---|---|---|")
    lines = [header]
    for r in rows:
        lines.append(f"| {r['geometry']} | {r['n']:,} | **{r['time_s']:.2f}** | {r['diagram_s']:.2f} | "
                     f"{r['assembly_s']:.2f} | {r['linear_solve_s']:.2f} | {r['iterations']} | "
                     f"{r['peak_rss_mb']:.0f} | {r['max_relative_mass_error']:.1e} |")
    return "\n".join(lines)


def plot(rows, path):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    figure, axes = plt.subplots(figsize=(6.4, 4.4))
    for geometry in dict.fromkeys(r["geometry"] for r in rows):
        points = sorted((r["n"], r["time_s"]) for r in rows if r["geometry"] == geometry)
        ns, times = zip(*points)
        line, = axes.loglog(ns, times, "o-", label=geometry)
        # N log N through the largest run: the slope a solve of that cost would follow
        n_top, t_top = points[-1]
        reference = [t_top * n * math.log(n) / (n_top * math.log(n_top)) for n in ns]
        axes.loglog(ns, reference, "--", color=line.get_color(), alpha=0.5, linewidth=1)
    axes.set_xlabel("sites N")
    axes.set_ylabel("solve time (s), tolerance 1e-6")
    axes.set_title("sdot bench on 2 cores (dashed: N log N)")
    axes.grid(True, which="both", alpha=0.3)
    axes.legend()
    figure.tight_layout()
    figure.savefig(path, dpi=110)


def main():
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--sdot", default="build/bin/sdot")
    parser.add_argument("--sizes", type=int, nargs="+", default=[1000, 10000, 100000, 1000000])
    parser.add_argument("--geometries", nargs="+", default=["plane", "sphere", "hyperbolic"])
    parser.add_argument("--plot", default="docs/images/scaling.png")
    parser.add_argument("--json", default=None, help="also write the raw bench lines here")
    args = parser.parse_args()
    rows = []
    for geometry in args.geometries:
        for n in args.sizes:
            result = bench(args.sdot, geometry, n)
            if result.get("status") not in ("converged", "precision_floor"):
                print(f"{geometry} N={n}: {result.get('status')}", file=sys.stderr)
            rows.append(result)
            print(f"{geometry:10s} {n:>9,}  {result['time_s']:8.2f} s  {result['peak_rss_mb']:7.0f} MB",
                  file=sys.stderr, flush=True)
    if args.json:
        with open(args.json, "w") as out:
            json.dump(rows, out, indent=1)
    plot(rows, args.plot)
    print(table(rows))


if __name__ == "__main__":
    main()
