#pragma once
/// \file report.hpp
/// The SVG histogram of the per-face area distortion d (initial and final maps).

#include <string>
#include <vector>

namespace sphparam {

/// An SVG document with two histograms of d = log((A_sphere/4π)/(A_mesh/A_total)) (non-finite
/// values are skipped): the initial map and the final map, on one axis.
std::string histogram_svg(const std::vector<double>& initial, const std::vector<double>& final_d,
                          const std::string& title);

}  // namespace sphparam
