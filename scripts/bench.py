#!/usr/bin/python3
"""Runs every benchmark of docs/benchmarks.md and regenerates its tables and the scaling plot.

    /usr/bin/python3 scripts/bench.py [--quick] [--build build] [--doc docs/benchmarks.md]
                                      [--sections core python densities param] [--sizes N ...]
                                      [--large] [--meshes DIR] [--json FILE]

Without --quick it rewrites the generated blocks of the document (between
`<!-- bench:NAME -->` and `<!-- /bench:NAME -->`) and docs/images/scaling.png. With --quick it runs
a smaller set (N up to 10^5, meshes up to 15,000 vertices, no density-mesh rows) in a few minutes
and only prints the tables; --large adds the 10^7-site core solves (every geometry) to the
tables and the scaling plot. Every row is one command, printed above its table; the machine, the
date and the commit go into the `machine` block.

The shared meshes (../shared/meshes) and the independent evaluator
(../shared/tools/eval_sphere_map.py) are used when they exist; the parameterization table is
skipped when they do not.
"""
import argparse
import datetime
import json
import math
import os
import pathlib
import platform
import re
import subprocess
import sys
import tempfile
import time

ROOT = pathlib.Path(__file__).resolve().parent.parent
GEOMETRIES = ["plane", "sphere", "hyperbolic"]
# The core table: each geometry at every size, and the periodic plane (`torus`, the plane's sites on
# the periodic unit square) from 10^5 sites on, next to the plane's rows.
# (geometry, smallest N, largest N).
CORE_ROWS = [("plane", 1, 10 ** 9), ("torus", 100_000, 10 ** 9), ("sphere", 1, 10 ** 9),
             ("hyperbolic", 1, 10 ** 9)]


def log(message):
    print(message, file=sys.stderr, flush=True)


def run_measured(command, env=None):
    """Runs a command; returns (stdout, wall seconds)."""
    start = time.perf_counter()
    process = subprocess.Popen(command, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=env)
    stdout, stderr = process.communicate()
    wall = time.perf_counter() - start
    if process.returncode != 0:
        raise RuntimeError(f"{' '.join(map(str, command))} exited with {process.returncode}: {stderr.strip()}")
    return stdout, wall


def wall_and_peak_rss(command, ok_codes=(0,)):
    """Wall seconds and peak RSS in MB (None without GNU time) of one run. The RSS comes from
    /usr/bin/time: a child forked from this interpreter would report the interpreter's own
    high-water mark from before exec whenever that is larger. Exit statuses outside `ok_codes`
    raise."""
    with tempfile.NamedTemporaryFile("r") as rss_file:
        gnu_time = pathlib.Path("/usr/bin/time")
        prefix = [str(gnu_time), "-f", "%M", "-o", rss_file.name] if gnu_time.exists() else []
        start = time.perf_counter()
        process = subprocess.run(prefix + [str(part) for part in command], stdout=subprocess.DEVNULL,
                                 stderr=subprocess.PIPE, text=True)
        wall = time.perf_counter() - start
        if process.returncode not in ok_codes:
            raise RuntimeError(f"{shell(command)} exited with {process.returncode}: {process.stderr.strip()}")
        rss = rss_file.read().strip().splitlines()
    return wall, (int(rss[-1]) / 1024 if prefix and rss else None)


def json_line(stdout, command):
    lines = [line for line in stdout.splitlines() if line.startswith("{")]
    if not lines:
        raise RuntimeError(f"no JSON line from {' '.join(map(str, command))}")
    return json.loads(lines[-1])


def shell(command):
    return " ".join(str(part) for part in command)


def markdown_table(columns, rows):
    """A markdown table: a header of column names, then one line per row of cell strings."""
    lines = ["| " + " | ".join(columns) + " |", "|" + "---|" * len(columns)]
    lines += ["| " + " | ".join(row) + " |" for row in rows]
    return "\n".join(lines)


# ---------------------------------------------------------------------------------------- machine


