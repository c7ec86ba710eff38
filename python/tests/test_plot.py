"""sdot.plot renders to PNG without a display (Agg backend)."""

import matplotlib

matplotlib.use("Agg")

import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import pytest  # noqa: E402

import sdot  # noqa: E402
import sdot.plot  # noqa: E402
from conftest import bumpy_mesh, sphere_sites  # noqa: E402


def rendered(tmp_path, name, draw):
    fig, ax = plt.subplots()
    draw(ax)
    path = tmp_path / name
    fig.savefig(path, dpi=60)
    plt.close(fig)
    image = plt.imread(path)
    assert path.stat().st_size > 2000
    return image


def drawn_fraction(image):
    """Fraction of pixels that are not white."""
    return float(np.mean(np.any(image[:, :, :3] < 0.95, axis=2)))


@pytest.fixture(scope="module")
def results():
    hexagon = 0.8 * np.column_stack((np.cos(np.arange(6) * np.pi / 3), np.sin(np.arange(6) * np.pi / 3)))
    return {
        "plane": sdot.solve(np.random.default_rng(0).random((80, 2))),
        "sphere": sdot.solve(sphere_sites(200, 1), geometry="sphere"),
        "hyperbolic": sdot.solve(np.random.default_rng(1).uniform(-0.4, 0.4, (60, 2)), geometry="hyperbolic",
                                 domain=hexagon),
    }


@pytest.mark.parametrize("geometry", ["plane", "sphere", "hyperbolic"])
@pytest.mark.parametrize("color_by", [None, "mass", "error"])
def test_cells_render(tmp_path, results, geometry, color_by):
    image = rendered(tmp_path, f"{geometry}.png",
                     lambda ax: sdot.plot.cells(results[geometry], ax=ax, color_by=color_by, centroids=True))
    assert drawn_fraction(image) > (0.02 if color_by is None else 0.08)


def test_cells_without_axes_and_bad_color_by(results):
    ax = sdot.plot.cells(results["plane"])
    assert ax.collections
    plt.close(ax.figure)
    with pytest.raises(ValueError, match="color_by"):
        sdot.plot.cells(results["plane"], color_by="colour")
    with pytest.raises(ValueError, match="one value per cell"):
        sdot.plot.cells(results["plane"], color_by=np.ones(3))
    plt.close("all")


def test_distortion_histogram_renders(tmp_path):
    vertices, faces = bumpy_mesh(2)
    _, report = sdot.sphere_parameterization(vertices, faces)
    image = rendered(tmp_path, "histogram.png", lambda ax: sdot.plot.distortion_histogram(report, ax=ax))
    assert drawn_fraction(image) > 0.05
    with pytest.raises(ValueError, match="area_distortion"):
        sdot.plot.distortion_histogram({})


def test_import_sdot_does_not_import_matplotlib():
    import subprocess
    import sys

    code = "import sys, sdot; sdot.solve([[0.5, 0.5]]); print('matplotlib' in sys.modules)"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "False"
