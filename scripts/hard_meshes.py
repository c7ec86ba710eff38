#!/usr/bin/python3
"""Generates the hard inputs of sdot-sphere-param (docs/spherical_parameterization.md, "Hard shapes").

    /usr/bin/python3 scripts/hard_meshes.py OUTDIR [--cases tubes capsule capsule40 spiky folds slivers cones]
                                           [--sizes 25000 60000 120000] [--seed 1]

Writes OUTDIR/CASE_SIZEk.off for every case and size: closed, genus-0, manifold, outward-oriented
triangle meshes of about SIZE vertices (the exact count is printed; the shape of a case does not
depend on SIZE, only its resolution does). Every case is deterministic (fixed seeds, numpy only).

  tubes    a body (ellipsoid) with 4 long thin limbs, each ending in a hand (a small ball) with 5
           fingers; every limb and finger is a closed-ended tube whose radius is 1/100 of its
           length, welded to the ball it leaves (tubes are limbs, never handles: genus 0)
  spiky    a sphere with --spikes (default 120) long spikes: the radial function
           r = 1 + 2.5 sum_k exp(-(angle to spike k / 0.06)^2) on a fine icosphere (star-shaped,
           so embedded and genus 0)
  cones    a sphere with 8 long conical spikes: r = 1 + 13 cos(pi/2 angle/0.15) within 0.15 rad
           (--cone-count, --cone-length and --cone-width change the 8, the 14 and the 0.15)
           of each spike's direction, 1 elsewhere (star-shaped): cones 14 radii long whose
           triangles are stretched about 90 times along them, so that few vertices resolve each
           spike (about 150 at 25k)
  folds    a cortex-like surface: r = 1 + 0.12 tanh(4 g) with g a domain-warped product of sines
           of frequency 18: folds about 0.17 wide and 0.24 deep (star-shaped)
  capsule  one closed tube whose length is 300 times its radius (3 times the ratio of the tubes
           case): rings of vertices, each turned by half a step from the last, about
           equilateral triangles, and each end closed by a fan around one apex vertex
  capsule40  the same tube 40 times as long as its radius: its Tutte map is crushed by about
           e^-33, within reach of the stretch reweighting (the capsule's e^-600 is not)
  slivers  an icosphere whose edges are split, a fifth of them at 1e-3 of their length from an
           end (neighbouring faces with 1000:1 area ratios) and a fifth at 2.5e-5 (0.001 degree
           needles), and a tenth of its faces split by a point 1e-5 of the face's height from an
           edge (flat slivers with angles near 180 degrees)
"""
import argparse
import math
import pathlib
import sys

import numpy as np

ICO_VERTICES = None
ICO_FACES = None


def icosahedron():
    t = (1 + 5 ** 0.5) / 2
    v = np.array([[-1, t, 0], [1, t, 0], [-1, -t, 0], [1, -t, 0], [0, -1, t], [0, 1, t], [0, -1, -t], [0, 1, -t],
                  [t, 0, -1], [t, 0, 1], [-t, 0, -1], [-t, 0, 1]], dtype=float)
    f = np.array([[0, 11, 5], [0, 5, 1], [0, 1, 7], [0, 7, 10], [0, 10, 11], [1, 5, 9], [5, 11, 4], [11, 10, 2],
                  [10, 7, 6], [7, 1, 8], [3, 9, 4], [3, 4, 2], [3, 2, 6], [3, 6, 8], [3, 8, 9], [4, 9, 5],
                  [2, 4, 11], [6, 2, 10], [8, 6, 7], [9, 8, 1]])
    return v / np.linalg.norm(v, axis=1)[:, None], f


