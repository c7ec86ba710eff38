// The bad-input matrix of sdot-sphere-param (docs/reliability.md): every malformed or unmappable
// mesh makes the command exit with code 2 and one line on stderr that names the file and the
// line, element or index, and writes nothing; the benign oddities (byte order mark, CRLF,
// comments, polygons, inward orientation) are accepted.
#include <gtest/gtest.h>
#include <sys/wait.h>

#include <algorithm>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <functional>
#include <map>
#include <string>

#include "mesh.hpp"
#include "support/scratch_directory.hpp"
#include "test_meshes.hpp"

namespace {

namespace fs = std::filesystem;
using namespace sphparam;

fs::path scratch() {
  return sdot::testing::scratch_directory("sdot_param_bad_input_test");
}

struct CommandRun {
  int exit_code;
  std::string err;
};

CommandRun run_command(const std::string& arguments) {
  const fs::path err = scratch() / "stderr.txt";
  const std::string command = std::string(SPHPARAM_COMMAND) + " " + arguments + " --quiet 2> " + err.string();
  const int status = std::system(command.c_str());
  return {WIFEXITED(status) ? WEXITSTATUS(status) : -1, sdot::testing::read_text(err)};
}

std::string off_text(const Mesh& mesh) {
  std::string s = "OFF\n" + std::to_string(mesh.vertices.size()) + " " + std::to_string(mesh.faces.size()) + " 0\n";
  for (const auto& v : mesh.vertices) {
    char line[96];
    std::snprintf(line, sizeof line, "%.17g %.17g %.17g\n", v.x(), v.y(), v.z());
    s += line;
  }
  for (const auto& f : mesh.faces)
    s += "3 " + std::to_string(f[0]) + " " + std::to_string(f[1]) + " " + std::to_string(f[2]) + "\n";
  return s;
}

Mesh base() {
  return test::icosphere(1);
}  // 42 vertices, 80 faces

/// The closed boundary surface of a set of unit cubes (x, y) in a one-cube-thick plate: a
/// genus-g surface for a plate with g holes.
Mesh plate(int width, int height, const std::vector<std::pair<int, int>>& holes) {
  auto present = [&](int x, int y) {
    return x >= 0 && y >= 0 && x < width && y < height &&
           std::find(holes.begin(), holes.end(), std::pair{x, y}) == holes.end();
  };
  Mesh mesh;
  std::map<std::array<int, 3>, int> index;
  auto vertex = [&](int x, int y, int z) {
    auto [it, inserted] = index.emplace(std::array{x, y, z}, static_cast<int>(mesh.vertices.size()));
    if (inserted) mesh.vertices.emplace_back(x, y, z);
    return it->second;
  };
  auto quad = [&](std::array<int, 3> a, std::array<int, 3> b, std::array<int, 3> c, std::array<int, 3> d) {
    const int i = vertex(a[0], a[1], a[2]), j = vertex(b[0], b[1], b[2]), k = vertex(c[0], c[1], c[2]),
              l = vertex(d[0], d[1], d[2]);
    mesh.faces.push_back({i, j, k});
    mesh.faces.push_back({i, k, l});
  };
  for (int x = 0; x < width; ++x)
    for (int y = 0; y < height; ++y) {
      if (!present(x, y)) continue;
      // counter-clockwise seen from outside
      quad({x, y, 0}, {x, y + 1, 0}, {x + 1, y + 1, 0}, {x + 1, y, 0});
      quad({x, y, 1}, {x + 1, y, 1}, {x + 1, y + 1, 1}, {x, y + 1, 1});
      if (!present(x - 1, y)) quad({x, y, 0}, {x, y, 1}, {x, y + 1, 1}, {x, y + 1, 0});
      if (!present(x + 1, y)) quad({x + 1, y, 0}, {x + 1, y + 1, 0}, {x + 1, y + 1, 1}, {x + 1, y, 1});
      if (!present(x, y - 1)) quad({x, y, 0}, {x + 1, y, 0}, {x + 1, y, 1}, {x, y, 1});
      if (!present(x, y + 1)) quad({x, y + 1, 0}, {x, y + 1, 1}, {x + 1, y + 1, 1}, {x + 1, y + 1, 0});
    }
  return mesh;
}

std::string binary_ply_header(const std::string& vertex_count, const std::string& face_count,
                              const std::string& list = "uchar int") {
  return "ply\nformat binary_little_endian 1.0\nelement vertex " + vertex_count +
         "\nproperty float x\nproperty float y\nproperty float z\nelement face " + face_count + "\nproperty list " +
         list + " vertex_indices\nend_header\n";
}

template <class T>
void append_binary(std::string& s, T value) {
  s.append(reinterpret_cast<const char*>(&value), sizeof value);
}

std::string binary_ply(const Mesh& mesh) {
  std::string s = binary_ply_header(std::to_string(mesh.vertices.size()), std::to_string(mesh.faces.size()));
  for (const auto& v : mesh.vertices)
    for (int c = 0; c < 3; ++c) append_binary(s, static_cast<float>(v[c]));
  for (const auto& f : mesh.faces) {
    append_binary(s, std::uint8_t{3});
    for (int i : f) append_binary(s, std::int32_t{i});
  }
  return s;
}

struct Case {
  const char* name;
  const char* file;  ///< the input's name (its extension chooses the reader)
  std::function<std::string()> content;
  const char* expected;  ///< in the one-line message
};

std::ostream& operator<<(std::ostream& out, const Case& c) {
  return out << c.name;
}

class BadMesh : public ::testing::TestWithParam<Case> {};

TEST_P(BadMesh, ExitsWithCode2AndOneLineNamingTheProblem) {
  const Case& c = GetParam();
  const fs::path input = scratch() / (std::string(c.name) + "_" + c.file);
  const fs::path output = scratch() / (std::string(c.name) + "_out.off");
  std::ofstream(input, std::ios::binary) << c.content();
  const CommandRun r = run_command(input.string() + " -o " + output.string());
  EXPECT_EQ(r.exit_code, 2) << r.err;
  EXPECT_NE(r.err.find(c.expected), std::string::npos) << r.err;
  EXPECT_NE(r.err.find(input.filename().string()), std::string::npos) << "names the file: " << r.err;
  EXPECT_EQ(std::count(r.err.begin(), r.err.end(), '\n'), 1) << r.err;
  EXPECT_FALSE(fs::exists(output));
}

Mesh with(std::function<void(Mesh&)> change) {
  Mesh m = base();
  change(m);
  return m;
}

INSTANTIATE_TEST_SUITE_P(
    Matrix, BadMesh,
    ::testing::Values(
        Case{"empty", "m.off", [] { return std::string(); }, "empty file"},
        Case{"empty_ply", "m.ply", [] { return std::string(); }, "empty file"},
        Case{"truncated_header", "m.off", [] { return std::string("OFF\n42"); },
             "unexpected end of file while reading the face count"},
        Case{"truncated_vertices", "m.off",
             [] {
               const std::string s = off_text(base());
               return s.substr(0, s.find("\n", s.size() / 4));
             },
             "unexpected end of file while reading vertex"},
        Case{"truncated_faces", "m.off",
             [] {
               const std::string s = off_text(base());
               return s.substr(0, s.size() - 40);
             },
             "of 80 announces 3 vertex indices, more than the rest of the file holds (truncated?)"},
        Case{"truncated_binary_ply", "m.ply",
             [] {
               const std::string s = binary_ply(base());
               return s.substr(0, s.size() - 100);
             },
             "of 80 has a list of 3 values, more than the rest of the file holds (truncated?)"},
        Case{"truncated_freesurfer", "lh.pial",
             [] {
               std::string s =
                   "\xFF\xFF\xFE"
                   "created by test\n\n";
               s += std::string("\0\0\0\x2A\0\0\0\x50", 8);  // 42 vertices, 80 faces, and nothing more
               return s;
             },
             "truncated"},
        Case{"more_faces_than_counted", "m.off",
             [] {
               std::string s = off_text(base());
               s.replace(s.find(" 80 0"), 5, " 79 0");
               return s;
             },
             "more data after the 79 faces"},
        Case{"fewer_vertices_than_counted", "m.off",
             [] {
               std::string s = off_text(base());
               s.replace(0, 7, "OFF\n50 ");
               return s;
             },
             "unexpected end of file while reading face 74 of 80"},
        Case{"huge_vertex_count", "m.off", [] { return std::string("OFF\n1000000000000 1 0\n0 0 0\n"); },
             "more than the file's"},
        Case{"huge_ply_element", "m.ply",
             [] { return binary_ply_header("1000000000000", "1") + std::string(64, '\0'); }, "more than the file's"},
        Case{"huge_ply_list", "m.ply",
             [] {
               std::string s = binary_ply_header("3", "1", "uint int");
               for (int k = 0; k < 9; ++k) append_binary(s, 0.5f * static_cast<float>(k % 3));
               append_binary(s, std::uint32_t{2147483648u});  // a list count of 2^31
               return s + std::string(12, '\0');
             },
             "has a list of 2147483648 values"},
        Case{"index_out_of_range", "m.off", [] { return off_text(with([](Mesh& m) { m.faces[3][1] = 42; })); },
             "face 3 has vertex index 42 but there are 42 vertices"},
        Case{"negative_index", "m.off", [] { return off_text(with([](Mesh& m) { m.faces[2][0] = -1; })); },
             "face 2 has vertex index -1"},
        Case{"negative_index_ply", "m.ply", [] { return binary_ply(with([](Mesh& m) { m.faces[5][2] = -7; })); },
             "face 5 has vertex index -7"},
        Case{"obj_index_zero", "m.obj", [] { return std::string("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 0\n"); },
             ":4: bad vertex index '0' in face 0"},
        Case{"nan_coordinate", "m.off",
             [] {
               std::string s = off_text(base());
               const auto line = s.find('\n', s.find('\n', 4) + 1) + 1;  // vertex 1
               return s.replace(line, s.find(' ', line) - line, "nan");
             },
             ":4: vertex 1 has a coordinate that is not a finite number ('nan')"},
        Case{"nan_coordinate_obj", "m.obj", [] { return std::string("v 0 0 0\nv 1 nan 0\nv 0 1 0\nf 1 2 3\n"); },
             ":2: vertex 1 has a coordinate that is not a finite number"},
        Case{"inf_coordinate", "m.off", [] { return off_text(with([](Mesh& m) { m.vertices[7].y() = INFINITY; })); },
             "vertex 7 has a coordinate that is not a finite number"},
        Case{"duplicate_faces", "m.off", [] { return off_text(with([](Mesh& m) { m.faces.push_back(m.faces[0]); })); },
             "(first: face 80 = face 0)"},
        Case{"degenerate_face", "m.off", [] { return off_text(with([](Mesh& m) { m.faces[4][2] = m.faces[4][0]; })); },
             "first: face 4"},
        Case{"split_by_duplicate_vertices", "m.off",  // a vertex repeated and used by some of its faces
             [] {
               return off_text(with([](Mesh& m) {
                 m.vertices.push_back(m.vertices[0]);
                 for (auto& f : m.faces)
                   if (f[0] == 0 && f[1] < 20) f[0] = 42;
               }));
             },
             "boundary edges"},
        Case{"non_manifold_edge", "m.off",
             [] {
               return off_text(with([](Mesh& m) {
                 m.vertices.emplace_back(3, 3, 3);
                 const Face f = m.faces[0];
                 m.faces.push_back({f[1], f[0], 42});
                 m.faces.push_back({f[0], f[1], 42});
               }));
             },
             "non-manifold edge"},
        Case{"open", "m.off", [] { return off_text(with([](Mesh& m) { m.faces.pop_back(); })); },
             "3 boundary edges (the surface is not closed: fill its holes; first: edge"},
        Case{"two_components", "m.off",
             [] {
               return off_text(with([](Mesh& m) {
                 const Mesh other = base();
                 const int offset = static_cast<int>(m.vertices.size());
                 for (const auto& v : other.vertices) m.vertices.push_back(v + Vec3(3, 0, 0));
                 for (const auto& f : other.faces) m.faces.push_back({f[0] + offset, f[1] + offset, f[2] + offset});
               }));
             },
             "2 connected components"},
        Case{"genus_1", "m.off",
             [] {
               return off_text(plate(3, 3, {{1, 1}}));
             },
             "genus 1"},
        Case{"genus_2", "m.off",
             [] {
               return off_text(plate(3, 5, {{1, 1}, {1, 3}}));
             },
             "genus 2"},
        Case{"unknown_format", "m.stl", [] { return off_text(base()); }, "unknown mesh format '.stl'"},
        Case{"not_off", "m.off", [] { return std::string("solid x\nfacet normal 0 0 1\n"); }, "not an OFF file"}),
    [](const ::testing::TestParamInfo<Case>& param_info) { return std::string(param_info.param.name); });

/// Input that reads the same as the plain OFF file: the command maps it (exit 0).
class AcceptedMesh : public ::testing::TestWithParam<Case> {};

TEST_P(AcceptedMesh, IsReadLikeThePlainFileAndMapped) {
  const Case& c = GetParam();
  const fs::path input = scratch() / (std::string(c.name) + "_" + c.file);
  const fs::path output = scratch() / (std::string(c.name) + "_out.off");
  std::ofstream(input, std::ios::binary) << c.content();
  const Mesh read = read_mesh(input.string());
  const Mesh plain = base();
  ASSERT_EQ(read.vertices.size(), plain.vertices.size());
  for (std::size_t v = 0; v < read.vertices.size(); ++v) EXPECT_EQ(read.vertices[v], plain.vertices[v]) << v;
  EXPECT_EQ(read.faces, plain.faces);
  const CommandRun r = run_command(input.string() + " -o " + output.string());
  EXPECT_EQ(r.exit_code, 0) << r.err;
  EXPECT_TRUE(fs::exists(output));
}

std::string with_crlf(const std::string& s) {
  std::string out;
  for (char ch : s) out += ch == '\n' ? std::string("\r\n") : std::string(1, ch);
  return out;
}

INSTANTIATE_TEST_SUITE_P(
    Matrix, AcceptedMesh,
    ::testing::Values(Case{"byte_order_mark", "m.off", [] { return "\xEF\xBB\xBF" + off_text(base()); }, ""},
                      Case{"byte_order_mark_obj", "m.obj",
                           [] {
                             std::string s = "\xEF\xBB\xBF";
                             for (const auto& v : base().vertices) {
                               char line[96];
                               std::snprintf(line, sizeof line, "v %.17g %.17g %.17g\n", v.x(), v.y(), v.z());
                               s += line;
                             }
                             for (const auto& f : base().faces)
                               s += "f " + std::to_string(f[0] + 1) + "/1/1 " + std::to_string(f[1] + 1) + "//2 " +
                                    std::to_string(f[2] + 1) + "\n";
                             return s;
                           },
                           ""},
                      Case{"crlf", "m.off", [] { return with_crlf(off_text(base())); }, ""},
                      Case{"comments_everywhere", "m.off",
                           [] {
                             std::string s = "# a comment first\n" + off_text(base());
                             std::string out;
                             for (char ch : s)
                               out +=
                                   ch == '\n' ? std::string(" # trailing comment\n# own line\n") : std::string(1, ch);
                             return out;
                           },
                           ""},
                      Case{"crlf_ascii_ply", "m.ply",
                           [] {
                             const Mesh m = base();
                             std::string s =
                                 "ply\nformat ascii 1.0\ncomment x\nelement vertex " +
                                 std::to_string(m.vertices.size()) +
                                 "\nproperty double x\nproperty double y\nproperty double z\nelement face " +
                                 std::to_string(m.faces.size()) +
                                 "\nproperty list uchar int vertex_indices\nend_header\n";
                             for (const auto& v : m.vertices) {
                               char line[96];
                               std::snprintf(line, sizeof line, "%.17g %.17g %.17g\n", v.x(), v.y(), v.z());
                               s += line;
                             }
                             for (const auto& f : m.faces)
                               s += "3 " + std::to_string(f[0]) + " " + std::to_string(f[1]) + " " +
                                    std::to_string(f[2]) + "\n";
                             return with_crlf(s);
                           },
                           ""},
                      Case{"face_colours", "m.off",
                           [] {
                             std::string s = off_text(base()), out;
                             std::size_t line_start = 0, line = 0;
                             while (line_start < s.size()) {
                               const std::size_t end = s.find('\n', line_start);
                               out += s.substr(line_start, end - line_start);
                               if (line++ >= 2 + 42) out += " 255 0 0";  // a colour after each face
                               out += "\n";
                               line_start = end + 1;
                             }
                             return out;
                           },
                           ""}),
    [](const ::testing::TestParamInfo<Case>& param_info) { return std::string(param_info.param.name); });

TEST(AcceptedMesh, InwardOrientationIsMappedKeepingIt) {
  Mesh m = base();
  for (auto& f : m.faces) std::swap(f[1], f[2]);
  const fs::path input = scratch() / "inward.off", output = scratch() / "inward_out.off";
  std::ofstream(input) << off_text(m);
  const CommandRun r = run_command(input.string() + " -o " + output.string());
  EXPECT_EQ(r.exit_code, 0) << r.err;
  EXPECT_EQ(read_mesh(output.string()).faces, m.faces);
}

// Found by the OFF fuzz harness: coordinates of 1e200 overflowed the areas, and the command
// wrote NaN vertices with exit code 0. The map does not depend on the scale.
TEST(AcceptedMesh, HugeAndTinyCoordinatesMapLikeUnitOnes) {
  const fs::path unit_output = scratch() / "unit_out.off";
  std::ofstream(scratch() / "unit.off") << off_text(base());
  ASSERT_EQ(run_command((scratch() / "unit.off").string() + " -o " + unit_output.string()).exit_code, 0);
  const Mesh unit_map = read_mesh(unit_output.string());
  for (const double scale : {0x1p600, 0x1p-600}) {  // powers of two: the same input bits scaled
    Mesh m = base();
    for (auto& v : m.vertices) v *= scale;
    const fs::path input = scratch() / "scaled.off", output = scratch() / "scaled_out.off";
    std::ofstream(input) << off_text(m);
    const CommandRun r = run_command(input.string() + " -o " + output.string());
    ASSERT_EQ(r.exit_code, 0) << scale << ": " << r.err;
    const Mesh map = read_mesh(output.string());
    ASSERT_EQ(map.vertices.size(), unit_map.vertices.size());
    for (std::size_t i = 0; i < map.vertices.size(); ++i) EXPECT_EQ(map.vertices[i], unit_map.vertices[i]) << i;
  }
  // The fuzzer's input: a tetrahedron with one corner at the origin and three at 1e200.
  const fs::path tetra = scratch() / "tetra.off", tetra_output = scratch() / "tetra_out.off";
  std::ofstream(tetra) << "OFF\n4 4 0\n0 0 0\n1e200 0 0\n0 1e200 0\n0 0 1e200\n"
                          "3 0 2 1\n3 0 1 3\n3 0 3 2\n3 1 2 3\n";
  const CommandRun r = run_command(tetra.string() + " -o " + tetra_output.string());
  ASSERT_EQ(r.exit_code, 0) << r.err;
  for (const auto& v : read_mesh(tetra_output.string()).vertices) EXPECT_NEAR(v.norm(), 1.0, 1e-12);
}

TEST(BadOptions, ExitWithCode2NamingTheOption) {
  const fs::path input = scratch() / "options.off";
  std::ofstream(input) << off_text(base());
  for (const auto& [arguments, expected] : std::vector<std::pair<std::string, std::string>>{
           {"--ot-tolerance 0", "--ot-tolerance: expected a positive number, got '0'"},
           {"--ot-tolerance -1", "--ot-tolerance: expected a positive number"},
           {"--ot-tolerance abc", "--ot-tolerance: expected a positive number, got 'abc'"},
           {"--ot-tolerance nan", "--ot-tolerance"},
           {"--sweeps x", "--sweeps: expected an integer"},
           {"--angle-weight -0.5", "--angle-weight: expected a non-negative number, got '-0.5'"},
           {"--angle-weight nan", "--angle-weight: expected a non-negative number, got 'nan'"},
           {"--angle-weight inf", "--angle-weight: expected a non-negative number, got 'inf'"},
           {"--angle-weight 1e999", "--angle-weight: expected a non-negative number, got '1e999'"},
           {"--angle-weight abc", "--angle-weight: expected a non-negative number, got 'abc'"},
           {"--radius 0", "--radius: expected a positive number"},
           {"--format stl", "--format: expected off, obj, ply or freesurfer, got 'stl'"}}) {
    const fs::path output = scratch() / "options_out.off";
    const CommandRun r = run_command(input.string() + " -o " + output.string() + " " + arguments);
    EXPECT_EQ(r.exit_code, 2) << arguments << ": " << r.err;
    EXPECT_NE(r.err.find(expected), std::string::npos) << r.err;
    EXPECT_EQ(std::count(r.err.begin(), r.err.end(), '\n'), 1) << r.err;
    EXPECT_FALSE(fs::exists(output));
  }
  const CommandRun device = run_command("/dev/zero --input-format off -o " + (scratch() / "o.off").string());
  EXPECT_EQ(device.exit_code, 2);
  EXPECT_NE(device.err.find("/dev/zero: is not a regular file"), std::string::npos) << device.err;
  const CommandRun missing =
      run_command((scratch() / "nowhere.off").string() + " -o " + (scratch() / "o.off").string());
  EXPECT_EQ(missing.exit_code, 2);
  EXPECT_NE(missing.err.find("nowhere.off: cannot open"), std::string::npos) << missing.err;
  const CommandRun unknown_output = run_command(input.string() + " -o " + (scratch() / "o.stl").string());
  EXPECT_EQ(unknown_output.exit_code, 2);
  EXPECT_NE(unknown_output.err.find("unknown mesh format '.stl'"), std::string::npos) << unknown_output.err;
}

}  // namespace
