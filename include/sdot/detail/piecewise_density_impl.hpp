#pragma once
// Implementation of piecewise_density.hpp (templates).

#include <algorithm>
#include <cmath>
#include <numbers>
#include <numeric>
#include <unordered_map>

#include "sdot/error.hpp"

namespace sdot::detail {

inline double angle_between(const Eigen::Vector3d& a, const Eigen::Vector3d& b) {
  return std::acos(std::clamp(a.dot(b), -1.0, 1.0));
}

/// Sutherland–Hodgman in homogeneous coordinates: keeps the part of `polygon` with n·X ≥ 0.
/// Intersections are points of the chord, which project onto the geodesic.
inline void clip_homogeneous(const std::vector<Eigen::Vector3d>& polygon, const Eigen::Vector3d& normal,
                             std::vector<Eigen::Vector3d>& out) {
  out.clear();
  const std::size_t n = polygon.size();
  for (std::size_t k = 0; k < n; ++k) {
    const Eigen::Vector3d& p = polygon[k];
    const Eigen::Vector3d& q = polygon[(k + 1) % n];
    const double dp = normal.dot(p), dq = normal.dot(q);
    if (dp >= 0) out.push_back(p);
    if ((dp >= 0) != (dq >= 0)) out.push_back((p + (dp / (dp - dq)) * (q - p)).normalized());
  }
}

}  // namespace sdot::detail

template <sdot::ProjectiveGeometry G>
sdot::PiecewiseDensity<G>::PiecewiseDensity(const G& geometry, const std::vector<DensityPiece<Point>>& pieces,
                                            ScalarField<Point> field, int quadrature_order, std::string name)
    : geometry_(geometry), name_(std::move(name)), field_(std::move(field)), quadrature_order_(quadrature_order) {
  if (quadrature_order < 1 || quadrature_order > 64)
    throw InputError("quadrature_order", "must be in 1..64, got " + std::to_string(quadrature_order));
  std::vector<Eigen::Vector3d> polygon;
  for (std::size_t p = 0; p < pieces.size(); ++p) {
    const auto& piece = pieces[p];
    const std::string field_name = indexed(name_, p);
    const std::size_t count = piece.polygon.size();
    if (count < 3) throw InputError(field_name, "has " + std::to_string(count) + " vertices; a piece needs at least 3");
    if (piece.kind == PieceKind::linear && count != 3)
      throw InputError(field_name, "a linear piece must be a triangle, got " + std::to_string(count) + " vertices");
    if (piece.kind == PieceKind::field && !field_)
      throw InputError(field_name, "is a field piece but the density has no field function");
    const std::size_t value_count = piece.kind == PieceKind::constant ? 1 : piece.kind == PieceKind::linear ? 3 : 0;
    for (std::size_t k = 0; k < value_count; ++k)
      if (!(std::isfinite(piece.values[k]) && piece.values[k] >= 0))
        throw InputError(indexed(field_name + ".values", k),
                         "must be a finite number >= 0, got " + std::to_string(piece.values[k]));
    polygon.clear();
    for (std::size_t k = 0; k < count; ++k) {
      const Eigen::Vector3d h =
          piece.polygon[k].allFinite() ? geometry.to_projective(piece.polygon[k]) : Eigen::Vector3d::Constant(NAN);
      if (!(h.allFinite() && h.norm() > 0))
        throw InputError(field_name,
                         "vertex " + std::to_string(k) + " is not a finite point of the " + std::string(G::name()));
      // Repeated corners (e.g. a pixel touching a pole) are merged.
      if (polygon.empty() || (h.normalized() - polygon.back()).norm() > 1e-15) polygon.push_back(h.normalized());
    }
    while (polygon.size() > 1 && (polygon.front() - polygon.back()).norm() <= 1e-15) polygon.pop_back();
    if (polygon.size() < 3) continue;  // zero area: contributes nothing
    const std::size_t corners = polygon.size();
    Eigen::Vector3d sum = Eigen::Vector3d::Zero();
    for (const auto& v : polygon) sum += v;
    if (!(sum.norm() > 1e-9))
      throw InputError(field_name, "does not fit in an open hemisphere of the chart (split it into smaller pieces)");
    const Eigen::Vector3d center = sum.normalized();
    double signed_area = 0, longest = 0;
    for (std::size_t k = 0; k < corners; ++k) {
      const auto& a = polygon[k];
      const auto& b = polygon[(k + 1) % corners];
      signed_area += center.dot(a.cross(b));
      longest = std::max(longest, (b - a).norm());
      if (center.dot(a) <= 1e-9)
        throw InputError(field_name, "does not fit in an open hemisphere of the chart (split it into smaller pieces)");
    }
    if (!(std::abs(signed_area) > 1e-13 * longest * longest)) continue;  // zero area: contributes nothing
    if (signed_area < 0) std::reverse(polygon.begin(), polygon.end());
    for (std::size_t k = 0; k < corners; ++k) {
      const auto& a = polygon[(k + corners - 1) % corners];
      const auto& b = polygon[k];
      const auto& c = polygon[(k + 1) % corners];
      if (a.cross(b).dot(c) < -1e-12 * (b - a).norm() * (c - b).norm())
        throw InputError(field_name, "is not convex at vertex " + std::to_string(k));
    }
    Eigen::Vector3d numerator = Eigen::Vector3d::Zero(), denominator = Eigen::Vector3d::Zero();
    if (piece.kind == PieceKind::linear) {
      // ρ(X) = v·λ / Σλ with Σ λ_k R_k = X: a = M⁻ᵀv, b = M⁻ᵀ1 for M = [R₀ R₁ R₂].
      Eigen::Matrix3d corners_matrix;
      for (int k = 0; k < 3; ++k) corners_matrix.col(k) = geometry.to_projective(piece.polygon[k]);
      const Eigen::Matrix3d inverse_transpose = corners_matrix.inverse().transpose();
      numerator = inverse_transpose * Eigen::Vector3d(piece.values[0], piece.values[1], piece.values[2]);
      denominator = inverse_transpose * Eigen::Vector3d::Ones();
    }
    add_unit_piece(polygon, piece.kind, piece.kind == PieceKind::constant ? piece.values[0] : 0.0, numerator,
                   denominator);
  }
  build_index();
}

