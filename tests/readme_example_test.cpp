// The README's C++ example, compiled and run so that it cannot rot.
#include <gtest/gtest.h>

#include <iostream>
#include <utility>

#include <sdot/geometries/plane.hpp>
#include <sdot/solver.hpp>

TEST(Readme, PlaneExample) {
  std::vector<sdot::Plane::Point> sites = {{0.2, 0.3}, {0.7, 0.2}, {0.5, 0.8}};
  Eigen::VectorXd masses(3);
  masses << 0.2, 0.3, 0.5;  // sum = area of the unit square
  const sdot::Plane plane;  // source: uniform on [0, 1]²
  auto result = sdot::solve(plane, sdot::UniformDensity{}, std::span(std::as_const(sites)), masses);
  if (!result.summary.converged()) std::cerr << result.summary.message << "\n";
  // result.weights, result.masses, result.centroids, result.transport_cost, result.diagram.cells
  ASSERT_TRUE(result.summary.converged());
  EXPECT_NEAR(result.masses[2], 0.5, 1e-9);
  EXPECT_EQ(result.diagram.cells.size(), 3u);
}
