#!/usr/bin/python3
"""Seed corpora of the libFuzzer harnesses (tests/fuzz): valid and nearly valid inputs per reader.

    scripts/fuzz_corpus.py OUT_DIR

writes OUT_DIR/<harness>/<seed> for the harnesses off, obj, ply, freesurfer, pgm, png, problem
and mesh_density (scripts/fuzz.sh runs it into the build folder). Standard library only; the
output is the same on every run.
"""

import json
import math
import struct
import sys
import zlib
from pathlib import Path

# ----------------------------------------------------------------------------------- meshes

TETRA_V = [(0, 0, 0), (1, 0, 0), (0, 1, 0), (0, 0, 1)]
TETRA_F = [(0, 2, 1), (0, 1, 3), (0, 3, 2), (1, 2, 3)]
CUBE_V = [(x, y, z) for z in (0, 1) for y in (0, 1) for x in (0, 1)]
CUBE_Q = [(0, 2, 3, 1), (4, 5, 7, 6), (0, 1, 5, 4), (2, 6, 7, 3), (0, 4, 6, 2), (1, 3, 7, 5)]
OCTA_V = [(1, 0, 0), (-1, 0, 0), (0, 1, 0), (0, -1, 0), (0, 0, 1), (0, 0, -1)]
OCTA_F = [(0, 2, 4), (2, 1, 4), (1, 3, 4), (3, 0, 4), (2, 0, 5), (1, 2, 5), (3, 1, 5), (0, 3, 5)]


def num(x):
    return repr(float(x)) if isinstance(x, float) else str(x)


def off_text(vertices, faces, header="OFF\n", newline="\n"):
    lines = [header.rstrip("\n"), f"{len(vertices)} {len(faces)} 0"]
    lines += [" ".join(num(c) for c in v) for v in vertices]
    lines += [" ".join([str(len(f))] + [str(i) for i in f]) for f in faces]
    return (newline.join(lines) + newline).encode()


def off_seeds():
    s = {
        "tetra.off": off_text(TETRA_V, TETRA_F),
        "octahedron.off": off_text(OCTA_V, OCTA_F),
        "cube_quads.off": off_text(CUBE_V, CUBE_Q),
        "crlf_bom.off": b"\xef\xbb\xbf" + off_text(TETRA_V, TETRA_F, newline="\r\n"),
        "comments.off": b"# a comment\nOFF # header\n# counts next\n4 4 6\n0 0 0\n1 0 0 # x\n0 1 0\n"
                        b"0 0 1\n\n3 0 2 1\n3 0 1 3 255 0 0\n3 0 3 2\n3 1 2 3\n",
        "counts_on_header_line.off": b"OFF 4 4 0\n0 0 0\n1 0 0\n0 1 0\n0 0 1\n3 0 2 1\n3 0 1 3\n3 0 3 2\n3 1 2 3\n",
        "short_face.off": b"OFF\n4 5 0\n0 0 0\n1 0 0\n0 1 0\n0 0 1\n3 0 2 1\n3 0 1 3\n3 0 3 2\n3 1 2 3\n2 0 1\n",
        "exponents.off": b"OFF\n4 4 0\n0e0 -0 +0\n1E+0 0 0\n0 .1e1 0\n0 0 1.\n3 0 2 1\n3 0 1 3\n3 0 3 2\n3 1 2 3\n",
        # nearly valid
        "huge_count.off": b"OFF\n1000000000000 4 0\n0 0 0\n",
        "huge_face.off": b"OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n2147483648 0 1 2\n",
        "index_out_of_range.off": b"OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 3\n",
        "negative_index.off": b"OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 -1 2\n",
        "nan.off": b"OFF\n3 1 0\nnan 0 0\n1 0 0\n0 1 inf\n3 0 1 2\n",
        "truncated.off": off_text(TETRA_V, TETRA_F)[:-9],
        "trailing_data.off": off_text(TETRA_V, TETRA_F) + b"3 0 1 2\n",
        "no_header.off": b"4 4 0\n0 0 0\n1 0 0\n0 1 0\n0 0 1\n3 0 2 1\n3 0 1 3\n3 0 3 2\n3 1 2 3\n",
    }
    return s