template <sdot::ProjectiveGeometry G>
void sdot::PiecewiseDensity<G>::add_unit_piece(const std::vector<Eigen::Vector3d>& polygon, PieceKind kind,
                                               double constant, const Eigen::Vector3d& numerator,
                                               const Eigen::Vector3d& denominator) {
  // Consecutive (nearly) equal corners, e.g. where a clip passes through a corner, would give
  // an edge without a direction.
  thread_local std::vector<Eigen::Vector3d> corners;
  corners.clear();
  for (const auto& v : polygon)
    if (corners.empty() || corners.back().cross(v).norm() > 1e-15) corners.push_back(v);
  while (corners.size() > 1 && corners.back().cross(corners.front()).norm() <= 1e-15) corners.pop_back();
  if (corners.size() < 3) return;
  Eigen::Vector3d sum = Eigen::Vector3d::Zero();
  for (const auto& v : corners) sum += v;
  const Eigen::Vector3d center = sum.normalized();
  double radius = 0;
  for (const auto& v : corners) radius = std::max(radius, detail::angle_between(center, v));
  kinds_.push_back(kind);
  constants_.push_back(constant);
  numerators_.push_back(numerator);
  denominators_.push_back(denominator);
  cap_centers_.push_back(center);
  cap_radii_.push_back(radius);
  for (std::size_t k = 0; k < corners.size(); ++k) {
    corners_.push_back(corners[k]);
    normals_.push_back(corners[k].cross(corners[(k + 1) % corners.size()]).normalized());
  }
  offsets_.push_back(static_cast<std::uint32_t>(corners_.size()));
}

template <sdot::ProjectiveGeometry G>
void sdot::PiecewiseDensity<G>::build_index() {
  tree_ = CapTree(cap_centers_, cap_radii_);
}

template <sdot::ProjectiveGeometry G>
double sdot::PiecewiseDensity<G>::local_value(std::size_t piece, const Point& x) const {
  switch (kinds_[piece]) {
    case PieceKind::constant:
      return constants_[piece];
    case PieceKind::linear: {
      const Eigen::Vector3d h = geometry_.to_projective(x);
      return std::max(0.0, numerators_[piece].dot(h) / denominators_[piece].dot(h));
    }
    case PieceKind::field:
    default:
      return field_(x);
  }
}

template <sdot::ProjectiveGeometry G>
sdot::CellIntegrals<typename G::Point> sdot::PiecewiseDensity<G>::integrate_piece(const G& geometry, std::size_t piece,
                                                                                  const Cell<Point>& polygon,
                                                                                  const Point& site,
                                                                                  bool with_cost) const {
  switch (kinds_[piece]) {
    case PieceKind::constant: {
      const double value = constants_[piece];
      if (value == 0) return {};
      auto integrals = geometry.integrate(polygon, site, with_cost);
      integrals.mass *= value;
      integrals.first_moment *= value;
      integrals.cost *= value;
      return integrals;
    }
    case PieceKind::linear: {
      const ScalarField<Point> rho = [this, piece](const Point& x) { return local_value(piece, x); };
      return geometry.integrate(polygon, site, rho, piece_order(piece), with_cost);
    }
    case PieceKind::field:
    default:
      return geometry.integrate(polygon, site, field_, piece_order(piece), with_cost);
  }
}

