// The sdot command end to end: problem files in, results and pictures out, clear errors.
#include <gtest/gtest.h>

#include <sys/wait.h>
#include <algorithm>
#include <array>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <sstream>
#include <string>
#include <vector>

#include "common.hpp"  // src/cli, through sdot_cli
#include "support/scratch_directory.hpp"

namespace {

namespace fs = std::filesystem;
using nlohmann::json;

struct Run {
  int exit_code;
  std::string out, err;
};

fs::path scratch() {
  return sdot::testing::scratch_directory("sdot_cli_test");
}

std::string slurp(const fs::path& path) {
  return sdot::testing::read_text(path);
}

/// The command with `arguments`, after `prefix` (e.g. "env VAR=value"; may be empty).
Run run_in(const std::string& prefix, const std::string& arguments) {
  const fs::path dir = scratch();
  const std::string command = prefix + " " + std::string(SDOT_COMMAND) + " " + arguments + " > " +
                              (dir / "stdout").string() + " 2> " + (dir / "stderr").string();
  const int status = std::system(command.c_str());
  return {WIFEXITED(status) ? WEXITSTATUS(status) : -1, slurp(dir / "stdout"), slurp(dir / "stderr")};
}

Run run(const std::string& arguments) {
  return run_in("", arguments);
}

std::string fmt_pair(double x, double y) {
  char buffer[64];
  std::snprintf(buffer, sizeof buffer, "[%.6f,%.6f]", x, y);
  return buffer;
}

fs::path write(const std::string& name, const std::string& content) {
  const fs::path path = scratch() / name;
  std::ofstream(path) << content;
  return path;
}

TEST(Cli, SolvesAPlaneProblemAndWritesResultAndSvg) {
  const auto problem = write("p.json", R"({"geometry": "plane", "sites": [[0.2,0.2],[0.8,0.3],[0.5,0.8],[0.3,0.6]],
    "masses": [1, 2, 3, 4], "tolerance": 1e-12})");
  const auto result_path = scratch() / "r.json", svg_path = scratch() / "d.svg";
  const auto r = run("solve " + problem.string() + " -o " + result_path.string() + " --svg " + svg_path.string());
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const json result = json::parse(slurp(result_path));
  EXPECT_EQ(result["status"], "converged");
  EXPECT_LE(result["max_relative_mass_error"].get<double>(), 1e-12);
  EXPECT_NEAR(result["mass_scale"].get<double>(), 0.1, 1e-15);
  const auto masses = result["masses"].get<std::vector<double>>();
  ASSERT_EQ(masses.size(), 4u);
  for (int i = 0; i < 4; ++i) EXPECT_NEAR(masses[i], 0.1 * (i + 1), 1e-12);
  double weight_sum = 0;
  for (double w : result["weights"].get<std::vector<double>>()) weight_sum += w;
  EXPECT_NEAR(weight_sum, 0, 1e-14);
  EXPECT_EQ(result["centroids"].size(), 4u);
  for (const char* key : {"iterations", "transport_cost", "timings", "history", "adjacency"})
    EXPECT_TRUE(result.contains(key)) << key;
  const std::string svg = slurp(svg_path);
  EXPECT_EQ(svg.rfind("<svg", 0), 0u);
  EXPECT_GE(static_cast<int>(std::count(svg.begin(), svg.end(), '\n')), 4 + 4 + 4);  // cells, sites, centroids
  EXPECT_NE(r.err.find("iteration"), std::string::npos) << "progress goes to stderr";
}

TEST(Cli, QuietSuppressesProgressAndResultGoesToStdout) {
  const auto problem = write("q.json", R"({"geometry": "plane", "sites": [[0.2,0.2],[0.8,0.3]]})");
  const auto r = run("solve " + problem.string() + " --quiet");
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_TRUE(r.err.empty()) << r.err;
  EXPECT_EQ(json::parse(r.out)["status"], "converged");
}

TEST(Cli, CustomDomainAndInitialWeights) {
  const auto problem = write("d.json", R"({"geometry": "plane", "sites": [[1,1],[3,1]],
    "domain": [[0,0],[4,0],[4,2],[0,2]], "weights": [0.1, -0.1], "density": {"type": "uniform"}})");
  const auto r = run("solve " + problem.string() + " --quiet");
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const json result = json::parse(r.out);
  EXPECT_NEAR(result["source_mass"].get<double>(), 8, 1e-14);
  EXPECT_NEAR(result["masses"][0].get<double>(), 4, 1e-9);
}

TEST(Cli, NonConvergenceIsExitCode3WithAResult) {
  const auto problem = write("n.json", R"({"geometry": "plane", "sites": [[0.1,0.1],[0.9,0.1],[0.5,0.9]],
    "masses": [1, 50, 100], "max_iterations": 0})");
  const auto r = run("solve " + problem.string() + " --quiet");
  EXPECT_EQ(r.exit_code, 3);
  EXPECT_EQ(json::parse(r.out)["status"], "iteration_limit");
}

