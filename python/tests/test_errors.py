"""Bad input: every case raises ValueError or TypeError naming the problem; none crashes."""

import numpy as np
import pytest

import sdot
from conftest import bumpy_mesh, icosphere, sphere_sites

SITES = np.random.default_rng(0).random((50, 2))
HEXAGON = 0.7 * np.column_stack((np.cos(np.arange(6) * np.pi / 3), np.sin(np.arange(6) * np.pi / 3)))


@pytest.mark.parametrize(
    "kwargs, error, match",
    [
        (dict(sites=np.zeros((5, 3))), ValueError, r"sites: must have 2 columns, got shape \(5, 3\)"),
        (dict(sites=np.zeros(5)), ValueError, r"sites: must be an array of shape \(n, 2\)"),
        (dict(sites=np.zeros((0, 2))), ValueError, "at least one site"),
        (dict(sites=SITES.astype(complex)), TypeError, "sites: must be an array of real numbers, got dtype complex128"),
        (dict(sites=[["a", "b"]]), TypeError, "dtype <U1"),
        (dict(sites=[[0.1, 0.2], [0.3]]), ValueError, "sites: cannot be read as an array"),
        (dict(sites=np.where(np.arange(100).reshape(50, 2) == 7, np.nan, SITES)), ValueError, r"sites\[3\]: is not finite"),
        (dict(sites=np.vstack((SITES, SITES[4]))), ValueError, r"sites\[50\].*sites\[4\]|sites\[4\].*sites\[50\]"),
        (dict(sites=SITES, masses=np.ones(49)), ValueError, "masses: there are 49 masses for 50 sites"),
        (dict(sites=SITES, masses=np.r_[np.full(49, 1 / 49), -0.01]), ValueError, r"masses\[49\]: must be a positive finite number"),
        (dict(sites=SITES, masses=np.r_[np.full(49, 1 / 49), 0.0]), ValueError, r"masses\[49\]: must be a positive finite number"),
        (dict(sites=SITES, masses=np.r_[np.full(49, 0.02), np.nan]), ValueError, r"masses\[49\]: is not finite"),
        (dict(sites=SITES, masses=np.full(50, 0.03)), ValueError, "masses: they sum to 1.5 but the source mass is 1"),
        (dict(sites=SITES, tolerance=0), ValueError, "tolerance: must be a positive number"),
        (dict(sites=SITES, tolerance=-1e-9), ValueError, "tolerance: must be a positive number"),
        (dict(sites=SITES, tolerance="tight"), TypeError, "tolerance: must be a number"),
        (dict(sites=SITES, max_iterations=-1), ValueError, "max_iterations: must be >= 0"),
        (dict(sites=SITES, geometry="cube"), ValueError, "geometry: must be one of"),
        (dict(sites=SITES, linear_solver="lu"), ValueError, "linear_solver: must be one of"),
        (dict(sites=SITES, weights=np.ones(3)), ValueError, "weights: there are 3 weights for 50 sites"),
        (dict(sites=SITES, callback=3), TypeError, "callback: must be callable"),
        (dict(sites=SITES, domain=[[0, 0], [1, 1], [1, 0], [0, 1]]), ValueError, "domain.*(intersect|self)"),
        (dict(sites=SITES, domain={"outer": [[0, 0], [1, 0]]}), ValueError, "domain"),
        (dict(sites=SITES, domain={"outr": [[0, 0], [1, 0], [0, 1]]}), ValueError, "domain: a polygon with holes"),
        (dict(sites=SITES, density=np.full((3, 3), -1.0)), ValueError, r"density\[0, 0\]: must be finite and >= 0"),
        (dict(sites=SITES, density=np.zeros((3, 3))), ValueError, "density.*(no mass|vanish)"),
        (dict(sites=SITES, density=lambda p: -np.ones(len(p))), ValueError, "the function returned -1"),
        (dict(sites=SITES, density=lambda p: np.ones(3)), ValueError, "one number per point"),
        (dict(sites=SITES, density=lambda p: "x"), ValueError, "one number per point"),
        (dict(sites=SITES, density=(np.zeros((3, 2)), [[0, 1, 5]], np.ones(3))), ValueError, r"density.triangles\[0\]"),
        (dict(sites=SITES, density=(np.zeros((3, 2)), [[0, 1, 2]], np.ones(2))), ValueError, "density.values"),
        (dict(sites=SITES, density=(np.zeros((3, 2)), [[0.5, 1, 2]], np.ones(3))), TypeError, "density.triangles"),
        (dict(sites=SITES, interpolation="bilinear"), ValueError, "but there is none"),
        (dict(sites=SITES, density=np.ones((2, 2)), interpolation="cubic"), ValueError, "interpolation: must be"),
        (dict(sites=SITES, builder="hull"), ValueError, "builder: only the sphere"),
        (dict(sites=sphere_sites(30, 1) * [1, 1, 0.0] + [0, 0, 0.0], geometry="sphere"), ValueError, "hemisphere"),
        (dict(sites=np.abs(sphere_sites(30, 1)), geometry="sphere"), ValueError, "hemisphere"),
        (dict(sites=np.vstack((sphere_sites(30, 1), [[0, 0, 0]])), geometry="sphere"), ValueError, r"sites\[30\].*zero"),
        (dict(sites=sphere_sites(30, 1), geometry="sphere", density=np.ones((4, 8)), extent=(0, 0, 1, 1)),
         ValueError, "longitude-latitude"),
        (dict(sites=sphere_sites(30, 1), geometry="sphere", domain={"center": [0, 0, 1]}), ValueError, "a cap is"),
        (dict(sites=SITES * 0.5, geometry="hyperbolic"), ValueError, "domain: missing"),
        (dict(sites=SITES * 0.5, geometry="hyperbolic", domain=HEXAGON, model="upper"), ValueError, "model: must be"),
        (dict(sites=SITES + 1, geometry="hyperbolic", domain=HEXAGON), ValueError, r"sites\[0\]"),
        (dict(sites=SITES * 0.5, geometry="hyperbolic", domain=HEXAGON, density=np.ones((3, 3))), ValueError,
         "image densities are available on the plane and the sphere"),
    ],
)
def test_bad_input_is_rejected_with_a_clear_message(kwargs, error, match):
    with pytest.raises(error, match=match):
        sdot.solve(**kwargs)


