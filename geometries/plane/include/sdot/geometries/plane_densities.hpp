#pragma once
/// \file plane_densities.hpp
/// Data densities on the plane: images over a rectangle and uniform densities on general
/// (non-convex, holed) regions. All are PiecewiseDensity<Plane>; combine a density with a
/// region through PiecewiseDensity::restricted_to(region.convex_pieces()).

#include <Eigen/Geometry>
#include <string>

#include "sdot/geometries/plane.hpp"
#include "sdot/geometries/plane_region.hpp"
#include "sdot/image.hpp"
#include "sdot/piecewise_density.hpp"

namespace sdot {

/// ρ from a grayscale image stretched over `rectangle` (row 0 along the top edge, y = max).
/// `constant`: ρ is the pixel's value on each pixel (integrated exactly);
/// `bilinear`: ρ interpolates the values at the pixel centres bilinearly (constant extension
/// over the outer half pixel), integrated by quadrature on the cells between pixel centres.
/// Values are multiplied by `scale`. Throws InputError naming `<field>` for an empty image or an
/// empty or non-finite rectangle.
[[nodiscard]] PiecewiseDensity<Plane> image_density(const Plane& plane, const GrayImage& image,
                                                    const Eigen::AlignedBox2d& rectangle,
                                                    ImageInterpolation interpolation, double scale = 1,
                                                    const std::string& field = "density");

/// ρ = 1 on `region`, 0 elsewhere (the uniform density of a non-convex or holed domain).
[[nodiscard]] PiecewiseDensity<Plane> region_density(const Plane& plane, const PlaneRegion& region);

}  // namespace sdot