struct BadInput {
  const char* name;
  const char* problem;
  const char* expected;  // in the one-line message
};

class CliBadInput : public ::testing::TestWithParam<BadInput> {};

TEST_P(CliBadInput, ExitsWithCode2AndAOneLineReason) {
  const auto& c = GetParam();
  write("tiny.pgm", "P2\n3 2\n255\n0 1 2 3 4 5\n");  // for cases that need a readable image
  write("black.pgm", "P2\n2 2\n255\n0 0 0 0\n");
  const auto path = write(std::string(c.name) + ".json", c.problem);
  const auto r = run("solve " + path.string() + " --quiet");
  EXPECT_EQ(r.exit_code, 2) << r.err;
  EXPECT_NE(r.err.find(c.expected), std::string::npos) << r.err;
  EXPECT_EQ(std::count(r.err.begin(), r.err.end(), '\n'), 1) << r.err;
  EXPECT_TRUE(r.out.empty());
}

INSTANTIATE_TEST_SUITE_P(
    Cases, CliBadInput,
    ::testing::Values(
        BadInput{"malformed", R"({"geometry": "plane", "sites": [[0,0],)", "malformed JSON"},
        BadInput{"empty_file", "", "empty_file.json: empty file"},
        BadInput{"device_as_density_file",
                 R"({"geometry": "plane", "sites": [[0.1,0.1]], "density": {"type": "image", "file": "/dev/zero"}})",
                 "/dev/zero: is not a regular file"},
        BadInput{"device_as_mesh_density_file",
                 R"({"geometry": "plane", "sites": [[0.1,0.1]], "density": {"type": "mesh", "file": "/dev/zero"}})",
                 "/dev/zero: is not a regular file"},
        BadInput{"folder_as_density_file",
                 R"({"geometry": "plane", "sites": [[0.1,0.1]], "density": {"type": "image", "file": "/tmp"}})",
                 "/tmp: is a folder, not a file"},
        BadInput{"blank_file", " \r\n\t\n", "blank_file.json: empty file"},
        BadInput{"truncated", R"({"geometry": "sphere", "sites": [[0,0,1],[0,1)", "truncated.json: malformed JSON"},
        BadInput{"infinite_coordinate", R"({"geometry": "plane", "sites": [[1e999, 0.5], [0.2, 0.2]]})",
                 "infinite_coordinate.json: malformed JSON: a number out of the range of doubles"},
        BadInput{"nan_mass", R"({"geometry": "plane", "sites": [[0.1,0.1],[0.5,0.5]], "masses": ["NaN", 1]})",
                 "masses[0]: must be a number"},
        BadInput{"zero_tolerance", R"({"geometry": "plane", "sites": [[0.1,0.1]], "tolerance": 0})",
                 "tolerance: must be a positive number"},
        BadInput{"zero_mass_image", R"({"geometry": "plane", "sites": [[0.1,0.1],[0.5,0.5]],
                     "density": {"type": "image", "file": "black.pgm"}})",
                 "density: has no mass on the source domain"},
        BadInput{"sphere_great_circle", R"({"geometry": "sphere", "sites": [[1,0,0],[0,1,0],[-1,0,0],[0,-1,0]]})",
                 "sites: all sites lie in a closed hemisphere"},
        BadInput{"sphere_coincident_after_normalisation",
                 R"({"geometry": "sphere", "sites": [[1,0,0],[2,0,0],[0,0,1],[0,0,-1],[-1,0,0]]})",
                 "sites[1]: duplicate of sites[0] (after normalisation)"},
        BadInput{"unknown_geometry", R"({"geometry": "cube", "sites": [[0,0]]})", "geometry: unknown geometry 'cube'"},
        // A fuzzer's find: |site|² overflowed into the default weights, and the regular
        // triangulation's exact predicates aborted on the infinity.
        BadInput{"plane_far_site", R"({"geometry": "plane", "sites": [[0.2,0.3],[0.5,0.8],[0.3,1e308]]})",
                 "sites[2]: is more than 1e100 domain radii from the domain's centre"},
        BadInput{"torus_far_site",
                 R"({"geometry": "torus", "periodic": [true, false], "sites": [[0.2,0.3],[0.5,-1e200]]})",
                 "sites[1]: is more than 1e100 box radii from the box along the axis that does not wrap"},
        BadInput{"torus_overflowing_weights",
                 R"({"geometry": "torus", "sites": [[0.2,0.3],[0.7,0.2],[0.5,0.8]], "weights": [1e308,-1e308,0]})",
                 "weights: the initial weights, from -1e+308 to 1e+308 after centring, give no diagram"},
        BadInput{"sphere_dominating_weight",
                 R"({"geometry": "sphere", "sites": [[1,0,0],[0,1,0],[0,0,1],[-1,0,0],[0,-1,0],[0.6,0,-0.8]],
                     "weights": [800,0,0,0,0,0]})",
                 "weights: the initial weights, from -133 to 667 after centring, give no diagram"},
        BadInput{"sphere_long_site",
                 R"({"geometry": "sphere", "sites": [[1e300,0,0],[0,1,0],[0,0,1],[-1,0,0],[0,-1,0],[0.6,0,-0.8]]})",
                 "sites[0]: has a length outside [1e-150, 1e150]"},
        BadInput{"hyperbolic_far_site", R"({"geometry": "hyperbolic", "sites_model": "hyperboloid",
                     "domain": {"model": "klein", "vertices": [[-0.5,-0.5],[0.5,-0.5],[0.5,0.5],[-0.5,0.5]]},
                     "sites": [[0,0,1],[1e153,0,1e153],[0,1,1.4142135623730951]]})",
                 "sites[1]: is too far from the origin (x3 > 1e100)"},
        BadInput{"missing_geometry", R"({"sites": [[0,0]]})", "geometry: missing"},
        BadInput{"torus_periodic", R"({"geometry": "torus", "sites": [[0.1,0.1],[0.5,0.5]], "periodic": [true]})",
                 "periodic: must be true, false or two booleans [x, y]"},
        BadInput{"torus_domain",
                 R"({"geometry": "torus", "sites": [[0.1,0.1],[0.5,0.5]], "domain": [[0,0],[1,0],[0,1]]})",
                 "domain: a periodic problem needs a rectangular box"},
        BadInput{"torus_duplicate", R"({"geometry": "torus", "sites": [[0.1,0.1],[0.5,0.5],[1.1,-0.9]]})",
                 "sites[2]: duplicate of sites[0] modulo the period"},
        BadInput{"nan_site", R"({"geometry": "plane", "sites": [[0.1,0.1],[0.5,"x"]]})",
                 "sites[1]: coordinate 1 is not a number"},
        BadInput{"short_site", R"({"geometry": "plane", "sites": [[0.1,0.1],[0.5]]})",
                 "sites[1]: must be an array of 2 numbers"},
        BadInput{"duplicate", R"({"geometry": "plane", "sites": [[0.1,0.1],[0.5,0.5],[0.1,0.1]]})",
                 "sites[2]: duplicate of sites[0]"},
        BadInput{"zero_mass", R"({"geometry": "plane", "sites": [[0.1,0.1],[0.5,0.5]], "masses": [1, 0]})",
                 "masses[1]: must be positive"},
        BadInput{"negative_mass", R"({"geometry": "plane", "sites": [[0.1,0.1],[0.5,0.5]], "masses": [-1, 1]})",
                 "masses[0]: must be positive"},
        BadInput{"mass_count", R"({"geometry": "plane", "sites": [[0.1,0.1],[0.5,0.5]], "masses": [1]})",
                 "masses: there are 1 masses for 2 sites"},
        BadInput{"degenerate_domain", R"({"geometry": "plane", "sites": [[0.1,0.1]], "domain": [[0,0],[1,1],[2,2]]})",
                 "domain: polygon is degenerate"},
        BadInput{"nonconvex_domain",
                 R"({"geometry": "plane", "sites": [[0.1,0.1]], "domain": [[0,0],[2,0],[1,0.3],[1,2]]})",
                 "domain[2]: polygon is not convex"},
        BadInput{"bad_tolerance", R"({"geometry": "plane", "sites": [[0.1,0.1]], "tolerance": -1})",
                 "tolerance: must be a positive number"},
        BadInput{"unknown_field", R"({"geometry": "plane", "sites": [[0.1,0.1]], "tolerence": 1e-9})",
                 "tolerence: unknown field"},
        BadInput{"unknown_density", R"({"geometry": "plane", "sites": [[0.1,0.1]], "density": {"type": "blob"}})",
                 "density.type: must be one of \"uniform\", \"mesh\", \"image\", got \"blob\""},
        BadInput{"image_without_file", R"({"geometry": "plane", "sites": [[0.1,0.1]], "density": {"type": "image"}})",
                 "density.file: an image density needs a file name"},
        BadInput{"image_missing_file",
                 R"({"geometry": "plane", "sites": [[0.1,0.1]], "density": {"type": "image", "file": "nowhere.png"}})",
                 "nowhere.png"},
        BadInput{"mesh_index", R"({"geometry": "plane", "sites": [[0.1,0.1],[0.6,0.6]], "density": {"type": "mesh",
                     "vertices": [[0,0],[1,0],[1,1],[0,1]], "triangles": [[0,1,2],[0,2,4]], "values": [1,1,1,1]}})",
                 "density.triangles[1]: vertex index 4 is out of range"},
        BadInput{"mesh_negative_value",
                 R"({"geometry": "plane", "sites": [[0.1,0.1],[0.6,0.6]], "density": {"type": "mesh",
                     "vertices": [[0,0],[1,0],[1,1],[0,1]], "triangles": [[0,1,2],[0,2,3]], "values": [1,1,-2,1]}})",
                 "density.values[2]: must be a finite number >= 0"},
        BadInput{"mesh_zero_mass", R"({"geometry": "plane", "sites": [[0.1,0.1],[0.6,0.6]], "density": {"type": "mesh",
                     "vertices": [[0,0],[1,0],[1,1],[0,1]], "triangles": [[0,1,2],[0,2,3]], "values": [0,0,0,0]}})",
                 "density: has no mass on the source domain"},
        BadInput{"mesh_outside_domain",
                 R"({"geometry": "plane", "sites": [[0.1,0.1],[0.6,0.6]], "density": {"type": "mesh",
                     "vertices": [[5,5],[6,5],[6,6]], "triangles": [[0,1,2]], "values": [1,1,1]}})",
                 "density: has no mass on the source domain"},
        BadInput{"mesh_two_value_kinds", R"({"geometry": "plane", "sites": [[0.1,0.1]], "density": {"type": "mesh",
                     "vertices": [[0,0],[1,0],[1,1]], "triangles": [[0,1,2]], "values": [1,1,1], "triangle_values": [1]}})",
                 "give exactly one of \"values\" (per vertex) and \"triangle_values\""},
        BadInput{"mesh_bad_vertex", R"({"geometry": "sphere", "sites": [[0,0,1],[0,1,-1],[1,0,-1],[-1,-1,-1]],
                     "density": {"type": "mesh", "vertices": [[0,0,1],[0,0,0],[1,0,0]], "triangles": [[0,1,2]], "values": [1,1,1]}})",
                 "density.vertices[1]: is the zero vector"},
        BadInput{"hyperbolic_image",
                 R"({"geometry": "hyperbolic", "domain": {"model": "klein", "vertices": [[0,0],[0.5,0],[0.2,0.5]]},
                     "sites": [[0.1,0.1]], "density": {"type": "image", "file": "x.pgm"}})",
                 "x.pgm"},
        BadInput{"sphere_cap_mesh",
                 R"({"geometry": "sphere", "domain": {"type": "cap", "center": [0,0,1], "angle": 0.5},
                     "sites": [[0,0.1,1],[0.1,0,1],[-0.1,-0.1,1]],
                     "density": {"type": "mesh", "vertices": [[0,0,1],[1,0,0],[0,1,0],[-1,0,0],[0,-1,0]],
                                 "triangles": [[0,1,2],[0,2,3],[0,3,4],[0,4,1]], "values": [1,1,1,1,1]}})",
                 "cap domain is not supported"},
        BadInput{"sphere_unreachable_site",
                 R"({"geometry": "sphere", "sites": [[1,0,0.1],[1,0.1,-0.1],[1,-0.1,-0.1],[-1,0,0]],
                     "density": {"type": "mesh", "vertices": [[1,0,0],[1,1,0],[1,0,1],[1,-1,0],[1,0,-1]],
                                 "triangles": [[0,1,2],[0,2,3],[0,3,4],[0,4,1]], "values": [1,1,1,1,1]}})",
                 "sites[3]: the cell of this site cannot receive mass"},
        BadInput{"hole_outside", R"({"geometry": "plane", "sites": [[0.1,0.1]],
                     "domain": {"outer": [[0,0],[1,0],[1,1],[0,1]], "holes": [[[2,2],[3,2],[3,3]]]}})",
                 "domain.holes[0]"},
        BadInput{"self_intersecting_domain", R"({"geometry": "plane", "sites": [[0.1,0.1]],
                     "domain": {"outer": [[0,0],[1,1],[1,0],[0,1]]}})",
                 "domain.outer"},
        BadInput{"bad_interpolation", R"({"geometry": "plane", "sites": [[0.1,0.1]],
                     "density": {"type": "image", "file": "tiny.pgm", "interpolation": "cubic"}})",
                 "density.interpolation: must be one of"},
        BadInput{"empty_sites", R"({"geometry": "plane", "sites": []})", "sites: at least one site is needed"},
        BadInput{"not_object", R"([1, 2, 3])", "the problem must be a JSON object"},
        BadInput{"hyperbolic_without_domain", R"({"geometry": "hyperbolic", "sites": [[0.1,0.1],[0.2,0.3]]})",
                 "domain: missing"},
        BadInput{"hyperbolic_ideal_point",
                 R"({"geometry": "hyperbolic", "domain": {"model": "klein", "vertices": [[0,0],[0.5,0],[0.2,1.2]]},
                     "sites": [[0.1,0.1]]})",
                 "domain[2]: Klein point lies on or outside the ideal boundary"},
        BadInput{"sphere_hemisphere", R"({"geometry": "sphere", "sites": [[0,0,1],[0,1,1],[1,0,1],[1,1,1]]})",
                 "sites: all sites lie in a closed hemisphere"},
        BadInput{"sphere_zero_site", R"({"geometry": "sphere", "sites": [[0,0,1],[0,0,0],[1,0,-1],[-1,0,-1]]})",
                 "sites[1]"}),
    [](const ::testing::TestParamInfo<BadInput>& param_info) { return std::string(param_info.param.name); });