template <sdot::ProjectiveGeometry G>
template <class Visit>
void sdot::PiecewiseDensity<G>::for_each_overlap(const Cell<Point>& cell, Visit&& visit) const {
  if (cell.empty()) return;
  // Cells are clipped by the pieces, not the other way round: a piece's edges come from
  // well-separated data points, while a Laguerre cell may have arbitrarily short edges whose
  // direction is not reliable.
  thread_local std::vector<Eigen::Vector3d> polygon, clipped, scratch;
  thread_local Cell<Point> piece_cell;
  polygon.clear();
  Eigen::Vector3d sum = Eigen::Vector3d::Zero();
  for (const auto& v : cell.vertices) {
    polygon.push_back(unit(v));
    sum += polygon.back();
  }
  Eigen::Vector3d center = Eigen::Vector3d::UnitZ();
  double radius = std::numbers::pi;  // a cell that is not small: query everything
  if (sum.norm() > 1e-9) {
    center = sum.normalized();
    double r = 0;
    for (const auto& v : polygon) r = std::max(r, detail::angle_between(center, v));
    if (r < std::numbers::pi / 2 - 1e-6) radius = r;
  }
  tree_.query(center, radius, [&](int index) {
    const auto piece = static_cast<std::size_t>(index);
    clipped = polygon;
    for (std::uint32_t k = offsets_[piece]; k < offsets_[piece + 1] && clipped.size() >= 3; ++k) {
      detail::clip_homogeneous(clipped, normals_[k], scratch);
      std::swap(clipped, scratch);
    }
    if (clipped.size() < 3) return;
    piece_cell.vertices.clear();
    for (const auto& v : clipped) piece_cell.vertices.push_back(geometry_.from_projective(v));
    piece_cell.neighbors.assign(clipped.size(), 0);
    visit(piece, static_cast<const Cell<Point>&>(piece_cell));
  });
}

template <sdot::ProjectiveGeometry G>
sdot::CellIntegrals<typename G::Point> sdot::PiecewiseDensity<G>::integrate_cell(const G& geometry,
                                                                                 const Cell<Point>& cell,
                                                                                 const Point& site,
                                                                                 bool with_cost) const {
  if constexpr (requires { geometry.is_circle_arc(0); }) {
    for (int label : cell.neighbors)
      if (geometry.is_circle_arc(label))
        throw InputError(name_, "piecewise densities need a domain bounded by geodesics; the " +
                                    std::string(G::name()) +
                                    "'s cap domain is not supported (use the whole sphere or a polygon domain)");
  }
  CellIntegrals<Point> result;
  for_each_overlap(cell, [&](std::size_t piece, const Cell<Point>& polygon) {
    const auto part = integrate_piece(geometry, piece, polygon, site, with_cost);
    result.mass += part.mass;
    result.first_moment += part.first_moment;
    result.cost += part.cost;
  });
  return result;
}

template <sdot::ProjectiveGeometry G>
double sdot::PiecewiseDensity<G>::facet_weight(const G& geometry, const Point& a, const Point& b, const Point& site_i,
                                               double weight_i, const Point& site_j, double weight_j) const {
  const Eigen::Vector3d ua = unit(a), ub = unit(b);
  const Eigen::Vector3d middle = (ua + ub).normalized();
  double result = 0;
  tree_.query(middle, detail::angle_between(ua, ub) / 2, [&](int index) {
    const auto piece = static_cast<std::size_t>(index);
    if (kinds_[piece] == PieceKind::constant && constants_[piece] == 0) return;
    double s0 = 0, s1 = 1, share = 1;
    for (std::uint32_t k = offsets_[piece]; k < offsets_[piece + 1]; ++k) {
      const double da = normals_[k].dot(ua), db = normals_[k].dot(ub);
      constexpr double on_edge = 1e-12;
      if (std::abs(da) <= on_edge && std::abs(db) <= on_edge) {
        share = 0.5;  // along the common edge of two pieces: the mean of both sides
        continue;
      }
      if (da < 0 && db < 0) return;
      if (da < 0) s0 = std::max(s0, da / (da - db));
      if (db < 0) s1 = std::min(s1, da / (da - db));
    }
    if (!(s1 > s0)) return;
    const Point pa = geometry_.from_projective((1 - s0) * ua + s0 * ub);
    const Point pb = geometry_.from_projective((1 - s1) * ua + s1 * ub);
    switch (kinds_[piece]) {
      case PieceKind::constant:
        result += share * constants_[piece] * geometry.facet_weight(pa, pb, site_i, weight_i, site_j, weight_j);
        break;
      case PieceKind::linear: {
        const ScalarField<Point> rho = [this, piece](const Point& x) { return local_value(piece, x); };
        result += share * geometry.facet_weight(pa, pb, site_i, weight_i, site_j, weight_j, rho, quadrature_order_);
        break;
      }
      case PieceKind::field:
        result += share * geometry.facet_weight(pa, pb, site_i, weight_i, site_j, weight_j, field_, piece_order(piece));
        break;
    }
  });
  return result;
}