def obj_text(vertices, faces, newline="\n"):
    lines = ["# tetrahedron", "o tetra"] + ["v " + " ".join(num(c) for c in v) for v in vertices]
    lines += ["f " + " ".join(str(i + 1) for i in f) for f in faces]
    return (newline.join(lines) + newline).encode()


def obj_seeds():
    vs = "".join(f"v {x} {y} {z}\n" for x, y, z in TETRA_V)
    vts = "vt 0 0\nvt 1 0\nvt 0 1\nvt 1 1\n"
    vns = "vn 0 0 1\nvn 0 1 0\nvn 1 0 0\nvn 0.577 0.577 0.577\n"
    faces = [(0, 2, 1), (0, 1, 3), (0, 3, 2), (1, 2, 3)]

    def form(fmt):
        return "".join("f " + " ".join(fmt.format(i + 1) for i in f) + "\n" for f in faces)

    s = {
        "tetra.obj": obj_text(TETRA_V, TETRA_F),
        "v_vt_vn.obj": (vs + vts + vns + form("{0}/{0}/{0}")).encode(),
        "v_vt.obj": (vs + vts + form("{0}/{0}")).encode(),
        "v_vn.obj": (vs + vns + form("{0}//{0}")).encode(),
        "negative.obj": (vs + "f -4 -2 -3\nf -4 -3 -1\nf -4 -1 -2\nf -3 -2 -1\n").encode(),
        "cube_quads.obj": ("".join(f"v {x} {y} {z}\n" for x, y, z in CUBE_V) +
                           "".join("f " + " ".join(str(i + 1) for i in q) + "\n" for q in CUBE_Q)).encode(),
        "groups_materials.obj": ("mtllib a.mtl\no thing\ng part\nusemtl red\ns off\n" + vs +
                                 "s 1\nl 1 2\np 3\n" + form("{0}")).encode(),
        "crlf_bom.obj": b"\xef\xbb\xbf" + obj_text(TETRA_V, TETRA_F, newline="\r\n"),
        "line_continuation.obj": ("v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1 1.0\n"
                                  "f 1 3 \\\n 2\nf 1 2 4\nf 1 4 3\nf 2 3 4\n").encode(),
        # nearly valid
        "zero_index.obj": (vs + "f 0 1 2\n").encode(),
        "out_of_range.obj": (vs + "f 1 2 5\n").encode(),
        "negative_out_of_range.obj": (vs + "f -1 -2 -5\n").encode(),
        "huge_index.obj": (vs + "f 1 2 99999999999999999999\n").encode(),
        "nan.obj": b"v nan 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n",
        "short_vertex.obj": b"v 1 2\nv 1 0 0\nv 0 1 0\nf 1 2 3\n",
        "bad_face_form.obj": (vs + "f 1/ 2// 3/x/\n").encode(),
        "empty_face.obj": (vs + "f\nf 1\nf 1 2\n").encode(),
    }
    return s


def ply_header(fmt, vertex_props, nv, face_elem, nf, extra=""):
    h = f"ply\nformat {fmt} 1.0\ncomment made by fuzz_corpus.py\n{extra}element vertex {nv}\n"
    h += "".join(f"property {t} {n}\n" for t, n in vertex_props)
    h += f"{face_elem}\n" if face_elem else ""
    return h.replace("{nf}", str(nf)) + "end_header\n"