def machine_block(build):
    def first(pattern, text, default="?"):
        match = re.search(pattern, text, re.MULTILINE)
        return match.group(1).strip() if match else default

    cpu = first(r"^Model name:\s*(.+)$", subprocess.run(["lscpu"], capture_output=True, text=True).stdout)
    memory_kb = int(first(r"^MemTotal:\s*(\d+)", pathlib.Path("/proc/meminfo").read_text(), "0"))
    compiler = "?"
    cache = build / "CMakeCache.txt"
    if cache.exists():
        cxx = first(r"^CMAKE_CXX_COMPILER:\w+=(.+)$", cache.read_text())
        if cxx != "?":
            compiler = subprocess.run([cxx, "--version"], capture_output=True, text=True).stdout.splitlines()[0]
    commit = subprocess.run(["git", "rev-parse", "--short", "HEAD"], capture_output=True, text=True,
                            cwd=ROOT).stdout.strip()
    # changes to the documents (this one included) do not change what was measured
    dirty = subprocess.run(["git", "status", "--porcelain", "--untracked-files=no", "--", ".", ":!docs"],
                           capture_output=True, text=True, cwd=ROOT).stdout.strip()
    return "\n".join([
        "| | |",
        "|---|---|",
        f"| CPU | {cpu}, {os.cpu_count()} cores |",
        f"| memory | {memory_kb / 1024 ** 2:.0f} GiB |",
        f"| system | {platform.system()} {platform.release()} |",
        f"| compiler | {compiler}, Release build (`scripts/build.sh`) |",
        f"| commit | {commit}{' with local changes' if dirty else ''} |",
        f"| date | {datetime.date.today().isoformat()} |",
    ])


# ------------------------------------------------------------------------------------- core solve


def core_command(sdot, geometry, n):
    return [sdot, "bench", "--geometry", geometry, "--n", str(n), "--tolerance", "1e-6", "--quiet"]


