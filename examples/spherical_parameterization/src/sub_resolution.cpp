// Removal of sub-resolution vertices before the map, and their barycentric placement after it.
#include "sub_resolution.hpp"

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <limits>

namespace sphparam {
namespace {

double triangle_area(const Mesh& mesh, int a, int b, int c) {
  const Vec3& p = mesh.vertices[u(a)];
  return 0.5 * (mesh.vertices[u(b)] - p).cross(mesh.vertices[u(c)] - p).norm();
}

/// Per-vertex incident faces of the current surface (dead faces stay listed and are skipped).
struct Incidence {
  const std::vector<Face>& faces;
  const std::vector<char>& face_alive;
  std::vector<std::vector<int>> of_vertex;

  [[nodiscard]] bool has_edge(int a, int b) const {
    for (int f : of_vertex[u(a)])
      if (face_alive[u(f)]) {
        const Face& t = faces[u(f)];
        if (t[0] == b || t[1] == b || t[2] == b) return true;
      }
    return false;
  }
  [[nodiscard]] bool has_face(int a, int b, int c) const {
    for (int f : of_vertex[u(a)])
      if (face_alive[u(f)]) {
        const Face& t = faces[u(f)];
        const bool with_b = t[0] == b || t[1] == b || t[2] == b;
        const bool with_c = t[0] == c || t[1] == c || t[2] == c;
        if (with_b && with_c) return true;
      }
    return false;
  }
};

/// Vertices of valence 3 or 4 whose smallest incident face is below `area_ratio` times the
/// largest: one O(F) pass, so meshes without any (nearly all) pay nothing more.
std::vector<int> candidates(const Mesh& mesh, const std::vector<Face>& faces, const std::vector<char>& face_alive,
                            double area_ratio) {
  const std::size_t nv = mesh.vertices.size();
  std::vector<int> valence(nv, 0);
  std::vector<double> smallest(nv, std::numeric_limits<double>::infinity()), largest(nv, 0.0);
  for (std::size_t f = 0; f < faces.size(); ++f) {
    if (!face_alive[f]) continue;
    const Face& t = faces[f];
    const double area = triangle_area(mesh, t[0], t[1], t[2]);
    for (int v : t) {
      ++valence[u(v)];
      smallest[u(v)] = std::min(smallest[u(v)], area);
      largest[u(v)] = std::max(largest[u(v)], area);
    }
  }
  std::vector<int> out;
  for (std::size_t v = 0; v < nv; ++v)
    if ((valence[v] == 3 || valence[v] == 4) && !(smallest[v] > area_ratio * largest[v]))
      out.push_back(static_cast<int>(v));
  return out;
}

}  // namespace

MeshReduction remove_sub_resolution_vertices(const Mesh& mesh, double area_ratio, int max_rounds) {
  MeshReduction result;
  const std::size_t nv = mesh.vertices.size();
  std::vector<Face> faces = mesh.faces;
  std::vector<char> face_alive(faces.size(), 1);
  std::vector<char> removed(nv, 0);
  std::size_t kept_count = nv;
  for (int round = 0; round < max_rounds; ++round) {
    const std::vector<int> todo = candidates(mesh, faces, face_alive, area_ratio);
    if (todo.empty()) break;
    Incidence incidence{faces, face_alive, std::vector<std::vector<int>>(nv)};
    for (std::size_t f = 0; f < faces.size(); ++f)
      if (face_alive[f])
        for (int v : faces[f]) incidence.of_vertex[u(v)].push_back(static_cast<int>(f));
    std::vector<char> blocked(nv, 0);  // neighbours of this round's removals
    const std::size_t removed_before = result.removed.size();
    for (int v : todo) {
      if (blocked[u(v)] || kept_count <= 4) continue;
      // the fan n0 … n(k-1), faces (v, n_i, n_i+1) counter-clockwise (outward orientation)
      std::vector<int> fan_faces;
      for (int f : incidence.of_vertex[u(v)])
        if (face_alive[u(f)]) fan_faces.push_back(f);
      const std::size_t k = fan_faces.size();
      if (k != 3 && k != 4) continue;
      std::vector<std::pair<int, int>> next;  // (n_i, n_i+1)
      for (int f : fan_faces) {
        const Face& t = faces[u(f)];
        const int at = t[0] == v ? 0 : t[1] == v ? 1 : 2;
        next.emplace_back(t[u((at + 1) % 3)], t[u((at + 2) % 3)]);
      }
      std::vector<int> fan{next[0].first};
      for (std::size_t step = 0; step + 1 < k; ++step) {
        const int last = fan.back();
        const auto it = std::find_if(next.begin(), next.end(), [&](const auto& e) { return e.first == last; });
        if (it == next.end()) break;
        fan.push_back(it->second);
      }
      if (fan.size() != k) continue;  // not a disk around v: leave it alone
      RemovedVertex r;
      r.vertex = v;
      std::vector<Face> replacement;
      if (k == 3) {
        if (incidence.has_face(fan[0], fan[1], fan[2])) continue;
        // barycentric weights: the area of the sub-face opposite each corner
        r.corners = {fan[0], fan[1], fan[2]};
        r.weights = {triangle_area(mesh, v, fan[1], fan[2]), triangle_area(mesh, v, fan[2], fan[0]),
                     triangle_area(mesh, v, fan[0], fan[1])};
        replacement = {{fan[0], fan[1], fan[2]}};
      } else {
        // the diagonal closest to a straight angle at v; v goes back on it
        auto cos_at_v = [&](int a, int b) {
          const Vec3 da = mesh.vertices[u(a)] - mesh.vertices[u(v)], db = mesh.vertices[u(b)] - mesh.vertices[u(v)];
          return da.dot(db) / std::max(da.norm() * db.norm(), std::numeric_limits<double>::min());
        };
        if (cos_at_v(fan[1], fan[3]) < cos_at_v(fan[0], fan[2])) std::rotate(fan.begin(), fan.begin() + 1, fan.end());
        if (incidence.has_edge(fan[0], fan[2])) continue;
        const double near_side = triangle_area(mesh, v, fan[3], fan[0]) + triangle_area(mesh, v, fan[0], fan[1]);
        const double far_side = triangle_area(mesh, v, fan[1], fan[2]) + triangle_area(mesh, v, fan[2], fan[3]);
        r.corners = {fan[0], fan[2], fan[1]};
        r.weights = {far_side, near_side, 0.0};  // t = near / (near + far) from fan[0]
        replacement = {{fan[0], fan[1], fan[2]}, {fan[0], fan[2], fan[3]}};
      }
      const double sum = r.weights[0] + r.weights[1] + r.weights[2];
      if (sum > 0 && std::isfinite(sum))
        for (double& w : r.weights) w /= sum;
      else
        r.weights = k == 3 ? std::array<double, 3>{1.0 / 3, 1.0 / 3, 1.0 / 3} : std::array<double, 3>{0.5, 0.5, 0.0};
      for (int f : fan_faces) face_alive[u(f)] = 0;
      for (const Face& t : replacement) {
        const int id = static_cast<int>(faces.size());
        faces.push_back(t);
        face_alive.push_back(1);
        for (int w : t) incidence.of_vertex[u(w)].push_back(id);
      }
      for (int w : fan) blocked[u(w)] = 1;
      removed[u(v)] = 1;
      --kept_count;
      result.removed.push_back(r);
    }
    if (result.removed.size() == removed_before) break;
    ++result.rounds;
  }
  if (result.removed.empty()) return result;
  std::vector<int> index(nv, -1);
  for (std::size_t v = 0; v < nv; ++v)
    if (!removed[v]) {
      index[v] = static_cast<int>(result.kept.size());
      result.kept.push_back(static_cast<int>(v));
      result.reduced.vertices.push_back(mesh.vertices[v]);
    }
  for (std::size_t f = 0; f < faces.size(); ++f)
    if (face_alive[f])
      result.reduced.faces.push_back({index[u(faces[f][0])], index[u(faces[f][1])], index[u(faces[f][2])]});
  return result;
}

std::vector<Vec3> restore_sub_resolution_vertices(const MeshReduction& reduction, const std::vector<Vec3>& reduced_map,
                                                  std::size_t full_vertex_count) {
  std::vector<Vec3> full(full_vertex_count, Vec3::Zero());
  for (std::size_t i = 0; i < reduction.kept.size(); ++i) full[u(reduction.kept[i])] = reduced_map[i];
  for (auto r = reduction.removed.rbegin(); r != reduction.removed.rend(); ++r) {
    Vec3 p = Vec3::Zero();
    for (int k = 0; k < 3; ++k) p += r->weights[u(k)] * full[u(r->corners[u(k)])];
    const double norm = p.norm();
    // antipodal corners only in a map that is already broken; keep the point on the sphere
    full[u(r->vertex)] = norm > 0 ? Vec3(p / norm) : full[u(r->corners[0])];
  }
  return full;
}

}  // namespace sphparam