def ply_seeds():
    xyz = [("float", "x"), ("float", "y"), ("float", "z")]
    face_list = "element face {nf}\nproperty list uchar int vertex_indices"
    s = {}
    # ascii
    body = "".join(f"{x} {y} {z}\n" for x, y, z in TETRA_V) + "".join(f"3 {a} {b} {c}\n" for a, b, c in TETRA_F)
    s["tetra_ascii.ply"] = (ply_header("ascii", xyz, 4, face_list, 4) + body).encode()
    s["crlf_ascii.ply"] = s["tetra_ascii.ply"].replace(b"\n", b"\r\n")
    props = xyz + [("float", "nx"), ("float", "ny"), ("float", "nz"), ("uchar", "red"), ("uchar", "green"),
                   ("uchar", "blue")]
    body = "".join(f"{x} {y} {z} 0 0 1 255 128 0\n" for x, y, z in TETRA_V)
    body += "".join(f"3 {a} {b} {c} 7\n" for a, b, c in TETRA_F)
    s["extra_properties_ascii.ply"] = (ply_header(
        "ascii", props, 4, "element face {nf}\nproperty list uint8 int32 vertex_index\nproperty int flags", 4,
        "obj_info generated\n") + body).encode()
    body = "".join(f"{x} {y} {z}\n" for x, y, z in CUBE_V) + "".join(
        "4 " + " ".join(map(str, q)) + "\n" for q in CUBE_Q)
    s["cube_quads_ascii.ply"] = (ply_header("ascii", xyz, 8, face_list, 6) + body).encode()
    # tristrips: a strip and a restart (-1)
    strip_elem = "element tristrips {nf}\nproperty list int int vertex_indices"
    body = "".join(f"{x} {y} {z}\n" for x, y, z in TETRA_V) + "7 0 2 1 3 -1 2 0\n"
    s["tristrips_ascii.ply"] = (ply_header("ascii", xyz, 4, strip_elem, 1) + body).encode()
    # binary little endian: float and double coordinates, several index types
    for name, vt, vfmt, lt, lfmt, it, ifmt in [
        ("float_uchar_int", "float", "<fff", "uchar", "<B", "int", "<iii"),
        ("double_uint_uint", "double", "<ddd", "uint", "<I", "uint", "<III"),
        ("float_ushort_short", "float32", "<fff", "ushort", "<H", "short", "<hhh"),
    ]:
        props = [(vt, "x"), (vt, "y"), (vt, "z")]
        head = ply_header("binary_little_endian", props, 4,
                          f"element face {{nf}}\nproperty list {lt} {it} vertex_indices", 4)
        data = b"".join(struct.pack(vfmt, *v) for v in TETRA_V)
        data += b"".join(struct.pack(lfmt, 3) + struct.pack(ifmt, *f) for f in TETRA_F)
        s[f"tetra_binary_{name}.ply"] = head.encode() + data
    head = ply_header("binary_little_endian", xyz, 4, strip_elem, 1)
    data = b"".join(struct.pack("<fff", *v) for v in TETRA_V) + struct.pack("<i", 7) + struct.pack(
        "<7i", 0, 2, 1, 3, -1, 2, 0)
    s["tristrips_binary.ply"] = head.encode() + data
    head = ply_header("binary_little_endian", xyz, 6, face_list, 8)
    data = b"".join(struct.pack("<fff", *v) for v in OCTA_V) + b"".join(
        struct.pack("<B3i", 3, *f) for f in OCTA_F)
    s["octahedron_binary.ply"] = head.encode() + data
    # nearly valid
    s["big_endian.ply"] = s["tetra_binary_float_uchar_int.ply"].replace(b"binary_little_endian",
                                                                         b"binary_big_endian")
    s["huge_vertex_count.ply"] = (ply_header("binary_little_endian", xyz, 10**12, face_list, 1)).encode()
    head = ply_header("binary_little_endian", xyz, 3,
                      "element face {nf}\nproperty list uint int vertex_indices", 1)
    s["list_count_2_31.ply"] = head.encode() + b"\0" * 36 + struct.pack("<I", 2**31) + struct.pack("<3i", 0, 1, 2)
    s["truncated_binary.ply"] = s["octahedron_binary.ply"][:-7]
    s["trailing_binary.ply"] = s["octahedron_binary.ply"] + b"\0\0\0\0"
    s["index_out_of_range.ply"] = (ply_header("ascii", xyz, 3, face_list, 1) + "0 0 0\n1 0 0\n0 1 0\n3 0 1 3\n").encode()
    s["nan_binary.ply"] = (ply_header("binary_little_endian", xyz, 3, face_list, 1).encode() +
                           struct.pack("<fff", math.nan, 0, 0) + struct.pack("<fff", 1, 0, 0) +
                           struct.pack("<fff", 0, 1, 0) + struct.pack("<B3i", 3, 0, 1, 2))
    s["float_indices.ply"] = (ply_header("ascii", xyz, 3, "element face {nf}\nproperty list uchar float vertex_indices",
                                         1) + "0 0 0\n1 0 0\n0 1 0\n3 0 1.5 2\n").encode()
    s["no_end_header.ply"] = b"ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\n"
    return s


