#pragma once
/// \file sub_resolution.hpp
/// Vertices below the resolution of the OT stage. The OT moves every vertex to the centroid of a
/// cell of its own mass, so a face far smaller than its vertices' cells (a flat sliver, a needle,
/// an edge split at 1/1000 of its length) gets an orientation at the mercy of one cell's
/// sampling error. Such vertices are removed before the map is computed, where one valid
/// retriangulation exists, and put back afterwards at their barycentric place in the face that
/// replaced them: their faces are then sub-triangles of a positively oriented face, with the
/// mesh's area ratios.

#include <array>
#include <cstddef>
#include <vector>

#include "mesh.hpp"

namespace sphparam {

/// A removed vertex: put back at normalize(Σ weights[k] · s[corners[k]]).
struct RemovedVertex {
  int vertex = 0;                   ///< index in the full mesh
  std::array<int, 3> corners{};     ///< full-mesh indices of the face (or edge) it lies in
  std::array<double, 3> weights{};  ///< barycentric weights, sum 1 (the third is 0 on an edge)
};

struct MeshReduction {
  Mesh reduced;                        ///< the kept vertices (renumbered) and the new faces
  std::vector<int> kept;               ///< reduced index → full index
  std::vector<RemovedVertex> removed;  ///< in the order of removal
  int rounds = 0;                      ///< rounds of independent removals that removed something
};

/// Removes, in rounds of independent vertices (no two removed vertices of one round adjacent),
/// each vertex whose smallest incident face is below `area_ratio` times its largest (face areas
/// in the mesh's 3D geometry) and that has one valid retriangulation:
/// - valence 3: its three faces become the enclosing triangle (unless that face exists);
/// - valence 4: its four faces become two along the diagonal through it that is closest to a
///   straight angle at the vertex (unless that edge exists); it is put back on that diagonal.
/// The barycentric weights are the mesh's sub-face area ratios. At least 4 vertices are kept.
/// Returns an empty `removed` (and no reduced mesh) when nothing qualifies.
MeshReduction remove_sub_resolution_vertices(const Mesh& mesh, double area_ratio = 1e-2, int max_rounds = 8);

/// The map of the full mesh from a map of the reduced mesh (unit vectors, one per reduced vertex):
/// kept vertices copied, removed ones placed in the reverse order of their removal.
std::vector<Vec3> restore_sub_resolution_vertices(const MeshReduction& reduction, const std::vector<Vec3>& reduced_map,
                                                  std::size_t full_vertex_count);

}  // namespace sphparam
