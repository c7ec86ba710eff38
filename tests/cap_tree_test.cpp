// The bounding-cap tree against brute force.
#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <algorithm>
#include <random>

#include "sdot/cap_tree.hpp"

namespace {

Eigen::Vector3d random_unit(std::mt19937_64& random) {
  std::normal_distribution<double> normal(0, 1);
  return Eigen::Vector3d(normal(random), normal(random), normal(random)).normalized();
}

double angle(const Eigen::Vector3d& a, const Eigen::Vector3d& b) {
  return std::atan2(a.cross(b).norm(), a.dot(b));
}

TEST(CapTree, QueryFindsExactlyTheMeetingCaps) {
  std::mt19937_64 random(8);
  std::uniform_real_distribution<double> uniform(0, 1);
  std::vector<Eigen::Vector3d> centres(3000);
  std::vector<double> radii(centres.size());
  for (std::size_t i = 0; i < centres.size(); ++i) {
    centres[i] = random_unit(random);
    radii[i] = i % 50 == 0 ? 2.0 : 0.05 * uniform(random);  // a few caps larger than a hemisphere
  }
  const sdot::CapTree tree(centres, radii);
  for (int q = 0; q < 200; ++q) {
    const Eigen::Vector3d centre = random_unit(random);
    const double radius = q % 20 == 0 ? 3.2 : 0.2 * uniform(random);
    std::vector<int> found;
    tree.query(centre, radius, [&](int i) { found.push_back(i); });
    std::sort(found.begin(), found.end());
    std::vector<int> expected;
    for (std::size_t i = 0; i < centres.size(); ++i)
      if (angle(centre, centres[i]) <= radius + radii[i] - 1e-9) expected.push_back(static_cast<int>(i));
    // Every meeting cap is found (exactness up to round-off on the boundary).
    EXPECT_TRUE(std::includes(found.begin(), found.end(), expected.begin(), expected.end())) << "query " << q;
    for (int i : found) EXPECT_LE(angle(centre, centres[static_cast<std::size_t>(i)]), radius + radii[i] + 1e-9);
  }
}

TEST(CapTree, TraverseVisitsEveryItemOnce) {
  std::mt19937_64 random(9);
  std::vector<Eigen::Vector3d> points(1000);
  for (auto& p : points) p = random_unit(random);
  const sdot::CapTree tree(points);
  std::vector<int> seen;
  tree.traverse([](const sdot::CapTree::Node&, int) { return true; }, [&](int i) { seen.push_back(i); });
  std::sort(seen.begin(), seen.end());
  ASSERT_EQ(seen.size(), points.size());
  for (std::size_t i = 0; i < seen.size(); ++i) EXPECT_EQ(seen[i], static_cast<int>(i));
  for (const auto& node : tree.nodes())  // every item lies in its node's cap
    for (int k = node.begin; k < node.end; ++k)
      EXPECT_GE(node.axis.dot(points[static_cast<std::size_t>(tree.order()[static_cast<std::size_t>(k)])]),
                node.cos_radius);
}

}  // namespace