def freesurfer_bytes(vertices, faces, created=b"created by fuzz_corpus on Thu Jan  1 00:00:00 1970\n\n",
                     magic=b"\xff\xff\xfe", counts=None):
    nv, nf = counts if counts else (len(vertices), len(faces))
    data = magic + created + struct.pack(">ii", nv, nf)
    data += b"".join(struct.pack(">fff", *v) for v in vertices)
    data += b"".join(struct.pack(">iii", *f) for f in faces)
    return data


def freesurfer_seeds():
    s = {
        "tetra.fs": freesurfer_bytes(TETRA_V, TETRA_F),
        "octahedron.fs": freesurfer_bytes(OCTA_V, OCTA_F),
        "short_created_line.fs": freesurfer_bytes(TETRA_V, TETRA_F, created=b"x\n\n"),
        "trailing_tags.fs": freesurfer_bytes(OCTA_V, OCTA_F) + struct.pack(">iii", 3, 0, 20) + b"vol geom\n",
        # nearly valid
        "huge_counts.fs": freesurfer_bytes([], [], counts=(2**31 - 1, 2**31 - 1)),
        "negative_counts.fs": freesurfer_bytes([], [], counts=(-1, 4)),
        "truncated.fs": freesurfer_bytes(OCTA_V, OCTA_F)[:-5],
        "index_out_of_range.fs": freesurfer_bytes(TETRA_V, [(0, 1, 4)] + TETRA_F[1:]),
        "nan.fs": freesurfer_bytes([(math.nan, 0, 0)] + TETRA_V[1:], TETRA_F),
        "no_blank_line.fs": freesurfer_bytes(TETRA_V, TETRA_F, created=b"created by nobody\n"),
        "quad_magic.fs": freesurfer_bytes(TETRA_V, TETRA_F, magic=b"\xff\xff\xff"),
    }
    return s


# ----------------------------------------------------------------------------------- images

def pgm_seeds():
    pix8 = bytes([0, 64, 128, 255, 32, 16])
    s = {
        "p2_8bit.pgm": b"P2\n# a comment\n3 2\n255\n0 64 128\n255 32 16\n",
        "p2_16bit.pgm": b"P2 2 2 65535 0 1000 65535 30000\n",
        "p2_maxval1.pgm": b"P2\n4 1\n1\n0 1 1 0",
        "p5_8bit.pgm": b"P5\n3 2\n255\n" + pix8,
        "p5_16bit.pgm": b"P5\n2 2\n65535\n" + struct.pack(">4H", 0, 1, 40000, 65535),
        "p5_comment.pgm": b"P5 #c\n3#c\n2 15\n" + bytes([0, 1, 15, 7, 3, 2]),
        "p5_crlf.pgm": b"P5\r\n3 2\r\n255\r" + pix8,
        # nearly valid
        "huge_50000.pgm": b"P5\n50000 50000\n255\n" + pix8,
        "huge_p2.pgm": b"P2\n16384 16384\n255\n1 2 3\n",
        "truncated_p5.pgm": b"P5\n3 2\n255\n" + pix8[:4],
        "truncated_p2.pgm": b"P2\n3 2\n255\n0 1 2 3",
        "above_maxval.pgm": b"P2\n2 1\n10\n5 11\n",
        "maxval_0.pgm": b"P5\n1 1\n0\n\0",
        "maxval_65536.pgm": b"P2\n1 1\n65536\n1\n",
        "zero_size.pgm": b"P5\n0 3\n255\n",
        "no_space.pgm": b"P53 2 255\n" + pix8,
        "long_number.pgm": b"P2\n1 1\n99999999999999999999999999\n1\n",
    }
    return s


