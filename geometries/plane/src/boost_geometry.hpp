#pragma once
// Boost.Geometry configured as the plane domains use it; shared by plane_region.cpp and its
// tests, and included before any other Boost header of the translation unit.

// Without its integer rescaling in set operations (the default from Boost 1.77 on): with it,
// computed intersection points are only accurate to about 1e-7 relative.
#define BOOST_GEOMETRY_NO_ROBUSTNESS
// Boost 1.74's Boost.Geometry includes a header it deprecated itself (a #pragma message).
#define BOOST_ALLOW_DEPRECATED_HEADERS

#pragma GCC diagnostic push  // GCC's false positives inside Boost.Geometry at -O2 (Clang has no such warning)
#if defined(__GNUC__) && !defined(__clang__)
#pragma GCC diagnostic ignored "-Wmaybe-uninitialized"
#endif
#include <boost/geometry.hpp>
#include <boost/geometry/geometries/point_xy.hpp>
#include <boost/geometry/geometries/polygon.hpp>
#include <boost/geometry/index/rtree.hpp>
#pragma GCC diagnostic pop

namespace sdot::plane_geometry {
namespace bg = boost::geometry;
using BPoint = bg::model::d2::point_xy<double>;
using BRing = bg::model::ring<BPoint, false, false>;        // counter-clockwise, open
using BPolygon = bg::model::polygon<BPoint, false, false>;  // outer ccw, holes cw, open
using BMulti = bg::model::multi_polygon<BPolygon>;
}  // namespace sdot::plane_geometry
