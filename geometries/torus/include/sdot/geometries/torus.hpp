#pragma once
/// \file torus.hpp
/// The periodic plane: a box [x0, x1] × [y0, y1] whose sides wrap around in x, in y or in both
/// (a flat torus, or a cylinder when one axis is periodic). Cost: half the squared distance on
/// the torus; cells are power cells of the periodic set of site images (docs/torus.md).

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <algorithm>
#include <array>
#include <atomic>
#include <cmath>
#include <cstdint>
#include <span>
#include <string_view>
#include <vector>

#include "sdot/chart_diagram.hpp"
#include "sdot/density.hpp"
#include "sdot/diagram.hpp"
#include "sdot/geometries/plane.hpp"

namespace sdot {

/// What one call of Torus::build_diagram did: how many ghost images it added (site images across
/// the periodic sides, within the margin), the margin in each axis, and how many diagrams it built
/// (more than one when a margin was too narrow for an exact cell).
struct GhostStatistics {
  std::size_t ghosts = 0;        ///< ghost images in the last (accepted) diagram
  Eigen::Vector2d margin{0, 0};  ///< the margin that diagram used, per axis (0 if not periodic)
  int builds = 0;                ///< power diagrams built (1 unless the margin had to grow)
  bool full_tiling = false;      ///< the margin reached a whole period (all 3 × 3 images)
};

/// The periodic plane: a model of `Geometry` (docs/torus.md). Weights ψ: the cell of site i is
/// {x : d(x, y_i)²/2 − ψ_i ≤ d(x, y_j)²/2 − ψ_j ∀j}, d the distance on the torus. A cell is returned
/// as the convex polygon it is on the covering plane, around the site wrapped into the box: its
/// vertices may lie outside the box (by less than half a period), and an edge's neighbour is the
/// site whose image lies across it (possibly the cell's own site, for a cell as wide as a period).
/// Along an axis that is not periodic, cells are clipped to the box, whose sides carry the
/// boundary labels of the plane's rectangle (0 bottom, 1 right, 2 top, 3 left).
class Torus {
 public:
  using Point = Eigen::Vector2d;  ///< a point (x, y) of the covering plane

  /// The unit square [0, 1]², periodic in x and in y.
  Torus();
  /// The box [x0, x1] × [y0, y1] (`box.min()`, `box.max()`); `periodic[0]` (x) and `periodic[1]`
  /// (y) say which axes wrap around. Throws InputError (field `domain`) when the box is not
  /// finite or has no positive size in each axis.
  Torus(const Eigen::AlignedBox2d& box, std::array<bool, 2> periodic);
  /// Copies the box, the periodicity and the current ghost margin.
  Torus(const Torus& other);
  /// Copies the box, the periodicity and the current ghost margin.
  Torus& operator=(const Torus& other);

  /// "torus", the geometry's name in problem files and on the command line.
  static constexpr std::string_view name() { return "torus"; }
  /// The box (the fundamental domain).
  [[nodiscard]] const Eigen::AlignedBox2d& box() const { return box_; }
  /// Which axes wrap around: x, y.
  [[nodiscard]] std::array<bool, 2> periodic() const { return periodic_; }
  /// The box's side lengths (the periods of the periodic axes).
  [[nodiscard]] Point period() const { return period_; }
  /// The box as a plane domain: cells and their pieces are integrated with its exact formulas.
  [[nodiscard]] const Plane& plane() const { return plane_; }

  /// `x` moved by whole periods into the box along the periodic axes: in [x0, x1) there (a point
  /// already inside is returned unchanged); the other coordinates are kept.
  [[nodiscard]] Point wrap(const Point& x) const {
    const bool inside = (!periodic_[0] || (x.x() >= box_.min().x() && x.x() < box_.max().x())) &&
                        (!periodic_[1] || (x.y() >= box_.min().y() && x.y() < box_.max().y()));
    return inside ? x : wrap_outside(x);
  }
  /// The transport cost d(x, y)²/2, d the distance on the torus (the nearest image of y).
  [[nodiscard]] double cost(const Point& x, const Point& y) const;
  /// Throws InputError for a non-finite coordinate or two sites that coincide modulo the
  /// periods (`sites[5]: duplicate of sites[2] modulo the period`), equal after wrapping up to
  /// the rounding of the wrap (a few units in the last place of the box's coordinates).
  void validate_sites(std::span<const Point> sites) const;
  /// Zero (the Voronoi diagram of the torus, whose cells are non-empty for distinct sites), plus,
  /// along an axis that is not periodic with sites outside the box, (1 − t)(y_i − c)²/2 in that
  /// coordinate (c the box's centre, t < 1): the cell of site i then holds the point of the box
  /// whose coordinate is c + t(y_i − c), so that every cell is non-empty.
  [[nodiscard]] Eigen::VectorXd default_weights(std::span<const Point> sites) const;
  /// `count` points uniform in the box, the same as Plane::uniform_samples over the box (the
  /// sites of `sdot bench --geometry torus`, which are those of the plane's bench).
  [[nodiscard]] std::vector<Point> uniform_samples(std::size_t count, std::uint64_t seed) const;

