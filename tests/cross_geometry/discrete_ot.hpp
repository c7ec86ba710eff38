#pragma once
// An exact discrete optimal transport solver that shares no code with sdot's solver:
// successive shortest paths on the transportation problem "M samples of mass 1 → N sites with
// integer capacities", with Dijkstra on the (small) site graph. It returns the assignment and
// the site potentials ψ (cells argmin_i c(x, y_i) − ψ_i), the discrete analogue of the weights.
#include <Eigen/Core>
#include <algorithm>
#include <cmath>
#include <limits>
#include <numeric>
#include <stdexcept>
#include <vector>

namespace sdot::testing {

struct DiscreteTransport {
  std::vector<int> assignment;  // site of each sample
  Eigen::VectorXd potentials;   // ψ, mean zero
  double cost = 0;              // Σ c(sample, its site) / M
};

/// Largest-remainder rounding of masses (any scale) to integers summing to `samples`.
inline std::vector<int> integer_capacities(const Eigen::VectorXd& masses, int samples) {
  const double total = masses.sum();
  std::vector<int> capacity(static_cast<std::size_t>(masses.size()));
  std::vector<std::pair<double, int>> remainder;
  int used = 0;
  for (Eigen::Index i = 0; i < masses.size(); ++i) {
    const double exact = masses[i] / total * samples;
    capacity[static_cast<std::size_t>(i)] = static_cast<int>(std::floor(exact));
    used += capacity[static_cast<std::size_t>(i)];
    remainder.emplace_back(exact - std::floor(exact), static_cast<int>(i));
  }
  std::sort(remainder.rbegin(), remainder.rend());
  for (int k = 0; used < samples; ++k, ++used)
    ++capacity[static_cast<std::size_t>(remainder[static_cast<std::size_t>(k)].second)];
  return capacity;
}

/// cost(s, i) = c(sample s, site i), an M × N matrix; capacities sum to M.
inline DiscreteTransport solve_discrete_transport(const Eigen::MatrixXd& cost, const std::vector<int>& capacity) {
  const auto samples = static_cast<int>(cost.rows());
  const auto sites = static_cast<int>(cost.cols());
  if (std::accumulate(capacity.begin(), capacity.end(), 0) != samples)
    throw std::invalid_argument("capacities must sum to the number of samples");
  const double infinity = std::numeric_limits<double>::infinity();
  std::vector<double> psi(static_cast<std::size_t>(sites), 0.0);
  std::vector<int> assignment(static_cast<std::size_t>(samples), -1), load(static_cast<std::size_t>(sites), 0);
  std::vector<std::vector<int>> members(static_cast<std::size_t>(sites));
  Eigen::MatrixXd edge(sites, sites);
  Eigen::MatrixXi witness(sites, sites);
  std::vector<double> distance(static_cast<std::size_t>(sites));
  std::vector<int> previous(static_cast<std::size_t>(sites));
  std::vector<char> done(static_cast<std::size_t>(sites));
  for (int s = 0; s < samples; ++s) {
    // Edge i → j: cheapest reduced cost of moving a sample of site i to site j (≥ 0).
    edge.setConstant(infinity);
    for (int i = 0; i < sites; ++i)
      for (int t : members[static_cast<std::size_t>(i)]) {
        const double own = cost(t, i) - psi[static_cast<std::size_t>(i)];
        for (int j = 0; j < sites; ++j) {
          const double w = cost(t, j) - psi[static_cast<std::size_t>(j)] - own;
          if (j != i && w < edge(i, j)) edge(i, j) = w, witness(i, j) = t;
        }
      }
    double best = infinity;
    for (int i = 0; i < sites; ++i) best = std::min(best, cost(s, i) - psi[static_cast<std::size_t>(i)]);
    for (int i = 0; i < sites; ++i) {
      distance[static_cast<std::size_t>(i)] = cost(s, i) - psi[static_cast<std::size_t>(i)] - best;
      previous[static_cast<std::size_t>(i)] = -1;
      done[static_cast<std::size_t>(i)] = 0;
    }
    int target = -1;
    for (int round = 0; round < sites; ++round) {
      int u = -1;
      for (int i = 0; i < sites; ++i)
        if (!done[static_cast<std::size_t>(i)] &&
            (u < 0 || distance[static_cast<std::size_t>(i)] < distance[static_cast<std::size_t>(u)]))
          u = i;
      done[static_cast<std::size_t>(u)] = 1;
      if (load[static_cast<std::size_t>(u)] < capacity[static_cast<std::size_t>(u)]) {
        target = u;
        break;
      }
      for (int j = 0; j < sites; ++j)
        if (!done[static_cast<std::size_t>(j)] &&
            distance[static_cast<std::size_t>(u)] + edge(u, j) < distance[static_cast<std::size_t>(j)]) {
          distance[static_cast<std::size_t>(j)] = distance[static_cast<std::size_t>(u)] + edge(u, j);
          previous[static_cast<std::size_t>(j)] = u;
        }
    }
    const double reach = distance[static_cast<std::size_t>(target)];
    for (int i = 0; i < sites; ++i)
      psi[static_cast<std::size_t>(i)] += std::min(distance[static_cast<std::size_t>(i)], reach);
    // Augment: every site on the path passes one sample down the path; s enters at its start.
    int j = target;
    while (previous[static_cast<std::size_t>(j)] >= 0) {
      const int i = previous[static_cast<std::size_t>(j)];
      const int t = witness(i, j);
      auto& from = members[static_cast<std::size_t>(i)];
      from.erase(std::find(from.begin(), from.end(), t));
      members[static_cast<std::size_t>(j)].push_back(t);
      assignment[static_cast<std::size_t>(t)] = j;
      j = i;
    }
    members[static_cast<std::size_t>(j)].push_back(s);
    assignment[static_cast<std::size_t>(s)] = j;
    ++load[static_cast<std::size_t>(target)];
  }
  DiscreteTransport result;
  result.assignment = assignment;
  result.potentials = Eigen::Map<Eigen::VectorXd>(psi.data(), sites);
  result.potentials.array() -= result.potentials.mean();
  for (int s = 0; s < samples; ++s) result.cost += cost(s, assignment[static_cast<std::size_t>(s)]) / samples;
  return result;
}

}  // namespace sdot::testing