def png_chunk(kind, data):
    return struct.pack(">I", len(data)) + kind + data + struct.pack(">I", zlib.crc32(kind + data) & 0xFFFFFFFF)


def pack_row(samples, depth):
    if depth == 8:
        return bytes(samples)
    if depth == 16:
        return b"".join(struct.pack(">H", v) for v in samples)
    per_byte = 8 // depth
    out = bytearray()
    for i in range(0, len(samples), per_byte):
        b = 0
        for k in range(per_byte):
            v = samples[i + k] if i + k < len(samples) else 0
            b |= v << (8 - depth * (k + 1))
        out.append(b)
    return bytes(out)


ADAM7 = [(0, 0, 8, 8), (4, 0, 8, 8), (0, 4, 4, 8), (2, 0, 4, 4), (0, 2, 2, 4), (1, 0, 2, 2), (0, 1, 1, 2)]


def png_bytes(width, height, depth, color, pixel, interlace=False, extra=b"", idat=None, ihdr_size=None,
              ihdr_depth=None):
    """pixel(x, y) -> list of samples; color: 0 gray, 2 rgb, 3 palette, 4 gray+alpha, 6 rgba.
    ihdr_size, ihdr_depth: what the header claims, when not the data's."""
    raw = bytearray()
    passes = ADAM7 if interlace else [(0, 0, 1, 1)]
    for x0, y0, dx, dy in passes:
        xs = range(x0, width, dx)
        if not xs:
            continue
        for y in range(y0, height, dy):
            samples = [s for x in xs for s in pixel(x, y)]
            raw += b"\0" + pack_row(samples, depth)
    w, h = ihdr_size if ihdr_size else (width, height)
    ihdr = struct.pack(">IIBBBBB", w, h, ihdr_depth or depth, color, 0, 0, 1 if interlace else 0)
    data = zlib.compress(bytes(raw), 9) if idat is None else idat
    return (b"\x89PNG\r\n\x1a\n" + png_chunk(b"IHDR", ihdr) + extra + png_chunk(b"IDAT", data) +
            png_chunk(b"IEND", b""))