def test_exceptions_raised_by_a_density_function_propagate():
    def rho(points):
        raise ZeroDivisionError("inside rho")

    with pytest.raises(ZeroDivisionError, match="inside rho"):
        sdot.solve(SITES, density=rho)


def test_initial_weights_that_empty_a_cell():
    weights = np.zeros(50)
    weights[0] = -10
    with pytest.raises(ValueError, match=r"weights\[0\]: the initial weights leave the cell of site 0 empty"):
        sdot.solve(SITES, weights=weights)


def test_sphere_parameterization_rejects_invalid_meshes():
    vertices, faces = icosphere(1)
    with pytest.raises(ValueError, match="boundary edges"):  # open: one face removed
        sdot.sphere_parameterization(vertices, faces[1:])
    with pytest.raises(ValueError, match=r"faces\[0\]: vertex index 999 is out of range"):
        sdot.sphere_parameterization(vertices, np.vstack(([[0, 1, 999]], faces)))
    with pytest.raises(ValueError, match=r"faces\[0\]: vertex index -1"):
        sdot.sphere_parameterization(vertices, np.vstack(([[0, 1, -1]], faces)))
    bad = vertices.copy()
    bad[3, 1] = np.inf
    with pytest.raises(ValueError, match=r"vertices\[3\]: is not finite"):
        sdot.sphere_parameterization(bad, faces)
    with pytest.raises(TypeError, match="faces: must be an array of integers"):
        sdot.sphere_parameterization(vertices, faces.astype(float))
    with pytest.raises(ValueError, match="components"):  # two spheres
        sdot.sphere_parameterization(np.vstack((vertices, vertices + 3)), np.vstack((faces, faces + len(vertices))))
    shape, shape_faces = bumpy_mesh(1)
    with pytest.raises(ValueError, match=r"target_weights\[2\]: must be positive"):
        sdot.sphere_parameterization(shape, shape_faces, target_weights=np.r_[1, 1, -1, np.ones(len(shape) - 3)])


def test_mesh_files(tmp_path):
    with pytest.raises(FileNotFoundError):
        sdot.read_mesh(tmp_path / "missing.off")
    broken = tmp_path / "broken.off"
    broken.write_text("OFF\n4 2 0\n0 0 0\n1 0 0\n")
    with pytest.raises(ValueError, match="broken.off"):
        sdot.read_mesh(broken)
