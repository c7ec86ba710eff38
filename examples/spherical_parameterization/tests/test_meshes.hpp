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
}  // namespace sphparam::test
