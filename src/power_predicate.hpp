#pragma once
// The semi-static filter of the 2-D power test in front of CGAL's exact one (regular_triangulation.cpp).
// CGAL's kernel filters this predicate only dynamically, with interval arithmetic and a switch of
// the rounding mode at every call; that took 15 % of a plane solve. Here the determinant is taken
// in double precision with a forward error bound, and only when its sign is within the bound does
// the caller ask CGAL's exact predicate.

#include <algorithm>
#include <cmath>
#include <optional>

namespace sdot::detail {

/// The sign of det[[p−t, |p−t|² − (w_p − w_t)], [q−t, …], [r−t, …]] (CGAL's
/// power_side_of_oriented_power_circleC2: positive when t is on the positive side of the power
/// circle of p, q, r, which is its inside when p, q, r turn counter-clockwise) when double precision certainly gives
/// it; empty when the value is within its rounding-error bound of 0 (exactly degenerate input always is) or when the
/// magnitudes leave the range where the bound holds (underflow, overflow, NaN).
inline std::optional<int> power_test_sign_by_filter(double px, double py, double pw, double qx, double qy, double qw,
                                                    double rx, double ry, double rw, double tx, double ty, double tw) {
  const double dpx = px - tx, dpy = py - ty, dqx = qx - tx, dqy = qy - ty, drx = rx - tx, dry = ry - ty;
  const double sp = dpx * dpx + dpy * dpy, sq = dqx * dqx + dqy * dqy, sr = drx * drx + dry * dry;
  const double wp = pw - tw, wq = qw - tw, wr = rw - tw;
  const double dpz = sp - wp, dqz = sq - wq, drz = sr - wr;
  const double determinant =
      dpz * (dqx * dry - drx * dqy) + dqz * (drx * dpy - dpx * dry) + drz * (dpx * dqy - dqx * dpy);
  // Forward error, with u = 2⁻⁵³ and X, Y, Z the bounds of the three columns' magnitudes:
  // the differences carry u, so each 2×2 minor is off by at most 8u·XY (|minor| ≤ 2XY); each z
  // by 5u·Z, Z ≥ |p−t|² + |w_p − w_t|; each product z·minor then by 23u·XYZ, and the two sums
  // add 12u·XYZ: 81u·XYZ ≈ 9.0e-15·XYZ. The bound below is four times that. Tiny magnitudes are
  // left to the exact predicate, where underflow would make the relative model wrong; huge ones
  // overflow to infinity or NaN, which fails both comparisons.
  const double x_bound = std::max({std::abs(dpx), std::abs(dqx), std::abs(drx)});
  const double y_bound = std::max({std::abs(dpy), std::abs(dqy), std::abs(dry)});
  const double z_bound = std::max({sp + std::abs(wp), sq + std::abs(wq), sr + std::abs(wr)});
  constexpr double tiny = 1e-70, huge = 1e70;
  if (!(x_bound > tiny && y_bound > tiny && z_bound > tiny && x_bound < huge && y_bound < huge && z_bound < huge))
    return std::nullopt;
  const double error_bound = 3.6e-14 * x_bound * y_bound * z_bound;
  if (determinant > error_bound) return 1;
  if (determinant < -error_bound) return -1;
  return std::nullopt;
}

}  // namespace sdot::detail