// Benign forms of a problem file are read as the plain one: a UTF-8 byte order mark, CRLF line
// ends, comments, and a domain given clockwise.
TEST(Cli, ByteOrderMarkCrlfCommentsAndClockwiseDomainsAreAccepted) {
  const std::string plain = R"({"geometry": "plane", "sites": [[0.2,0.2],[0.8,0.3],[0.5,0.8]],
    "domain": [[0,0],[1,0],[1,1],[0,1]], "tolerance": 1e-12})";
  std::string crlf;
  for (char c : plain) crlf += c == '\n' ? std::string("\r\n") : std::string(1, c);
  const std::vector<std::pair<std::string, std::string>> variants{
      {"plain", plain},
      {"bom", "\xEF\xBB\xBF" + plain},
      {"crlf", crlf},
      {"comments", "// a problem\n{ /* the sites */ " + plain.substr(1) + " // end\n"},
      {"clockwise", R"({"geometry": "plane", "sites": [[0.2,0.2],[0.8,0.3],[0.5,0.8]],
        "domain": [[0,0],[0,1],[1,1],[1,0]], "tolerance": 1e-12})"}};
  std::vector<double> reference;
  for (const auto& [name, text] : variants) {
    const auto r = run("solve " + write(name + "_accepted.json", text).string() + " --quiet");
    ASSERT_EQ(r.exit_code, 0) << name << ": " << r.err;
    const auto weights = json::parse(r.out)["weights"].get<std::vector<double>>();
    if (reference.empty()) reference = weights;
    ASSERT_EQ(weights.size(), reference.size()) << name;
    for (std::size_t i = 0; i < weights.size(); ++i) EXPECT_NEAR(weights[i], reference[i], 1e-12) << name;
  }
}