def icosphere(n):
    """Unit geodesic sphere of frequency n (10 n^2 + 2 vertices), outward oriented."""
    v0, f0 = icosahedron()
    # barycentric grid of one face: points (i, j) with i + j <= n
    ij = [(i, j) for i in range(n + 1) for j in range(n + 1 - i)]
    local = {p: k for k, p in enumerate(ij)}
    bary = np.array([[n - i - j, i, j] for i, j in ij], dtype=float) / n
    tris = []
    for i in range(n):
        for j in range(n - i):
            tris.append((local[(i, j)], local[(i + 1, j)], local[(i, j + 1)]))
            if i + j + 1 < n:
                tris.append((local[(i + 1, j)], local[(i + 1, j + 1)], local[(i, j + 1)]))
    tris = np.array(tris)
    points, faces = [], []
    for k, face in enumerate(f0):
        p = bary @ v0[face]
        points.append(p / np.linalg.norm(p, axis=1)[:, None])
        faces.append(tris + k * len(ij))
    points = np.concatenate(points)
    faces = np.concatenate(faces)
    # weld the shared edge points
    _, first, inverse = np.unique(np.round(points * 1e9).astype(np.int64), axis=0, return_index=True,
                                  return_inverse=True)
    inverse = inverse.reshape(-1)
    v = points[first]
    f = inverse[faces]
    return orient_outward(v, f)


def orient_outward(v, f):
    n = np.cross(v[f[:, 1]] - v[f[:, 0]], v[f[:, 2]] - v[f[:, 0]])
    centre = v[f].mean(axis=1)
    flip = np.einsum('ij,ij->i', n, centre) < 0  # star-shaped about the origin: per face
    f = f.copy()
    f[flip] = f[flip][:, [0, 2, 1]]
    return v, f


def size_to_frequency(size):
    return max(4, int(round(math.sqrt(max(size - 2, 10) / 10))))


def spike_directions(count, seed):
    """Fibonacci-spiral directions, slightly jittered (well separated, deterministic)."""
    rng = np.random.default_rng(seed)
    k = np.arange(count) + 0.5
    z = 1 - 2 * k / count
    phi = math.pi * (3 - math.sqrt(5)) * k + rng.uniform(-0.2, 0.2, count)
    d = np.stack([np.sqrt(1 - z * z) * np.cos(phi), np.sqrt(1 - z * z) * np.sin(phi), z], axis=1)
    return d / np.linalg.norm(d, axis=1)[:, None]


# ----------------------------------------------------------------------------------- the cases
def sphere_and_spike_angles(size, count, seed):
    """An icosphere of about `size` vertices and each vertex's angle to each of `count` spike
    directions (vertices × spikes)."""
    v, f = icosphere(size_to_frequency(size))
    return v, f, np.arccos(np.clip(v @ spike_directions(count, seed).T, -1, 1))


def spiky(size, seed, spikes=120, length=2.5, width=0.06):
    v, f, angle = sphere_and_spike_angles(size, spikes, seed)
    r = 1 + length * np.exp(-(angle / width) ** 2).sum(axis=1)
    return v * r[:, None], f


def cones(size, seed, count=8, length=14.0, width=0.15):
    v, f, angle = sphere_and_spike_angles(size, count, seed)
    r = 1 + np.where(angle < width, (length - 1) * np.cos(0.5 * math.pi * (angle / width)), 0).max(axis=1)
    return v * r[:, None], f


def folds(size, seed, frequency=18.0, depth=0.12):
    v, f = icosphere(size_to_frequency(size))
    rng = np.random.default_rng(seed)
    rotation, _ = np.linalg.qr(rng.normal(size=(3, 3)))
    x, y, z = (v @ rotation).T
    # domain warping turns a grid of bumps into winding gyri separated by narrow sulci
    u1 = x + 0.15 * np.sin(5 * y + 1) + 0.08 * np.sin(9 * z)
    u2 = y + 0.15 * np.sin(5 * z + 2) + 0.08 * np.sin(9 * x)
    u3 = z + 0.15 * np.sin(5 * x + 3) + 0.08 * np.sin(9 * y)
    g = np.sin(frequency * u1) * np.sin(frequency * u2) + 0.6 * np.sin(frequency * u3)
    r = 1 + depth * np.tanh(4 * g)
    return v * r[:, None], f