def png_seeds():
    def g(x, y):
        return [(x * 37 + y * 11) % 256]

    def rgb(x, y):
        return [(x * 40) % 256, (y * 60) % 256, ((x + y) * 25) % 256]

    palette = png_chunk(b"PLTE", bytes([0, 0, 0, 255, 0, 0, 0, 255, 0, 0, 0, 255]))
    s = {
        "gray8.png": png_bytes(5, 3, 8, 0, g),
        "gray1.png": png_bytes(9, 2, 1, 0, lambda x, y: [(x + y) % 2]),
        "gray2.png": png_bytes(5, 2, 2, 0, lambda x, y: [(x + y) % 4]),
        "gray4.png": png_bytes(3, 3, 4, 0, lambda x, y: [(x * 5 + y) % 16]),
        "gray16.png": png_bytes(3, 2, 16, 0, lambda x, y: [(x * 20000 + y * 7) % 65536]),
        "gray_alpha.png": png_bytes(3, 2, 8, 4, lambda x, y: g(x, y) + [200]),
        "rgb8.png": png_bytes(4, 3, 8, 2, rgb),
        "rgb16.png": png_bytes(2, 2, 16, 2, lambda x, y: [v * 257 for v in rgb(x, y)]),
        "rgba8.png": png_bytes(3, 2, 8, 6, lambda x, y: rgb(x, y) + [128]),
        "palette.png": png_bytes(4, 2, 8, 3, lambda x, y: [(x + y) % 4], extra=palette),
        "palette2_trns.png": png_bytes(4, 2, 2, 3, lambda x, y: [(x + y) % 4],
                                       extra=palette + png_chunk(b"tRNS", bytes([0, 255]))),
        "interlaced_gray.png": png_bytes(9, 9, 8, 0, g, interlace=True),
        "interlaced_rgb.png": png_bytes(10, 7, 8, 2, rgb, interlace=True),
        "gamma_text.png": png_bytes(2, 2, 8, 0, g, extra=png_chunk(b"gAMA", struct.pack(">I", 45455)) +
                          png_chunk(b"tEXt", b"Comment\0fuzz")),
        # nearly valid
        "huge_50000.png": png_bytes(1, 1, 8, 0, g, ihdr_size=(50000, 50000)),
        "large_16384.png": png_bytes(1, 1, 16, 2, rgb, ihdr_size=(16384, 16384)),
        "tall_1x2_28.png": png_bytes(1, 1, 1, 0, lambda x, y: [1], ihdr_size=(1, 2**28)),
        "zero_width.png": png_bytes(1, 1, 8, 0, g, ihdr_size=(0, 1)),
        "truncated_idat.png": png_bytes(8, 8, 8, 0, g, idat=zlib.compress(bytes(30))),
        "bad_crc.png": png_bytes(3, 2, 8, 0, g)[:-5] + b"\0\0\0\0\0",
        "palette_missing_plte.png": png_bytes(4, 2, 8, 3, lambda x, y: [(x + y) % 4]),
        "bad_depth.png": png_bytes(2, 2, 8, 0, g, ihdr_depth=3),
    }
    return s


# ----------------------------------------------------------------------------------- problems