TEST(Cli, PlaneDomainWithHolesAndImageDensity) {
  // A square with two holes; an image density given relative to the problem file.
  std::string pgm = "P2\n8 8\n255\n";
  for (int k = 0; k < 64; ++k) pgm.append(std::to_string(40 + 3 * k)).append(" ");
  write("ramp.pgm", pgm + "\n");
  std::string sites;
  for (int i = 0; i < 12; ++i)
    for (int j = 0; j < 12; ++j) sites.append(sites.empty() ? "" : ",").append(fmt_pair((i + 0.5) / 3, (j + 0.37) / 3));
  const std::string domain =
      R"("domain": {"outer": [[0,0],[4,0],[4,4],[0,4]], "holes": [[[1,1],[2,1],[2,2],[1,2]], [[2.5,2.5],[3.5,2.5],[3.5,3.5],[2.5,3.5]]]})";
  const auto uniform = write("holes.json", R"({"geometry": "plane", "sites": [)" + sites + "], " + domain + "}");
  const auto svg_path = scratch() / "holes.svg";
  auto r = run("solve " + uniform.string() + " --quiet --svg " + svg_path.string());
  ASSERT_EQ(r.exit_code, 0) << r.err;
  json result = json::parse(r.out);
  EXPECT_EQ(result["status"], "converged");
  EXPECT_NEAR(result["source_mass"].get<double>(), 14, 1e-12);
  EXPECT_NE(result["message"].get<std::string>().find("continuation"), std::string::npos);  // sites in the holes
  EXPECT_NE(slurp(svg_path).find("fill=\"white\""), std::string::npos);                     // the holes drawn
  const auto image = write("holes_image.json",
                           R"({"geometry": "plane", "sites": [)" + sites + "], " + domain +
                               R"(, "density": {"type": "image", "file": "ramp.pgm", "interpolation": "constant"}})");
  r = run("solve " + image.string() + " --quiet");
  ASSERT_EQ(r.exit_code, 0) << r.err;
  result = json::parse(r.out);
  EXPECT_EQ(result["status"], "converged");
  double expected = 0;  // pixels are 0.5 × 0.5; the holes cover whole pixels
  for (int row = 0; row < 8; ++row)
    for (int column = 0; column < 8; ++column) {
      const double x = (column + 0.5) / 2, y = 4 - (row + 0.5) / 2;
      const bool in_hole = (x > 1 && x < 2 && y > 1 && y < 2) || (x > 2.5 && x < 3.5 && y > 2.5 && y < 3.5);
      if (!in_hole) expected += (40 + 3 * (row * 8 + column)) / 255.0 * 0.25;
    }
  EXPECT_NEAR(result["source_mass"].get<double>(), expected, 1e-12 * expected);
}

