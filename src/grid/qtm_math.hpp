// Deterministic elementary maths for the grid, identical on the CPU and on CUDA devices.
//
// The CUDA and C libraries' sin/cos differ in their last bits, so a cell centre computed
// with them on the GPU need not equal the CPU's, and nearest-site decisions built on it
// could differ. These functions use only +, -, *, / and sqrt, which IEEE 754 rounds
// identically on both sides as long as FMA contraction is off (the build passes
// -ffp-contract=off to the host compiler and --fmad=false to nvcc for every target that
// links qtmv::grid).
#pragma once

#include "qtm_host_device.hpp"

// The CPU's sincos_series in SSE2 lanes (x86-64 has SSE2 always); elsewhere, and in device code,
// the scalar series.
#if defined(__SSE2__)
#include <emmintrin.h>
#define QTMV_SSE2_SERIES 1
#else
#define QTMV_SSE2_SERIES 0
#endif

namespace qtmv::grid {

/// A point of the unit sphere (or any 3-vector): x towards (0 E, 0 N), y towards (90 E, 0 N),
/// z towards the north pole.
struct Vec3 {
  double x, y, z;
};

QTMV_HD inline double dot(const Vec3& a, const Vec3& b) { return a.x * b.x + a.y * b.y + a.z * b.z; }

QTMV_HD inline Vec3 cross(const Vec3& a, const Vec3& b) {
  return {a.y * b.z - a.z * b.y, a.z * b.x - a.x * b.z, a.x * b.y - a.y * b.x};
}

QTMV_HD inline Vec3 operator+(const Vec3& a, const Vec3& b) { return {a.x + b.x, a.y + b.y, a.z + b.z}; }
QTMV_HD inline Vec3 operator-(const Vec3& a, const Vec3& b) { return {a.x - b.x, a.y - b.y, a.z - b.z}; }

/// Squared chord length |a - b|^2 between two unit vectors: monotone in the great-circle
/// distance and precise for short distances, so it is what nearest-site comparisons use.
QTMV_HD inline double chord2(const Vec3& a, const Vec3& b) {
  const Vec3 d = a - b;
  return dot(d, d);
}

constexpr double kPi = 3.14159265358979323846;
constexpr double kDegree = kPi / 180.0;  ///< one degree (radians)

/// The two series of sincos_deg in r^2 (r in radians, |r| <= pi/4 plus rounding), in Horner form:
/// sin r = r * ps and cos r = 1 - r^2/2 * pc. Their truncation error (< 1e-19) lies far below
/// double precision. The reciprocals are folded at compile time: multiplying is far faster than
/// dividing.
QTMV_HD inline void sincos_series(double r2, double* ps_out, double* pc_out) {
  // sin r = r (1 - r^2/(2*3) (1 - r^2/(4*5) (1 - ...))), to r^17.
  double ps = 1.0 - r2 * (1.0 / 272.0);  // 16*17
  ps = 1.0 - r2 * (1.0 / 210.0) * ps;    // 14*15
  ps = 1.0 - r2 * (1.0 / 156.0) * ps;    // 12*13
  ps = 1.0 - r2 * (1.0 / 110.0) * ps;    // 10*11
  ps = 1.0 - r2 * (1.0 / 72.0) * ps;     // 8*9
  ps = 1.0 - r2 * (1.0 / 42.0) * ps;     // 6*7
  ps = 1.0 - r2 * (1.0 / 20.0) * ps;     // 4*5
  ps = 1.0 - r2 * (1.0 / 6.0) * ps;      // 2*3
  // cos r = 1 - r^2/(1*2) (1 - r^2/(3*4) (1 - ...)), to r^18.
  double pc = 1.0 - r2 * (1.0 / 306.0);  // 17*18
  pc = 1.0 - r2 * (1.0 / 240.0) * pc;    // 15*16
  pc = 1.0 - r2 * (1.0 / 182.0) * pc;    // 13*14
  pc = 1.0 - r2 * (1.0 / 132.0) * pc;    // 11*12
  pc = 1.0 - r2 * (1.0 / 90.0) * pc;     // 9*10
  pc = 1.0 - r2 * (1.0 / 56.0) * pc;     // 7*8
  pc = 1.0 - r2 * (1.0 / 30.0) * pc;     // 5*6
  pc = 1.0 - r2 * (1.0 / 12.0) * pc;     // 3*4
  *ps_out = ps;
  *pc_out = pc;
}

#if QTMV_SSE2_SERIES
/// sincos_series with the two series in the two lanes of an SSE2 register: each lane takes the
/// scalar code's IEEE operations in its order, so the bits are the same, in half the
/// instructions (sincos_deg is the CPU's labelling's commonest function).
inline void sincos_series_sse2(double r2, double* ps_out, double* pc_out) {
  const __m128d one = _mm_set1_pd(1.0), v2 = _mm_set1_pd(r2);
  // Lanes: low the sine's series, high the cosine's (_mm_set_pd takes the high lane first).
  __m128d p = _mm_sub_pd(one, _mm_mul_pd(v2, _mm_set_pd(1.0 / 306.0, 1.0 / 272.0)));
  p = _mm_sub_pd(one, _mm_mul_pd(_mm_mul_pd(v2, _mm_set_pd(1.0 / 240.0, 1.0 / 210.0)), p));
  p = _mm_sub_pd(one, _mm_mul_pd(_mm_mul_pd(v2, _mm_set_pd(1.0 / 182.0, 1.0 / 156.0)), p));
  p = _mm_sub_pd(one, _mm_mul_pd(_mm_mul_pd(v2, _mm_set_pd(1.0 / 132.0, 1.0 / 110.0)), p));
  p = _mm_sub_pd(one, _mm_mul_pd(_mm_mul_pd(v2, _mm_set_pd(1.0 / 90.0, 1.0 / 72.0)), p));
  p = _mm_sub_pd(one, _mm_mul_pd(_mm_mul_pd(v2, _mm_set_pd(1.0 / 56.0, 1.0 / 42.0)), p));
  p = _mm_sub_pd(one, _mm_mul_pd(_mm_mul_pd(v2, _mm_set_pd(1.0 / 30.0, 1.0 / 20.0)), p));
  p = _mm_sub_pd(one, _mm_mul_pd(_mm_mul_pd(v2, _mm_set_pd(1.0 / 12.0, 1.0 / 6.0)), p));
  *ps_out = _mm_cvtsd_f64(p);
  *pc_out = _mm_cvtsd_f64(_mm_unpackhi_pd(p, p));
}
#endif

/// sin and cos of an angle x (degrees), |x| <= 720, to within about one unit in the last
/// place. The quadrant is taken off in degrees, where it is exact, and the remainder,
/// at most 45 degrees, goes through sincos_series.
QTMV_HD inline void sincos_deg(double x, double* s, double* c) {
  // Round to the nearest quadrant without depending on the math library's rint. A product in
  // place of the division (slow on GPUs) may round a tie the other way: r then lands at the
  // other end of [-45, 45] degrees, where the series is just as accurate.
  const double q = x * (1.0 / 90.0);
  long long n = static_cast<long long>(q >= 0 ? q + 0.5 : q - 0.5);
  const double r = (x - 90.0 * static_cast<double>(n)) * kDegree;  // |r| <= pi/4 (+rounding)
  const double r2 = r * r;
  double ps, pc;
#if QTMV_SSE2_SERIES && !defined(__CUDA_ARCH__)
  sincos_series_sse2(r2, &ps, &pc);
#else
  sincos_series(r2, &ps, &pc);
#endif
  const double sr = r * ps;
  const double cr = 1.0 - r2 * (1.0 / 2.0) * pc;
  switch (static_cast<int>(((n % 4) + 4) % 4)) {
    case 0: *s = sr; *c = cr; break;
    case 1: *s = cr; *c = -sr; break;
    case 2: *s = -sr; *c = -cr; break;
    default: *s = -cr; *c = sr; break;
  }
}

/// Unit vector of a point given by longitude and latitude (degrees).
QTMV_HD inline Vec3 unit_vector(double lon, double lat) {
  double slon, clon, slat, clat;
  sincos_deg(lon, &slon, &clon);
  sincos_deg(lat, &slat, &clat);
  return {clat * clon, clat * slon, slat};
}

}  // namespace qtmv::grid
