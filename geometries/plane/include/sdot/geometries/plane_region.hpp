#pragma once
/// \file plane_region.hpp
/// General plane domains: unions of polygons with holes, validated, normalised and cut into
/// convex pieces (so that code working on convex polygons can handle them piece by piece).

#include <Eigen/Core>
#include <string>
#include <vector>

namespace sdot {

/// A polygon with holes in the plane: an outer ring and hole rings (any orientation, not closed:
/// the first vertex is not repeated).
struct PolygonWithHoles {
  std::vector<Eigen::Vector2d> outer;               ///< the outer ring
  std::vector<std::vector<Eigen::Vector2d>> holes;  ///< the hole rings (possibly none)
};

/// A region of the plane: the union of polygons with holes.
///
/// Construction validates every polygon and throws InputError naming the field, e.g.
/// `domain.polygons[1].holes[0][3]` for a non-finite vertex, or `domain.polygons[0].outer` for a
/// ring with fewer than 3 distinct vertices, a self-intersecting ring (the message says which two
/// edges meet, and where) or a ring of zero area; `domain.polygons[0].holes[1]` for a hole that is
/// not inside its outer ring or that overlaps another hole. Other invalid configurations (e.g.
/// holes sharing an edge) are reported with Boost.Geometry's reason. Rings may touch at single
/// points. Overlapping or touching polygons are merged (Boost.Geometry's union).
class PlaneRegion {
 public:
  /// \param polygons  the polygons (at least one); they may overlap or touch.
  /// \param field  the name of the input, used in error messages (`<field>.polygons[i]...`).
  explicit PlaneRegion(std::vector<PolygonWithHoles> polygons, const std::string& field = "domain");

  /// The exact area (shoelace formula over the normalised rings).
  [[nodiscard]] double area() const { return area_; }
  /// The centroid of the region's area.
  [[nodiscard]] Eigen::Vector2d centroid() const { return centroid_; }
  /// The lower-left corner of the axis-aligned bounding box.
  [[nodiscard]] Eigen::Vector2d lower() const { return lower_; }
  /// The upper-right corner of the axis-aligned bounding box.
  [[nodiscard]] Eigen::Vector2d upper() const { return upper_; }
  /// True when `x` is inside the region or on its boundary.
  [[nodiscard]] bool contains(const Eigen::Vector2d& x) const;

  /// The region as interior-disjoint convex polygons (counter-clockwise, without repeated or
  /// collinear vertices, each of positive area) whose union is the region, computed once at
  /// construction by a sweep in O((V + pieces) log V) for V vertices. Vertical lines through the
  /// vertices cut the region into trapezoids, each between two boundary edges crossing a slab
  /// (the vertical slab decomposition); neighbouring trapezoids are one piece as long as their
  /// union stays convex (across a slab boundary where the two bounding chains go on, turning the
  /// convex way). So every piece is x-monotone, with vertical left and right sides (or corners);
  /// a convex region is one piece and there are at most about V pieces. Pieces may meet at
  /// T-junctions.
  [[nodiscard]] const std::vector<std::vector<Eigen::Vector2d>>& convex_pieces() const { return pieces_; }

  /// The normalised polygons (outer counter-clockwise, holes clockwise, pairwise
  /// interior-disjoint) after the union.
  [[nodiscard]] const std::vector<PolygonWithHoles>& polygons() const { return polygons_; }

 private:
  std::vector<PolygonWithHoles> polygons_;
  std::vector<std::vector<Eigen::Vector2d>> pieces_;
  double area_ = 0;
  Eigen::Vector2d centroid_ = Eigen::Vector2d::Zero();
  Eigen::Vector2d lower_ = Eigen::Vector2d::Zero();
  Eigen::Vector2d upper_ = Eigen::Vector2d::Zero();
};

}  // namespace sdot