TEST(Cli, MeshDensitiesOnTheSphereAndInH2) {
  // The octahedron's faces with ρ = 1 + 0.9 z at the vertices, from a mesh file.
  write("octahedron.json", R"({"vertices": [[1,0,0],[-1,0,0],[0,1,0],[0,-1,0],[0,0,1],[0,0,-1]],
      "triangles": [[0,2,4],[2,1,4],[1,3,4],[3,0,4],[2,0,5],[1,2,5],[3,1,5],[0,3,5]],
      "values": [1, 1, 1, 1, 1.9, 0.1]})");
  const auto sphere = write("sphere_mesh.json", R"({"geometry": "sphere",
      "sites": [[0,0,1],[0,0,-1],[1,0,0],[-1,0,0],[0,1,0],[0,-1,0],[0.5,0.5,0.5],[-0.5,0.5,-0.5]],
      "density": {"type": "mesh", "file": "octahedron.json"}, "tolerance": 1e-11})");
  auto r = run("solve " + sphere.string() + " --quiet");
  ASSERT_EQ(r.exit_code, 0) << r.err;
  json result = json::parse(r.out);
  EXPECT_EQ(result["status"], "converged");
  EXPECT_LE(result["max_relative_mass_error"].get<double>(), 1e-11);
  // The mesh tiles the sphere and the interpolant's mean over the octants is 1 by symmetry.
  EXPECT_NEAR(result["source_mass"].get<double>(), 4 * M_PI, 1e-10);
  const auto h2 = write("h2_mesh.json", R"({"geometry": "hyperbolic",
      "domain": {"model": "klein", "vertices": [[-0.5,-0.5],[0.5,-0.5],[0.5,0.5],[-0.5,0.5]]},
      "sites": [[-0.2,-0.2],[0.25,-0.1],[0.1,0.3],[-0.3,0.2],[0,0]],
      "density": {"type": "mesh", "vertices": [[-0.5,-0.5],[0.5,-0.5],[0.5,0.5],[-0.5,0.5]],
                  "triangles": [[0,1,2],[0,2,3]], "values": [1, 2, 3, 0]}})");
  r = run("solve " + h2.string() + " --quiet");
  ASSERT_EQ(r.exit_code, 0) << r.err;
  result = json::parse(r.out);
  EXPECT_EQ(result["status"], "converged");
}

