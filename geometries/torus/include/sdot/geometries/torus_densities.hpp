#pragma once
/// \file torus_densities.hpp
/// Densities on the periodic plane: any density of the plane given over the box (a mesh or an
/// image as PiecewiseDensity<Plane>, a FunctionDensity, …), repeated with the periods.
///
///     sdot::Torus torus;                                          // the unit square, periodic
///     auto image = sdot::image_density(torus.plane(), gray, box, sdot::ImageInterpolation::bilinear);
///     auto result = sdot::solve(torus, sdot::PeriodicDensity(image), sites, masses);

#include <utility>

#include "sdot/density.hpp"
#include "sdot/geometries/plane.hpp"
#include "sdot/geometries/torus.hpp"

namespace sdot {

/// ρ(x) = ρ_box(wrap(x)) on the torus, for a density ρ_box of the plane `D` (a model of
/// `Density<Plane>`) over the box. A cell of the torus is a polygon of the covering plane that
/// may cross the box's periodic sides: it is cut along them, and each piece is moved by whole
/// periods into the box and integrated there by `D` (the first moment moved back), so mesh and
/// image densities keep their exact piece-by-piece integration. A model of `Density<Torus>`.
template <class D>
class PeriodicDensity {
 public:
  using Point = Torus::Point;  ///< a point of the covering plane

  /// The density of the box to repeat.
  explicit PeriodicDensity(D density) : density_(std::move(density)) {}
  /// The density of the box.
  [[nodiscard]] const D& box_density() const { return density_; }
  /// The box density's piece count (of a PiecewiseDensity; the bench line reports it).
  [[nodiscard]] std::size_t piece_count() const requires requires(const D& d) { d.piece_count(); }
  { return density_.piece_count(); }

  /// Mass, first moment (on the covering plane, around the wrapped site) and cost of the cell.
  [[nodiscard]] CellIntegrals<Point> integrate_cell(const Torus& torus, const Cell<Point>& cell, const Point& site,
                                                    bool with_cost = true) const {
    const Point own = torus.wrap(site);
    CellIntegrals<Point> total;
    torus.for_each_part_in_box(cell, [&](const Cell<Point>& part, const Point& shift) {
      const auto piece = density_.integrate_cell(torus.plane(), part, Point(own - shift), with_cost);
      total.mass += piece.mass;
      total.first_moment += piece.first_moment + piece.mass * shift;
      total.cost += piece.cost;
    });
    return total;
  }

  /// ∫_{[a,b]} ρ ds / |y_i − y_j'| (y_j' the image across, Torus::image_across), the edge cut
  /// along the box's periodic sides like the cells; on a side, the mean of both faces.
  [[nodiscard]] double facet_weight(const Torus& torus, const Point& a, const Point& b, const Point& site_i,
                                    double weight_i, const Point& site_j, double weight_j) const {
    const Point own = torus.wrap(site_i);
    const Point image = torus.image_across(a, b, site_i, weight_i, site_j, weight_j);
    double result = 0;
    torus.for_each_segment_part_in_box(a, b, [&](const Point& p, const Point& q, const Point& shift, double share) {
      result += share * density_.facet_weight(torus.plane(), p, q, Point(own - shift), weight_i, Point(image - shift),
                                              weight_j);
    });
    return result;
  }

 private:
  D density_;
};

}  // namespace sdot