template <sdot::ProjectiveGeometry G>
sdot::PiecewiseDensity<G> sdot::PiecewiseDensity<G>::restricted_to(const std::vector<std::vector<Point>>& region,
                                                                   const std::string& field) const {
  // Clip every piece overlapping a region piece by that region piece: the region's pieces come
  // from data (well-conditioned edges) and are convex.
  const std::vector<DensityPiece<Point>> region_pieces = [&] {
    std::vector<DensityPiece<Point>> pieces(region.size());
    for (std::size_t r = 0; r < region.size(); ++r) pieces[r].polygon = region[r], pieces[r].values[0] = 1;
    return pieces;
  }();
  const PiecewiseDensity<G> validated(geometry_, region_pieces, {}, quadrature_order_, field);
  PiecewiseDensity<G> result(geometry_, {}, field_, quadrature_order_, name_);
  std::vector<Eigen::Vector3d> clipped, scratch;
  for (std::size_t r = 0; r < validated.piece_count(); ++r) {
    tree_.query(validated.cap_centers_[r], validated.cap_radii_[r], [&](int index) {
      const auto piece = static_cast<std::size_t>(index);
      const auto piece_corners = corners(piece);
      clipped.assign(piece_corners.begin(), piece_corners.end());
      for (std::uint32_t k = validated.offsets_[r]; k < validated.offsets_[r + 1] && clipped.size() >= 3; ++k) {
        detail::clip_homogeneous(clipped, validated.normals_[k], scratch);
        std::swap(clipped, scratch);
      }
      // Drop slivers of round-off size.
      if (clipped.size() < 3) return;
      double twice_area = 0;
      for (std::size_t k = 1; k + 1 < clipped.size(); ++k)
        twice_area += clipped[0].cross(clipped[k]).dot(clipped[k + 1]);
      if (!(twice_area > 1e-15 * cap_radii_[piece] * cap_radii_[piece])) return;
      result.add_unit_piece(clipped, kinds_[piece], constants_[piece], numerators_[piece], denominators_[piece]);
    });
  }
  result.build_index();
  return result;
}

template <sdot::ProjectiveGeometry G>
double sdot::PiecewiseDensity<G>::total_mass() const {
  const auto count = static_cast<std::ptrdiff_t>(kinds_.size());
  double total = 0;
#pragma omp parallel for reduction(+ : total) schedule(dynamic, 1024)
  for (std::ptrdiff_t p = 0; p < count; ++p) {
    Cell<Point> polygon;
    for (const auto& v : corners(static_cast<std::size_t>(p))) polygon.vertices.push_back(geometry_.from_projective(v));
    polygon.neighbors.assign(polygon.vertices.size(), 0);
    total += integrate_piece(geometry_, static_cast<std::size_t>(p), polygon, polygon.vertices[0], false).mass;
  }
  return total;
}

template <sdot::ProjectiveGeometry G>
double sdot::PiecewiseDensity<G>::value(const Point& x) const {
  const Eigen::Vector3d ux = unit(x);
  double found = 0;
  bool done = false;
  tree_.query(ux, 0, [&](int index) {
    const auto piece = static_cast<std::size_t>(index);
    if (done) return;
    for (std::uint32_t k = offsets_[piece]; k < offsets_[piece + 1]; ++k)
      if (normals_[k].dot(ux) < -1e-15) return;
    found = local_value(piece, x);
    done = true;
  });
  return found;
}