// Outputs are replaced atomically (sdot::write_file_atomically): a run that fails leaves the
// previous result and picture byte-identical, and no other file in their folder.
TEST(Cli, AFailedSolveLeavesThePreviousOutputsByteIdentical) {
  const fs::path dir = scratch() / "previous_outputs";
  fs::create_directories(dir);
  const fs::path result = dir / "result.json", svg = dir / "diagram.svg";
  const auto good = write("previous_good.json", R"({"geometry": "plane", "sites": [[0.2,0.2],[0.8,0.3],[0.5,0.8]]})");
  ASSERT_EQ(run("solve " + good.string() + " --quiet -o " + result.string() + " --svg " + svg.string()).exit_code, 0);
  const std::string old_result = slurp(result), old_svg = slurp(svg);
  ASSERT_FALSE(old_result.empty());
  ASSERT_FALSE(old_svg.empty());
  auto folder = [&] {
    std::vector<std::string> names;
    for (const auto& entry : fs::directory_iterator(dir)) names.push_back(entry.path().filename().string());
    std::sort(names.begin(), names.end());
    return names;
  };

  // Bad input: the run stops before any output.
  const auto bad = write("previous_bad.json", R"({"geometry": "plane", "sites": [[0.1,0.1],[0.5,0.5],[0.1,0.1]]})");
  auto r = run("solve " + bad.string() + " --quiet --output " + result.string() + " --svg " + svg.string());
  EXPECT_EQ(r.exit_code, 2) << r.err;
  EXPECT_NE(r.err.find("sites[2]: duplicate of sites[0]"), std::string::npos) << r.err;
  EXPECT_EQ(slurp(result), old_result);
  EXPECT_EQ(slurp(svg), old_svg);
  EXPECT_EQ(folder(), (std::vector<std::string>{"diagram.svg", "result.json"}));

  // A picture that cannot be written (its folder would be inside the result file): the result is
  // replaced whole, the previous picture stays, and the error names the picture's path.
  const auto other = write("previous_other.json", R"({"geometry": "plane", "sites": [[0.3,0.3],[0.7,0.6]]})");
  const fs::path bad_svg = result / "diagram.svg";
  r = run("solve " + other.string() + " --quiet -o " + result.string() + " --svg " + bad_svg.string());
  EXPECT_EQ(r.exit_code, 2) << r.err;
  EXPECT_NE(r.err.find(bad_svg.string() + ": cannot write: "), std::string::npos) << r.err;
  EXPECT_EQ(std::count(r.err.begin(), r.err.end(), '\n'), 1) << r.err;
  EXPECT_EQ(json::parse(slurp(result))["weights"].size(), 2u) << "the new result";
  EXPECT_EQ(slurp(svg), old_svg);
  EXPECT_EQ(folder(), (std::vector<std::string>{"diagram.svg", "result.json"}));

  // A result path that is a folder: nothing is written there or beside it.
  fs::create_directories(dir / "a_folder");
  r = run("solve " + good.string() + " --quiet -o " + (dir / "a_folder").string());
  EXPECT_EQ(r.exit_code, 2) << r.err;
  EXPECT_NE(r.err.find((dir / "a_folder").string() + ": cannot write: Is a directory"), std::string::npos) << r.err;
  EXPECT_TRUE(fs::is_empty(dir / "a_folder"));
  EXPECT_EQ(folder(), (std::vector<std::string>{"a_folder", "diagram.svg", "result.json"}));
}

