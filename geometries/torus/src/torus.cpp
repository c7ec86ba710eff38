#include "sdot/geometries/torus.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <string>

#include "sdot/chart_diagram.hpp"
#include "sdot/error.hpp"
#include "sdot/quadrature.hpp"

namespace sdot {
namespace {

/// The first ghost margin, in mean site spacings: wide enough for the Voronoi cells of uniform
/// random sites at 10⁶ (a few spacings across at most), narrow enough that the ghosts stay a few
/// percent of the sites (4·4·√N of them in the unit square).
constexpr double initial_margin_factor = 4;

std::string interval(double low, double high) {
  char text[64];
  std::snprintf(text, sizeof text, "[%.6g, %.6g]", low, high);
  return text;
}

/// The lower envelope g(t) = min_k (t − t_k)² + c_k of parabolas of one shape, and a floor:
/// min(g(t), floor). Built in O(k log k) (sorted by t_k, then the classic hull of parabolas),
/// evaluated in O(log k).
class SideEnvelope {
 public:
  SideEnvelope(std::vector<std::pair<double, double>> parabolas, double floor) : floor_(floor) {
    std::sort(parabolas.begin(), parabolas.end());
    for (const auto& [t, c] : parabolas) {
      if (c >= floor_) continue;
      if (!center_.empty() && center_.back() == t) {  // same centre: the lower one wins everywhere
        if (c >= offset_.back()) continue;
        center_.pop_back(), offset_.pop_back(), start_.pop_back();
      }
      double from = -std::numeric_limits<double>::infinity();
      while (!center_.empty()) {
        // Where the new parabola gets below the last one (to its right from then on).
        from = ((c + t * t) - (offset_.back() + center_.back() * center_.back())) / (2 * (t - center_.back()));
        if (from > start_.back()) break;
        center_.pop_back(), offset_.pop_back(), start_.pop_back();
        from = -std::numeric_limits<double>::infinity();
      }
      center_.push_back(t), offset_.push_back(c), start_.push_back(from);
    }
  }
  double operator()(double t) const {
    if (center_.empty()) return floor_;
    const auto k = static_cast<std::size_t>(std::upper_bound(start_.begin(), start_.end(), t) - start_.begin()) - 1;
    return std::min(floor_, (t - center_[k]) * (t - center_[k]) + offset_[k]);
  }

