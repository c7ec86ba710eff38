#pragma once
// Generated genus-0 test meshes (no files from shared/).
#include "mesh.hpp"

namespace sphparam::test {
/// Icosphere with `level` 1-to-4 subdivisions, vertices on the unit sphere, outward.
Mesh icosphere(int level);
/// Icosphere scaled to an ellipsoid with semi-axes a, b, c.
Mesh ellipsoid(int level, double a, double b, double c);
/// Unit icosphere with `count` long thin spikes: the vertices within `width` (radians) of each
/// spike direction are pushed out to radius up to `length`.
Mesh spiky_sphere(int level, int count, double length, double width);
/// Icosphere with random smooth bumps r = 1 + Σ a_k exp(-|x - c_k|²/s²) (fixed seed).
Mesh bumpy_sphere(int level, int bumps, double amplitude, unsigned seed);
/// Icosphere with sub-resolution vertices (the `slivers` case of scripts/hard_meshes.py): every
/// third edge whose two faces are untouched is split on its chord, alternately at 1e-3 (1000:1
/// area ratios) and at 2.5e-5 of its length (0.001° needles), and every seventh face left whole
/// gets a point 1e-5 of its height inside its first edge (a flat sliver). The icosphere's
/// vertices come first.
Mesh sliver_sphere(int level);
/// A closed tube along z of radius 1 and length `length` (the `tubes` case of
/// scripts/hard_meshes.py in its simplest form): rings of `around` vertices, each turned by half
/// a step from the last, about equilateral triangles between them, and each end closed by a fan
/// around one apex vertex half a ring spacing beyond it. Outward oriented.
Mesh capsule(int around, double length);
}  // namespace sphparam::test