def problem_seeds():
    square = [[0, 0], [1, 0], [1, 1], [0, 1]]
    plane_sites = [[0.2, 0.3], [0.7, 0.2], [0.5, 0.8], [0.3, 0.6], [0.85, 0.75]]
    sphere_sites = [[1, 0, 0], [0, 1, 0], [0, 0, 1], [-1, 0, 0], [0, -1, 0], [0.6, 0, -0.8]]
    octa_mesh = {"vertices": [list(v) for v in OCTA_V], "triangles": [list(f) for f in OCTA_F]}
    klein_domain = {"model": "klein", "vertices": [[-0.5, -0.5], [0.5, -0.5], [0.5, 0.5], [-0.5, 0.5]]}
    klein_sites = [[-0.2, -0.2], [0.2, -0.1], [0.1, 0.25], [-0.15, 0.2]]
    problems = {
        "plane_basic": {"geometry": "plane", "sites": plane_sites},
        "plane_masses_tolerance": {"geometry": "plane", "sites": plane_sites, "masses": [1, 2, 3, 4, 5],
                                   "tolerance": 1e-10, "max_iterations": 30, "linear_solver": "ldlt"},
        "plane_convex_domain": {"geometry": "plane", "sites": [[1, 1], [2, 1.5], [1.5, 2.5]],
                                "domain": [[0, 0], [3, 0], [3, 3], [0, 3]], "linear_solver": "cg"},
        "plane_holes": {"geometry": "plane", "sites": [[0.5, 0.5], [3.5, 0.5], [2, 3.5], [1.5, 1.5]],
                        "domain": {"outer": [[0, 0], [4, 0], [4, 4], [0, 4]],
                                   "holes": [[[1, 1], [2, 1], [2, 2], [1, 2]]]}},
        "plane_polygons": {"geometry": "plane", "sites": [[0.5, 0.5], [2.5, 0.5], [0.4, 0.6]],
                           "domain": {"polygons": [{"outer": square},
                                                   {"outer": [[2, 0], [3, 0], [3, 1], [2, 1]]}]}},
        "plane_mesh_density": {"geometry": "plane", "sites": plane_sites,
                               "density": {"type": "mesh", "vertices": square, "triangles": [[0, 1, 2], [0, 2, 3]],
                                           "values": [1, 2, 3, 0], "quadrature_order": 5}},
        "plane_mesh_triangle_values": {"geometry": "plane", "sites": plane_sites,
                                       "density": {"type": "mesh", "vertices": square,
                                                   "triangles": [[0, 1, 2], [0, 2, 3]], "triangle_values": [0.5, 2]}},
        "plane_image_density": {"geometry": "plane", "sites": plane_sites,
                                "density": {"type": "image", "file": "photo.pgm", "interpolation": "constant",
                                            "rectangle": [0, 0, 1, 1], "scale": 2}},
        "plane_weights": {"geometry": "plane", "sites": plane_sites[:3], "weights": [0, 0.01, -0.01],
                          "density": {"type": "uniform"}},
        "sphere_basic": {"geometry": "sphere", "sites": sphere_sites},
        "sphere_cap": {"geometry": "sphere", "sites": [[0, 0, 1], [0.3, 0, 0.95], [0, 0.3, 0.95]],
                       "domain": {"type": "cap", "center": [0, 0, 1], "angle": 0.6}},
        "sphere_polygon": {"geometry": "sphere", "sites": [[0.2, 0.2, 0.95], [0.5, 0.1, 0.86], [0.1, 0.5, 0.86]],
                           "domain": {"type": "polygon", "vertices": [[0, 0, 1], [1, 0, 0], [0, 1, 0]]},
                           "masses": [1, 1, 2]},
        "sphere_mesh_density": {"geometry": "sphere", "sites": sphere_sites, "domain": {"type": "sphere"},
                                "density": dict(type="mesh", values=[1, 2, 1, 2, 3, 0.5], **octa_mesh)},
        "sphere_image_density": {"geometry": "sphere", "sites": sphere_sites,
                                 "density": {"type": "image", "file": "earth.png", "interpolation": "linear"}},
        "torus": {"geometry": "torus", "sites": plane_sites, "domain": [0, 0, 1, 1], "periodic": True},
        "torus_one_axis_mesh_density": {"geometry": "torus", "sites": plane_sites, "periodic": [True, False],
                                        "density": {"type": "mesh", "vertices": square, "triangles": [[0, 1, 2]],
                                                    "values": [1, 2, 1, 1]}},
        "hyperbolic_klein": {"geometry": "hyperbolic", "domain": klein_domain, "sites": klein_sites},
        "hyperbolic_poincare": {"geometry": "hyperbolic", "sites_model": "poincare",
                                "domain": {"model": "poincare", "vertices": [[0.5, 0], [0, 0.5], [-0.5, 0], [0, -0.5]]},
                                "sites": [[0.1, 0.1], [-0.1, 0.2], [0, -0.2]], "masses": [1, 2, 3]},
        "hyperbolic_hyperboloid": {"geometry": "hyperbolic", "sites_model": "klein",
                                   "domain": {"model": "hyperboloid",
                                              "vertices": [[1.5, 0, 1.8027756377319946],
                                                           [-0.75, 1.299038105676658, 1.8027756377319946],
                                                           [-0.75, -1.299038105676658, 1.8027756377319946]]},
                                   "sites": [[0.1, 0], [-0.1, 0.1], [0, -0.1]]},
        "hyperbolic_mesh_density": {"geometry": "hyperbolic", "domain": klein_domain, "sites": klein_sites,
                                    "density": {"type": "mesh", "vertices": [[-0.6, -0.6], [0.6, -0.6], [0.6, 0.6],
                                                                             [-0.6, 0.6]],
                                                "triangles": [[0, 1, 2], [0, 2, 3]], "values": [1, 2, 1, 0.5]}},
        # nearly valid
        "unknown_field": {"geometry": "plane", "sites": plane_sites, "tolerence": 1e-6},
        "negative_mass": {"geometry": "plane", "sites": plane_sites[:2], "masses": [1, -1]},
        "unknown_geometry": {"geometry": "cube", "sites": plane_sites},
        "wrong_dimension": {"geometry": "sphere", "sites": plane_sites},
        "nonconvex_domain": {"geometry": "plane", "sites": plane_sites[:2],
                             "domain": [[0, 0], [2, 0], [1, 0.2], [1, 2]]},
        "outside_site": {"geometry": "hyperbolic", "domain": klein_domain, "sites": [[0.99, 0], [0, 0]]},
        "big_iterations": {"geometry": "plane", "sites": plane_sites[:2], "max_iterations": 4294967301},
        "zero_sphere_site": {"geometry": "sphere", "sites": [[0, 0, 0], [1, 0, 0]]},
        "density_index_out_of_range": {"geometry": "plane", "sites": plane_sites,
                                       "density": {"type": "mesh", "vertices": square,
                                                   "triangles": [[0, 1, 4]], "values": [1, 1, 1, 1]}},
    }
    return {name + ".json": json.dumps(p, indent=1).encode() for name, p in problems.items()}


