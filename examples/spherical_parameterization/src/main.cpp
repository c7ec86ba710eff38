// sdot-sphere-param: area-preserving spherical parameterization of a closed genus-0 mesh.
#include <cerrno>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <iostream>
#include <nlohmann/json.hpp>
#include <sdot/detail/runtime_settings.hpp>
#include <sdot/error.hpp>
#include <sdot/output_file.hpp>
#include <string>
#if defined(__GLIBC__)
#include <malloc.h>
#endif

#include "mesh.hpp"
#include "pipeline.hpp"
#include "report.hpp"
#include "run.hpp"

using namespace sphparam;
using json = nlohmann::json;

namespace {

const char* usage =
    "usage: sdot-sphere-param INPUT -o OUTPUT [--report REPORT.json] [--svg HISTOGRAM.svg]\n"
    "                         [--target-weights FILE] [--refine N] [--max-refine N] [--reweightings N]\n"
    "                         [--no-optimize] [--coarse-transport D] [--ot-tolerance T] [--sweeps N]\n"
    "                         [--angle-weight L] [--ply-ascii] [--format FMT] [--input-format FMT]\n"
    "                         [--radius R] [--quiet]\n"
    "\n"
    "Maps a closed genus-0 triangle mesh onto the unit sphere without area distortion and without\n"
    "flipped faces (semi-discrete optimal transport with sdot's sphere geometry).\n"
    "INPUT and OUTPUT are OFF, OBJ, PLY (ascii or binary little-endian) or FreeSurfer surfaces\n"
    "(lh.pial, rh.white, lh.sphere, ...), by their names, or FreeSurfer's magic bytes for INPUT.\n"
    "The output has the same vertices and triangles in the same order, every vertex on the sphere.\n"
    "  --report FILE          JSON report: input statistics, stage times, Newton iterations,\n"
    "                         mass error, distortion metrics (as shared/tools/eval_sphere_map.py)\n"
    "  --svg FILE             histogram of the per-face area distortion, initial and final map\n"
    "  --target-weights FILE  one positive factor per vertex: the region around a vertex gets\n"
    "                         its mesh area times the factor (area-controllable map)\n"
    "  --refine N             Dirac refinement levels of the OT stage (default 0; -1: 1 up to 15k vertices)\n"
    "  --max-refine N         when flips survive the untangling, rerun OT with one more refinement\n"
    "                         level, up to N levels (default 1)\n"
    "  --reweightings N       stretch reweightings of the initial Tutte map at most (default 40;\n"
    "                         they run only while more than 0.5% of the faces are crushed below e^-4)\n"
    "  --coarse-to-fine       when the Tutte map stays crushed, start from a coarse-to-fine map\n"
    "                         (edge collapses, then vertices put back) instead; without it only a\n"
    "                         map crushed below rounding (long thin tubes) does\n"
    "  --no-optimize          skip the final area-correcting optimization\n"
    "  --separation-threshold X  run site-separation passes while the shortest edge of the map\n"
    "                         is below X*sqrt(4pi/N) (default 5e-5; 0 disables them)\n"
    "  --separation-delta D   separation radius of their representatives, times sqrt(4pi/N) (default 0.1)\n"
    "  --coarse-transport D   from 40,000 to 500,000 vertices, move the sites by the displacement\n"
    "                         of a coarse OT on representatives D*sqrt(4pi/N) apart before the\n"
    "                         OT (default 8; 0 disables it)\n"
    "  --ot-tolerance T       max relative mass error of the OT solve (default 0.15)\n"
    "  --sweeps N             sweeps of the area optimization at most (default 200; 2000 when\n"
    "                         --angle-weight is above 0.005)\n"
    "  --angle-weight L       weight of the angle (MIPS) term against the area term in the\n"
    "                         final optimization, L >= 0 (default 0.005): 0 is purely\n"
    "                         area-preserving; larger L trades area for angles, and from about\n"
    "                         10 the map leans towards conformal\n"
    "  --ply-ascii            write PLY as ascii (default binary little-endian)\n"
    "  --format FMT           OUTPUT's format whatever its name: off, obj, ply or freesurfer\n"
    "  --input-format FMT     INPUT's format whatever its name\n"
    "  --radius R             radius of the output sphere (default 1; FreeSurfer's ?h.sphere: 100)\n"
    "  --quiet                no progress output\n";

double since(std::chrono::steady_clock::time_point t) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t).count();
}

std::vector<double> read_factors(const std::string& path, std::size_t count) {
  std::ifstream in(path);
  if (!in) throw FileError(path + ": cannot open the target weights");
  std::vector<double> v;
  std::string tok;
  while (in >> tok) {
    if (tok[0] == '#') {
      std::getline(in, tok);
      continue;
    }
    char* end = nullptr;
    const double x = std::strtod(tok.c_str(), &end);
    if (end == tok.c_str() || *end != '\0')
      throw FileError(path + ": target weight " + std::to_string(v.size()) + " is not a number: '" + tok + "'");
    if (!(std::isfinite(x) && x > 0))
      throw FileError(path + ": target weight " + std::to_string(v.size()) + " must be positive and finite, got " +
                      tok);
    v.push_back(x);
  }
  if (v.size() != count)
    throw FileError(path + ": " + std::to_string(v.size()) + " target weights for " + std::to_string(count) +
                    " vertices (one per vertex of the input file is needed)");
  return v;
}