 private:
  double floor_;
  std::vector<double> center_, offset_, start_;  // parabola k is the lowest from start_[k] on
};

/// Raises `target` to at least `value` (concurrent callers keep the largest).
void store_max(std::atomic<double>& target, double value) {
  double current = target.load(std::memory_order_relaxed);
  while (current < value && !target.compare_exchange_weak(current, value, std::memory_order_relaxed)) {
  }
}

}  // namespace

Torus::Torus() : Torus(Eigen::AlignedBox2d(Point(0, 0), Point(1, 1)), {true, true}) {}

Torus::Torus(const Eigen::AlignedBox2d& box, std::array<bool, 2> periodic)
    : box_(box), periodic_(periodic), margin_factor_(initial_margin_factor) {
  const Point low = box.min(), high = box.max();
  if (!(low.allFinite() && high.allFinite() && high.x() > low.x() && high.y() > low.y()))
    throw InputError("domain", "the box must be finite with positive size, got " + interval(low.x(), high.x()) + " x " +
                                   interval(low.y(), high.y()));
  period_ = high - low;
  plane_ = Plane(ConvexPolygon::rectangle(low.x(), low.y(), high.x(), high.y()));
}

Torus::Torus(const Torus& other)
    : box_(other.box_),
      periodic_(other.periodic_),
      period_(other.period_),
      plane_(other.plane_),
      margin_factor_(other.margin_factor()) {}

Torus& Torus::operator=(const Torus& other) {
  box_ = other.box_;
  periodic_ = other.periodic_;
  period_ = other.period_;
  plane_ = other.plane_;
  margin_factor_.store(other.margin_factor(), std::memory_order_relaxed);
  return *this;
}

Torus::Point Torus::wrap_outside(const Point& x) const {
  Point result = x;
  for (int d = 0; d < 2; ++d) {
    if (!periodic_[static_cast<std::size_t>(d)]) continue;
    const double low = box_.min()[d], high = box_.max()[d], period = period_[d];
    double v = x[d];
    if (v >= low && v < high) continue;  // inside along this axis: unchanged, to the last bit
    v -= period * std::floor((v - low) / period);
    // Round-off can leave v at the upper side or just below the lower one.
    if (v >= high) v -= period;
    if (v < low) v = v + period < high ? v + period : low;
    result[d] = v;
  }
  return result;
}

double Torus::cost(const Point& x, const Point& y) const {
  Point difference = x - y;
  for (int d = 0; d < 2; ++d)
    if (periodic_[static_cast<std::size_t>(d)]) difference[d] -= period_[d] * std::round(difference[d] / period_[d]);
  return difference.squaredNorm() / 2;
}

std::vector<Torus::Point> Torus::image_shifts() const {
  std::vector<Point> shifts{Point::Zero()};
  for (int sx = -1; sx <= 1; ++sx)
    for (int sy = -1; sy <= 1; ++sy) {
      if ((sx != 0 && !periodic_[0]) || (sy != 0 && !periodic_[1]) || (sx == 0 && sy == 0)) continue;
      shifts.emplace_back(sx * period_.x(), sy * period_.y());
    }
  return shifts;
}

void Torus::validate_sites(std::span<const Point> sites) const {
  // Along an axis that does not wrap, farther than this from the box, squared distances overflow.
  constexpr double max_radii = 1e100;
  const double radius = box_.diagonal().norm() / 2;
  for (std::size_t i = 0; i < sites.size(); ++i) {
    if (!sites[i].allFinite()) throw InputError(indexed("sites", i), "coordinate is not finite");
    for (int d = 0; d < 2; ++d)
      if (!periodic_[static_cast<std::size_t>(d)] && !(std::abs(sites[i][d] - box_.center()[d]) <= max_radii * radius))
        throw InputError(indexed("sites", i),
                         "is more than 1e100 box radii from the box along the axis that does "
                         "not wrap");
  }
  // Two sites are the same point of the torus when their wrapped coordinates agree: within
  // `tolerance` (circularly) along a periodic axis, where wrapping rounds (0.3 + 1 − 1 is not
  // 0.3), exactly along another. Sites are bucketed on a grid of `bucket` (64 tolerances) along
  // the periodic axes, so only sites of one bucket, or of neighbouring buckets near their common
  // side, are compared.
  const std::size_t n = sites.size();
  std::vector<Point> wrapped(n);
  for (std::size_t i = 0; i < n; ++i) wrapped[i] = wrap(sites[i]);
  Point tolerance = Point::Zero(), bucket = Point::Ones();
  std::array<double, 2> bucket_count{0, 0};
  for (int d = 0; d < 2; ++d)
    if (periodic_[static_cast<std::size_t>(d)]) {
      const double scale = std::max({std::abs(box_.min()[d]), std::abs(box_.max()[d]), period_[d]});
      tolerance[d] = 8 * std::numeric_limits<double>::epsilon() * scale;
      bucket[d] = 64 * tolerance[d];
      bucket_count[static_cast<std::size_t>(d)] = std::ceil(period_[d] / bucket[d]);
    }
  auto key = [&](const Point& p, int d) {
    return periodic_[static_cast<std::size_t>(d)] ? std::floor((p[d] - box_.min()[d]) / bucket[d]) : p[d];
  };
  struct Entry {
    double key[2];
    std::size_t index;
  };
  std::vector<Entry> entries(n);
  for (std::size_t i = 0; i < n; ++i) entries[i] = {{key(wrapped[i], 0), key(wrapped[i], 1)}, i};
  auto less = [](const Entry& a, const Entry& b) {
    if (a.key[0] != b.key[0]) return a.key[0] < b.key[0];
    if (a.key[1] != b.key[1]) return a.key[1] < b.key[1];
    return a.index < b.index;
  };
  std::sort(entries.begin(), entries.end(), less);
  auto same_point = [&](std::size_t i, std::size_t j) {
    for (int d = 0; d < 2; ++d) {
      double gap = std::abs(wrapped[i][d] - wrapped[j][d]);
      if (!periodic_[static_cast<std::size_t>(d)]) {
        if (gap != 0) return false;
        continue;
      }
      gap = std::min(gap, period_[d] - gap);
      if (gap > tolerance[d]) return false;
    }
    return true;
  };
  auto check = [&](std::size_t i, std::size_t j) {
    if (i == j || !same_point(i, j)) return;
    const auto [first, second] = std::minmax(i, j);
    throw InputError(indexed("sites", second), "duplicate of sites[" + std::to_string(first) + "] modulo the period");
  };
  for (std::size_t begin = 0; begin < n;) {
    std::size_t end = begin + 1;
    while (end < n && entries[end].key[0] == entries[begin].key[0] && entries[end].key[1] == entries[begin].key[1])
      ++end;
    for (std::size_t a = begin; a < end; ++a)
      for (std::size_t b = a + 1; b < end; ++b) check(entries[a].index, entries[b].index);
    begin = end;
  }
  // Neighbouring buckets, from the sites near a bucket's side (the last bucket's upper side is
  // the box's, whose neighbour across is the first bucket).
  for (const Entry& entry : entries) {
    std::array<std::vector<double>, 2> offsets{std::vector<double>{0}, std::vector<double>{0}};
    for (int d = 0; d < 2; ++d) {
      if (!periodic_[static_cast<std::size_t>(d)]) continue;
      const double k = entry.key[d], count = bucket_count[static_cast<std::size_t>(d)];
      const double position = wrapped[entry.index][d] - box_.min()[d];
      auto& list = offsets[static_cast<std::size_t>(d)];
      if (position - k * bucket[d] <= 2 * tolerance[d]) list.push_back(k == 0 ? count - 1 - k : -1);
      if (std::min((k + 1) * bucket[d], period_[d]) - position <= 2 * tolerance[d])
        list.push_back(k + 1 >= count ? -k : 1);
    }
    for (double dx : offsets[0])
      for (double dy : offsets[1]) {
        if (dx == 0 && dy == 0) continue;
        const Entry probe{{entry.key[0] + dx, entry.key[1] + dy}, 0};
        for (auto it = std::lower_bound(entries.begin(), entries.end(), probe, less);
             it != entries.end() && it->key[0] == probe.key[0] && it->key[1] == probe.key[1]; ++it)
          check(entry.index, it->index);
      }
  }
}

Eigen::VectorXd Torus::default_weights(std::span<const Point> sites) const {
  // Along a non-periodic axis the weight (1 − t)(y − c)²/2 makes the power, in that coordinate,
  // that of the Voronoi diagram of c + t(y − c): the cell of site i holds the point whose
  // periodic coordinates are those of its wrapped site and whose others are c + t(y_i − c).
  const Point center = box_.center();
  Point shrink = Point::Ones();
  for (int d = 0; d < 2; ++d) {
    if (periodic_[static_cast<std::size_t>(d)]) continue;
    const double half = period_[d] / 2;
    for (const auto& site : sites) {
      const double offset = std::abs(site[d] - center[d]);
      if (offset > half) shrink[d] = std::min(shrink[d], 0.99 * half / offset);
    }
  }
  Eigen::VectorXd weights = Eigen::VectorXd::Zero(static_cast<Eigen::Index>(sites.size()));
  for (std::size_t i = 0; i < sites.size(); ++i)
    for (int d = 0; d < 2; ++d)
      weights[static_cast<Eigen::Index>(i)] +=
          (1 - shrink[d]) * (sites[i][d] - center[d]) * (sites[i][d] - center[d]) / 2;
  return weights;
}

std::vector<Torus::Point> Torus::uniform_samples(std::size_t count, std::uint64_t seed) const {
  return plane_.uniform_samples(count, seed);
}

Diagram<Torus::Point> Torus::build_diagram(std::span<const Point> sites, const Eigen::VectorXd& weights) const {
  GhostStatistics statistics;
  return build_diagram(sites, weights, statistics);
}

Diagram<Torus::Point> Torus::build_diagram(std::span<const Point> sites, const Eigen::VectorXd& weights,
                                           bool stop_at_empty_cell) const {
  GhostStatistics statistics;
  return build_diagram(sites, weights, statistics, stop_at_empty_cell);
}

Diagram<Torus::Point> Torus::build_diagram(std::span<const Point> sites, const Eigen::VectorXd& weights,
                                           GhostStatistics& statistics, bool stop_at_empty_cell) const {
  statistics = {};
  Diagram<Point> diagram;
  const std::size_t n = sites.size();
  if (n == 0) return diagram;
  // Coordinates relative to the box's centre (as the plane's builder does) and power weights 2ψ.
  const Point origin = box_.center();
  const Point low = box_.min() - origin, high = box_.max() - origin;
  std::vector<Vec2> centers(n);
  std::vector<double> power_weights(n);
  for (std::size_t i = 0; i < n; ++i) {
    centers[i] = wrap(sites[i]) - origin;
    power_weights[i] = 2 * weights[static_cast<Eigen::Index>(i)];
  }
  const double max_power_weight = 2 * weights.maxCoeff();
  const double spacing = std::sqrt(period_.prod() / static_cast<double>(n));
  const std::vector<Point> shifts = image_shifts();
  // Edges of the grown box that are not the domain's: its sides across a periodic axis.
  const std::array<bool, 4> artificial{periodic_[1], periodic_[0], periodic_[1], periodic_[0]};
  std::vector<int> owner;  // the site of each ghost
  const auto count = static_cast<std::ptrdiff_t>(n);
  double factor = margin_factor();
  for (;;) {
    Point margin = Point::Zero();
    bool full_tiling = true;
    for (int d = 0; d < 2; ++d)
      if (periodic_[static_cast<std::size_t>(d)]) {
        margin[d] = std::min(factor * spacing, period_[d]);
        full_tiling = full_tiling && margin[d] >= period_[d];
      }
    const Point grown_low = low - margin, grown_high = high + margin;
    // The ghosts: every image (one period away) that lies in the grown box.
    centers.resize(n);
    power_weights.resize(n);
    owner.clear();
    // Shift by shift, so that the ghosts follow their sites' order (a space-filling curve when the
    // solver calls) and consecutive ghosts lie close together: the triangulation inserts them
    // with short walks. Site by site, a corner site's images alternate between far sides.
    for (std::size_t s = 1; s < shifts.size(); ++s)
      for (std::size_t i = 0; i < n; ++i) {
        const Vec2 c = centers[i];
        if (!((periodic_[0] && (c.x() - low.x() <= margin.x() || high.x() - c.x() <= margin.x())) ||
              (periodic_[1] && (c.y() - low.y() <= margin.y() || high.y() - c.y() <= margin.y()))))
          continue;
        const Vec2 image = c + shifts[s];
        bool inside = true;
        for (int d = 0; d < 2; ++d)
          if (periodic_[static_cast<std::size_t>(d)])
            inside = inside && image[d] >= grown_low[d] && image[d] <= grown_high[d];
        if (!inside) continue;
        const double power_weight = power_weights[i];
        centers.push_back(image);
        power_weights.push_back(power_weight);
        owner.push_back(static_cast<int>(i));
      }
    std::vector<ChartCell> cells = build_power_diagram(
        centers, power_weights, ConvexPolygon::rectangle(grown_low.x(), grown_low.y(), grown_high.x(), grown_high.y()),
        {}, stop_at_empty_cell, PowerDiagramMethod::automatic, n, warm_start_.get());
    ++statistics.builds;
    // An empty cell is empty in the exact diagram too: a ghost only adds competitors, and a site
    // hidden among a subset of the images is hidden among all of them. The line search that asked
    // rejects the step whatever the other cells are.
    if (stop_at_empty_cell && std::any_of(cells.begin(), cells.begin() + count,
                                          [](const ChartCell& cell) { return cell.vertices.empty(); })) {
      diagram.cells.resize(n);
      return diagram;
    }

    // Is every site's cell exact? Not when it reaches a side of the grown box across a periodic
    // axis (the box cuts it there), nor when an image left out is below it at a vertex v: every
    // such image lies beyond such a side, so each side is checked against the images beyond it.
    // With a = the distance from v to the side, b the image's distance beyond it and t, t_z
    // their coordinates along it, |v − z|² − 2ψ_z ≥ a² + [b² + 2a₀b + (t − t_z)² − 2ψ_z] for
    // a ≥ a₀ ≥ 0: the bracket's minimum over the images, g(t), is the lower envelope of parabolas
    // in t (SideEnvelope), and v is safe when a² + g(t) > |v − y_i|² − 2ψ_i. Powers differ by an
    // affine function, so the vertices decide for the whole cell. Only vertices closer to a side
    // than √(|v − y_i|² − 2ψ_i + 2 max ψ) can have an image of any weight below them there.
    // `shortfall`: by how much the margin should grow for the failing vertices.
    struct SideVertex {
      double distance, along, power;  // a, t and |v − y_i|² − 2ψ_i
    };
    std::array<std::vector<SideVertex>, 4> near;  // per grown-box edge: 0 bottom, 1 right, 2 top, 3 left
    bool reaches_side = false;
#pragma omp parallel
    {
      std::array<std::vector<SideVertex>, 4> local;
      bool local_reaches = false;
#pragma omp for schedule(static) nowait
      for (std::ptrdiff_t i = 0; i < count; ++i) {
        const ChartCell& cell = cells[static_cast<std::size_t>(i)];
        for (int label : cell.neighbors)
          if (is_boundary(label) && artificial[static_cast<std::size_t>(-1 - label)]) local_reaches = true;
        for (const Vec2& v : cell.vertices) {
          const double power =
              (v - centers[static_cast<std::size_t>(i)]).squaredNorm() - power_weights[static_cast<std::size_t>(i)];
          const double reach_squared = power + max_power_weight;
          const std::array<double, 4> distance{v.y() - grown_low.y(), grown_high.x() - v.x(), grown_high.y() - v.y(),
                                               v.x() - grown_low.x()};
          for (std::size_t edge = 0; edge < 4; ++edge)
            if (artificial[edge] && distance[edge] * distance[edge] < reach_squared)
              local[edge].push_back({std::max(distance[edge], 0.0), edge % 2 == 0 ? v.x() : v.y(), power});
        }
      }
#pragma omp critical
      {
        reaches_side = reaches_side || local_reaches;
        for (std::size_t edge = 0; edge < 4; ++edge)
          near[edge].insert(near[edge].end(), local[edge].begin(), local[edge].end());
      }
    }
    double shortfall = -1;  // < 0: exact
    for (std::size_t edge = 0; edge < 4 && !reaches_side; ++edge) {
      const auto& vertices = near[edge];
      if (vertices.empty()) continue;
      const int d = edge % 2 == 0 ? 1 : 0;  // the axis across this edge
      const int t_axis = 1 - d;
      double closest = std::numeric_limits<double>::infinity(),
             largest_power = -std::numeric_limits<double>::infinity();
      for (const auto& v : vertices)
        closest = std::min(closest, v.distance), largest_power = std::max(largest_power, v.power);
      // Images further beyond than `depth` cannot be below any of these vertices.
      const double depth = std::sqrt(std::max(0.0, largest_power + max_power_weight));
      if (depth >= period_[d] - margin[d]) {  // weights far apart: images two periods away matter
        shortfall = std::max(shortfall, depth - (period_[d] - margin[d]));
        continue;
      }
      // The images beyond this edge: y_j ± period along d, for y_j beyond the band of the ghosts
      // (b = their distance beyond the edge), and along t also moved by ± a period if periodic.
      const bool upper = edge == 1 || edge == 2;
      std::vector<std::pair<double, double>> parabolas;  // (t_z, b² + 2a₀b − 2ψ_z)
      for (std::size_t j = 0; j < n; ++j) {
        const double y = centers[j][d];
        const double beyond = upper ? y - (low[d] + margin[d]) : (high[d] - margin[d]) - y;
        if (!(beyond > 0 && beyond <= depth)) continue;
        const double offset = beyond * beyond + 2 * closest * beyond - power_weights[j];
        const double t = centers[j][t_axis];
        parabolas.emplace_back(t, offset);
        if (periodic_[static_cast<std::size_t>(t_axis)]) {
          parabolas.emplace_back(t - period_[t_axis], offset);
          parabolas.emplace_back(t + period_[t_axis], offset);
        }
      }
      const SideEnvelope envelope(std::move(parabolas), depth * depth + 2 * closest * depth - max_power_weight);
      // Some 10⁴ vertices at 10⁶ sites: not worth a parallel region (whose threads wait on a busy
      // machine).
      for (const SideVertex& v : vertices) {
        const double below = envelope(v.along);
        if (!(v.distance * v.distance + below > v.power))
          shortfall = std::max({shortfall, 0.0, std::sqrt(std::max(0.0, v.power - below)) - v.distance});
      }
    }
    const bool exact = !reaches_side && shortfall < 0;
    if (exact || full_tiling) {
      statistics.ghosts = owner.size();
      statistics.margin = margin;
      statistics.full_tiling = full_tiling;
      store_max(margin_factor_, factor);
      diagram.cells.resize(n);
#pragma omp parallel for schedule(static)
      for (std::ptrdiff_t i = 0; i < count; ++i) {
        Cell<Point>& cell = diagram.cells[static_cast<std::size_t>(i)];
        cell = std::move(cells[static_cast<std::size_t>(i)]);
        for (auto& v : cell.vertices) v += origin;
        for (int& label : cell.neighbors)
          if (!is_boundary(label) && label >= static_cast<int>(n)) label = owner[static_cast<std::size_t>(label) - n];
      }
      return diagram;
    }
    // Images only get added as the margin grows, and cells only shrink then: growing it by the
    // shortfall (plus a little, for the next Newton step's weights) settles the vertices found
    // failing. A cell cut by a grown side may extend past it: the margin doubles.
    const double grown = factor + 1.1 * std::max(shortfall, 0.0) / spacing + 0.25;
    factor = reaches_side ? std::max(2 * factor, grown) : grown;
  }
}

CellIntegrals<Torus::Point> Torus::integrate(const Cell<Point>& cell, const Point& site, bool with_cost) const {
  return plane_.integrate(cell, wrap(site), with_cost);
}

CellIntegrals<Torus::Point> Torus::integrate(const Cell<Point>& cell, const Point& site, const ScalarField<Point>& rho,
                                             int order, bool with_cost) const {
  // By parts moved into the box: ρ is read there only, and a ρ that does not match across the
  // box's sides (not periodic) is integrated as accurately as a smooth one.
  const Point own = wrap(site);
  CellIntegrals<Point> total;
  for_each_part_in_box(cell, [&](const Cell<Point>& part, const Point& shift) {
    const auto piece = plane_.integrate(part, Point(own - shift), rho, order, with_cost);
    total.mass += piece.mass;
    total.first_moment += piece.first_moment + piece.mass * shift;
    total.cost += piece.cost;
  });
  return total;
}

Torus::Point Torus::image_offset(const Point& a, const Point& b, const Point& own, double weight_i, const Point& base,
                                 double weight_j) const {
  // On the bisector of y_i and z = y_i + u, ½|x − y_i|² − ψ_i = ½|x − z|² − ψ_j, that is
  // u·(x − y_i) − |u|²/2 − ψ_i + ψ_j = 0, at both ends of the edge.
  auto imbalance = [&](const Point& u) {
    const double half = u.squaredNorm() / 2 + weight_i - weight_j;
    return std::abs(u.dot(a - own) - half) + std::abs(u.dot(b - own) - half);
  };
  // Nearly always the image nearest to the site (another one is a period further and misses the
  // bisector by about a period times the edge's distance to it): accepted when it balances to
  // round-off, else every image is tried (tiny N, cells as wide as the box).
  Point nearest = base - own;  // both in the box: less than a period apart along each axis
  for (int d = 0; d < 2; ++d)
    if (periodic_[static_cast<std::size_t>(d)]) {
      if (nearest[d] > period_[d] / 2) nearest[d] -= period_[d];
      if (nearest[d] < -period_[d] / 2) nearest[d] += period_[d];
    }
  const double scale = nearest.squaredNorm() + std::abs(nearest.dot(a - own)) + std::abs(nearest.dot(b - own)) +
                       std::abs(weight_i) + std::abs(weight_j);
  if (imbalance(nearest) <= 1e-9 * scale) return nearest;
  Point best = nearest;
  double best_imbalance = std::numeric_limits<double>::infinity();
  for (const Point& shift : image_shifts()) {
    const Point u = base - own + shift;
    const double value = imbalance(u);
    if (value < best_imbalance) best_imbalance = value, best = u;
  }
  return best;
}

Torus::Point Torus::image_across(const Point& a, const Point& b, const Point& site_i, double weight_i,
                                 const Point& site_j, double weight_j) const {
  const Point own = wrap(site_i);
  return own + image_offset(a, b, own, weight_i, wrap(site_j), weight_j);
}

double Torus::facet_weight(const Point& a, const Point& b, const Point& site_i, double weight_i, const Point& site_j,
                           double weight_j) const {
  const Point own = wrap(site_i);
  return (b - a).norm() / image_offset(a, b, own, weight_i, wrap(site_j), weight_j).norm();
}

double Torus::facet_weight(const Point& a, const Point& b, const Point& site_i, double weight_i, const Point& site_j,
                           double weight_j, const ScalarField<Point>& rho, int order) const {
  const Point own = wrap(site_i);
  const double distance = image_offset(a, b, own, weight_i, wrap(site_j), weight_j).norm();
  double integral = 0;
  for_each_segment_part_in_box(a, b, [&](const Point& p, const Point& q, const Point&, double share) {
    for (const auto& node : gauss_legendre(order))
      integral += share * node.weight * rho(p + node.x * (q - p)) * (q - p).norm();
  });
  return integral / distance;
}

}  // namespace sdot