def mesh_density_seeds():
    """First byte: geometry (byte % 3: plane, sphere, hyperbolic) and mesh in a file (byte / 3 % 2)."""
    square = {"vertices": [[0, 0], [1, 0], [1, 1], [0, 1]], "triangles": [[0, 1, 2], [0, 2, 3]]}
    octa = {"vertices": [list(v) for v in OCTA_V], "triangles": [list(f) for f in OCTA_F]}
    klein = {"vertices": [[-0.6, -0.6], [0.6, -0.6], [0.6, 0.6], [-0.6, 0.6]], "triangles": [[0, 1, 2], [0, 2, 3]]}
    meshes = [("plane", square, [1, 2, 3, 0], [0.5, 2]), ("sphere", octa, [1, 2, 1, 2, 3, 0.5], [1] * 7 + [0]),
              ("hyperbolic", klein, [1, 2, 1, 0.5], [1, 3])]
    s = {}
    for g, (name, mesh, values, triangle_values) in enumerate(meshes):
        for in_file in (0, 1):
            byte = bytes([g + 3 * in_file])
            where = "file" if in_file else "inline"
            s[f"{name}_{where}_values.json"] = byte + json.dumps(dict(values=values, **mesh)).encode()
            s[f"{name}_{where}_triangle_values.json"] = byte + json.dumps(
                dict(triangle_values=triangle_values, **mesh)).encode()
            s[f"{name}_{where}_order.json"] = byte + json.dumps(
                dict(values=values, quadrature_order=9, **mesh)).encode()
        # nearly valid
        byte = bytes([g])
        s[f"{name}_both_values.json"] = byte + json.dumps(dict(values=values, triangle_values=triangle_values,
                                                               **mesh)).encode()
        s[f"{name}_bad_index.json"] = byte + json.dumps(
            dict(values=values, vertices=mesh["vertices"], triangles=[[0, 1, 99]])).encode()
        s[f"{name}_negative_value.json"] = byte + json.dumps(dict(values=[-1] + values[1:], **mesh)).encode()
        s[f"{name}_degenerate.json"] = byte + json.dumps(
            dict(values=values, vertices=mesh["vertices"], triangles=[[0, 1, 1]])).encode()
    return s


def main():
    if len(sys.argv) != 2:
        sys.exit(__doc__)
    out = Path(sys.argv[1])
    harnesses = {"off": off_seeds, "obj": obj_seeds, "ply": ply_seeds, "freesurfer": freesurfer_seeds,
                 "pgm": pgm_seeds, "png": png_seeds, "problem": problem_seeds, "mesh_density": mesh_density_seeds}
    for harness, seeds in harnesses.items():
        folder = out / harness
        folder.mkdir(parents=True, exist_ok=True)
        for name, data in seeds().items():
            (folder / name).write_bytes(data)
        print(f"fuzz_corpus: {len(seeds())} seeds in {folder}")


if __name__ == "__main__":
    main()
