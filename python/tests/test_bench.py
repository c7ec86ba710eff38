"""python -m sdot.bench prints the line of `sdot bench` for the same problem."""

import json
import os
import subprocess
import sys

import pytest

from conftest import run


@pytest.mark.parametrize("geometry", ["plane", "sphere", "hyperbolic", "torus"])
def test_bench_line_matches_the_command(sdot_command, geometry):
    args = ["--geometry", geometry, "--n", "3000", "--seed", "3", "--tolerance", "1e-8", "--quiet"]
    python = json.loads(
        subprocess.run([sys.executable, "-m", "sdot.bench", *args], capture_output=True, text=True, check=True).stdout
    )
    command = json.loads(run(sdot_command, "bench", *args).stdout)
    assert set(command) <= set(python)
    assert python["geometry"] == command["geometry"] and python["n"] == command["n"] == 3000
    assert python["status"] == command["status"] == "converged"
    assert python["iterations"] == command["iterations"]
    assert python["max_relative_mass_error"] <= 1e-8 and command["max_relative_mass_error"] <= 1e-8
    if geometry != "hyperbolic":  # H² sites pass through the hyperboloid reader: equal up to rounding
        assert python["max_relative_mass_error"] == pytest.approx(command["max_relative_mass_error"], rel=1e-6)
    assert 0 <= python["python_overhead_s"] < python["wall_s"]


def test_bench_rejects_bad_arguments():
    out = subprocess.run([sys.executable, "-m", "sdot.bench", "--geometry", "cube", "--n", "10"],
                         capture_output=True, text=True)
    assert out.returncode == 2 and "invalid choice" in out.stderr


def test_bench_reports_the_heap_huge_pages_setting():
    def setting(tunables):
        env = {k: v for k, v in os.environ.items() if k != "GLIBC_TUNABLES"}
        if tunables is not None:
            env["GLIBC_TUNABLES"] = tunables
        out = subprocess.run([sys.executable, "-m", "sdot.bench", "--geometry", "plane", "--n", "200", "--quiet"],
                             capture_output=True, text=True, check=True, env=env)
        return json.loads(out.stdout)["glibc_malloc_hugetlb"]

    assert setting(None) == "default"
    assert setting("glibc.malloc.top_pad=65536:glibc.malloc.hugetlb=1") == "1"