template <sdot::ProjectiveGeometry G>
sdot::PiecewiseDensity<G> sdot::mesh_density(const G& geometry, std::span<const typename G::Point> vertices,
                                             std::span<const std::array<int, 3>> triangles,
                                             std::span<const double> vertex_values, int quadrature_order,
                                             const std::string& name) {
  using Point = typename G::Point;
  if (vertex_values.size() != vertices.size())
    throw InputError(name + ".values", "has " + std::to_string(vertex_values.size()) + " values for " +
                                           std::to_string(vertices.size()) + " vertices");
  for (std::size_t i = 0; i < vertices.size(); ++i) {
    if (!vertices[i].allFinite()) throw InputError(indexed(name + ".vertices", i), "is not finite");
    if (!(std::isfinite(vertex_values[i]) && vertex_values[i] >= 0))
      throw InputError(indexed(name + ".values", i),
                       "must be a finite number >= 0, got " + std::to_string(vertex_values[i]));
  }
  std::vector<DensityPiece<Point>> pieces(triangles.size());
  for (std::size_t t = 0; t < triangles.size(); ++t) {
    auto& piece = pieces[t];
    piece.kind = PieceKind::linear;
    for (int k = 0; k < 3; ++k) {
      const int v = triangles[t][static_cast<std::size_t>(k)];
      if (v < 0 || static_cast<std::size_t>(v) >= vertices.size())
        throw InputError(indexed(name + ".triangles", t), "vertex index " + std::to_string(v) + " is out of range (" +
                                                              std::to_string(vertices.size()) + " vertices)");
      piece.polygon.push_back(vertices[static_cast<std::size_t>(v)]);
      piece.values[static_cast<std::size_t>(k)] = vertex_values[static_cast<std::size_t>(v)];
    }
  }
  return PiecewiseDensity<G>(geometry, pieces, {}, quadrature_order, name + ".triangles");
}

template <sdot::ProjectiveGeometry G>
sdot::PiecewiseDensity<G> sdot::mesh_density_per_triangle(const G& geometry,
                                                          std::span<const typename G::Point> vertices,
                                                          std::span<const std::array<int, 3>> triangles,
                                                          std::span<const double> triangle_values,
                                                          const std::string& name) {
  using Point = typename G::Point;
  if (triangle_values.size() != triangles.size())
    throw InputError(name + ".values", "has " + std::to_string(triangle_values.size()) + " values for " +
                                           std::to_string(triangles.size()) + " triangles");
  std::vector<DensityPiece<Point>> pieces(triangles.size());
  for (std::size_t t = 0; t < triangles.size(); ++t) {
    auto& piece = pieces[t];
    piece.kind = PieceKind::constant;
    piece.values[0] = triangle_values[t];
    for (int v : triangles[t]) {
      if (v < 0 || static_cast<std::size_t>(v) >= vertices.size())
        throw InputError(indexed(name + ".triangles", t), "vertex index " + std::to_string(v) + " is out of range (" +
                                                              std::to_string(vertices.size()) + " vertices)");
      if (!vertices[static_cast<std::size_t>(v)].allFinite())
        throw InputError(indexed(name + ".vertices", static_cast<std::size_t>(v)), "is not finite");
      piece.polygon.push_back(vertices[static_cast<std::size_t>(v)]);
    }
  }
  return PiecewiseDensity<G>(geometry, pieces, {}, 3, name + ".triangles");
}

template <sdot::ProjectiveGeometry G>
sdot::TriangleMesh<typename G::Point> sdot::subdivide(const G& geometry, const TriangleMesh<typename G::Point>& mesh,
                                                      int levels) {
  TriangleMesh<typename G::Point> result = mesh;
  for (int level = 0; level < levels; ++level) {
    std::unordered_map<std::uint64_t, int> midpoints;
    auto midpoint = [&](int a, int b) {
      const auto key = (static_cast<std::uint64_t>(std::min(a, b)) << 32) | static_cast<std::uint32_t>(std::max(a, b));
      const auto [it, inserted] = midpoints.try_emplace(key, static_cast<int>(result.vertices.size()));
      if (inserted) {
        const auto& pa = result.vertices[static_cast<std::size_t>(a)];
        const auto& pb = result.vertices[static_cast<std::size_t>(b)];
        result.vertices.push_back(geometry.from_projective(geometry.to_projective(pa).normalized() +
                                                           geometry.to_projective(pb).normalized()));
      }
      return it->second;
    };
    std::vector<std::array<int, 3>> finer;
    finer.reserve(4 * result.triangles.size());
    for (const auto& [a, b, c] : result.triangles) {
      const int ab = midpoint(a, b), bc = midpoint(b, c), ca = midpoint(c, a);
      finer.push_back({a, ab, ca});
      finer.push_back({ab, b, bc});
      finer.push_back({ca, bc, c});
      finer.push_back({ab, bc, ca});
    }
    result.triangles = std::move(finer);
  }
  return result;
}
