#pragma once
/// \file cap_tree.hpp
/// A bounding-cap tree over items on the unit sphere (each a cap: unit centre, angular radius;
/// points have radius 0). Each node keeps a cap containing its items' caps; callers prune with
/// their own bound (`traverse`) or ask which items meet a cap (`query`). Used by the sphere's
/// diagram builder (with a per-node scale bound) and by piecewise densities (on the unit
/// sphere of the projective chart).

#include <Eigen/Core>
#include <cmath>
#include <numbers>
#include <span>
#include <vector>

namespace sdot {

/// A binary tree of bounding caps over caps on the unit sphere (leaves of at most 8 items),
/// built once from the items; read-only afterwards, so concurrent queries are safe.
class CapTree {
 public:
  /// A node: a cap containing the caps of its items.
  struct Node {
    Eigen::Vector3d axis = Eigen::Vector3d::UnitZ();  ///< unit centre of the node's cap
    ///@{
    double cos_radius = -1, sin_radius = 0;  ///< cosine and sine of its angular radius (padded by round-off)
    ///@}
    ///@{
    int begin = 0, end = 0;  ///< items order()[begin, end)
    ///@}
    ///@{
    int left = -1, right = -1;  ///< children, as indices into nodes() (-1 for a leaf)
    ///@}
  };

  /// An empty tree (no nodes).
  CapTree() = default;
  /// `centres` are unit vectors; `radii` their angular radii (empty: all zero).
  explicit CapTree(std::span<const Eigen::Vector3d> centres, std::span<const double> radii = {});

  /// The nodes; node 0 is the root (none for an empty tree).
  [[nodiscard]] const std::vector<Node>& nodes() const { return nodes_; }
  /// Item indices, each node's items contiguous.
  [[nodiscard]] const std::vector<int>& order() const { return order_; }

  /// Depth first from the root: `enter(node, node_index)` says whether to look inside a node,
  /// `item(i)` is called for the items of the leaves entered.
  template <class Enter, class Item>
  void traverse(Enter&& enter, Item&& item) const {
    if (nodes_.empty()) return;
    int stack[128];
    int top = 0;
    stack[top++] = 0;
    while (top > 0) {
      const int index = stack[--top];
      const Node& node = nodes_[static_cast<std::size_t>(index)];
      if (!enter(node, index)) continue;
      if (node.left < 0) {
        for (int k = node.begin; k < node.end; ++k) item(order_[static_cast<std::size_t>(k)]);
      } else {
        stack[top++] = node.left;
        stack[top++] = node.right;
      }
    }
  }

  /// Calls visit(i) for every item whose cap meets the cap (centre, radius). Caps (c₁, r₁) and
  /// (c₂, r₂) meet when c₁·c₂ ≥ cos(r₁ + r₂) = cos r₁ cos r₂ − sin r₁ sin r₂: no inverse cosine.
  template <class Visit>
  void query(const Eigen::Vector3d& centre, double radius, Visit&& visit) const {
    constexpr double slack = 1e-12;
    const double cos_r = std::cos(radius), sin_r = std::sin(radius);
    const bool everything = radius >= std::numbers::pi;
    auto meets = [&](const Eigen::Vector3d& c, double cos_other, double sin_other) {
      // r + r_other ≥ π (cos of the sum ≤ −1 with a non-negative sine of the sum) meets anything.
      return everything || sin_r * cos_other + cos_r * sin_other < 0 ||
             centre.dot(c) >= cos_r * cos_other - sin_r * sin_other - slack;
    };
    traverse([&](const Node& node, int) { return meets(node.axis, node.cos_radius, node.sin_radius); },
             [&](int i) {
               const auto k = static_cast<std::size_t>(i);
               if (meets(centres_[k], cos_radii_[k], sin_radii_[k])) visit(i);
             });
  }

 private:
  static constexpr int leaf_size = 8;
  int build(int begin, int end);

  std::vector<Eigen::Vector3d> centres_;
  std::vector<double> cos_radii_, sin_radii_;
  std::vector<int> order_;
  std::vector<Node> nodes_;
};

}  // namespace sdot
