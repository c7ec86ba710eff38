#pragma once
/// \file mesh.hpp
/// Triangle meshes for the spherical parameterization example: reading and writing OFF, OBJ
/// and PLY (ascii and binary little-endian, `face` lists or `tristrips`), validation of closed
/// genus-0 manifolds, and the distortion metrics of `shared/tools/eval_sphere_map.py`.

#include <Eigen/Core>
#include <array>
#include <cmath>
#include <cstddef>
#include <stdexcept>
#include <string>
#include <string_view>
#include <vector>

namespace sphparam {

using Vec3 = Eigen::Vector3d;
using Face = std::array<int, 3>;

/// An index (vertex, face, slot: non-negative where used) as a container position.
inline std::size_t u(int i) {
  return static_cast<std::size_t>(i);
}
inline std::size_t u(std::ptrdiff_t i) {
  return static_cast<std::size_t>(i);
}

struct Mesh {
  std::vector<Vec3> vertices;
  std::vector<Face> faces;
};

/// A file that cannot be read or written, or is malformed (the message names the file and line).
class FileError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

/// What the reader had to do to get triangles.
struct ReadInfo {
  std::size_t polygons = 0;           ///< faces with more than 3 vertices (fan-triangulated)
  std::size_t polygon_triangles = 0;  ///< triangles those polygons became
  std::size_t short_faces = 0;        ///< faces with fewer than 3 vertices (ignored)
  std::string format;                 ///< "off", "obj", "ply ascii", "ply binary_little_endian"
};

/// The format of a mesh file by its name: "off", "obj" or "ply" by extension (case-insensitive),
/// "freesurfer" for FreeSurfer's surface names (lh.pial, rh.white, lh.sphere, *.inflated, ...),
/// "" when the name does not say.
std::string mesh_format(const std::string& path);

/// Reads a mesh in `format` ("off", "obj", "ply", "freesurfer"), or by its name (mesh_format)
/// when `format` is empty, or by its magic bytes (FreeSurfer) when the name does not say.
/// Polygons are fan-triangulated as (v0, vk, vk+1), like the evaluator. Throws FileError.
Mesh read_mesh(const std::string& path, ReadInfo* info = nullptr, const std::string& format = "");

/// Parses the bytes of a mesh file in `format` ("off", "obj", "ply" or "freesurfer"); `name` starts every
/// error message. Accepts a UTF-8 byte order mark, CRLF line ends and comments. Rejects, with a
/// FileError naming the line, element or index: counts that the bytes cannot hold (before any
/// allocation of their size), truncation, data after the announced counts, indices out of range
/// and coordinates that are not finite.
Mesh parse_mesh(std::string_view bytes, const std::string& format, const std::string& name, ReadInfo* info = nullptr);

/// Writes `format` ("off", "obj", "ply", "freesurfer"), or the format its name says (mesh_format)
/// when `format` is empty; PLY is binary little-endian unless `ply_ascii`. Text coordinates are
/// the shortest that read back exactly; FreeSurfer stores float32. The file is replaced
/// atomically (a failure leaves a previous file intact). Throws FileError.
void write_mesh(const std::string& path, const Mesh& mesh, bool ply_ascii = false, const std::string& format = "");

/// Lower-case file extension without the dot ("" if none).
std::string extension(const std::string& path);

// ------------------------------------------------------------------------------- validation

/// One defect found in the input, with its count.
struct Defect {
  std::string name;  ///< "boundary edges", "non-manifold vertices", ...
  std::size_t count = 0;
  bool fatal = true;    ///< false: repaired or accepted (polygons, unreferenced vertices, ...)
  std::string message;  ///< full sentence, names the defect and gives the count
};

struct Validation {
  std::vector<Defect> defects;
  std::size_t vertices = 0, faces = 0, edges = 0;
  std::size_t unreferenced = 0;
  int euler_characteristic = 0;
  int components = 0;
  double signed_volume = 0;
  bool inward = false;  ///< consistently oriented but with negative signed volume
  double min_angle_deg = 0;
  double area_ratio = 0;  ///< largest over smallest face area
  [[nodiscard]] bool ok() const {
    for (const auto& d : defects)
      if (d.fatal) return false;
    return true;
  }
};

/// Checks a mesh for the defects listed in the issue. Counts every defect found.
Validation validate(const Mesh& mesh, const ReadInfo& info = {});

/// Scales `mesh` by the power of two that brings its largest finite coordinate into [0.5, 1) and
/// returns the exponent e (the mesh was multiplied by 2^-e). Exact, so a map computed on the
/// scaled mesh has the same bits as on the original, but coordinates of 1e200 no longer overflow
/// the areas (nor 1e-200 underflow them).
int scale_by_power_of_two(Mesh& mesh);

/// Removes vertices that no face references; `kept[i]` is the old index of new vertex i.
Mesh drop_unreferenced(const Mesh& mesh, std::vector<int>* kept = nullptr);

// ------------------------------------------------------------------------------- metrics

/// Distortion of a spherical map, defined exactly as in shared/tools/sphmesh.py (evaluate_map).
struct Metrics {
  double area_mean_abs = 0, area_std = 0, area_max_abs = 0;
  std::size_t area_nonfinite = 0;
  double angle_mean_abs_deg = 0, angle_p95_deg = 0;
  std::size_t flips = 0;
  double sph_area_sum_over_4pi = 0;
  std::vector<double> d;  ///< per-face log area ratio (may hold ±inf)
};

/// `orientation_sign` is +1 for an outward-oriented input, −1 for an inward one.
Metrics evaluate_map(const Mesh& mesh, const std::vector<Vec3>& sphere, double orientation_sign);

/// True where triangle_area_from_det takes its series: den > 0 and |num| < 0.01·den (no
/// short-circuit, so that loops over it vectorize).
inline bool triangle_area_series_applies(double num, double den) {
  return (den > 0) & (std::abs(num) < 0.01 * den);
}
/// 2·atan(x) by a four-term series, exact to rounding for |x| < 0.01 (next term < 1.2e-17
/// relative).
inline double twice_atan_series(double x) {
  const double x2 = x * x;
  return 2 * x * (1 - x2 * (1.0 / 3 - x2 * (1.0 / 5 - x2 / 7)));
}
/// 2·atan2(num, den): the area of a spherical triangle (a, b, c) from num = det[a, b, c] and
/// den = 1 + a·b + b·c + c·a (Van Oosterom–Strackee). For the small triangles of fine meshes
/// the series above, several times cheaper than atan2, which dominated the area optimization.
inline double triangle_area_from_det(double num, double den) {
  if (triangle_area_series_applies(num, den)) return twice_atan_series(num / den);
  return 2 * std::atan2(num, den);
}
/// Exact spherical-triangle area (unsigned), Van Oosterom–Strackee.
double spherical_triangle_area(const Vec3& a, const Vec3& b, const Vec3& c);
/// Signed version: negative when det[a, b, c] < 0.
double signed_spherical_triangle_area(const Vec3& a, const Vec3& b, const Vec3& c);

/// Face areas of a mesh.
std::vector<double> face_areas(const Mesh& mesh);

}  // namespace sphparam
