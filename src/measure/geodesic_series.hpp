// WGS84's constants and the order-6 series of Karney's inverse geodesic (geodesic_math.hpp):
// the ellipsoid's coefficients, computed once on the host, and the series in eps evaluated from
// them, identical on the CPU and on CUDA devices (deterministic_math.hpp's operations only).
#pragma once

#include <cmath>

#include "grid/qtm_host_device.hpp"
#include "measure/deterministic_math.hpp"

namespace qtmv::measure {

/// Order of Karney's series (GeographicLib's default GEOGRAPHICLIB_GEODESIC_ORDER).
constexpr int kGeodesicOrder = 6;
constexpr int kA3Count = kGeodesicOrder;                                 ///< coefficients of A3 in eps
constexpr int kC3Count = (kGeodesicOrder * (kGeodesicOrder - 1)) / 2;  ///< coefficients of C3[1..5]
constexpr int kC4Count = (kGeodesicOrder * (kGeodesicOrder + 1)) / 2;  ///< coefficients of C4[0..5]

/// WGS84's constants and Karney's series coefficients (order 6), computed once on the host
/// and passed by value to kernels (a plain struct of doubles, no pointers).
struct Ellipsoid {
  double a;      ///< equatorial radius (m)
  double f;      ///< flattening
  double f1;     ///< 1 - f
  double e2;     ///< eccentricity squared
  double ep2;    ///< second eccentricity squared, e2 / (1 - e2)
  double n;      ///< third flattening, f / (2 - f)
  double b;      ///< polar semi-axis (m)
  double c2;     ///< authalic radius squared (m^2)
  double etol2;  ///< sig12 (radians) below which a line counts as "really short"
  double A3x[kA3Count];  ///< A3 as a polynomial in eps, highest power first
  double C3x[kC3Count];  ///< C3[l] / eps^l as polynomials in eps, l = 1..5
  double C4x[kC4Count];  ///< C4[l] / eps^l as polynomials in eps, l = 0..5
};

namespace detail {

// The tolerances of GeographicLib's inverse problem (its etol2 is the ellipsoid's).
constexpr double kTol0 = kEpsilon;          ///< Newton's convergence on lambda12 (radians)
constexpr double kTol1 = 200 * kTol0;       ///< the strip near the cut (astroid)
constexpr double kTol2 = 0x1p-26;           ///< sqrt(kTol0)
constexpr double kTolB = kTol0;             ///< smallest bisection bracket
constexpr double kXThresh = 1000 * kTol2;   ///< the strip near the cut (astroid)
constexpr int kMaxIt1 = 20;                 ///< Newton steps before falling back to bisection
constexpr int kMaxIt2 = kMaxIt1 + 53 + 10;  ///< all steps: enough bisections for 53 bits

/// Clenshaw summation: sinp ? sum_{i=1..n} c[i] sin(2 i x) : sum_{i=0..n-1} c[i] cos((2 i + 1) x).
QTMV_HD inline double sin_cos_series(bool sinp, double sinx, double cosx, const double* c, int n) {
  c += (n + (sinp ? 1 : 0));  // one beyond the last element
  const double ar = 2 * (cosx - sinx) * (cosx + sinx);  // 2 cos(2x)
  double y0 = (n & 1) ? *--c : 0, y1 = 0;
  n /= 2;
  while (n--) {
    y1 = ar * y0 - y1 + *--c;
    y0 = ar * y1 - y0 + *--c;
  }
  return sinp ? 2 * sinx * cosx * y0 : cosx * (y0 - y1);
}

// The series in eps of Karney 2013 (order 6). Each polynomial in eps^2 is
// evaluated by Horner's rule and divided by its common denominator, as GeographicLib does.

/// A1 - 1 (the scale of the distance integral I1).
QTMV_HD inline double a1m1(double eps) {
  const double eps2 = sq(eps);
  const double t = (((eps2 + 4) * eps2 + 64) * eps2 + 0) / 256;
  return (t + eps) / (1 - eps);
}

/// C1[1..6] (the Fourier coefficients of I1), into c[1..6].
QTMV_HD inline void c1_coeffs(double eps, double* c) {
  const double eps2 = sq(eps);
  double d = eps;
  c[1] = d * ((-1 * eps2 + 6) * eps2 - 16) / 32;
  d *= eps;
  c[2] = d * ((-9 * eps2 + 64) * eps2 - 128) / 2048;
  d *= eps;
  c[3] = d * (9 * eps2 - 16) / 768;
  d *= eps;
  c[4] = d * (3 * eps2 - 5) / 512;
  d *= eps;
  c[5] = d * -7 / 1280;
  d *= eps;
  c[6] = d * -7 / 2048;
}

/// A2 - 1 (the scale of the reduced-length integral I2).
QTMV_HD inline double a2m1(double eps) {
  const double eps2 = sq(eps);
  const double t = (((-11 * eps2 - 28) * eps2 - 192) * eps2 + 0) / 256;
  return (t - eps) / (1 + eps);
}

/// C2[1..6] (the Fourier coefficients of I2), into c[1..6].
QTMV_HD inline void c2_coeffs(double eps, double* c) {
  const double eps2 = sq(eps);
  double d = eps;
  c[1] = d * ((eps2 + 2) * eps2 + 16) / 32;
  d *= eps;
  c[2] = d * ((35 * eps2 + 64) * eps2 + 384) / 2048;
  d *= eps;
  c[3] = d * (15 * eps2 + 80) / 768;
  d *= eps;
  c[4] = d * (7 * eps2 + 35) / 512;
  d *= eps;
  c[5] = d * 63 / 1280;
  d *= eps;
  c[6] = d * 77 / 2048;
}

/// A3 (the scale of the longitude integral I3).
QTMV_HD inline double a3f(const Ellipsoid& e, double eps) { return polyval(kA3Count - 1, e.A3x, eps); }

/// C3[1..5] (the Fourier coefficients of I3), into c[1..5].
QTMV_HD inline void c3_coeffs(const Ellipsoid& e, double eps, double* c) {
  double mult = 1;
  int o = 0;
  for (int l = 1; l < kGeodesicOrder; ++l) {
    const int m = kGeodesicOrder - l - 1;  // order of the polynomial in eps
    mult *= eps;
    c[l] = mult * polyval(m, e.C3x + o, eps);
    o += m + 1;
  }
}

/// C4[0..5] (the Fourier coefficients of the area integral I4), into c[0..5].
QTMV_HD inline void c4_coeffs(const Ellipsoid& e, double eps, double* c) {
  double mult = 1;
  int o = 0;
  for (int l = 0; l < kGeodesicOrder; ++l) {
    const int m = kGeodesicOrder - l - 1;
    c[l] = mult * polyval(m, e.C4x + o, eps);
    o += m + 1;
    mult *= eps;
  }
}

/// eps = k2 / (2 (1 + sqrt(1 + k2)) + k2), the expansion parameter for k^2 = k2.
QTMV_HD inline double eps_of(double k2) { return k2 / (2 * (1 + ::sqrt(1 + k2)) + k2); }

/// Builds the constants and the series coefficients of an oblate ellipsoid (0 <= f < 1/150 or
/// so; the prolate branches of GeographicLib are left out) from Karney's order-6 tables.
inline Ellipsoid make_ellipsoid(double a, double f) {
  Ellipsoid e{};
  e.a = a;
  e.f = f;
  e.f1 = 1 - f;
  e.e2 = f * (2 - f);
  e.ep2 = e.e2 / sq(e.f1);
  e.n = f / (2 - f);
  e.b = a * e.f1;
  // c2 = (a^2 + b^2 atanh(e) / e) / 2, with atanh(e) / e = sum_k e2^k / (2k + 1).
  double atanh_ratio = 1, power = 1;
  for (int k = 1; k < 40; ++k) {
    power *= e.e2;
    atanh_ratio += power / (2 * k + 1);
  }
  e.c2 = (sq(a) + sq(e.b) * atanh_ratio) / 2;
  // The sig12 threshold for "really short" lines (GeographicLib's etol2).
  e.etol2 = 0.1 * kTol2 / ::sqrt(max_of(0.001, ::fabs(f)) * min_of(1.0, 1 - f / 2) / 2);

  // Karney's tables (order 6): each polynomial in n (highest power first) followed by its
  // common denominator; A3 by descending power of eps, C3[l] and C4[l] likewise.
  const double a3_table[] = {
      -3, 128,                 // eps^5
      -2, -3, 64,              // eps^4
      -1, -3, -1, 16,          // eps^3
      3, -1, -2, 8,            // eps^2
      1, -1, 2,                // eps^1
      1, 1,                    // eps^0
  };
  int o = 0, k = 0;
  for (int j = kGeodesicOrder - 1; j >= 0; --j) {
    const int m = kGeodesicOrder - j - 1 < j ? kGeodesicOrder - j - 1 : j;  // order of the polynomial in n
    e.A3x[k++] = polyval(m, a3_table + o, e.n) / a3_table[o + m + 1];
    o += m + 2;
  }
  const double c3_table[] = {
      3, 128,               // C3[1] eps^5
      2, 5, 128,            // C3[1] eps^4
      -1, 3, 3, 64,         // C3[1] eps^3
      -1, 0, 1, 8,          // C3[1] eps^2
      -1, 1, 4,             // C3[1] eps^1
      5, 256,               // C3[2] eps^5
      1, 3, 128,            // C3[2] eps^4
      -3, -2, 3, 64,        // C3[2] eps^3
      1, -3, 2, 32,         // C3[2] eps^2
      7, 512,               // C3[3] eps^5
      -10, 9, 384,          // C3[3] eps^4
      5, -9, 5, 192,        // C3[3] eps^3
      7, 512,               // C3[4] eps^5
      -14, 7, 512,          // C3[4] eps^4
      21, 2560,             // C3[5] eps^5
  };
  o = 0;
  k = 0;
  for (int l = 1; l < kGeodesicOrder; ++l) {
    for (int j = kGeodesicOrder - 1; j >= l; --j) {
      const int m = kGeodesicOrder - j - 1 < j ? kGeodesicOrder - j - 1 : j;
      e.C3x[k++] = polyval(m, c3_table + o, e.n) / c3_table[o + m + 1];
      o += m + 2;
    }
  }
  const double c4_table[] = {
      97, 15015,                                   // C4[0] eps^5
      1088, 156, 45045,                            // C4[0] eps^4
      -224, -4784, 1573, 45045,                    // C4[0] eps^3
      -10656, 14144, -4576, -858, 45045,           // C4[0] eps^2
      64, 624, -4576, 6864, -3003, 15015,          // C4[0] eps^1
      100, 208, 572, 3432, -12012, 30030, 45045,   // C4[0] eps^0
      1, 9009,                                     // C4[1] eps^5
      -2944, 468, 135135,                          // C4[1] eps^4
      5792, 1040, -1287, 135135,                   // C4[1] eps^3
      5952, -11648, 9152, -2574, 135135,           // C4[1] eps^2
      -64, -624, 4576, -6864, 3003, 135135,        // C4[1] eps^1
      8, 10725,                                    // C4[2] eps^5
      1856, -936, 225225,                          // C4[2] eps^4
      -8448, 4992, -1144, 225225,                  // C4[2] eps^3
      -1440, 4160, -4576, 1716, 225225,            // C4[2] eps^2
      -136, 63063,                                 // C4[3] eps^5
      1024, -208, 105105,                          // C4[3] eps^4
      3584, -3328, 1144, 315315,                   // C4[3] eps^3
      -128, 135135,                                // C4[4] eps^5
      -2560, 832, 405405,                          // C4[4] eps^4
      128, 99099,                                  // C4[5] eps^5
  };
  o = 0;
  k = 0;
  for (int l = 0; l < kGeodesicOrder; ++l) {
    for (int j = kGeodesicOrder - 1; j >= l; --j) {
      const int m = kGeodesicOrder - j - 1;
      e.C4x[k++] = polyval(m, c4_table + o, e.n) / c4_table[o + m + 1];
      o += m + 2;
    }
  }
  return e;
}

}  // namespace detail

/// WGS84: a = 6378137 m, f = 1/298.257223563.
inline Ellipsoid wgs84_ellipsoid() { return detail::make_ellipsoid(6378137.0, 1 / 298.257223563); }

}  // namespace qtmv::measure
