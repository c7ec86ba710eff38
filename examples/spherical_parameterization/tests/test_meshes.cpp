#include "test_meshes.hpp"

#include <cmath>
#include <map>
#include <random>

namespace sphparam::test {

Mesh icosphere(int level) {
  const double t = (1 + std::sqrt(5.0)) / 2;
  Mesh m;
  m.vertices = {{-1, t, 0},  {1, t, 0},  {-1, -t, 0}, {1, -t, 0}, {0, -1, t},  {0, 1, t},
                {0, -1, -t}, {0, 1, -t}, {t, 0, -1},  {t, 0, 1},  {-t, 0, -1}, {-t, 0, 1}};
  for (auto& v : m.vertices) v.normalize();
  m.faces = {{0, 11, 5},  {0, 5, 1},  {0, 1, 7},  {0, 7, 10}, {0, 10, 11}, {1, 5, 9}, {5, 11, 4},
             {11, 10, 2}, {10, 7, 6}, {7, 1, 8},  {3, 9, 4},  {3, 4, 2},   {3, 2, 6}, {3, 6, 8},
             {3, 8, 9},   {4, 9, 5},  {2, 4, 11}, {6, 2, 10}, {8, 6, 7},   {9, 8, 1}};
  for (int l = 0; l < level; ++l) {
    std::map<std::pair<int, int>, int> mid;
    auto get = [&](int a, int b) {
      auto k = std::make_pair(std::min(a, b), std::max(a, b));
      auto it = mid.find(k);
      if (it != mid.end()) return it->second;
      const int i = static_cast<int>(m.vertices.size());
      m.vertices.push_back(
          (m.vertices[static_cast<std::size_t>(a)] + m.vertices[static_cast<std::size_t>(b)]).normalized());
      mid[k] = i;
      return i;
    };
    std::vector<Face> faces;
    for (const auto& f : m.faces) {
      const int ab = get(f[0], f[1]), bc = get(f[1], f[2]), ca = get(f[2], f[0]);
      faces.push_back({f[0], ab, ca});
      faces.push_back({ab, f[1], bc});
      faces.push_back({ca, bc, f[2]});
      faces.push_back({ab, bc, ca});
    }
    m.faces = std::move(faces);
  }
  return m;
}

Mesh ellipsoid(int level, double a, double b, double c) {
  Mesh m = icosphere(level);
  for (auto& v : m.vertices) v = Vec3(a * v.x(), b * v.y(), c * v.z());
  return m;
}

Mesh spiky_sphere(int level, int count, double length, double width) {
  Mesh m = icosphere(level);
  std::mt19937 rng(7);
  std::normal_distribution<double> n(0, 1);
  std::vector<Vec3> dirs;
  for (int k = 0; k < count; ++k) dirs.push_back(Vec3(n(rng), n(rng), n(rng)).normalized());
  for (auto& v : m.vertices) {
    double r = 1;
    for (const auto& d : dirs) {
      const double ang = std::acos(std::clamp(v.dot(d), -1.0, 1.0));
      if (ang < width) r = std::max(r, 1 + (length - 1) * std::cos(0.5 * M_PI * ang / width));
    }
    v *= r;
  }
  return m;
}

Mesh capsule(int around, double length) {
  const double step = 2 * M_PI / around;
  const double spacing = 2 * std::sin(step / 2) * std::sqrt(3.0) / 2;  // equilateral rings
  const int rings = std::max(2, static_cast<int>(std::lround(length / spacing)) + 1);
  Mesh m;
  for (int k = 0; k < rings; ++k)
    for (int j = 0; j < around; ++j) {
      const double angle = (j + 0.5 * (k % 2)) * step;
      m.vertices.emplace_back(std::cos(angle), std::sin(angle), length * k / (rings - 1));
    }
  auto at = [around](int k, int j) { return k * around + (j % around + around) % around; };
  for (int k = 0; k + 1 < rings; ++k)
    for (int j = 0; j < around; ++j) {
      // the vertex of ring k + 1 between (k, j) and (k, j + 1): even rings are at whole steps
      const int up = j + k % 2;
      m.faces.push_back({at(k, j), at(k, j + 1), at(k + 1, up)});
      m.faces.push_back({at(k, j), at(k + 1, up), at(k + 1, up - 1)});
    }
  const int bottom = static_cast<int>(m.vertices.size());
  m.vertices.emplace_back(0, 0, -spacing / 2);
  const int top = bottom + 1;
  m.vertices.emplace_back(0, 0, length + spacing / 2);
  for (int j = 0; j < around; ++j) {
    m.faces.push_back({bottom, at(0, j + 1), at(0, j)});
    m.faces.push_back({top, at(rings - 1, j), at(rings - 1, j + 1)});
  }
  return m;
}

Mesh bumpy_sphere(int level, int bumps, double amplitude, unsigned seed) {
  Mesh m = icosphere(level);
  std::mt19937 rng(seed);
  std::normal_distribution<double> n(0, 1);
  std::uniform_real_distribution<double> uni(-1, 1);
  std::vector<Vec3> c;
  std::vector<double> a;
  for (int k = 0; k < bumps; ++k)
    c.push_back(Vec3(n(rng), n(rng), n(rng)).normalized()), a.push_back(amplitude * uni(rng));
  for (auto& v : m.vertices) {
    double r = 1;
    for (int k = 0; k < bumps; ++k)
      r += a[static_cast<std::size_t>(k)] * std::exp(-(v - c[static_cast<std::size_t>(k)]).squaredNorm() / 0.15);
    v *= std::max(r, 0.2);
  }
  return m;
}

Mesh sliver_sphere(int level) {
  const Mesh sphere = icosphere(level);
  const auto at = [&](int i) { return sphere.vertices[static_cast<std::size_t>(i)]; };
  Mesh m;
  m.vertices = sphere.vertices;
  std::map<std::pair<int, int>, std::vector<std::size_t>> edge_faces;
  for (std::size_t f = 0; f < sphere.faces.size(); ++f)
    for (int k = 0; k < 3; ++k) {
      const int a = sphere.faces[f][static_cast<std::size_t>(k)],
                b = sphere.faces[f][static_cast<std::size_t>((k + 1) % 3)];
      edge_faces[{std::min(a, b), std::max(a, b)}].push_back(f);
    }
  std::vector<char> used(sphere.faces.size(), 0);
  int eligible = 0, splits = 0;
  for (const auto& [edge, faces] : edge_faces) {
    if (used[faces[0]] || used[faces[1]] || eligible++ % 3 != 0) continue;
    const double t = splits++ % 2 == 0 ? 1e-3 : 2.5e-5;
    const auto [a, b] = edge;
    const int p = static_cast<int>(m.vertices.size());
    m.vertices.push_back(at(a) + t * (at(b) - at(a)));
    for (std::size_t f : faces) {
      used[f] = 1;
      Face tri = sphere.faces[f];
      while (tri[0] != a) tri = {tri[1], tri[2], tri[0]};
      if (tri[1] == b)  // (a, b, c) -> (a, p, c), (p, b, c)
        m.faces.push_back({a, p, tri[2]}), m.faces.push_back({p, b, tri[2]});
      else  // (a, c, b) -> (a, c, p), (p, c, b)
        m.faces.push_back({a, tri[1], p}), m.faces.push_back({p, tri[1], b});
    }
  }
  int whole = 0;
  for (std::size_t f = 0; f < sphere.faces.size(); ++f) {
    if (used[f]) continue;
    const Face& t = sphere.faces[f];
    if (whole++ % 7 != 0) {
      m.faces.push_back(t);
      continue;
    }
    const Vec3 middle = 0.5 * (at(t[0]) + at(t[1]));
    const int p = static_cast<int>(m.vertices.size());
    m.vertices.push_back(middle + 1e-5 * (at(t[2]) - middle));
    m.faces.push_back({t[0], t[1], p}), m.faces.push_back({t[1], t[2], p}), m.faces.push_back({t[2], t[0], p});
  }
  return m;
}

}  // namespace sphparam::test