  /// The cells: the power diagram of the wrapped sites and of their ghost images within a margin
  /// of the periodic sides, over the box grown by that margin; each site's cell is kept when no
  /// image left out could cut it (else the margin grows and the diagram is rebuilt, up to the
  /// whole 3 × 3 tiling, which is exact). The margin that worked is the start of the next call.
  [[nodiscard]] Diagram<Point> build_diagram(std::span<const Point> sites, const Eigen::VectorXd& weights) const;
  /// With `stop_at_empty_cell`, the builder may stop at the first empty cell (see the solver's
  /// line search) and leave the other cells empty.
  [[nodiscard]] Diagram<Point> build_diagram(std::span<const Point> sites, const Eigen::VectorXd& weights,
                                             bool stop_at_empty_cell) const;
  /// The same, reporting the ghosts and margins in `statistics`.
  [[nodiscard]] Diagram<Point> build_diagram(std::span<const Point> sites, const Eigen::VectorXd& weights,
                                             GhostStatistics& statistics, bool stop_at_empty_cell = false) const;

  /// Exact area, first moment (on the covering plane) and ∫ d(x, y)²/2 of a cell, y the site.
  [[nodiscard]] CellIntegrals<Point> integrate(const Cell<Point>& cell, const Point& site, bool with_cost = true) const;
  /// The same for ρ given on the box, by quadrature on the parts of the cell moved into the box
  /// (for_each_part_in_box): ρ is only read in the box, and need not match across its sides.
  [[nodiscard]] CellIntegrals<Point> integrate(const Cell<Point>& cell, const Point& site,
                                               const ScalarField<Point>& rho, int order, bool with_cost = true) const;
  /// |ab| / |y_i − y_j'|, y_j' the image of y_j across the edge (see image_across).
  [[nodiscard]] double facet_weight(const Point& a, const Point& b, const Point& site_i, double weight_i,
                                    const Point& site_j, double weight_j) const;
  /// ∫_{[a,b]} ρ ds / |y_i − y_j'| for ρ given on the box, by Gauss–Legendre quadrature on the
  /// parts of the edge moved into the box (for_each_segment_part_in_box).
  [[nodiscard]] double facet_weight(const Point& a, const Point& b, const Point& site_i, double weight_i,
                                    const Point& site_j, double weight_j, const ScalarField<Point>& rho,
                                    int order) const;
  /// The centroid M / m of a cell, wrapped into the box.
  [[nodiscard]] Point centroid(const CellIntegrals<Point>& integrals) const {
    return wrap(integrals.first_moment / integrals.mass);
  }

  /// The image of `site_j` (wrapped, then moved by −1, 0 or +1 period along each periodic axis)
  /// whose power bisector with the wrapped `site_i` carries the edge [a, b] of the cell of site i:
  /// the image nearest to site i when it balances the powers at a and b to round-off (nearly
  /// always), else the one with the smallest power difference there.
  [[nodiscard]] Point image_across(const Point& a, const Point& b, const Point& site_i, double weight_i,
                                   const Point& site_j, double weight_j) const;
  /// Calls `visit(part, shift)` for each non-empty part of `cell` (a polygon of the covering
  /// plane) between the lines of the box's periodic sides, moved by −shift (whole periods) into
  /// the box: how a density given on the box is integrated over a cell that crosses a side.
  template <class Visit>
  void for_each_part_in_box(const Cell<Point>& cell, Visit&& visit) const;
  /// Calls `visit(p, q, shift, share)` for each part [p, q] of the segment [a, b] between the
  /// lines of the box's periodic sides, moved by −shift into the box, with share 1; a part lying
  /// on such a line is visited twice with share ½, read just inside the box at each of its two
  /// faces (the mean of both sides, as a density along the common edge of two of its pieces).
  template <class Visit>
  void for_each_segment_part_in_box(const Point& a, const Point& b, Visit&& visit) const;
  /// The current ghost margin, in mean site spacings √(area / N) (grows when a margin is found
  /// too narrow; the next diagram starts from it).
  [[nodiscard]] double margin_factor() const { return margin_factor_.load(std::memory_order_relaxed); }

 private:
  /// wrap() for a point outside the box along a periodic axis.
  [[nodiscard]] Point wrap_outside(const Point& x) const;
  /// The shifts s (−1, 0 or +1 per periodic axis, 0 along the others) of the 3^k images.
  [[nodiscard]] std::vector<Point> image_shifts() const;
  /// image_across for wrapped sites `own` and `base`, as the offset of the image from `own`.
  [[nodiscard]] Point image_offset(const Point& a, const Point& b, const Point& own, double weight_i, const Point& base,
                                   double weight_j) const;