/// Exits with code 2 and a one-line message naming the option.
[[noreturn]] void bad_option(const std::string& option, const std::string& problem) {
  std::cerr << "error: " << option << ": " << problem << "\n";
  std::exit(2);
}

/// A finite number option, > 0 (or ≥ 0 when `zero_allowed`).
double number_option(const std::string& option, const std::string& text, bool zero_allowed) {
  char* end = nullptr;
  const double x = std::strtod(text.c_str(), &end);
  if (text.empty() || *end != '\0' || !std::isfinite(x) || x < 0 || (x == 0 && !zero_allowed))
    bad_option(option, std::string("expected a ") + (zero_allowed ? "non-negative" : "positive") + " number, got '" +
                           text + "'");
  return x;
}

/// An integer option ≥ `least`.
int integer_option(const std::string& option, const std::string& text, int least) {
  char* end = nullptr;
  errno = 0;
  const long x = std::strtol(text.c_str(), &end, 10);
  if (text.empty() || *end != '\0' || errno != 0 || x < least || x > 1000000)
    bad_option(option, "expected an integer from " + std::to_string(least) + " to 1000000, got '" + text + "'");
  return static_cast<int>(x);
}

std::string format_option(const std::string& option, const std::string& text) {
  if (text != "off" && text != "obj" && text != "ply" && text != "freesurfer")
    bad_option(option, "expected off, obj, ply or freesurfer, got '" + text + "'");
  return text;
}

}  // namespace