def core_rows(sdot, sizes, repeats_small):
    """The core rows in CORE_ROWS order. The runs are interleaved: size by size, each repeat runs
    every geometry in turn, so that rows compared in the table (the torus against the plane) ran
    minutes apart at most, through the same drifts of the shared machine's speed."""
    runs = {}  # (geometry, n) -> its runs
    for n in sorted(set(sizes)):
        geometries = [g for g, smallest, largest in CORE_ROWS if smallest <= n <= largest]
        for _ in range(repeats_small if n <= 100_000 else 1):
            for geometry in geometries:
                command = core_command(sdot, geometry, n)
                stdout, _ = run_measured(command)
                runs.setdefault((geometry, n), []).append(json_line(stdout, command))
    rows = []
    for geometry, smallest, largest in CORE_ROWS:
        for n in (n for n in sizes if smallest <= n <= largest):
            # the run of median total time stands for the row, so its stages add up
            measured = sorted(runs[(geometry, n)], key=lambda r: r["time_s"])
            row = dict(measured[len(measured) // 2], runs=len(measured))
            if row.get("status") not in ("converged", "precision_floor"):
                log(f"{geometry} N={n}: status {row.get('status')}")
            rows.append(row)
            log(f"core {geometry:10s} {n:>10,}  {row['time_s']:8.2f} s  {row['peak_rss_mb']:7.0f} MB")
    return rows


def core_table(rows):
    columns = ["geometry", "N", "time (s)", "diagram (s)", "assembly (s)", "linear solve (s)", "iterations",
               "peak RSS (MB)", "max rel. mass error", "runs"]
    return markdown_table(columns, [
        [r["geometry"], f"{r['n']:,}", f"**{r['time_s']:.2f}**", f"{r['diagram_s']:.2f}", f"{r['assembly_s']:.2f}",
         f"{r['linear_solve_s']:.2f}", str(r["iterations"]), f"{r['peak_rss_mb']:.0f}",
         f"{r['max_relative_mass_error']:.1e}", str(r["runs"])] for r in rows])


def memory_table(rows):
    return markdown_table(["geometry", "N", "peak RSS (MB)", "per site (bytes)"], [
        [r["geometry"], f"{r['n']:,}", f"{r['peak_rss_mb']:.0f}", f"{r['peak_rss_mb'] * 2 ** 20 / r['n']:,.0f}"]
        for r in rows if r["n"] >= 100_000])


def scaling_plot(rows, path):
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
    axes.set_title(f"sdot bench on {os.cpu_count()} cores (dashed: N log N)")
    axes.grid(True, which="both", alpha=0.3)
    axes.legend()
    figure.tight_layout()
    figure.savefig(path, dpi=110)


# --------------------------------------------------------------------------------- python package


def python_rows(build, sdot, n):
    env = dict(os.environ, PYTHONPATH=str(build / "python"))
    rows = []
    for geometry in GEOMETRIES:
        command = [sys.executable, "-m", "sdot.bench", "--geometry", geometry, "--n", str(n), "--quiet"]
        stdout, _ = run_measured(command, env)
        python = json_line(stdout, command)
        command = [sdot, "bench", "--geometry", geometry, "--n", str(n), "--quiet"]
        stdout, _ = run_measured(command)
        native = json_line(stdout, command)
        rows.append((python, native))
        log(f"python {geometry:10s} overhead {python['python_overhead_s']:.3f} s")
    return rows


def python_table(rows):
    columns = ["geometry", "N", "Python `time_s`", "Python overhead", "overhead / time", "peak RSS (MB)",
               "command's peak RSS (MB)", "iterations (Python / command)"]
    return markdown_table(columns, [
        [python["geometry"], f"{python['n']:,}", f"{python['time_s']:.2f} s", f"{python['python_overhead_s']:.3f} s",
         f"{100 * python['python_overhead_s'] / python['time_s']:.1f} %", f"{python['peak_rss_mb']:.0f}",
         f"{native['peak_rss_mb']:.0f}", f"{python['iterations']} / {native['iterations']}"]
        for python, native in rows])


# ----------------------------------------------------------------------------- densities from data


def density_rows(sdot, n, triangles):
    rows = []
    for geometry in GEOMETRIES:
        command = core_command(sdot, geometry, n)[:-1] + ["--density-triangles", str(triangles), "--quiet"]
        stdout, _ = run_measured(command)
        rows.append(json_line(stdout, command))
        log(f"density {geometry:10s} {rows[-1]['time_s']:8.2f} s")
    return rows


def density_table(rows):
    columns = ["geometry", "N", "triangles", "density build (s)", "time (s)", "diagram (s)", "assembly (s)",
               "linear solve (s)", "iterations", "peak RSS (MB)"]
    return markdown_table(columns, [
        [r["geometry"], f"{r['n']:,}", f"{r['density_triangles']:,}", f"{r['density_build_s']:.2f}",
         f"**{r['time_s']:.2f}**", f"{r['diagram_s']:.2f}", f"{r['assembly_s']:.2f}", f"{r['linear_solve_s']:.2f}",
         str(r["iterations"]), f"{r['peak_rss_mb']:.0f}"] for r in rows])


# ----------------------------------------------------------------------- spherical parameterization


# Runs per parameterization and hard-shape row (1 with --quick): see median_run.
PARAM_REPEATS = 3


def median_run(command, report_path, repeats, ok_codes=(0,)):
    """Runs `command` `repeats` times; the run of median wall time (its wall, peak RSS and
    report) stands for the row. The machine's speed drifts between runs (the same binary on
    spiky_120k: 3.9-6.5 s within an hour), and one run is one sample of that drift."""
    runs = []
    for _ in range(repeats):
        wall, rss = wall_and_peak_rss(command, ok_codes=ok_codes)
        runs.append((wall, rss, json.loads(pathlib.Path(report_path).read_text())))
    runs.sort(key=lambda run: run[0])
    return runs[len(runs) // 2]


def param_rows(build, meshes, evaluator, max_vertices, repeats):
    binary = build / "bin" / "sdot-sphere-param"
    entries = []
    for path in sorted(meshes.glob("*.off")):
        with open(path) as mesh:
            header = mesh.readline().strip()
            counts = header[3:].split() if len(header) > 3 else mesh.readline().split()
        entries.append((int(counts[0]), path))
    rows = []
    with tempfile.TemporaryDirectory() as scratch:
        for vertices, path in sorted(entries):
            if vertices > max_vertices:
                continue
            output = pathlib.Path(scratch) / f"{path.stem}.off"
            report_path = pathlib.Path(scratch) / f"{path.stem}.json"
            wall, rss, report = median_run([binary, path, "-o", output, "--report", report_path, "--quiet"],
                                           report_path, repeats)
            metrics = report["final_map"]
            source = "report"
            if evaluator:
                command = [sys.executable, evaluator, path, output, "--json"]
                metrics = json_line(run_measured(command)[0], command)
                source = "evaluator"
            rows.append(dict(mesh=path.stem, vertices=vertices, wall=wall, rss=rss, report=report,
                             metrics=metrics, source=source))
            log(f"param {path.stem:16s} {vertices:>8,}  {wall:6.2f} s  flips {metrics['flips']}")
    return rows


def param_table(rows):
    columns = ["mesh", "V", "time (s)", "peak RSS (MB)", "area mean\\|d\\|", "std", "max\\|d\\|", "angle (°)",
               "flips", "Newton it", "initial map (s)", "OT (s)", "untangling (s)", "area opt. (s)"]
    cells = []
    for r in rows:
        m, times = r["metrics"], r["report"]["times"]
        untangle = times.get("untangle_regularized_s", 0) + times.get("untangle_laplacian_s", 0)
        cells.append([r["mesh"], f"{r['vertices']:,}", f"**{r['wall']:.2f}**",
                      "–" if r["rss"] is None else f"{r['rss']:.0f}", f"{m['area_mean_abs']:.4f}",
                      f"{m['area_std']:.3f}", f"{m['area_max_abs']:.3f}", f"{m['angle_mean_abs_deg']:.1f}",
                      f"**{m['flips']}**", str(r["report"]["ot"]["newton_iterations"]),
                      f"{times['initial_map_s']:.2f}", f"{times['ot_centroids_s']:.2f}", f"{untangle:.2f}",
                      f"{times['area_optimization_s']:.2f}"])
    return markdown_table(columns, cells)


# ----------------------------------------------------------------------------------- hard shapes

HARD_CASES = [(case, [25_000, 60_000, 120_000, 150_000])
              for case in ("slivers", "folds", "spiky", "tubes", "capsule", "capsule40", "cones")]


def hard_rows(build, repeats):
    """sdot-sphere-param on the generated hard shapes (scripts/hard_meshes.py); exit status 3
    (flipped faces left) is a result here, not an error."""
    binary = build / "bin" / "sdot-sphere-param"
    rows = []
    with tempfile.TemporaryDirectory() as scratch:
        for case, sizes in HARD_CASES:
            command = [sys.executable, ROOT / "scripts" / "hard_meshes.py", scratch, "--cases", case, "--sizes"]
            subprocess.run(command + [str(size) for size in sizes], check=True, stdout=subprocess.DEVNULL)
            for size in sizes:
                path = pathlib.Path(scratch) / f"{case}_{size // 1000}k.off"
                report_path = path.with_suffix(".json")
                wall, rss, report = median_run([binary, path, "-o", path.with_suffix(".out.off"), "--report",
                                                report_path, "--quiet"], report_path, repeats, ok_codes=(0, 3))
                rows.append(dict(case=case, vertices=report["input_statistics"]["vertices"], wall=wall, rss=rss,
                                 report=report))
                log(f"hard {path.stem:12s} {wall:7.2f} s  flips {report['final_map']['flips']}")
    return rows


def hard_table(rows):
    columns = ["case", "V", "time (s)", "budget (s)", "peak RSS (MB)", "area mean\\|d\\|", "angle (°)", "flips",
               "fallbacks", "sub-resolution vertices", "slowest stages (s)"]
    cells = []
    for r in rows:
        report, m = r["report"], r["report"]["final_map"]
        stages = sorted(((t, name[:-2]) for name, t in report["times"].items()
                         if name not in ("total_s", "compute_s", "read_s", "write_s")), reverse=True)[:2]
        budget = 3 * r["vertices"] / 100_000 + 0.5
        cells.append([r["case"], f"{r['vertices']:,}", f"**{r['wall']:.2f}**", f"{budget:.2f}",
                      "–" if r["rss"] is None else f"{r['rss']:.0f}", f"{m['area_mean_abs']:.4f}",
                      f"{m['angle_mean_abs_deg']:.1f}", f"**{m['flips']}**", str(report["fallbacks"]["total"]),
                      f"{report['sub_resolution_vertices']:,}", ", ".join(f"{name} {t:.2f}" for t, name in stages)])
    return markdown_table(columns, cells)


# ------------------------------------------------------------------------------------- the document


def replace_block(text, name, content):
    pattern = re.compile(rf"(<!-- bench:{name} -->\n).*?(<!-- /bench:{name} -->)", re.DOTALL)
    if not pattern.search(text):
        raise RuntimeError(f"the document has no block <!-- bench:{name} --> … <!-- /bench:{name} -->")
    return pattern.sub(lambda m: m.group(1) + content + "\n" + m.group(2), text)


def main():
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--quick", action="store_true", help="smaller set, print only")
    parser.add_argument("--build", default="build")
    parser.add_argument("--doc", default="docs/benchmarks.md")
    parser.add_argument("--plot", default="docs/images/scaling.png")
    parser.add_argument("--sections", nargs="+", default=["core", "python", "densities", "param", "hard"],
                        choices=["core", "python", "densities", "param", "hard"])
    parser.add_argument("--sizes", type=int, nargs="+", help="core-solve sizes (default 1e3 … 1e6)")
    parser.add_argument("--large", action="store_true",
                        help="add N = 1e7 to the core solve (every geometry: about 14 minutes and 11 GB more)")
    parser.add_argument("--meshes", default=str(ROOT.parent / "shared" / "meshes"))
    parser.add_argument("--json", help="also write every raw figure here")
    args = parser.parse_args()

    os.chdir(ROOT)
    build = pathlib.Path(args.build)
    sdot = build / "bin" / "sdot"
    if not sdot.exists():
        sys.exit(f"{sdot} not found: build first (scripts/build.sh) or pass --build DIR")
    sizes = args.sizes or ([1000, 10_000, 100_000] if args.quick else [1000, 10_000, 100_000, 1_000_000])
    if args.large:
        sizes = sorted(set(sizes) | {10_000_000})
    blocks, raw = {"machine": machine_block(build)}, {}

    if "core" in args.sections:
        rows = core_rows(str(sdot), sizes, repeats_small=1 if args.quick else 5)
        raw["core"] = rows
        blocks["core"] = core_table(rows)
        blocks["memory"] = memory_table(rows)
        if not args.quick:
            scaling_plot(rows, args.plot)
    if "python" in args.sections:
        rows = python_rows(build, str(sdot), 10_000 if args.quick else 100_000)
        raw["python"] = rows
        blocks["python"] = python_table(rows)
    if "densities" in args.sections and not args.quick:
        rows = density_rows(str(sdot), 100_000, 1_000_000)
        raw["densities"] = rows
        blocks["densities"] = density_table(rows)
    if "param" in args.sections:
        meshes = pathlib.Path(args.meshes)
        evaluator = meshes.parent / "tools" / "eval_sphere_map.py"
        if meshes.is_dir():
            rows = param_rows(build, meshes, evaluator if evaluator.exists() else None,
                              15_000 if args.quick else 10 ** 9, 1 if args.quick else PARAM_REPEATS)
            raw["param"] = [{k: v for k, v in r.items() if k != "report"} | {"times": r["report"]["times"]}
                            for r in rows]
            blocks["param"] = param_table(rows)
        else:
            log(f"{meshes} not found: parameterization table skipped")

    if "hard" in args.sections and not args.quick:
        rows = hard_rows(build, PARAM_REPEATS)
        raw["hard"] = [{k: v for k, v in r.items() if k != "report"} | {"times": r["report"]["times"]} for r in rows]
        blocks["hard"] = hard_table(rows)

    if args.json:
        pathlib.Path(args.json).write_text(json.dumps(raw, indent=1))
    for name, content in blocks.items():
        print(f"\n## {name}\n\n{content}")
    if not args.quick:
        doc = pathlib.Path(args.doc)
        text = doc.read_text()
        for name, content in blocks.items():
            text = replace_block(text, name, content)
        doc.write_text(text)
        log(f"{doc} updated: {', '.join(blocks)}")


if __name__ == "__main__":
    main()