def slivers(size, seed):
    v, f = icosphere(size_to_frequency(size / 1.7))  # the splits add about 0.7 vertices per vertex
    rng = np.random.default_rng(seed)
    vertices = list(v)
    faces = [tuple(t) for t in f]
    # edges, each with its two faces; pick edges whose faces are all distinct (no face split twice)
    edge_faces = {}
    for k, (a, b, c) in enumerate(faces):
        for p, q in ((a, b), (b, c), (c, a)):
            edge_faces.setdefault((min(p, q), max(p, q)), []).append(k)
    edges = list(edge_faces)
    order = rng.permutation(len(edges))
    used = np.zeros(len(faces), dtype=bool)
    alive = [True] * len(faces)
    new_faces = []
    splits = 0
    for e in order:
        a, b = edges[e]
        f1, f2 = edge_faces[(a, b)]
        if used[f1] or used[f2]:
            continue
        kind = splits % 5  # 0: area ratio 1000:1, 1: 0.001 degree needles, else unsplit
        splits += 1
        if kind > 1:
            continue
        used[f1] = used[f2] = True
        t = 1e-3 if kind == 0 else 2.5e-5
        p = len(vertices)
        vertices.append(v[a] + t * (v[b] - v[a]))  # on the chord: exact area ratios
        for fk in (f1, f2):
            alive[fk] = False
            tri = list(faces[fk])
            i = tri.index(a)
            # rotate so the face is (a, x, y); the split edge is (a, b) in either direction
            tri = tri[i:] + tri[:i]
            if tri[1] == b:  # (a, b, c) -> (a, p, c), (p, b, c)
                c = tri[2]
                new_faces += [(a, p, c), (p, b, c)]
            else:  # (a, c, b) -> (a, c, p), (p, c, b)
                c = tri[1]
                new_faces += [(a, c, p), (p, c, b)]
    # flat slivers: a tenth of the untouched faces get a point just inside one of their edges
    for k in rng.permutation(len(faces)):
        if used[k] or not alive[k] or rng.random() > 0.1:
            continue
        a, b, c = faces[k]
        alive[k] = False
        m = 0.5 * (v[a] + v[b])
        p = len(vertices)
        vertices.append(m + 1e-5 * (v[c] - m))
        new_faces += [(a, b, p), (b, c, p), (c, a, p)]
    faces = [t for t, keep in zip(faces, alive) if keep] + new_faces
    return np.array(vertices), np.array(faces)


# ------------------------------------------------------------------------------------- capsule
def capsule(size, seed, ratio=300.0):
    """A tube of radius 1 and length `ratio` with about `size` vertices (seed unused: no randomness)."""
    # V = around * rings with rings = ratio / spacing, spacing = 2 sin(pi/around) sqrt(3)/2 ~ pi sqrt(3)/around
    around = max(6, round(math.sqrt(size * math.pi * math.sqrt(3) / ratio)))
    step = 2 * math.pi / around
    spacing = 2 * math.sin(step / 2) * math.sqrt(3) / 2
    rings = max(2, round(ratio / spacing) + 1)
    k, j = np.meshgrid(np.arange(rings), np.arange(around), indexing='ij')
    angle = (j + 0.5 * (k % 2)) * step
    v = np.stack([np.cos(angle), np.sin(angle), ratio * k / (rings - 1)], axis=-1).reshape(-1, 3)

    def at(kk, jj):
        return kk * around + jj % around

    kk, jj = np.meshgrid(np.arange(rings - 1), np.arange(around), indexing='ij')
    kk, jj = kk.ravel(), jj.ravel()
    up = jj + kk % 2  # the vertex of ring k + 1 between (k, j) and (k, j + 1)
    sides = np.concatenate([np.stack([at(kk, jj), at(kk, jj + 1), at(kk + 1, up)], axis=1),
                            np.stack([at(kk, jj), at(kk + 1, up), at(kk + 1, up - 1)], axis=1)])
    bottom, top = len(v), len(v) + 1
    v = np.vstack([v, [[0, 0, -spacing / 2], [0, 0, ratio + spacing / 2]]])
    ring = np.arange(around)
    caps = np.concatenate([np.stack([np.full(around, bottom), at(0, ring + 1), at(0, ring)], axis=1),
                           np.stack([np.full(around, top), at(rings - 1, ring), at(rings - 1, ring + 1)], axis=1)])
    return v, np.concatenate([sides, caps])