int main(int argc, char** argv) {
  // Passive OpenMP waits: under load igea_134k took 12.5 s with libgomp's spinning waits and
  // 3.6-4.2 s with passive ones. Huge pages on the heap: spiky_120k 6.0-6.1 s -> 5.3-5.4 s,
  // most of it in the initial map's factorisations (runtime_settings.hpp).
  sdot::detail::rerun_with_runtime_settings(argv, "SDOT_SPHERE_PARAM_REEXEC", {.heap_huge_pages = true});
#if defined(__GLIBC__)
  // The stages allocate and free arrays of several MB many times (diagrams, Newton matrices,
  // factors, per-stage copies of the map). By default glibc maps many of them afresh and gives
  // them back to the kernel when freed, so their pages are faulted in and zeroed again on the
  // next use. Keeping freed memory in the heap made igea_134k faster in 8 of 9 interleaved pairs.
  mallopt(M_MMAP_THRESHOLD, 32 << 20);
  mallopt(M_TRIM_THRESHOLD, 1 << 30);
  mallopt(M_TOP_PAD, 16 << 20);
#endif
  std::string input, output, report_path, svg_path, weights_path, input_format, output_format;
  double radius = 1;
  PipelineOptions options;
  bool quiet = false, ply_ascii = false;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    auto value = [&](const char* what) -> std::string {
      if (i + 1 >= argc) {
        std::cerr << "error: " << a << " needs " << what << "\n" << usage;
        std::exit(2);
      }
      return argv[++i];
    };
    if (a == "-h" || a == "--help") {
      std::cout << usage;
      return 0;
    } else if (a == "-o" || a == "--output")
      output = value("a file");
    else if (a == "--report")
      report_path = value("a file");
    else if (a == "--svg")
      svg_path = value("a file");
    else if (a == "--target-weights")
      weights_path = value("a file");
    else if (a == "--refine")
      options.refine = integer_option(a, value("a number"), -1);
    else if (a == "--max-refine")
      options.max_refine = integer_option(a, value("a number"), 0);
    else if (a == "--reweightings")
      options.max_reweightings = integer_option(a, value("a number"), 0);
    else if (a == "--coarse-to-fine")
      options.hierarchical_initial_map = true;
    else if (a == "--no-optimize")
      options.optimize = false;
    else if (a == "--separation-delta")
      options.separation_delta = number_option(a, value("a number"), false);
    else if (a == "--coarse-transport")
      options.coarse_transport_spacing = number_option(a, value("a number"), true);
    else if (a == "--separation-threshold")
      options.min_spacing = number_option(a, value("a number"), true);
    else if (a == "--ot-tolerance")
      options.ot_tolerance = number_option(a, value("a number"), false);
    else if (a == "--sweeps")
      options.optimizer.max_sweeps = integer_option(a, value("a number"), 0);
    else if (a == "--angle-weight")
      options.optimizer.angle_weight = number_option(a, value("a number"), true);
    else if (a == "--format")
      output_format = format_option(a, value("a format"));
    else if (a == "--input-format")
      input_format = format_option(a, value("a format"));
    else if (a == "--radius")
      radius = number_option(a, value("a number"), false);
    else if (a == "--ply-ascii")
      ply_ascii = true;
    else if (a == "--quiet")
      quiet = true;
    else if (!a.empty() && a[0] == '-') {
      std::cerr << "error: unknown option " << a << "\n" << usage;
      return 2;
    } else if (input.empty())
      input = a;
    else {
      std::cerr << "error: unexpected argument " << a << "\n" << usage;
      return 2;
    }
  }
  if (input.empty() || output.empty()) {
    std::cerr << usage;
    return 2;
  }
  if (output_format.empty() && mesh_format(output).empty())
    bad_option(output, "unknown mesh format '." + extension(output) +
                           "' (use .off, .obj, .ply, a FreeSurfer surface name, or --format)");
  const auto start = std::chrono::steady_clock::now();
  auto progress = [&](const std::string& s) {
    if (quiet) return;
    char b[32];
    std::snprintf(b, sizeof b, "[%8.3f s] ", since(start));
    std::cerr << b << s << std::endl;
  };
  json report;
  report["input"] = input;
  report["runtime"] = {{"omp_wait_policy", sdot::detail::omp_wait_policy_setting()},
                       {"glibc_malloc_hugetlb", sdot::detail::heap_huge_pages_setting()}};
  report["output"] = output;
  auto write_report = [&] {
    if (report_path.empty()) return;
    try {
      sdot::write_file_atomically(report_path, report.dump(2) + "\n");
    } catch (const sdot::Error& e) {
      std::cerr << "error: " << e.what() << "\n";  // the run's outcome and exit code stand
    }
  };
  try {
    auto t = std::chrono::steady_clock::now();
    ReadInfo info;
    Mesh raw = read_mesh(input, &info, input_format);
    const double read_s = since(t);
    const std::vector<double> factors =
        weights_path.empty() ? std::vector<double>{} : read_factors(weights_path, raw.vertices.size());
    options.progress = progress;
    // The initial map's metrics appear only in the report and the histogram.
    const bool want_initial = !report_path.empty() || !svg_path.empty();
    RunResult run = run_parameterization(std::move(raw), info, options, factors, want_initial, input);
    // Bad input is one line: the fatal defects, each naming its first instance.
    std::string fatal;
    for (const auto& d : run.report["input_statistics"]["defects"]) {
      if (!d["fatal"].get<bool>()) {
        if (!quiet) std::cerr << "warning: " << input << ": " << d["message"].get<std::string>() << "\n";
      } else {
        fatal += (fatal.empty() ? "" : "; ") + d["message"].get<std::string>();
      }
    }
    report.update(run.report);
    if (run.status == "invalid_input") {
      std::cerr << "error: " << input << ": not a closed genus-0 manifold triangle mesh: " << fatal
                << "; nothing written\n";
      write_report();
      return 2;
    }
    if (run.status == "failed") {
      std::cerr << "error: " << input << ": " << run.errors.front() << " (an internal error); nothing written\n";
      write_report();
      return 1;
    }
    for (auto& v : run.output.vertices) v *= radius;
    t = std::chrono::steady_clock::now();
    write_mesh(output, run.output, ply_ascii, output_format);
    const double write_s = since(t);
    const double total_s = since(start);
    progress("wrote " + output);
    json times = {{"read_s", read_s}};
    times.update(report["times"]);
    times["write_s"] = write_s;
    times["total_s"] = total_s;
    report["times"] = times;
    write_report();
    const Metrics& m1 = run.final_map;
    if (!svg_path.empty()) {
      try {
        sdot::write_file_atomically(svg_path, histogram_svg(run.initial.d, m1.d, "Area distortion: " + input));
      } catch (const sdot::Error& e) {
        std::cerr << "error: " << e.what() << "\n";
      }
    }
    char line[256];
    std::snprintf(line, sizeof line,
                  "done in %.3f s: area mean|d| %.4f, std %.4f, max|d| %.3f, angle %.2f deg, flips %zu", total_s,
                  m1.area_mean_abs, m1.area_std, m1.area_max_abs, m1.angle_mean_abs_deg, m1.flips);
    progress(line);
    if (run.status == "ot_not_converged") {
      if (!quiet)
        std::cerr << "warning: " << input << ": the OT solve did not converge ("
                  << run.report["ot"]["status"].get<std::string>() << ": "
                  << run.report["ot"]["message"].get<std::string>()
                  << "); the map has no flipped face but does not preserve the areas\n";
      return 4;
    }
    return m1.flips == 0 ? 0 : 3;
  } catch (const FileError& e) {
    std::cerr << "error: " << e.what() << "\n";
    report["status"] = "file_error";
    report["error"] = e.what();
    write_report();
    return 2;
  } catch (const std::exception& e) {
    std::cerr << "error: " << e.what() << "\n";
    report["status"] = "error";
    report["error"] = e.what();
    write_report();
    return 1;
  }
}