TEST(Cli, UsageErrors) {
  EXPECT_EQ(run("").exit_code, 2);
  EXPECT_EQ(run("frobnicate").exit_code, 2);
  EXPECT_EQ(run("bench --geometry plane").exit_code, 2);
  EXPECT_EQ(run("bench --geometry plane --n abc").exit_code, 2);
  const auto r = run("solve /nonexistent/problem.json");
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_NE(r.err.find("cannot open"), std::string::npos);
  EXPECT_EQ(run("--help").exit_code, 0);
}

TEST(Cli, BenchPrintsOneJsonLine) {
  const auto r = run("bench --geometry plane --n 500 --seed 3 --tolerance 1e-8 --quiet");
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_EQ(std::count(r.out.begin(), r.out.end(), '\n'), 1);
  const json line = json::parse(r.out);
  for (const char* key : {"geometry", "n", "iterations", "max_relative_mass_error", "time_s", "diagram_s",
                          "linear_solve_s", "peak_rss_mb"})
    EXPECT_TRUE(line.contains(key)) << key;
  EXPECT_EQ(line["n"], 500);
  EXPECT_LE(line["max_relative_mass_error"].get<double>(), 1e-8);
}

TEST(Cli, OpenMPThreadsWaitPassivelyUnlessToldOtherwise) {
  // spinning waits cost a loaded machine much of its time (sdot::detail::rerun_with_runtime_settings)
  const auto policy_of = [](const std::string& environment) {
    const auto r = run_in(environment, "bench --geometry plane --n 300 --quiet");
    EXPECT_EQ(r.exit_code, 0) << r.err;
    return json::parse(r.out)["omp_wait_policy"].get<std::string>();
  };
#ifdef _OPENMP
  EXPECT_EQ(policy_of("env -u OMP_WAIT_POLICY -u GOMP_SPINCOUNT -u SDOT_COMMAND_REEXEC"), "passive");
#endif
  EXPECT_EQ(policy_of("env OMP_WAIT_POLICY=active"), "active");
}

TEST(Cli, GlibcTunablesAreReadByName) {
  using sdot::detail::glibc_tunable;
  EXPECT_EQ(glibc_tunable(nullptr, "glibc.malloc.hugetlb"), "default");
  EXPECT_EQ(glibc_tunable("", "glibc.malloc.hugetlb"), "default");
  EXPECT_EQ(glibc_tunable("glibc.malloc.hugetlb=1", "glibc.malloc.hugetlb"), "1");
  EXPECT_EQ(glibc_tunable("glibc.malloc.top_pad=65536:glibc.malloc.hugetlb=0", "glibc.malloc.hugetlb"), "0");
  EXPECT_EQ(glibc_tunable("glibc.malloc.hugetlb=0:glibc.malloc.hugetlb=1", "glibc.malloc.hugetlb"), "1");  // last wins
  // a longer name that starts with the same letters is another tunable
  EXPECT_EQ(glibc_tunable("glibc.malloc.hugetlbx=1:glibc.malloc.top_pad=0", "glibc.malloc.hugetlb"), "default");
}

TEST(Cli, AsksForHeapHugePagesUnlessTheEnvironmentSaysOtherwise) {
  // page faults of large arrays (sdot::detail::RuntimeSettings::heap_huge_pages)
  const auto hugetlb_of = [](const std::string& environment) {
    const auto r = run_in(environment, "bench --geometry sphere --n 300 --quiet");
    EXPECT_EQ(r.exit_code, 0) << r.err;
    return json::parse(r.out)["glibc_malloc_hugetlb"].get<std::string>();
  };
#if defined(__linux__) && defined(__GLIBC__)
  EXPECT_EQ(hugetlb_of("env -u GLIBC_TUNABLES -u SDOT_COMMAND_REEXEC"), "1");
  EXPECT_EQ(hugetlb_of("env -u SDOT_COMMAND_REEXEC GLIBC_TUNABLES=glibc.malloc.hugetlb=0"), "0");
#endif
}

