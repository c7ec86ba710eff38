"""scripts/hard_meshes.py: the generated hard inputs of sdot-sphere-param
(docs/spherical_parameterization.md, "Hard shapes")."""

import importlib.util
import pathlib
import subprocess
import sys

import numpy as np
import pytest

SCRIPT = pathlib.Path(__file__).resolve().parents[2] / "scripts" / "hard_meshes.py"
_spec = importlib.util.spec_from_file_location("hard_meshes", SCRIPT)
hard = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(hard)


@pytest.mark.parametrize("case", sorted(hard.CASES))
def test_every_case_is_a_closed_outward_genus0_mesh_and_deterministic(case):
    v, f = hard.CASES[case](3000, 1)
    v, f = np.asarray(v, float), np.asarray(f, np.int64)
    hard.check(v, f, case)  # raises AssertionError naming the defect
    v2, f2 = hard.CASES[case](3000, 1)
    assert np.array_equal(v, np.asarray(v2, float)) and np.array_equal(f, np.asarray(f2, np.int64))


def test_cones_are_eight_long_spikes_of_few_vertices():
    v, _ = hard.cones(25000, 1)
    r = np.linalg.norm(v, axis=1)
    assert r.max() == pytest.approx(14.0, rel=0.02)  # the spikes' tips, 14 radii out
    lifted = r > 1 + 1e-9
    assert 8 * 100 < lifted.sum() < 8 * 200  # about 150 vertices per spike at 25k
    # eight separate spikes: the lifted vertices cluster around eight directions
    tips = hard.spike_directions(8, 1)
    nearest = np.argmax((v[lifted] / r[lifted, None]) @ tips.T, axis=1)
    assert len(np.unique(nearest)) == 8


def test_cone_options_set_the_count_length_and_width(tmp_path):
    subprocess.run([sys.executable, str(SCRIPT), str(tmp_path), "--cases", "cones", "--sizes", "3000",
                    "--cone-count", "4", "--cone-length", "10", "--cone-width", "0.3"], check=True,
                   capture_output=True)
    lines = (tmp_path / "cones_3k.off").read_text().split("\n")
    nv = int(lines[1].split()[0])
    v = np.array([list(map(float, line.split())) for line in lines[2:2 + nv]])
    r = np.linalg.norm(v, axis=1)
    assert r.max() == pytest.approx(10.0, rel=0.05)
    lifted = r > 1 + 1e-9
    tips = hard.spike_directions(4, 1)
    nearest = np.argmax((v[lifted] / r[lifted, None]) @ tips.T, axis=1)
    assert len(np.unique(nearest)) == 4
    # within 0.3 rad of a tip direction, not beyond
    angle = np.arccos(np.clip(np.max((v[lifted] / r[lifted, None]) @ tips.T, axis=1), -1, 1))
    assert angle.max() < 0.3 and angle.max() > 0.2
    bad = subprocess.run([sys.executable, str(SCRIPT), str(tmp_path), "--cases", "cones", "--sizes", "3000",
                          "--cone-width", "2"], capture_output=True, text=True)
    assert bad.returncode != 0 and "--cone-width" in bad.stderr
