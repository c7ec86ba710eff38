"""FreeSurfer binary triangle surfaces (lh.pial, lh.white, lh.sphere): sdot's reader and writer
against nibabel's (skipped when python3-nibabel is absent), and the command's ?h.sphere output."""

import os

import numpy as np
import pytest

import sdot
from conftest import icosphere, run


def bumpy_surface():
    vertices, faces = icosphere(3)
    rng = np.random.default_rng(4)
    radius = 1 + 0.2 * np.sin(3 * vertices[:, 0]) * np.cos(2 * vertices[:, 1]) + 0.01 * rng.random(len(vertices))
    return 60 * vertices * radius[:, None], faces  # millimetres, as a cortex


def test_round_trip_by_name_and_by_format(tmp_path):
    vertices, faces = bumpy_surface()
    for name in ("lh.pial", "rh.white", "lh.sphere"):
        sdot.write_mesh(tmp_path / name, vertices, faces)
        back_vertices, back_faces = sdot.read_mesh(tmp_path / name)
        np.testing.assert_array_equal(back_faces, faces)
        np.testing.assert_array_equal(back_vertices, vertices.astype(np.float32))  # float32 on disk
    sdot.write_mesh(tmp_path / "surface.bin", vertices, faces, format="freesurfer")
    back_vertices, _ = sdot.read_mesh(tmp_path / "surface.bin")  # no name: the magic bytes say it
    np.testing.assert_array_equal(back_vertices, vertices.astype(np.float32))
    with pytest.raises(ValueError, match="format: must be one of"):
        sdot.read_mesh(tmp_path / "lh.pial", format="mgh")


def test_truncated_and_hostile_files_are_value_errors(tmp_path):
    vertices, faces = bumpy_surface()
    sdot.write_mesh(tmp_path / "lh.pial", vertices, faces)
    data = (tmp_path / "lh.pial").read_bytes()
    (tmp_path / "lh.cut").write_bytes(data[:-5])
    with pytest.raises(ValueError, match="truncated"):
        sdot.read_mesh(tmp_path / "lh.cut")
    header_end = data.index(b"\n\n") + 2
    hostile = data[:header_end] + (2**31 - 1).to_bytes(4, "big") + (2**31 - 1).to_bytes(4, "big")
    (tmp_path / "lh.huge").write_bytes(hostile)
    with pytest.raises(ValueError, match="claims 2147483647 vertices"):
        sdot.read_mesh(tmp_path / "lh.huge")
    bad_index = bytearray(data)
    bad_index[-4:] = (len(vertices)).to_bytes(4, "big")
    (tmp_path / "lh.index").write_bytes(bytes(bad_index))
    with pytest.raises(ValueError, match=f"face {len(faces) - 1} has vertex index {len(vertices)}"):
        sdot.read_mesh(tmp_path / "lh.index")


def test_nibabel_reads_what_sdot_writes_and_sdot_reads_what_nibabel_writes(tmp_path):
    freesurfer = pytest.importorskip("nibabel.freesurfer")
    vertices, faces = bumpy_surface()
    sdot.write_mesh(tmp_path / "lh.pial", vertices, faces)
    nib_vertices, nib_faces, stamp = freesurfer.read_geometry(str(tmp_path / "lh.pial"), read_stamp=True)
    assert stamp.startswith("created by")
    np.testing.assert_array_equal(nib_faces, faces)
    np.testing.assert_array_equal(nib_vertices, vertices.astype(np.float32))

    freesurfer.write_geometry(str(tmp_path / "rh.white"), vertices, faces, create_stamp="created by nibabel")
    back_vertices, back_faces = sdot.read_mesh(tmp_path / "rh.white")
    np.testing.assert_array_equal(back_faces, faces)
    np.testing.assert_array_equal(back_vertices, vertices.astype(np.float32))

    # With FreeSurfer's volume geometry tags after the faces, as real lh.pial files have.
    volume_info = {
        "head": np.array([2, 0, 20], dtype=np.int32), "valid": "1  # volume info valid",
        "filename": "vol.nii", "volume": np.array([256, 256, 256]), "voxelsize": np.array([1.0, 1.0, 1.0]),
        "xras": np.array([-1.0, 0, 0]), "yras": np.array([0, 0, -1.0]), "zras": np.array([0, 1.0, 0]),
        "cras": np.array([0.5, -2.0, 3.0]),
    }
    freesurfer.write_geometry(str(tmp_path / "lh.tagged"), vertices, faces, volume_info=volume_info)
    back_vertices, back_faces = sdot.read_mesh(tmp_path / "lh.tagged", format="freesurfer")
    np.testing.assert_array_equal(back_faces, faces)
    np.testing.assert_array_equal(back_vertices, vertices.astype(np.float32))


def test_command_maps_a_freesurfer_surface_to_a_sphere_of_radius_100(sphere_param_command, tmp_path):
    freesurfer = pytest.importorskip("nibabel.freesurfer")
    vertices, faces = bumpy_surface()
    freesurfer.write_geometry(str(tmp_path / "lh.white"), vertices, faces)
    run(sphere_param_command, tmp_path / "lh.white", "-o", tmp_path / "lh.sphere", "--radius", "100", "--quiet")
    sphere_vertices, sphere_faces = freesurfer.read_geometry(str(tmp_path / "lh.sphere"))
    np.testing.assert_array_equal(sphere_faces, faces)
    np.testing.assert_allclose(np.linalg.norm(sphere_vertices, axis=1), 100, rtol=1e-6)
