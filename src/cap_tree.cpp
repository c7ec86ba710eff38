#include "sdot/cap_tree.hpp"

#include <algorithm>

namespace sdot {

CapTree::CapTree(std::span<const Eigen::Vector3d> centres, std::span<const double> radii)
    : centres_(centres.begin(), centres.end()), cos_radii_(centres.size(), 1.0), sin_radii_(centres.size(), 0.0) {
  for (std::size_t k = 0; k < radii.size() && k < centres.size(); ++k) {
    cos_radii_[k] = std::cos(radii[k]);
    sin_radii_[k] = std::sin(radii[k]);
  }
  order_.resize(centres.size());
  for (std::size_t k = 0; k < order_.size(); ++k) order_[k] = static_cast<int>(k);
  nodes_.reserve(2 * centres.size() / leaf_size + 2);
  if (!centres.empty()) build(0, static_cast<int>(centres.size()));
}

int CapTree::build(int begin, int end) {
  const int index = static_cast<int>(nodes_.size());
  nodes_.emplace_back();
  Eigen::Vector3d low = Eigen::Vector3d::Constant(INFINITY), high = -low, sum = Eigen::Vector3d::Zero();
  for (int k = begin; k < end; ++k) {
    const auto& c = centres_[static_cast<std::size_t>(order_[static_cast<std::size_t>(k)])];
    low = low.cwiseMin(c);
    high = high.cwiseMax(c);
    sum += c;
  }
  Node node;
  node.begin = begin;
  node.end = end;
  if (sum.norm() > 1e-12) {
    // The node's radius: the largest ∠(axis, c_i) + r_i, as its cosine cos ∠ cos r − sin ∠ sin r
    // (no inverse cosine), padded by round-off.
    node.axis = sum.normalized();
    double cos_radius = 1;
    for (int k = begin; k < end; ++k) {
      const auto i = static_cast<std::size_t>(order_[static_cast<std::size_t>(k)]);
      const double c = std::clamp(node.axis.dot(centres_[i]), -1.0, 1.0);
      const double s = std::sqrt(1 - c * c);
      // The sum of the two angles exceeds π when the sine of the sum is negative: anything.
      const double sin_sum = s * cos_radii_[i] + c * sin_radii_[i];
      cos_radius = sin_sum < 0 ? -1.0 : std::min(cos_radius, c * cos_radii_[i] - s * sin_radii_[i]);
    }
    node.cos_radius = std::max(-1.0, cos_radius - 1e-12);
    node.sin_radius = std::sqrt(std::max(0.0, 1 - node.cos_radius * node.cos_radius)) + 1e-12;
  }  // else: the items surround the origin, the node's cap is the whole sphere (cos −1)
  if (end - begin > leaf_size) {
    Eigen::Index axis = 0;
    (high - low).maxCoeff(&axis);
    const int middle = begin + (end - begin) / 2;
    std::nth_element(order_.begin() + begin, order_.begin() + middle, order_.begin() + end, [&](int a, int b) {
      return centres_[static_cast<std::size_t>(a)][axis] < centres_[static_cast<std::size_t>(b)][axis];
    });
    node.left = build(begin, middle);
    node.right = build(middle, end);
  }
  nodes_[static_cast<std::size_t>(index)] = node;
  return index;
}

}  // namespace sdot
