"""sdot.sphere_parameterization and the mesh readers: the same code as sdot-sphere-param."""

import json

import numpy as np
import pytest

import sdot
from conftest import bumpy_mesh, run


def signed_volumes(vertices, faces):
    a, b, c = (vertices[faces[:, k]] for k in range(3))
    return np.einsum("ij,ij->i", a, np.cross(b, c))


def test_parameterization_of_a_generated_mesh():
    vertices, faces = bumpy_mesh(3)  # 642 vertices, areas varying several times
    lines = []
    sphere, report = sdot.sphere_parameterization(vertices, faces, progress=lines.append)
    assert sphere.shape == vertices.shape
    assert np.allclose(np.linalg.norm(sphere, axis=1), 1, atol=1e-12)
    assert report["status"] == "ok"
    assert report["final_map"]["flips"] == 0
    assert np.all(signed_volumes(sphere, faces) > 0)  # no face flipped, independently of the report
    assert report["final_map"]["area_mean_abs"] < report["initial_map"]["area_mean_abs"]
    assert report["final_map"]["area_mean_abs"] < 0.05
    assert len(report["area_distortion"]["final"]) == len(faces)
    assert any("read" in line for line in lines)


def test_inward_orientation_is_accepted():
    vertices, faces = bumpy_mesh(2)
    sphere, report = sdot.sphere_parameterization(vertices, faces[:, ::-1])
    assert report["status"] == "ok" and report["input_statistics"]["orientation"] == -1
    assert np.all(signed_volumes(sphere, faces[:, ::-1]) < 0)  # the map keeps the input's orientation


def test_python_and_the_command_give_the_same_map(sphere_param_command, tmp_path):
    vertices, faces = bumpy_mesh(3)
    mesh = tmp_path / "bumpy.off"
    sdot.write_mesh(mesh, vertices, faces)
    out, report_file = tmp_path / "sphere.off", tmp_path / "report.json"
    run(sphere_param_command, mesh, "-o", out, "--report", report_file, "--quiet")
    command_sphere, command_faces = sdot.read_mesh(out)
    sphere, report = sdot.sphere_parameterization(vertices, faces)
    assert np.array_equal(command_faces, faces)
    assert np.abs(command_sphere - sphere).max() <= 1e-12
    command_report = json.loads(report_file.read_text())
    assert command_report["final_map"] == pytest.approx(report["final_map"], rel=1e-9)
    assert command_report["ot"]["newton_iterations"] == report["ot"]["newton_iterations"]


@pytest.mark.parametrize("name, ascii", [("m.off", False), ("m.obj", False), ("m.ply", False), ("m.ply", True)])
def test_mesh_round_trip(tmp_path, name, ascii):
    vertices, faces = bumpy_mesh(1)
    path = tmp_path / name
    sdot.write_mesh(path, vertices, faces, ply_ascii=ascii)
    read_vertices, read_faces = sdot.read_mesh(path)
    assert np.array_equal(read_vertices, vertices)  # round-trip exact
    assert np.array_equal(read_faces, faces) and read_faces.dtype == np.int64


def test_unreferenced_vertices_keep_their_rows():
    vertices, faces = bumpy_mesh(2)
    extra = np.vstack((vertices, [[10.0, 0, 0]]))
    sphere, report = sdot.sphere_parameterization(extra, faces)
    assert sphere.shape == extra.shape and np.isfinite(sphere).all()
    assert report["input_statistics"]["vertices_in_file"] == len(extra)
    reference, _ = sdot.sphere_parameterization(vertices, faces)
    assert np.array_equal(sphere[:-1], reference)


def test_angle_weight_trades_area_for_angles():
    vertices, faces = bumpy_mesh(3)
    _, by_default = sdot.sphere_parameterization(vertices, faces)
    sphere, conformal = sdot.sphere_parameterization(vertices, faces, angle_weight=20)
    assert by_default["optimizer"]["angle_weight"] == 0.005 and by_default["optimizer"]["sweep_limit"] == 200
    assert conformal["optimizer"]["angle_weight"] == 20 and conformal["optimizer"]["sweep_limit"] == 2000
    assert np.all(signed_volumes(sphere, faces) > 0)
    assert conformal["final_map"]["flips"] == 0
    assert conformal["final_map"]["angle_mean_abs_deg"] < by_default["final_map"]["angle_mean_abs_deg"]
    assert conformal["final_map"]["area_mean_abs"] > by_default["final_map"]["area_mean_abs"]
    _, limited = sdot.sphere_parameterization(vertices, faces, angle_weight=20, sweeps=5)
    assert limited["optimizer"]["sweep_limit"] == 5 and limited["optimizer"]["sweeps"] <= 5


@pytest.mark.parametrize("bad", [-0.1, float("nan"), float("inf"), "abc", None])
def test_bad_angle_weight_is_a_value_error(bad):
    vertices, faces = bumpy_mesh(1)
    with pytest.raises(ValueError, match="angle_weight"):
        sdot.sphere_parameterization(vertices, faces, angle_weight=bad)


_NAN, _INF = float("nan"), float("inf")


@pytest.mark.parametrize(
    "option, bad",
    [("coarse_transport", value) for value in (-1.0, _NAN, _INF)]
    + [("separation_delta", value) for value in (0.0, -1.0, _NAN, _INF)]
    + [("separation_threshold", value) for value in (-1.0, _NAN, _INF)],
)
def test_bad_spacing_option_is_a_value_error_naming_it(option, bad):
    vertices, faces = bumpy_mesh(1)
    with pytest.raises(ValueError, match=option):
        sdot.sphere_parameterization(vertices, faces, **{option: bad})
