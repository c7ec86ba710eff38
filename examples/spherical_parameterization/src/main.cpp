// sdot-sphere-param: area-preserving spherical parameterization of a closed genus-0 mesh.
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <iostream>
#include <nlohmann/json.hpp>
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
    "                         [--no-optimize] [--ot-tolerance T] [--sweeps N] [--ply-ascii] [--quiet]\n"
    "\n"
    "Maps a closed genus-0 triangle mesh onto the unit sphere without area distortion and without\n"
    "flipped faces (semi-discrete optimal transport with sdot's sphere geometry).\n"
    "INPUT and OUTPUT are OFF, OBJ or PLY (by extension; PLY ascii or binary little-endian).\n"
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
    "  --no-optimize          skip the final area-correcting optimization\n"
    "  --separation-threshold X  run site-separation passes while the shortest edge of the map\n"
    "                         is below X*sqrt(4pi/N) (default 5e-5; 0 disables them)\n"
    "  --separation-delta D   separation radius of their representatives, times sqrt(4pi/N) (default 0.1)\n"
    "  --ot-tolerance T       max relative mass error of the OT solve (default 0.05)\n"
    "  --sweeps N             sweeps of the area optimization at most (default 200)\n"
    "  --ply-ascii            write PLY as ascii (default binary little-endian)\n"
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

}  // namespace

int main(int argc, char** argv) {
#if defined(__GLIBC__)
  // The stages allocate and free arrays of several MB many times (diagrams, Newton matrices,
  // factors, per-stage copies of the map). By default glibc maps many of them afresh and gives
  // them back to the kernel when freed, so their pages are faulted in and zeroed again on the
  // next use. Keeping freed memory in the heap made igea_134k faster in 8 of 9 interleaved pairs.
  mallopt(M_MMAP_THRESHOLD, 32 << 20);
  mallopt(M_TRIM_THRESHOLD, 1 << 30);
  mallopt(M_TOP_PAD, 16 << 20);
#endif
  std::string input, output, report_path, svg_path, weights_path;
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
      options.refine = std::atoi(value("a number").c_str());
    else if (a == "--max-refine")
      options.max_refine = std::atoi(value("a number").c_str());
    else if (a == "--reweightings")
      options.max_reweightings = std::atoi(value("a number").c_str());
    else if (a == "--no-optimize")
      options.optimize = false;
    else if (a == "--separation-delta")
      options.separation_delta = std::atof(value("a number").c_str());
    else if (a == "--separation-threshold")
      options.min_spacing = std::atof(value("a number").c_str());
    else if (a == "--ot-tolerance")
      options.ot_tolerance = std::atof(value("a number").c_str());
    else if (a == "--sweeps")
      options.optimizer.max_sweeps = std::atoi(value("a number").c_str());
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
  const auto start = std::chrono::steady_clock::now();
  auto progress = [&](const std::string& s) {
    if (quiet) return;
    char b[32];
    std::snprintf(b, sizeof b, "[%8.3f s] ", since(start));
    std::cerr << b << s << std::endl;
  };
  json report;
  report["input"] = input;
  report["output"] = output;
  auto write_report = [&] {
    if (report_path.empty()) return;
    std::ofstream out(report_path);
    out << report.dump(2) << "\n";
    if (!out) std::cerr << "error: cannot write the report " << report_path << "\n";
  };
  try {
    auto t = std::chrono::steady_clock::now();
    ReadInfo info;
    const Mesh raw = read_mesh(input, &info);
    const double read_s = since(t);
    const std::vector<double> factors =
        weights_path.empty() ? std::vector<double>{} : read_factors(weights_path, raw.vertices.size());
    options.progress = progress;
    // The initial map's metrics appear only in the report and the histogram.
    const bool want_initial = !report_path.empty() || !svg_path.empty();
    RunResult run = run_parameterization(raw, info, options, factors, want_initial, input);
    for (const auto& d : run.report["input_statistics"]["defects"])
      std::cerr << (d["fatal"].get<bool>() ? "error: " : "warning: ") << input << ": "
                << d["message"].get<std::string>() << "\n";
    report.update(run.report);
    if (run.status == "invalid_input") {
      std::cerr << "error: " << input << " is not a valid closed genus-0 manifold triangle mesh; nothing written\n";
      write_report();
      return 1;
    }
    t = std::chrono::steady_clock::now();
    write_mesh(output, run.output, ply_ascii);
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
      std::ofstream svg(svg_path);
      svg << histogram_svg(run.initial.d, m1.d, "Area distortion: " + input);
      if (!svg) std::cerr << "error: cannot write " << svg_path << "\n";
    }
    char line[256];
    std::snprintf(line, sizeof line,
                  "done in %.3f s: area mean|d| %.4f, std %.4f, max|d| %.3f, angle %.2f deg, flips %zu", total_s,
                  m1.area_mean_abs, m1.area_std, m1.area_max_abs, m1.angle_mean_abs_deg, m1.flips);
    progress(line);
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
