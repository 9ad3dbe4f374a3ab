// The inverse geodesic problem on the WGS84 ellipsoid, identical on the CPU and on CUDA devices.
//
// This is C. F. F. Karney's algorithm (Algorithms for geodesics, J. Geodesy 87, 43-55 (2013)),
// computing what GeographicLib's Geodesic::GenInverse computes for the mask DISTANCE | AREA with
// its default series order 6: the distance s12 and the area S12 between the geodesic and the
// equator. The steps, their order and the series follow GeographicLib so that the results agree
// with it to within a few units in the last place.
//
// Determinism: the C library and CUDA's libdevice differ in the last bits of sin, cos, atan2,
// hypot and cbrt, so these headers use only +, -, *, /, sqrt (correctly rounded on both sides),
// fabs, copysign, remainder (exact) and comparisons, and builds the rest from them. FMA
// contraction is off for every target linking qtmv::grid (-ffp-contract=off, nvcc
// --fmad=false), so each expression rounds identically on both sides.
//
// The parts: deterministic_math.hpp (the elementary functions), geodesic_series.hpp (the
// ellipsoid and Karney's series), geodesic_inverse.hpp (the inverse problem, geodesic_inverse).
#pragma once

#include "measure/deterministic_math.hpp"
#include "measure/geodesic_inverse.hpp"
#include "measure/geodesic_series.hpp"