  Eigen::AlignedBox2d box_;
  std::array<bool, 2> periodic_{true, true};
  Point period_;
  Plane plane_;
  /// The ghost margin in mean spacings: the start of the next build_diagram (atomic: concurrent
  /// solves on one Torus may update it).
  mutable std::atomic<double> margin_factor_;
  /// The last diagram's regular triangulation (sites and ghosts), the start of the next build
  /// with the same ghosts.
  std::shared_ptr<PowerDiagramWarmStart> warm_start_ = make_power_diagram_warm_start();
};

template <class Visit>
void Torus::for_each_part_in_box(const Cell<Point>& cell, Visit&& visit) const {
  const Point low = box_.min(), high = box_.max();
  // The tiles [low + s·period, high + s·period] the cell overlaps, per periodic axis.
  Point bounds_low = cell.vertices[0], bounds_high = cell.vertices[0];
  for (const auto& v : cell.vertices) bounds_low = bounds_low.cwiseMin(v), bounds_high = bounds_high.cwiseMax(v);
  std::array<int, 2> first{0, 0}, last{0, 0};
  for (std::size_t d = 0; d < 2; ++d)
    if (periodic_[d]) {
      const auto axis = static_cast<Eigen::Index>(d);
      first[d] = static_cast<int>(std::floor((bounds_low[axis] - high[axis]) / period_[axis])) + 1;
      last[d] = std::max(first[d], static_cast<int>(std::ceil((bounds_high[axis] - low[axis]) / period_[axis])) - 1);
    }
  if (first == last && first == std::array<int, 2>{0, 0}) {  // inside the box: most cells
    visit(cell, Point(Point::Zero()));
    return;
  }
  for (int sx = first[0]; sx <= last[0]; ++sx)
    for (int sy = first[1]; sy <= last[1]; ++sy) {
      const Point shift(sx * period_.x(), sy * period_.y());
      Cell<Point> part = cell;
      for (std::size_t d = 0; d < 2; ++d) {
        if (first[d] == last[d]) continue;
        const auto axis = static_cast<Eigen::Index>(d);
        clip(part, Point::Unit(axis), -(low[axis] + shift[axis]), boundary_label(0));
        clip(part, -Point::Unit(axis), high[axis] + shift[axis], boundary_label(0));
      }
      if (part.empty()) continue;
      for (auto& v : part.vertices) v -= shift;
      visit(part, shift);
    }
}

template <class Visit>
void Torus::for_each_segment_part_in_box(const Point& a, const Point& b, Visit&& visit) const {
  const Point low = box_.min();
  // Parameters t ∈ (0, 1) where the segment crosses a line low + k·period of a periodic axis
  // (at most two per axis: a cell is less than a period wide).
  std::array<double, 8> cuts{0, 1};
  std::size_t cut_count = 2;
  for (int d = 0; d < 2; ++d) {
    if (!periodic_[static_cast<std::size_t>(d)] || a[d] == b[d]) continue;
    const double from = std::min(a[d], b[d]), to = std::max(a[d], b[d]);
    for (double k = std::ceil((from - low[d]) / period_[d]); k <= std::floor((to - low[d]) / period_[d]); ++k) {
      const double t = (low[d] + k * period_[d] - a[d]) / (b[d] - a[d]);
      if (t > 0 && t < 1 && cut_count < cuts.size()) cuts[cut_count++] = t;
    }
  }
  // Insertion sort of a few numbers (std::sort's unrolled paths trip -Warray-bounds here).
  for (std::size_t k = 1; k < cut_count; ++k)
    for (std::size_t m = k; m > 0 && cuts[m - 1] > cuts[m]; --m) std::swap(cuts[m - 1], cuts[m]);
  for (std::size_t k = 0; k + 1 < cut_count; ++k) {
    if (!(cuts[k + 1] > cuts[k])) continue;
    const Point p = a + cuts[k] * (b - a), q = a + cuts[k + 1] * (b - a), middle = (p + q) / 2;
    Point shift = Point::Zero(), nudge = Point::Zero();
    for (int d = 0; d < 2; ++d) {
      if (!periodic_[static_cast<std::size_t>(d)]) continue;
      const double line = std::round((middle[d] - low[d]) / period_[d]);
      const double tolerance = 1e-10 * period_[d];
      if (std::abs(p[d] - q[d]) <= tolerance && std::abs(middle[d] - low[d] - line * period_[d]) <= tolerance) {
        shift[d] = line * period_[d];  // on a side's line: read on its two faces below
        nudge[d] = 1e-8 * period_[d];
      } else {
        shift[d] = std::floor((middle[d] - low[d]) / period_[d]) * period_[d];
      }
    }
    if (nudge.isZero()) {
      visit(Point(p - shift), Point(q - shift), shift, 1.0);
      continue;
    }
    // The face at the box's lower side (moved in by `nudge`), and the face at its upper side,
    // one period back along the axes of that line.
    const Point back = shift - (nudge.array() > 0).cast<double>().matrix().cwiseProduct(period_);
    visit(Point(p - shift + nudge), Point(q - shift + nudge), shift, 0.5);
    visit(Point(p - back - nudge), Point(q - back - nudge), back, 0.5);
  }
}

}  // namespace sdot