TEST(Cli, LargeProblemsMapTheirArraysFromTheSystem) {
  // glibc's own threshold below large_problem_sites (speed), 1 MB from there (peak memory)
  EXPECT_EQ(sdot::cli::mmap_threshold_for(1), 0u);
  EXPECT_EQ(sdot::cli::mmap_threshold_for(sdot::cli::large_problem_sites - 1), 0u);
  EXPECT_EQ(sdot::cli::mmap_threshold_for(sdot::cli::large_problem_sites), std::size_t{1} << 20);
  EXPECT_EQ(sdot::cli::mmap_threshold_for(10'000'000), std::size_t{1} << 20);
  const auto small = run("bench --geometry sphere --n 300 --quiet");
  ASSERT_EQ(small.exit_code, 0) << small.err;
  EXPECT_EQ(json::parse(small.out)["mmap_threshold"], "default");
#ifdef __GLIBC__
  // a loose tolerance: the policy is chosen before the solve, whatever it takes
  const auto large =
      run("bench --geometry plane --n " + std::to_string(sdot::cli::large_problem_sites) + " --tolerance 0.5 --quiet");
  ASSERT_EQ(large.exit_code, 0) << large.err;
#ifdef __SANITIZE_ADDRESS__
  // AddressSanitizer's allocator ignores mallopt (it returns 0): nothing was set
  EXPECT_EQ(json::parse(large.out)["mmap_threshold"], "default");
#else
  EXPECT_EQ(json::parse(large.out)["mmap_threshold"], 1 << 20);
#endif
#endif
}

TEST(Cli, DemoWritesResultsAndPictures) {
  const auto out = scratch() / "demo_out";
  const auto r = run("demo --quiet --out " + out.string());
  ASSERT_EQ(r.exit_code, 0) << r.err;
  for (const std::string geometry : {"plane", "sphere", "hyperbolic"}) {
    EXPECT_TRUE(fs::exists(out / (geometry + "_problem.json"))) << geometry;
    EXPECT_EQ(slurp(out / (geometry + "_diagram.svg")).rfind("<svg", 0), 0u) << geometry;
    EXPECT_EQ(json::parse(slurp(out / (geometry + "_result.json")))["status"], "converged") << geometry;
  }
}

TEST(Cli, BenchEveryGeometry) {
  for (const std::string geometry : {"sphere", "hyperbolic", "torus"}) {
    const auto r = run("bench --geometry " + geometry + " --n 300 --quiet");
    ASSERT_EQ(r.exit_code, 0) << r.err;
    EXPECT_EQ(json::parse(r.out)["geometry"], geometry);
  }
}

TEST(Cli, BenchWithAMeshDensity) {
  // --density-triangles T: a mesh density of about T triangles in every geometry.
  for (const std::string geometry : {"plane", "sphere", "hyperbolic"}) {
    const auto r = run("bench --geometry " + geometry + " --n 300 --density-triangles 3000 --quiet");
    ASSERT_EQ(r.exit_code, 0) << r.err;
    const json line = json::parse(r.out);
    EXPECT_EQ(line["status"], "converged") << geometry;
    const auto triangles = line["density_triangles"].get<double>();
    EXPECT_GT(triangles, 1500) << geometry;
    EXPECT_LT(triangles, 6000) << geometry;
    EXPECT_TRUE(line.contains("density_build_s"));
  }
  EXPECT_EQ(run("bench --geometry plane --n 10 --density-triangles 0").exit_code, 2);
}

// Integers outside int's range, found while writing the fuzz harnesses (tests/fuzz): get<int>()
// wrapped them (max_iterations 4294967301 ran 5 iterations, triangle index 4294967298 became
// vertex 2) and quadrature_order 1e10 was cast to int (undefined behaviour).
INSTANTIATE_TEST_SUITE_P(
    OutOfRangeIntegers, CliBadInput,
    ::testing::Values(BadInput{"huge_max_iterations",
                               R"({"geometry": "plane", "sites": [[0.1,0.1],[0.5,0.5]], "max_iterations": 4294967301})",
                               "max_iterations: must be an integer, got 4294967301"},
                      BadInput{
                          "huge_negative_max_iterations",
                          R"({"geometry": "plane", "sites": [[0.1,0.1],[0.5,0.5]], "max_iterations": -4294967291})",
                          "max_iterations: must be an integer, got -4294967291"},
                      BadInput{"huge_triangle_index", R"({"geometry": "plane", "sites": [[0.1,0.1],[0.5,0.5]],
                     "density": {"type": "mesh", "vertices": [[0,0],[1,0],[1,1],[0,1]],
                                 "triangles": [[0,1,2],[0,3,4294967298]], "values": [1,1,1,1]}})",
                               "density.triangles[1]: vertex index 4294967298 is out of range (4 vertices)"},
                      BadInput{"huge_quadrature_order", R"({"geometry": "plane", "sites": [[0.1,0.1],[0.5,0.5]],
                     "density": {"type": "mesh", "vertices": [[0,0],[1,0],[1,1]], "triangles": [[0,1,2]],
                                 "values": [1,1,1], "quadrature_order": 1e10}})",
                               "density.quadrature_order: must be an integer in 1..64"},
                      BadInput{"fractional_quadrature_order", R"({"geometry": "plane", "sites": [[0.1,0.1],[0.5,0.5]],
                     "density": {"type": "mesh", "vertices": [[0,0],[1,0],[1,1]], "triangles": [[0,1,2]],
                                 "values": [1,1,1], "quadrature_order": 3.5}})",
                               "density.quadrature_order: must be an integer in 1..64"}),
    [](const ::testing::TestParamInfo<BadInput>& param_info) { return std::string(param_info.param.name); });

}  // namespace