# --------------------------------------------------------------------------------- tubes body
def loops_of_boundary(faces):
    """Boundary loops of an open mesh, each as the vertex cycle of its faces' boundary edges."""
    directed = set()
    for a, b, c in faces:
        directed.update(((a, b), (b, c), (c, a)))
    nxt = {}
    for a, b in directed:
        if (b, a) not in directed:
            assert a not in nxt, "pinched boundary"
            nxt[a] = b
    loops, seen = [], set()
    for start in nxt:
        if start in seen:
            continue
        loop, x = [], start
        while x not in seen:
            seen.add(x)
            loop.append(x)
            x = nxt[x]
        loops.append(loop)
    return loops


class Builder:
    def __init__(self):
        self.v = []
        self.f = []

    def add_points(self, points):
        first = len(self.v)
        self.v.extend(np.asarray(points))
        return list(range(first, first + len(points)))

    def ball(self, centre, radii, frame, frequency, holes):
        """A ball (ellipsoid) with holes; holes = [(direction in the ball's frame, angle)].
        Returns the hole loops, each ordered as its boundary edges run in the ball's faces."""
        v, f = icosphere(frequency)
        dirs = np.array([h[0] for h in holes])
        angles = np.array([h[1] for h in holes])
        # faces whose centre is within the angle (less a third of an edge: the hole's boundary
        # runs along the outer corners) go, and at least the nearest face
        centres = v[f].mean(axis=1)
        centres /= np.linalg.norm(centres, axis=1)[:, None]
        angle_to = np.arccos(np.clip(centres @ dirs.T, -1, 1))
        keep = ~(angle_to < (angles - 0.35 * 1.1 / frequency)[None, :]).any(axis=1)
        keep[np.argmin(angle_to, axis=0)] = False
        # grow the holes where their boundary pinches (a vertex on two stretches of it)
        while True:
            kept = f[keep]
            e = np.concatenate([kept[:, [0, 1]], kept[:, [1, 2]], kept[:, [2, 0]]])
            keys = e[:, 0] * len(v) + e[:, 1]
            boundary = ~np.isin(e[:, 1] * len(v) + e[:, 0], keys)
            starts, counts = np.unique(e[boundary, 0], return_counts=True)
            pinched = starts[counts > 1]
            if len(pinched) == 0:
                break
            keep &= ~np.isin(f, pinched).any(axis=1)
        f = f[keep]
        used = np.unique(f)
        index = -np.ones(len(v), dtype=int)
        points = (v[used] * radii) @ frame.T + centre
        ids = self.add_points(points)
        index[used] = ids
        faces = index[f]
        self.f.extend(map(tuple, faces))
        loops = loops_of_boundary(faces)
        assert len(loops) == len(holes), (len(loops), len(holes))
        unit = {i: v[used[k]] for k, i in enumerate(ids)}
        ordered = []
        for d, _ in holes:
            ordered.append(max(loops, key=lambda lp: np.mean([unit[i] @ d for i in lp])))
        return ordered

    def frame_of(self, loop, axis):
        e1 = np.cross(axis, [0.3, 0.5, 0.8])
        e1 /= np.linalg.norm(e1)
        return e1, np.cross(axis, e1)

    def zip_loops(self, a, b, axis, centre):
        """Faces between loop a (other side has edges a[i] -> a[i+1]) and loop b (other side
        has edges b[j+1] -> b[j]); both run the same way around `axis`."""
        e1, e2 = self.frame_of(a, axis)

        def angles(loop):
            q = np.array([self.v[i] for i in loop]) - centre
            return np.unwrap(np.arctan2(q @ e2, q @ e1))

        ta, tb = angles(a), angles(b)
        sense = np.sign(ta[-1] - ta[0])
        assert sense == np.sign(tb[-1] - tb[0]), "loops run opposite ways"
        ta, tb = sense * (ta - ta[0]), sense * (tb - ta[0])
        tb = np.mod(tb + math.pi, 2 * math.pi) - math.pi
        j0 = int(np.argmin(np.abs(tb)))
        b = b[j0:] + b[:j0]
        tb = np.concatenate([tb[j0:], tb[:j0]])
        tb = tb[0] + np.mod(tb - tb[0], 2 * math.pi)
        na, nb = len(a), len(b)
        ta = list(ta) + [2 * math.pi]
        tb = list(tb) + [tb[0] + 2 * math.pi]
        i = j = 0
        while i < na or j < nb:
            if j == nb or (i < na and ta[i + 1] < tb[j + 1]):
                self.f.append((a[(i + 1) % na], a[i % na], b[j % nb]))
                i += 1
            else:
                self.f.append((a[i % na], b[j % nb], b[(j + 1) % nb]))
                j += 1

    def ring(self, centre, axis, radius, count, twist, sense_loop):
        e1, e2 = self.frame_of(None, axis)
        phi = 2 * math.pi * (np.arange(count) + twist) / count
        pts = centre + radius * (np.cos(phi)[:, None] * e1 + np.sin(phi)[:, None] * e2)
        ids = self.add_points(pts)
        q = np.array([self.v[i] for i in sense_loop]) - centre
        t = np.unwrap(np.arctan2(q @ e2, q @ e1))
        return ids if t[-1] > t[0] else ids[::-1]

    def tube(self, loop, axis, radius, length, count, end="cap"):
        """A tube leaving `loop` along `axis`: `count` vertices around, rings about equilateral,
        closed by a hemispherical cap (end == "cap") or left open (returns its last ring)."""
        base = np.mean([self.v[i] for i in loop], axis=0)
        step = 2 * math.pi * radius / count * math.sqrt(3) / 2
        rings = max(2, int(round(length / step)))
        previous = loop
        for k in range(1, rings + 1):
            centre = base + axis * (length * k / rings)
            current = self.ring(centre, axis, radius, count, 0.5 * k, previous)
            self.zip_loops(previous, current, axis, centre)
            previous = current
        if end != "cap":
            return previous, base + axis * length
        top = base + axis * length
        cap_rings = max(1, count // 4)
        for k in range(1, cap_rings + 1):
            psi = 0.5 * math.pi * k / (cap_rings + 1)
            centre = top + axis * radius * math.sin(psi)
            current = self.ring(centre, axis, radius * math.cos(psi), count, 0.5 * (rings + k), previous)
            self.zip_loops(previous, current, axis, centre)
            previous = current
        tip = self.add_points([top + axis * radius])[0]
        n = len(previous)
        for i in range(n):
            self.f.append((previous[(i + 1) % n], previous[i], tip))
        return None


def frame_with_axis(axis):
    axis = axis / np.linalg.norm(axis)
    e1 = np.cross(axis, [0.3, 0.5, 0.8])
    e1 /= np.linalg.norm(e1)
    return np.stack([e1, np.cross(axis, e1), axis], axis=1)  # columns: e1, e2, axis


def tubes(size, seed, limbs=4, fingers=5, ratio=100.0):
    # limb ring: `around` vertices; a limb has about ratio / (pi sqrt 3) * around^2 vertices
    per = ratio / (math.pi * math.sqrt(3))
    around = 6
    while True:  # 4 limbs, 20 fingers (2/3 as many around), body and hands
        finger_around = max(6, int(round(around * 2 / 3)))
        estimate = limbs * per * around ** 2 + limbs * fingers * per * finger_around ** 2
        estimate += 10 * (around * 2.4) ** 2 * 1.5
        if estimate >= size or around > 200:
            break
        around += 1
    rng = np.random.default_rng(seed)
    bld = Builder()
    body_radii = np.array([0.6, 0.4, 1.0])
    # body holes sized so that a loop has about `around` vertices
    body_frequency = max(6, int(round(around * 2.4)))
    edge = 1.1 / body_frequency
    hole = around * edge / (2 * math.pi)
    print('tubes: %d vertices around a limb, %d around a finger' % (around, finger_around), file=sys.stderr)
    limb_dirs = [np.array(d, dtype=float) for d in ([1, 0.2, 0.5], [-1, -0.2, 0.5], [0.5, 0.1, -1], [-0.5, -0.1, -1])]
    limb_dirs = [d / np.linalg.norm(d) for d in limb_dirs[:limbs]]
    loops = bld.ball(np.zeros(3), body_radii, np.eye(3), body_frequency, [(d, hole) for d in limb_dirs])
    for d, loop in zip(limb_dirs, loops):
        pts = np.array([bld.v[i] for i in loop])
        centre = pts.mean(axis=0)
        axis = d * body_radii
        axis = d / body_radii  # the ellipsoid's normal at d
        axis /= np.linalg.norm(axis)
        radius = np.linalg.norm(pts - centre, axis=1).mean()
        last, end = bld.tube(loop, axis, radius, ratio * radius, around, end="open")
        # the hand: a ball of 2.5 limb radii, entered at -axis, fingers on a 55 degree cone
        hand_radius = 2.5 * radius
        hand_hole = math.asin(radius / hand_radius)
        frame = frame_with_axis(axis)
        finger_hole = finger_around / around * hand_hole
        hand_frequency = max(4, int(round(1.1 * finger_around / (2 * math.pi * finger_hole))))
        holes = [(np.array([0, 0, -1.0]), hand_hole)]
        spin = rng.uniform(0, 2 * math.pi)
        for k in range(fingers):
            a = spin + 2 * math.pi * k / fingers
            c = math.radians(55)
            holes.append((np.array([math.sin(c) * math.cos(a), math.sin(c) * math.sin(a), math.cos(c)]), finger_hole))
        hand_centre = end + axis * hand_radius * math.cos(hand_hole)
        hand_loops = bld.ball(hand_centre, np.full(3, hand_radius), frame, hand_frequency, holes)
        # the hand's entry loop runs the opposite way to the limb's rings: zip against it reversed
        entry = hand_loops[0][::-1]
        bld.zip_loops(last, entry, axis, end)
        for (fd, _), floop in zip(holes[1:], hand_loops[1:]):
            fpts = np.array([bld.v[i] for i in floop])
            fcentre = fpts.mean(axis=0)
            faxis = frame @ fd
            fradius = np.linalg.norm(fpts - fcentre, axis=1).mean()
            bld.tube(floop, faxis, fradius, ratio * fradius, finger_around, end="cap")
    return np.array(bld.v), np.array(bld.f)


# ---------------------------------------------------------------------------------- checks, io
def check(v, f, name):
    """Closed, manifold (every edge in two faces, once each way, no pinched vertex), genus 0,
    connected, outward (positive signed volume)."""
    e = np.concatenate([f[:, [0, 1]], f[:, [1, 2]], f[:, [2, 0]]])
    keys = e[:, 0].astype(np.int64) * len(v) + e[:, 1]
    assert len(np.unique(keys)) == len(keys), name + ": an edge twice in one direction"
    reverse = e[:, 1].astype(np.int64) * len(v) + e[:, 0]
    assert np.isin(reverse, keys).all(), name + ": open edge"
    edges = len(keys) // 2
    used = len(np.unique(f))
    assert used == len(v), name + ": unreferenced vertices"
    assert used - edges + len(f) == 2, name + ": Euler characteristic %d" % (used - edges + len(f))
    # pinched vertices: the faces around each vertex form one fan (count the corner cycles)
    nxt = {}
    for a, b, c in f:
        for x, y, z in ((a, b, c), (b, c, a), (c, a, b)):
            nxt[(x, y)] = z  # around x: edge x->y is followed by edge x->z
    seen = set()
    fans = 0
    for (x, y) in nxt:
        if (x, y) in seen:
            continue
        fans += 1
        while (x, y) not in seen:
            seen.add((x, y))
            y = nxt[(x, y)]
    assert fans == len(v), name + ": pinched vertex"
    volume = np.einsum('ij,ij->i', v[f[:, 0]], np.cross(v[f[:, 1]], v[f[:, 2]])).sum() / 6
    assert volume > 0, name + ": inward"
    # connected (genus 0 then follows from chi = 2)
    parent = np.arange(len(v))

    def find(i):
        while parent[i] != i:
            parent[i] = parent[parent[i]]
            i = parent[i]
        return i

    for a, b in e[: len(f)]:
        ra, rb = find(a), find(b)
        if ra != rb:
            parent[ra] = rb
    for a, b in e[len(f):]:
        ra, rb = find(a), find(b)
        if ra != rb:
            parent[ra] = rb
    assert len({find(i) for i in range(len(v))}) == 1, name + ": not connected"


def statistics(v, f):
    a, b, c = v[f[:, 0]], v[f[:, 1]], v[f[:, 2]]
    area = 0.5 * np.linalg.norm(np.cross(b - a, c - a), axis=1)
    angles = []
    for p, q, r in ((a, b, c), (b, c, a), (c, a, b)):
        x, y = q - p, r - p
        angles.append(np.degrees(np.arctan2(np.linalg.norm(np.cross(x, y), axis=1), np.einsum('ij,ij->i', x, y))))
    return area.max() / area.min(), np.min(angles)


def write_off(path, v, f):
    with open(path, 'w') as out:
        out.write('OFF\n%d %d 0\n' % (len(v), len(f)))
        np.savetxt(out, v, fmt='%.17g')
        np.savetxt(out, np.concatenate([np.full((len(f), 1), 3), f], axis=1), fmt='%d')


def capsule40(size, seed):
    """A tube of radius 1 and length 40: crushed by about e^-33 in the Tutte map, which the stretch
    reweighting can still open (unlike the capsule's e^-600)."""
    return capsule(size, seed, ratio=40.0)


CASES = {'tubes': tubes, 'capsule': capsule, 'capsule40': capsule40, 'spiky': spiky, 'folds': folds,
         'slivers': slivers, 'cones': cones}


def main():
    p = argparse.ArgumentParser(description=__doc__.split('\n\n')[0],
                                formatter_class=argparse.RawDescriptionHelpFormatter, epilog=__doc__)
    p.add_argument('outdir')
    p.add_argument('--cases', nargs='+', default=list(CASES), choices=list(CASES))
    p.add_argument('--sizes', nargs='+', type=int, default=[25000, 60000, 120000],
                   help='about this many vertices per mesh (default 25000 60000 120000)')
    p.add_argument('--seed', type=int, default=1)
    p.add_argument('--spikes', type=int, default=120, help='spikes of the spiky case (50-200)')
    p.add_argument('--cone-count', type=int, default=8, help='spikes of the cones case (default 8)')
    p.add_argument('--cone-length', type=float, default=14.0,
                   help='length of the cones in sphere radii, tip to centre (default 14)')
    p.add_argument('--cone-width', type=float, default=0.15,
                   help='angular radius of each cone at its base, in radians (default 0.15)')
    args = p.parse_args()
    out = pathlib.Path(args.outdir)
    out.mkdir(parents=True, exist_ok=True)
    for case in args.cases:
        for size in args.sizes:
            if case == 'spiky':
                v, f = spiky(size, args.seed, spikes=args.spikes)
            elif case == 'cones':
                if args.cone_count < 1 or not args.cone_length > 1 or not 0 < args.cone_width < 1:
                    p.error('--cone-count must be >= 1, --cone-length > 1 and --cone-width in (0, 1)')
                v, f = cones(size, args.seed, args.cone_count, args.cone_length, args.cone_width)
            else:
                v, f = CASES[case](size, args.seed)
            v = np.asarray(v, dtype=float)
            f = np.asarray(f, dtype=np.int64)
            check(v, f, case)
            ratio, min_angle = statistics(v, f)
            path = out / ('%s_%dk.off' % (case, round(size / 1000)))
            write_off(path, v, f)
            print('%s: %d vertices, %d faces, area ratio max/min %.3g, min angle %.3g deg' %
                  (path, len(v), len(f), ratio, min_angle), flush=True)


if __name__ == '__main__':
    sys.exit(main())
