"""Meshes: reading and writing (the readers of the sdot-sphere-param command) and the spherical
parameterization (the same library code as the command)."""

import json
import math
import os
import sys
import time

from . import _sdot
from ._solve import _float_array, _int_array


_MESH_FORMATS = (None, "off", "obj", "ply", "freesurfer")


def _check_format(format):
    if format not in _MESH_FORMATS:
        raise ValueError(f"format: must be one of off, obj, ply, freesurfer (or None: by the name), got {format!r}")
    return format or ""


def read_mesh(path, *, format=None):
    """Reads a triangle mesh: OFF, OBJ, PLY ascii or binary, or a FreeSurfer surface.

    The format is `format` ("off", "obj", "ply", "freesurfer"), or by the name when None:
    the extension, or FreeSurfer's names (lh.pial, rh.white, lh.sphere, ...), or the FreeSurfer
    magic bytes. Returns (vertices (n, 3) float64, faces (m, 3) int64); polygons are
    fan-triangulated. Raises FileNotFoundError for a missing file and ValueError (naming the file
    and line or element) for a malformed one."""
    path = os.fspath(path)
    format = _check_format(format)
    if not os.path.exists(path):
        raise FileNotFoundError(f"{path}: no such file")
    vertices, faces, _ = _sdot.read_mesh(path, format)
    return vertices, faces


def write_mesh(path, vertices, faces, *, ply_ascii=False, format=None):
    """Writes a triangle mesh as OFF, OBJ, PLY or a FreeSurfer surface (`format`, or by the name
    as for read_mesh), with round-trip exact coordinates (FreeSurfer stores float32). PLY is
    binary unless `ply_ascii`. The file is replaced atomically."""
    format = _check_format(format)
    vertices = _float_array(vertices, "vertices", ndim=2, columns=(3,))
    faces = _int_array(faces, "faces")
    _sdot.write_mesh(os.fspath(path), vertices, faces, bool(ply_ascii), format)


def sphere_parameterization(
    vertices,
    faces,
    *,
    target_weights=None,
    refine=0,
    max_refine=1,
    reweightings=40,
    optimize=True,
    ot_tolerance=0.15,
    sweeps=None,
    angle_weight=0.005,
    separation_threshold=5e-5,
    separation_delta=0.1,
    coarse_transport=8.0,
    progress=False,
):
    """Maps a closed genus-0 triangle mesh onto the unit sphere, area-preserving and without
    flipped faces (the pipeline of `sdot-sphere-param`; options as its flags).

    Parameters
    ----------
    vertices : (n, 3) array; faces : (m, 3) integer array (either orientation, consistently).
    target_weights : optional (n,) positive factors: the region around a vertex gets its mesh
        area times the factor.
    angle_weight : λ ≥ 0, the weight of the angle (MIPS) term against the area term in the final
        optimization (``--angle-weight``): 0 is purely area-preserving, the default 0.005 keeps
        triangles well shaped, larger values trade area for angles (from about 10 the map leans
        towards conformal).
    sweeps : sweeps of the final optimization at most; None: 200, or 2000 when `angle_weight`
        is above 0.005 (``--sweeps``).
    coarse_transport : from 40,000 to 500,000 vertices, the sites move by the displacement of a
        coarse OT on representatives this many times sqrt(4π/n) apart before the OT, which saves
        some of its Newton steps (``--coarse-transport``); 0 disables it.
    separation_threshold, separation_delta : the site-separation passes for crushed maps
        (``--separation-threshold``, ``--separation-delta``): they run while the shortest edge of
        the map is below separation_threshold·sqrt(4π/n) (≥ 0; 0 disables them), on
        representatives separation_delta·sqrt(4π/n) apart (> 0).
    progress : print the stage lines on stderr, or a callable that receives each line.

    Returns
    -------
    (sphere_vertices, report): an (n, 3) array of unit vectors, row i the image of vertex i (a
    vertex that no face uses is projected radially from the vertex centroid), and the command's
    report as a dict (input statistics, stage times, Newton iterations, distortion metrics), with
    ``report["area_distortion"]`` holding the per-face log area ratios of the initial and final
    maps (numpy arrays, for `sdot.plot.distortion_histogram`). ``report["status"]`` is "ok",
    "flipped_faces" (faces left flipped) or "ot_not_converged" (no flipped face, but the OT solve
    stopped short of its tolerance, so the areas are not preserved; ``report["ot"]`` says why).

    Raises ValueError naming the defects for a mesh that is not a closed genus-0 manifold, and
    naming the option for an option out of its range.
    """
    vertices = _float_array(vertices, "vertices", ndim=2, columns=(3,))
    faces = _int_array(faces, "faces")
    if target_weights is not None:
        target_weights = _float_array(target_weights, "target_weights", ndim=1)
    try:
        angle_weight = float(angle_weight)
    except (TypeError, ValueError):
        raise ValueError(f"angle_weight: expected a finite number >= 0, got {angle_weight!r}") from None
    if not (math.isfinite(angle_weight) and angle_weight >= 0):
        raise ValueError(f"angle_weight: expected a finite number >= 0, got {angle_weight!r}")
    options = {
        "refine": int(refine),
        "max_refine": int(max_refine),
        "reweightings": int(reweightings),
        "optimize": bool(optimize),
        "ot_tolerance": float(ot_tolerance),
        "angle_weight": angle_weight,
        "separation_threshold": float(separation_threshold),
        "separation_delta": float(separation_delta),
        "coarse_transport": float(coarse_transport),
    }
    if sweeps is not None:
        options["sweeps"] = int(sweeps)
    hook = None
    if callable(progress):
        hook = progress
    elif progress:
        start = time.monotonic()

        def hook(line):
            sys.stderr.write(f"[{time.monotonic() - start:8.3f} s] {line}\n")

    sphere, report_json, initial_d, final_d = _sdot.sphere_parameterization(
        vertices, faces, options, target_weights, hook
    )
    report = json.loads(report_json)
    report["area_distortion"] = {"initial": initial_d, "final": final_d}
    return sphere, report
