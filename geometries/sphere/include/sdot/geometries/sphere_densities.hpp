#pragma once
/// \file sphere_densities.hpp
/// Data densities on the sphere: equirectangular (longitude–latitude) images, e.g. a
/// population or elevation map of the Earth. Meshes use sdot::mesh_density directly.

#include <string>

#include "sdot/geometries/sphere.hpp"
#include "sdot/image.hpp"
#include "sdot/piecewise_density.hpp"

namespace sdot {

/// The point of longitude λ and latitude φ (radians): (cos φ cos λ, cos φ sin λ, sin φ).
[[nodiscard]] Sphere::Point from_longitude_latitude(double longitude, double latitude);

/// ρ from an equirectangular image covering the whole sphere: column 0 starts at longitude −180°,
/// columns run eastwards, row 0 starts at latitude +90°. Each pixel is the geodesic quadrilateral
/// through its four corners (a triangle at the poles); these tile the sphere exactly.
/// `constant`: ρ is the pixel's value on its quadrilateral, integrated exactly;
/// `linear`: ρ is piecewise linear (centrally projected) on the triangles between pixel centres
/// (each quadrilateral of four neighbouring centres split in two, periodic in longitude, and a
/// fan to each pole whose value is the mean of the nearest row); it interpolates the pixel
/// values at the pixel centres. `bilinear` is not offered: a (longitude, latitude)-bilinear
/// function is not smooth on geodesic pieces, and quadrature across its kinks would limit the
/// solver's accuracy to about 1e-8 (measured).
/// Values are multiplied by `scale`. Throws InputError naming `<field>` for an image with fewer
/// than 3 columns (a pixel must span less than 180°), an empty image, or `bilinear`.
[[nodiscard]] PiecewiseDensity<Sphere> equirectangular_density(const Sphere& sphere, const GrayImage& image,
                                                               ImageInterpolation interpolation, double scale = 1,
                                                               const std::string& field = "density");

}  // namespace sdot
