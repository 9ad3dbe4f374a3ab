// The inverse geodesic problem on the WGS84 ellipsoid, identical on the CPU and on CUDA devices.
//
// This is C. F. F. Karney's algorithm (Algorithms for geodesics, J. Geodesy 87, 43-55 (2013)),
// computing what GeographicLib's Geodesic::GenInverse computes for the mask DISTANCE | AREA with
// its default series order 6: the distance s12 and the area S12 between the geodesic and the
// equator. The steps, their order and the series follow GeographicLib so that the results agree
// with it to within a few units in the last place.
//
// Determinism: the C library and CUDA's libdevice differ in the last bits of sin, cos, atan2,
// hypot and cbrt, so this file uses only +, -, *, /, sqrt (correctly rounded on both sides),
// fabs, copysign, remainder (exact) and comparisons, and builds the rest from them. FMA
// contraction is off for every target linking qtmv::grid (-ffp-contract=off, nvcc
// --fmad=false), so each expression rounds identically on both sides.
#pragma once

#include <cmath>

#include "grid/qtm_host_device.hpp"
#include "grid/qtm_math.hpp"

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

/// Result of the inverse problem.
struct InverseSolution {
  double s12;  ///< geodesic distance (metres)
  double S12;  ///< area between the geodesic and the equator (square metres), signed as GeographicLib's
};

namespace detail {

constexpr double kEpsilon = 0x1p-52;        ///< DBL_EPSILON
constexpr double kTiny = 0x1p-511;          ///< sqrt(DBL_MIN): underflow guard
constexpr double kTol0 = kEpsilon;          ///< Newton's convergence on lambda12 (radians)
constexpr double kTol1 = 200 * kTol0;       ///< the strip near the cut (astroid)
constexpr double kTol2 = 0x1p-26;           ///< sqrt(kTol0)
constexpr double kTolB = kTol0;             ///< smallest bisection bracket
constexpr double kXThresh = 1000 * kTol2;   ///< the strip near the cut (astroid)
constexpr int kMaxIt1 = 20;                 ///< Newton steps before falling back to bisection
constexpr int kMaxIt2 = kMaxIt1 + 53 + 10;  ///< all steps: enough bisections for 53 bits
constexpr double kDblMax = 1.7976931348623157e308;
constexpr double kQuarterTurn = 90.0;  ///< degrees
constexpr double kHalfTurn = 180.0;    ///< degrees
constexpr double kFullTurn = 360.0;    ///< degrees
// pi/2 and pi as unevaluated sums hi + lo (from mpmath at 300 bits).
constexpr double kHalfPiHi = 1.5707963267948966;
constexpr double kHalfPiLo = 6.123233995736766e-17;
constexpr double kPiHi = 3.141592653589793;
constexpr double kPiLo = 1.2246467991473532e-16;

QTMV_HD inline double sq(double x) { return x * x; }
QTMV_HD inline double max_of(double x, double y) { return x > y ? x : y; }
QTMV_HD inline double min_of(double x, double y) { return x < y ? x : y; }
QTMV_HD inline bool sign_bit(double x) { return ::copysign(1.0, x) < 0; }
QTMV_HD inline void swap_values(double* x, double* y) {
  const double t = *x;
  *x = *y;
  *y = t;
}

/// Polynomial sum_{k=0..order} p[k] x^(order-k) by Horner's rule (p[0] is the highest power).
QTMV_HD inline double polyval(int order, const double* p, double x) {
  double y = order < 0 ? 0 : *p++;
  while (--order >= 0) y = y * x + *p++;
  return y;
}

/// hypot(x, y) to within an ulp by C. F. Borges' corrected algorithm (An improved algorithm for
/// hypot(a, b), 2019): sqrt(x^2 + y^2) and one Newton step with the residual h^2 - x^2 - y^2
/// computed without cancellation. This is also glibc's hypot (2.35 on, without FMA), so the
/// reduced latitudes, normalised with it, get GeographicLib's bits: an ulp there moves a
/// point by 0.7 nm, most of the tolerance of short lines. Scaled by powers of two (exact) far
/// from 1 so that nothing overflows or underflows.
QTMV_HD inline double det_hypot(double x, double y) {
  double big = ::fabs(x), small = ::fabs(y);
  if (small > big) {
    const double t = big;
    big = small;
    small = t;
  }
  if (!(big <= kDblMax) || small != small) return ::fabs(x) + ::fabs(y);  // inf or nan
  if (big == 0) return 0;
  double scale = 1;
  if (big > 0x1p+500) {
    scale = 0x1p-600;
  } else if (big < 0x1p-500) {
    scale = 0x1p+600;
  }
  big *= scale;
  small *= scale;
  double h = ::sqrt(big * big + small * small);
  double t1, t2;
  if (h <= 2 * small) {
    const double delta = h - small;
    t1 = big * (2 * delta - big);
    t2 = (delta - 2 * (big - small)) * delta;
  } else {
    const double delta = h - big;
    t1 = 2 * delta * (big - 2 * small);
    t2 = (4 * delta - small) * small + delta * delta;
  }
  h -= (t1 + t2) / (2 * h);
  return h / scale;
}

/// Scales (x, y) to a unit vector.
QTMV_HD inline void norm2(double* x, double* y) {
  const double h = det_hypot(*x, *y);
  *x /= h;
  *y /= h;
}

/// atan(c) for c = j/16, j = 3..16, as hi + lo (from mpmath at 300 bits).
QTMV_HD inline void atan_sixteenths(int j, double* hi, double* lo) {
  switch (j) {
    case 3: *hi = 0.18534794999569476; *lo = 4.180692268843079e-18; break;
    case 4: *hi = 0.24497866312686414; *lo = 1.0698755618734451e-17; break;
    case 5: *hi = 0.3028848683749714; *lo = -1.1010827903001369e-17; break;
    case 6: *hi = 0.35877067027057225; *lo = -2.4623815582638635e-17; break;
    case 7: *hi = 0.4124104415973873; *lo = -1.587652227770689e-17; break;
    case 8: *hi = 0.4636476090008061; *lo = 2.2698777452961687e-17; break;
    case 9: *hi = 0.5123894603107377; *lo = -2.5462781472855804e-17; break;
    case 10: *hi = 0.5585993153435624; *lo = -5.4556305485916264e-18; break;
    case 11: *hi = 0.6022873461349642; *lo = 2.950430737228402e-17; break;
    case 12: *hi = 0.6435011087932844; *lo = 1.5834785051444286e-17; break;
    case 13: *hi = 0.6823165548747481; *lo = 6.943223671560008e-18; break;
    case 14: *hi = 0.7188299996216245; *lo = -2.1478388444456983e-17; break;
    case 15: *hi = 0.7531512809621944; *lo = -2.4256934659182068e-17; break;
    default: *hi = 0.7853981633974483; *lo = 3.061616997868383e-17; break;  // j = 16
  }
}

/// atan(t) for 0 <= t <= 1 as hi + lo (|lo| < hi / 5), without rounding the sum.
///
/// Below t = 5/32 the Taylor series t - t^3/3 + t^5/5 - ... to t^21 is used directly (the first
/// term left out, t^23/23, is below 2^-59 t). Above, t is reduced with the nearest c = j/16:
/// atan(t) = atan(c) + atan(t'), t' = (t - c) / (1 + t c), |t'| <= 1/32, where t - c is exact
/// (Sterbenz) and the Taylor series to t'^11 leaves out less than 2^-65. The coefficients are
/// the exact Taylor coefficients (-1)^k / (2k + 1), rounded once.
QTMV_HD inline void atan_unit(double t, double* hi, double* lo) {
  constexpr double kDirectBelow = 5.0 / 32.0;
  if (t < kDirectBelow) {
    const double z = t * t;
    double q = -1.0 / 21.0;
    q = 1.0 / 19.0 + z * q;
    q = -1.0 / 17.0 + z * q;
    q = 1.0 / 15.0 + z * q;
    q = -1.0 / 13.0 + z * q;
    q = 1.0 / 11.0 + z * q;
    q = -1.0 / 9.0 + z * q;
    q = 1.0 / 7.0 + z * q;
    q = -1.0 / 5.0 + z * q;
    q = 1.0 / 3.0 + z * q;
    *hi = t;
    *lo = -(t * (z * q));
    return;
  }
  const int j = static_cast<int>(t * 16.0 + 0.5);  // 3..16
  const double c = static_cast<double>(j) * (1.0 / 16.0);
  const double tr = (t - c) / (1.0 + t * c);
  const double z = tr * tr;
  double q = -1.0 / 11.0;
  q = 1.0 / 9.0 + z * q;
  q = -1.0 / 7.0 + z * q;
  q = 1.0 / 5.0 + z * q;
  q = -1.0 / 3.0 + z * q;
  double chi, clo;
  atan_sixteenths(j, &chi, &clo);
  *hi = chi;
  *lo = clo + (tr + tr * (z * q));
}

}  // namespace detail

/// atan2(y, x) (radians, in [-pi, pi]) to within about one ulp, with the signed zeros and
/// infinities of the C library's atan2. The ratio of the smaller to the larger magnitude
/// (in [0, 1]) goes through atan_unit; the quadrant's pi/2 or pi is added in two parts.
QTMV_HD inline double det_atan2(double y, double x) {
  using namespace detail;
  if (x != x || y != y) return x + y;
  const double ax = ::fabs(x), ay = ::fabs(y);
  const bool steep = ay > ax;  // |angle from the x axis| > 45 degrees
  double t;
  if (ax == ay) {
    t = ax == 0 ? 0 : 1;  // also both infinite
  } else {
    t = steep ? ax / ay : ay / ax;
  }
  double hi, lo;
  atan_unit(t, &hi, &lo);
  // angle = base + sign * atan(t) with base in {0, pi/2, pi}.
  double base_hi = 0, base_lo = 0, sign = 1;
  if (sign_bit(x)) {
    if (steep) {
      base_hi = kHalfPiHi; base_lo = kHalfPiLo;
    } else {
      base_hi = kPiHi; base_lo = kPiLo; sign = -1;
    }
  } else if (steep) {
    base_hi = kHalfPiHi; base_lo = kHalfPiLo; sign = -1;
  }
  hi *= sign;
  lo *= sign;
  // Fast two-sum of base_hi + hi (|base_hi| >= |hi| or base_hi = 0), keeping its error.
  const double s = base_hi + hi;
  const double err = base_hi == 0 ? 0 : hi - (s - base_hi);
  const double angle = s + ((err + base_lo) + lo);
  return ::copysign(angle, y);
}

namespace detail {

/// A value as an unevaluated sum hi + lo.
struct DoubleDouble {
  double hi, lo;
};

/// Exact product a * b = hi + *lo (Dekker's splitting, no FMA), for |a b| far from overflow.
QTMV_HD inline double two_product(double a, double b, double* lo) {
  constexpr double kSplitter = 134217729.0;  // 2^27 + 1
  const double p = a * b;
  double t = kSplitter * a;
  const double ahi = t - (t - a), alo = a - ahi;
  t = kSplitter * b;
  const double bhi = t - (t - b), blo = b - bhi;
  *lo = ((ahi * bhi - p) + ahi * blo + alo * bhi) + alo * blo;
  return p;
}

/// Real cube root, correctly rounded but for rare cases. The argument is scaled by powers of 8
/// (exact) into [1, 8), where Newton's method from the chord 1 + (m - 1) / 7 converges in five
/// steps; a sixth with the residual r^3 - m computed exactly (two_product) rounds it.
QTMV_HD inline double det_cbrt(double x) {
  double m = ::fabs(x);
  if (m == 0 || !(m <= kDblMax)) return x;
  double root_scale = 1;
  while (m >= 0x1p+60) { m *= 0x1p-60; root_scale *= 0x1p+20; }
  while (m < 0x1p-60) { m *= 0x1p+60; root_scale *= 0x1p-20; }
  while (m >= 8) { m *= 0.125; root_scale *= 2; }
  while (m < 1) { m *= 8; root_scale *= 0.5; }
  double r = 1 + (m - 1) * (1.0 / 7.0);
  for (int k = 0; k < 5; ++k) r -= (r * r * r - m) / (3 * r * r);
  double r2lo, r3lo;
  const double r2 = two_product(r, r, &r2lo);
  const double r3 = two_product(r2, r, &r3lo);
  const double residual = (r3 - m) + (r3lo + r2lo * r);  // r3 - m is exact (Sterbenz)
  r -= residual / (3 * r2);
  return ::copysign(r * root_scale, x);
}

/// sin and cos of c = j/64 (radians), j = 1..51, as hi + lo (from mpmath at 300 bits).
QTMV_HD inline void sincos_sixtyfourths(int j, DoubleDouble* s, DoubleDouble* c) {
  switch (j) {
    case 1: *s = {0.015624364224883372, -1.2650937552759816e-19};
            *c = {0.9998779321710066, 3.216122229972341e-17}; break;
    case 2: *s = {0.03124491398532608, -1.562781562225433e-18};
            *c = {0.9995117584851364, -3.418806487972947e-17}; break;
    case 3: *s = {0.04685783574813424, -2.3419368365610254e-18};
            *c = {0.9989015683384429, -2.1425557800399754e-17}; break;
    case 4: *s = {0.0624593178423802, -2.040259504585711e-18};
            *c = {0.9980475107000991, 3.3232291674141346e-17}; break;
    case 5: *s = {0.07804555138996731, -5.449443782005793e-18};
            *c = {0.9969497940760287, -1.2467075728553626e-17}; break;
    case 6: *s = {0.09361273123551289, 1.4628632005878733e-18};
            *c = {0.9956086864580017, 3.312922430932991e-17}; break;
    case 7: *s = {0.10915705687532236, 6.6284699502736666e-18};
            *c = {0.9940245152582091, 1.3287985046260087e-17}; break;
    case 8: *s = {0.12467473338522769, -2.925947496057858e-18};
            *c = {0.992197667229329, 4.754870575189364e-17}; break;
    case 9: *s = {0.1401619723470637, -9.946847113883478e-18};
            *c = {0.9901285883701071, -4.589906353553811e-18}; break;
    case 10: *s = {0.15561499277355603, 8.886053372342288e-18};
             *c = {0.9878177838164719, 4.91917302237681e-17}; break;
    case 11: *s = {0.17103002203139503, -9.954774726452923e-18};
             *c = {0.9852658177182139, -4.925721262944555e-17}; break;
    case 12: *s = {0.18640329676226988, 2.3493796901281573e-18};
             *c = {0.9824733131012553, -3.919920375420088e-17}; break;
    case 13: *s = {0.2017310638016388, 5.587232815460113e-18};
             *c = {0.9794409517155483, 1.3108769521526758e-17}; break;
    case 14: *s = {0.21700958109501015, 1.1170071073364376e-17};
             *c = {0.9761694738686353, -7.850690609285027e-18}; break;
    case 15: *s = {0.23223511861151147, -8.318080852687206e-18};
             *c = {0.9726596782449127, 2.3920264546490165e-17}; break;
    case 16: *s = {0.24740395925452294, -7.53102495590706e-18};
             *c = {0.9689124217106447, 5.071436662403936e-17}; break;
    case 17: *s = {0.2625123997691533, -2.2534597527902125e-17};
             *c = {0.964928619104771, -3.0345542681018625e-18}; break;
    case 18: *s = {0.2775567516463363, 1.7674070262791822e-17};
             *c = {0.9607092430155619, -2.807827063516729e-17}; break;
    case 19: *s = {0.29253334202332754, 7.516944930327352e-18};
             *c = {0.9562553235431753, -3.148450868841629e-17}; break;
    case 20: *s = {0.30743851458038085, 1.1004366442765296e-19};
             *c = {0.9515679480481722, -3.8614834675674123e-17}; break;
    case 21: *s = {0.3222686304333866, 2.093773358126606e-17};
             *c = {0.9466482608860534, -3.911683334934152e-17}; break;
    case 22: *s = {0.33702006902225307, 1.0312279860787216e-17};
             *c = {0.9414974631278811, -4.8523830236797095e-18}; break;
    case 23: *s = {0.3516892289948141, -2.5616208736069942e-17};
             *c = {0.9361168122670553, -5.2350302039683216e-17}; break;
    case 24: *s = {0.36627252908604757, -9.938814562106524e-18};
             *c = {0.9305076219123143, 4.488760003328074e-18}; break;
    case 25: *s = {0.38076640899239017, 2.1372528646211374e-17};
             *c = {0.924671261467036, 5.5444125388034563e-17}; break;
    case 26: *s = {0.39516733024093426, -1.9613487871414228e-17};
             *c = {0.9186091557949183, -4.0564150104514996e-17}; break;
    case 27: *s = {0.40947177705329507, -5.679403000091266e-18};
             *c = {0.9123227848721178, 2.6349040211413332e-17}; break;
    case 28: *s = {0.42367625720393803, -2.331800700068871e-17};
             *c = {0.9058136834259364, 4.2864666490805214e-17}; break;
    case 29: *s = {0.4377773028727551, 7.64345629962023e-18};
             *c = {0.8990834405601384, 9.076951775075616e-18}; break;
    case 30: *s = {0.4517714714916838, -8.234073942098903e-18};
             *c = {0.8921336993669944, 2.3160655211380166e-17}; break;
    case 31: *s = {0.46565534658516017, 1.459870391051426e-17};
             *c = {0.8849661565261433, -7.690557775987357e-18}; break;
    case 32: *s = {0.479425538604203, -5.103969860556013e-18};
             *c = {0.8775825618903728, -4.2623149864279997e-17}; break;
    case 33: *s = {0.49307868575392305, 5.605083973871755e-18};
             *c = {0.8699847180584174, 1.657385110740923e-17}; break;
    case 34: *s = {0.5066114548142574, -3.269413423618168e-17};
             *c = {0.8621744799348805, 4.4132427578105805e-18}; break;
    case 35: *s = {0.520020541953727, -3.983266745698455e-17};
             *c = {0.8541537542773854, 5.420565102675286e-18}; break;
    case 36: *s = {0.5333026735360201, 5.129318115032044e-17};
             *c = {0.8459244992310679, 1.549506647350329e-17}; break;
    case 37: *s = {0.5464546069192036, 8.399754840929507e-18};
             *c = {0.8374887238505236, 4.3337026043948396e-17}; break;
    case 38: *s = {0.5594731312473669, 1.575565514488728e-17};
             *c = {0.8288484876093257, 1.1163935406617444e-17}; break;
    case 39: *s = {0.5723550682345072, 2.6575872357215316e-17};
             *c = {0.820005899897234, -3.912431748209128e-17}; break;
    case 40: *s = {0.5850972729404622, -5.4883972461161805e-17};
             *c = {0.8109631195052179, -3.091333486122179e-17}; break;
    case 41: *s = {0.5976966345387015, 5.450323593054385e-17};
             *c = {0.8017223540984184, 4.0134533311087014e-17}; break;
    case 42: *s = {0.6101500770757914, -1.479826990758988e-17};
             *c = {0.7922858596771786, -2.9049779312834576e-17}; break;
    case 43: *s = {0.6224545602223437, -6.049035765709707e-18};
             *c = {0.7826559400262728, -1.474071641211487e-17}; break;
    case 44: *s = {0.6346070800152693, -3.4568582392624965e-17};
             *c = {0.7728349461524715, 4.231014921891023e-17}; break;
    case 45: *s = {0.6466046695911524, 4.567647714393289e-19};
             *c = {0.7628252757105762, 1.6672995021546628e-17}; break;
    case 46: *s = {0.6584443999105676, -3.7736386700306717e-17};
             *c = {0.7526293724180665, -1.2970993013150526e-17}; break;
    case 47: *s = {0.6701233804731629, 6.183536725574959e-18};
             *c = {0.7422497254585013, -1.2339303604869521e-17}; break;
    case 48: *s = {0.6816387600233341, 4.410467313197903e-17};
             *c = {0.7316888688738209, -1.0475824306512768e-17}; break;
    case 49: *s = {0.692987727246318, -5.3543290798909455e-17};
             *c = {0.7209493809456964, 3.494986701478816e-17}; break;
    case 50: *s = {0.7041675114545337, -3.94095700584825e-17};
             *c = {0.7100338835660797, 1.505272211891291e-17}; break;
    case 51: *s = {0.7151753832640076, -1.466099578328228e-17};
             *c = {0.6989450415971057, -5.5261332036460915e-18}; break;
    default: *s = {0, 0};  // j = 0 is not looked up; j <= 51 for |x| <= 0.8
             *c = {1, 0}; break;
  }
}

/// sin and cos of x (radians), |x| <= 0.8, correctly rounded but for about 2 cases in 10^4
/// (the C library's are off in about one in 400). Latitudes need this: one ulp in the sine of
/// a latitude moves a line's end by up to 0.7 nm, more than the tolerance of short lines.
///
/// Near zero (|x| <= 1/128) the Taylor series of sin x - x and cos x - 1 are added to x and 1
/// (terms to x^9 and x^8; the first left out is below 2^-60 of the result). Elsewhere
/// x = c + d with c = j/64 from a table and |d| <= 1/128 exact (Sterbenz):
///   sin x = S + C d + (S (cos d - 1) + C (sin d - d)),
///   cos x = C - S d + (C (cos d - 1) - S (sin d - d)),
/// with the table's S, C as hi + lo, C d and S d exact products, and the rest (at most 2^-15 of
/// the result) in plain double, where its rounding is far below the result's last place.
QTMV_HD inline void sincos_kernel(double x, double* sinx, double* cosx) {
  constexpr double kTableStep = 64.0;  // table at multiples of 1/64
  const double ax = ::fabs(x);
  const int j = static_cast<int>(ax * kTableStep + 0.5);
  const double d = j == 0 ? ax : ax - static_cast<double>(j) * (1.0 / kTableStep);
  const double z = d * d;
  // sin d - d = d z (-1/3! + z/5! - z^2/7! + z^3/9!); cos d - 1 = z (-1/2! + z/4! - z^2/6! + z^3/8!).
  const double sin_tail = d * (z * (-1.0 / 6.0 + z * (1.0 / 120.0 + z * (-1.0 / 5040.0 + z * (1.0 / 362880.0)))));
  const double cos_tail = z * (-1.0 / 2.0 + z * (1.0 / 24.0 + z * (-1.0 / 720.0 + z * (1.0 / 40320.0))));
  double s, c;
  if (j == 0) {
    s = d + sin_tail;
    c = 1 + cos_tail;
  } else {
    DoubleDouble ts, tc;
    sincos_sixtyfourths(j, &ts, &tc);
    // sin: S_hi + C_hi d exactly as s0 + e (fast two-sum: S_hi > 2 |C_hi d|), then the rest.
    double plo;
    double p = two_product(tc.hi, d, &plo);
    double s0 = ts.hi + p;
    double e = p - (s0 - ts.hi);
    s = s0 + (((e + plo) + (ts.lo + tc.lo * d)) + (ts.hi * cos_tail + tc.hi * sin_tail));
    // cos: C_hi - S_hi d likewise (C_hi > 0.69 > |S_hi d|).
    p = two_product(ts.hi, d, &plo);
    s0 = tc.hi - p;
    e = (tc.hi - s0) - p;
    c = s0 + (((e - plo) + (tc.lo - ts.lo * d)) + (tc.hi * cos_tail - ts.hi * sin_tail));
  }
  *sinx = ::copysign(1.0, x) < 0 ? -s : s;
  *cosx = c;
}

/// sin and cos of x (radians), |x| <= 8 pi: x less its nearest multiple of pi/2 (Cody and
/// Waite: pi/2 in three parts, the first of 33 bits so that n times it is exact), then
/// sincos_kernel.
QTMV_HD inline void sincos_rad(double x, double* sinx, double* cosx) {
  constexpr double kTwoOverPi = 0.6366197723675814;
  constexpr double kHalfPi1 = 1.5707963267341256;     // pi/2 to 33 bits
  constexpr double kHalfPi2 = 6.077100506506192e-11;  // the next bits
  constexpr double kHalfPi3 = 3.5215598651832e-27;    // the rest
  const double qn = x * kTwoOverPi;
  const int n = static_cast<int>(qn >= 0 ? qn + 0.5 : qn - 0.5);
  const double nd = static_cast<double>(n);
  const double r = ((x - nd * kHalfPi1) - nd * kHalfPi2) - nd * kHalfPi3;
  double s, c;
  sincos_kernel(r, &s, &c);
  switch (((n % 4) + 4) % 4) {
    case 0: *sinx = s; *cosx = c; break;
    case 1: *sinx = c; *cosx = -s; break;
    case 2: *sinx = -s; *cosx = -c; break;
    default: *sinx = -c; *cosx = s; break;
  }
}

/// Error-free sum: returns s = round(u + v) and sets *t = (u + v) - s exactly (Knuth).
QTMV_HD inline double sum_exact(double u, double v, double* t) {
  const double s = u + v;
  double up = s - v;
  double vpp = s - up;
  up -= u;
  vpp -= v;
  *t = s != 0 ? 0 - (up + vpp) : s;
  return s;
}

/// remainder(x, m) (m > 0), taken only where |x| > m / 2: within [-m/2, m/2] it is x itself,
/// to the bit (a quotient of exactly 1/2 rounds to the even 0), and remainder is slow beside the
/// rest of a geodesic's arithmetic.
QTMV_HD inline double remainder_of(double x, double m) { return ::fabs(x) <= 0.5 * m ? x : ::remainder(x, m); }

/// Difference y - x of two angles (degrees) reduced to [-180, 180], exactly as hi + *e.
QTMV_HD inline double ang_diff(double x, double y, double* e) {
  double t;
  double d = sum_exact(remainder_of(-x, kFullTurn), remainder_of(y, kFullTurn), &t);
  // This second sum changes d only if |d| < 128, so no further remainder is needed.
  d = sum_exact(remainder_of(d, kFullTurn), t, &t);
  // The sign of d = -180, 0, 180: from y - x if t = 0, else opposite to t.
  if (d == 0 || ::fabs(d) == kHalfTurn) d = ::copysign(d, t == 0 ? y - x : -t);
  *e = t;
  return d;
}

/// Rounds an angle (degrees) so that tiny values become exactly representable steps of
/// 2^-57: angles this close to zero count as zero (e.g. points on the equator).
QTMV_HD inline double ang_round(double x) {
  constexpr double kZ = 1.0 / 16.0;
  double y = ::fabs(x);
  const double w = kZ - y;
  y = w > 0 ? kZ - w : y;
  return ::copysign(y, x);
}

/// Latitude (degrees) or nan if out of [-90, 90].
QTMV_HD inline double lat_fix(double x) { return ::fabs(x) > kQuarterTurn ? ::nan("") : x; }

/// sin and cos of (x + t) degrees, x reduced exactly by its nearest multiple of 90 degrees
/// first (remainder is exact), t a small correction added if round_sum. With the signed zeros
/// of GeographicLib.
QTMV_HD inline void sincos_deg_reduced(double x, double t, bool round_sum, double* sinx, double* cosx) {
  const double r0 = remainder_of(x, kQuarterTurn);  // |r0| <= 45
  const int q = static_cast<int>((x - r0) / kQuarterTurn);  // x - r0 is an exact multiple of 90
  const double r = round_sum ? ang_round(r0 + t) : r0;
  double s, c;
  sincos_kernel(r * grid::kDegree, &s, &c);  // the same argument as GeographicLib's sincosd
  switch (((q % 4) + 4) % 4) {
    case 0: *sinx = s; *cosx = c; break;
    case 1: *sinx = c; *cosx = -s; break;
    case 2: *sinx = -s; *cosx = -c; break;
    default: *sinx = -c; *cosx = s; break;
  }
  *cosx += 0.0;  // -0 to +0
  if (*sinx == 0) *sinx = ::copysign(*sinx, x);
}

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

/// Distance s12 / b of a geodesic given sig12 and its ends on the auxiliary sphere; with
/// want_reduced also the reduced length m12 / b (GeographicLib's Lengths with DISTANCE and/or
/// REDUCEDLENGTH; the two formulas for J12 differ in their rounding, so both are kept).
QTMV_HD inline void lengths(double eps, double sig12, double ssig1, double csig1, double dn1, double ssig2,
                            double csig2, double dn2, bool want_distance, bool want_reduced, double* s12b,
                            double* m12b) {
  double ca[kGeodesicOrder + 1], cb[kGeodesicOrder + 1];
  double a1 = a1m1(eps);
  c1_coeffs(eps, ca);
  double m0x = 0, a2 = 0, j12 = 0;
  if (want_reduced) {
    a2 = a2m1(eps);
    c2_coeffs(eps, cb);
    m0x = a1 - a2;
    a2 = 1 + a2;
  }
  a1 = 1 + a1;
  if (want_distance) {
    const double b1 = sin_cos_series(true, ssig2, csig2, ca, kGeodesicOrder) -
                      sin_cos_series(true, ssig1, csig1, ca, kGeodesicOrder);
    *s12b = a1 * (sig12 + b1);
    if (want_reduced) {
      const double b2 = sin_cos_series(true, ssig2, csig2, cb, kGeodesicOrder) -
                        sin_cos_series(true, ssig1, csig1, cb, kGeodesicOrder);
      j12 = m0x * sig12 + (a1 * b1 - a2 * b2);
    }
  } else if (want_reduced) {
    for (int l = 1; l <= kGeodesicOrder; ++l) cb[l] = a1 * ca[l] - a2 * cb[l];
    j12 = m0x * sig12 + (sin_cos_series(true, ssig2, csig2, cb, kGeodesicOrder) -
                         sin_cos_series(true, ssig1, csig1, cb, kGeodesicOrder));
  }
  if (want_reduced) {
    // The parentheses keep the cancellation exact for coincident points.
    *m12b = dn2 * (csig1 * ssig2) - dn1 * (ssig1 * csig2) - csig1 * csig2 * j12;
  }
}

/// Positive root k of k^4 + 2 k^3 - (x^2 + y^2 - 1) k^2 - 2 y^2 k - y^2 = 0 (Karney's
/// astroid), for the start of nearly antipodal lines.
QTMV_HD inline double astroid(double x, double y) {
  const double p = sq(x), q = sq(y), r = (p + q - 1) / 6;
  if (q == 0 && r <= 0) return 0;  // y = 0 with |x| <= 1
  // Multiplied through by r^3 and r to avoid dividing by r = 0.
  const double s = p * q / 4;  // r^3 s
  const double r2 = sq(r), r3 = r * r2;
  const double disc = s * (s + 2 * r3);  // zero on the evolute p^(1/3) + q^(1/3) = 1
  double u = r;
  if (disc >= 0) {
    double t3 = s + r3;
    // The sign of the sqrt that maximises |t3| avoids cancellation; u does not depend on it.
    t3 += t3 < 0 ? -::sqrt(disc) : ::sqrt(disc);  // (r t)^3
    const double t = det_cbrt(t3);                  // r t
    u += t + (t != 0 ? r2 / t : 0);
  } else {
    // t is complex, u real: the cube root that avoids cancellation.
    const double ang = det_atan2(::sqrt(-disc), -(s + r3));
    double sa, ca;
    sincos_rad(ang / 3, &sa, &ca);
    u += 2 * r * ca;
  }
  const double v = ::sqrt(sq(u) + q);             // positive
  const double uv = u < 0 ? q / (v - u) : u + v;  // u + v without cancellation, positive
  const double w = (uv - q) / (2 * v);
  return uv / (::sqrt(uv + sq(w)) + w);
}

/// The ends of one geodesic on the auxiliary sphere, kept between Lambda12 and the caller.
struct LineState {
  double salp2, calp2;  ///< azimuth at point 2
  double sig12;         ///< arc length on the auxiliary sphere (radians)
  double ssig1, csig1, ssig2, csig2;
  double eps;
  double domg12;  ///< lam12 - omg12 (radians)
};

/// The longitude difference lam12 (radians) of the geodesic leaving point 1 at azimuth alp1,
/// less the target lam120 (given by its sin and cos), and d(lam12)/d(alp1) if diffp.
QTMV_HD inline double lambda12(const Ellipsoid& e, double sbet1, double cbet1, double dn1, double sbet2, double cbet2,
                               double dn2, double salp1, double calp1, double slam120, double clam120,
                               bool diffp, double* dlam12, LineState* st) {
  if (sbet1 == 0 && calp1 == 0) calp1 = -kTiny;  // break the degeneracy of the equatorial line
  const double salp0 = salp1 * cbet1;           // sin(alp1) cos(bet1) = sin(alp0)
  const double calp0 = det_hypot(calp1, salp1 * sbet1);
  // tan(bet1) = tan(sig1) cos(alp1); tan(omg1) = sin(alp0) tan(sig1).
  st->ssig1 = sbet1;
  const double somg1 = salp0 * sbet1;
  st->csig1 = calp1 * cbet1;
  const double comg1 = calp1 * cbet1;
  norm2(&st->ssig1, &st->csig1);
  // Symmetries for |bet2| = -bet1, where the Newton iteration could be singular.
  st->salp2 = cbet2 != cbet1 ? salp0 / cbet2 : salp1;
  st->calp2 = cbet2 != cbet1 || ::fabs(sbet2) != -sbet1
                  ? ::sqrt(sq(calp1 * cbet1) + (cbet1 < -sbet1 ? (cbet2 - cbet1) * (cbet1 + cbet2)
                                                                 : (sbet1 - sbet2) * (sbet1 + sbet2))) /
                        cbet2
                  : ::fabs(calp1);
  st->ssig2 = sbet2;
  const double somg2 = salp0 * sbet2;
  st->csig2 = st->calp2 * cbet2;
  const double comg2 = st->calp2 * cbet2;
  norm2(&st->ssig2, &st->csig2);
  // sig12 = sig2 - sig1 and omg12 = omg2 - omg1, in [0, pi].
  st->sig12 = det_atan2(max_of(0.0, st->csig1 * st->ssig2 - st->ssig1 * st->csig2) + 0.0,
                        st->csig1 * st->csig2 + st->ssig1 * st->ssig2);
  const double somg12 = max_of(0.0, comg1 * somg2 - somg1 * comg2) + 0.0;
  const double comg12 = comg1 * comg2 + somg1 * somg2;
  // eta = omg12 - lam120
  const double eta = det_atan2(somg12 * clam120 - comg12 * slam120, comg12 * clam120 + somg12 * slam120);
  const double k2 = sq(calp0) * e.ep2;
  st->eps = eps_of(k2);
  double c3[kGeodesicOrder];
  c3_coeffs(e, st->eps, c3);
  const double b312 = sin_cos_series(true, st->ssig2, st->csig2, c3, kGeodesicOrder - 1) -
                      sin_cos_series(true, st->ssig1, st->csig1, c3, kGeodesicOrder - 1);
  st->domg12 = -e.f * a3f(e, st->eps) * salp0 * (st->sig12 + b312);
  const double lam12 = eta + st->domg12;
  if (diffp) {
    if (st->calp2 == 0) {
      *dlam12 = -2 * e.f1 * dn1 / sbet1;
    } else {
      double unused = 0, m12b = 0;
      lengths(st->eps, st->sig12, st->ssig1, st->csig1, dn1, st->ssig2, st->csig2, dn2, false, true, &unused,
              &m12b);
      *dlam12 = m12b * (e.f1 / (st->calp2 * cbet2));
    }
  }
  return lam12;
}

/// Starting azimuth alp1 for Newton's method. Returns sig12 >= 0 (and
/// sets alp2 and dnm) for really short lines, which need no iteration, else -1.
QTMV_HD inline double inverse_start(const Ellipsoid& e, double sbet1, double cbet1, double sbet2, double cbet2,
                                    double lam12, double slam12, double clam12, double* salp1, double* calp1,
                                    double* salp2, double* calp2, double* dnm) {
  double sig12 = -1;
  // bet12 = bet2 - bet1 in [0, pi); bet12a = bet2 + bet1 in (-pi, 0]
  const double sbet12 = sbet2 * cbet1 - cbet2 * sbet1;
  const double cbet12 = cbet2 * cbet1 + sbet2 * sbet1;
  const double sbet12a = sbet2 * cbet1 + cbet2 * sbet1;
  const bool shortline = cbet12 >= 0 && sbet12 < 0.5 && cbet2 * lam12 < 0.5;
  double somg12, comg12;
  if (shortline) {
    // sin((bet1 + bet2) / 2)^2 = (sbet1 + sbet2)^2 / ((sbet1 + sbet2)^2 + (cbet1 + cbet2)^2)
    double sbetm2 = sq(sbet1 + sbet2);
    sbetm2 /= sbetm2 + sq(cbet1 + cbet2);
    *dnm = ::sqrt(1 + e.ep2 * sbetm2);
    const double omg12 = lam12 / (e.f1 * *dnm);
    sincos_rad(omg12, &somg12, &comg12);
  } else {
    somg12 = slam12;
    comg12 = clam12;
  }
  *salp1 = cbet2 * somg12;
  *calp1 = comg12 >= 0 ? sbet12 + cbet2 * sbet1 * sq(somg12) / (1 + comg12)
                       : sbet12a - cbet2 * sbet1 * sq(somg12) / (1 - comg12);
  const double ssig12 = det_hypot(*salp1, *calp1);
  const double csig12 = sbet1 * sbet2 + cbet1 * cbet2 * comg12;
  constexpr double kAstroidMaxN = 0.1;  // skip the astroid for more eccentric ellipsoids
  if (shortline && ssig12 < e.etol2) {
    // Really short lines: the spherical solution with the mean dn is accurate enough.
    *salp2 = cbet1 * somg12;
    *calp2 = sbet12 - cbet1 * sbet2 * (comg12 >= 0 ? sq(somg12) / (1 + comg12) : 1 - comg12);
    norm2(salp2, calp2);
    sig12 = det_atan2(ssig12, csig12);
  } else if (::fabs(e.n) > kAstroidMaxN || csig12 >= 0 ||
             ssig12 >= 6 * ::fabs(e.n) * grid::kPi * sq(cbet1)) {
    // The zeroth-order spherical estimate will do.
  } else {
    // Nearly antipodal (oblate only): scale lam12 and bet2 to the astroid's x, y, with the
    // antipode at the origin and the singular point at y = 0, x = -1.
    const double lam12x = det_atan2(-slam12, -clam12);  // lam12 - pi
    const double k2 = sq(sbet1) * e.ep2;
    const double lamscale = e.f * cbet1 * a3f(e, eps_of(k2)) * grid::kPi;
    const double betscale = lamscale * cbet1;
    const double x = lam12x / lamscale;
    const double y = sbet12a / betscale;
    if (y > -kTol1 && x > -1 - kXThresh) {
      // The strip near the cut.
      *salp1 = min_of(1.0, -x);
      *calp1 = -::sqrt(1 - sq(*salp1));
    } else {
      // omg12 near pi from the astroid, then the spherical formula for alp1.
      const double k = astroid(x, y);
      const double omg12a = lamscale * (-x * k / (1 + k));
      double somg12a, comg12a;
      sincos_rad(omg12a, &somg12a, &comg12a);
      somg12 = somg12a;
      comg12 = -comg12a;
      *salp1 = cbet2 * somg12;
      *calp1 = sbet12a - cbet2 * sbet1 * sq(somg12) / (1 - comg12);
    }
  }
  // Sanity check on the start; the backwards test lets nan through.
  if (!(*salp1 <= 0)) {
    norm2(salp1, calp1);
  } else {
    *salp1 = 1;
    *calp1 = 0;
  }
  return sig12;
}

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

/// Inverse geodesic problem between (lat1, lon1) and (lat2, lon2) (degrees, |lat| <= 90, any
/// longitude): the distance s12 (metres) and the area S12 (square metres) between the
/// geodesic and the equator, as GeographicLib's Geodesic::GenInverse with DISTANCE | AREA.
QTMV_HD inline InverseSolution geodesic_inverse(const Ellipsoid& e, double lat1, double lon1, double lat2,
                                                double lon2) {
  using namespace detail;
  // Longitude difference, exactly as lon12 + lon12s, made non-negative.
  double lon12s;
  double lon12 = ang_diff(lon1, lon2, &lon12s);
  int lonsign = sign_bit(lon12) ? -1 : 1;
  lon12 *= lonsign;
  lon12s *= lonsign;
  const double lam12 = lon12 * grid::kDegree;
  double slam12, clam12;
  sincos_deg_reduced(lon12, lon12s, true, &slam12, &clam12);
  lon12s = (kHalfTurn - lon12) - lon12s;  // the supplementary longitude difference

  // Latitudes this close to the equator count as on it.
  lat1 = ang_round(lat_fix(lat1));
  lat2 = ang_round(lat_fix(lat2));
  // Canonical form: 0 <= lon12 <= 180, -90 <= lat1 <= -0, lat1 <= lat2 <= -lat1. The signs
  // record the transformation (1: none).
  const int swapp = ::fabs(lat1) < ::fabs(lat2) || lat2 != lat2 ? -1 : 1;
  if (swapp < 0) {
    lonsign *= -1;
    swap_values(&lat1, &lat2);
  }
  const int latsign = sign_bit(lat1) ? 1 : -1;
  lat1 *= latsign;
  lat2 *= latsign;

  // Reduced latitudes; cbet = +tiny at the poles.
  double sbet1, cbet1, sbet2, cbet2;
  sincos_deg_reduced(lat1, 0, false, &sbet1, &cbet1);
  sbet1 *= e.f1;
  norm2(&sbet1, &cbet1);
  cbet1 = max_of(kTiny, cbet1);
  sincos_deg_reduced(lat2, 0, false, &sbet2, &cbet2);
  sbet2 *= e.f1;
  norm2(&sbet2, &cbet2);
  cbet2 = max_of(kTiny, cbet2);
  // Force bet2 = +/- bet1 exactly where the sensitive measure of |bet1| - |bet2| vanishes.
  if (cbet1 < -sbet1) {
    if (cbet2 == cbet1) sbet2 = ::copysign(sbet1, sbet2);
  } else {
    if (::fabs(sbet2) == -sbet1) cbet2 = cbet1;
  }
  const double dn1 = ::sqrt(1 + e.ep2 * sq(sbet1));
  const double dn2 = ::sqrt(1 + e.ep2 * sq(sbet2));

  double s12x = 0, salp1 = 0, calp1 = 0, salp2 = 0, calp2 = 0;
  bool meridian = lat1 == -kQuarterTurn || slam12 == 0;
  if (meridian) {
    // Both ends on one full meridian: the geodesic may run along it.
    calp1 = clam12;
    salp1 = slam12;
    calp2 = 1;
    salp2 = 0;
    // tan(bet) = tan(sig) cos(alp)
    const double ssig1 = sbet1, csig1 = calp1 * cbet1;
    const double ssig2 = sbet2, csig2 = calp2 * cbet2;
    double sig12 = det_atan2(max_of(0.0, csig1 * ssig2 - ssig1 * csig2) + 0.0, csig1 * csig2 + ssig1 * ssig2);
    double m12x = 0;
    lengths(e.n, sig12, ssig1, csig1, dn1, ssig2, csig2, dn2, true, true, &s12x, &m12x);
    // m12 < 0 means a meridian that is not a shortest path (prolate, nearly antipodal).
    if (sig12 < 1 || m12x >= 0) {
      // Zero length geodesics, and no negative s12 for short lines.
      if (sig12 < 3 * kTiny || (sig12 < kTol0 && (s12x < 0 || m12x < 0))) {
        sig12 = m12x = s12x = 0;
      }
      s12x *= e.b;
    } else {
      meridian = false;
    }
  }

  double omg12 = 0, somg12 = 2, comg12 = 0;  // somg12 = 2: still to be computed
  if (!meridian && sbet1 == 0 && (e.f <= 0 || lon12s >= e.f * kHalfTurn)) {
    // Along the equator.
    calp1 = calp2 = 0;
    salp1 = salp2 = 1;
    s12x = e.a * lam12;
    omg12 = lam12 / e.f1;
  } else if (!meridian) {
    double dnm = 0;
    const double sig12 = inverse_start(e, sbet1, cbet1, sbet2, cbet2, lam12, slam12, clam12, &salp1, &calp1,
                                       &salp2, &calp2, &dnm);
    if (sig12 >= 0) {
      // Really short lines: no iteration.
      s12x = sig12 * e.b * dnm;
      omg12 = lam12 / (e.f1 * dnm);
    } else {
      // Newton's method on lambda12(alp1) - lam12 = 0, which has one root in (0, pi) with a
      // positive slope. (alp1a, alp1b) brackets the root; a step that leaves it, or a
      // non-positive slope, falls back to bisection.
      LineState st{};
      double salp1a = kTiny, calp1a = 1, salp1b = kTiny, calp1b = -1;
      bool tripn = false, tripb = false;
      for (int numit = 0;; ++numit) {
        double dv = 0;
        const double v = lambda12(e, sbet1, cbet1, dn1, sbet2, cbet2, dn2, salp1, calp1, slam12, clam12,
                                  numit < kMaxIt1, &dv, &st);
        // The reversed test lets nan escape.
        if (tripb || !(::fabs(v) >= (tripn ? 8 : 1) * kTol0) || numit == kMaxIt2) break;
        if (v > 0 && (numit > kMaxIt1 || calp1 / salp1 > calp1b / salp1b)) {
          salp1b = salp1;
          calp1b = calp1;
        } else if (v < 0 && (numit > kMaxIt1 || calp1 / salp1 < calp1a / salp1a)) {
          salp1a = salp1;
          calp1a = calp1;
        }
        if (numit < kMaxIt1 && dv > 0) {
          const double dalp1 = -v / dv;
          if (::fabs(dalp1) < grid::kPi) {
            double sdalp1, cdalp1;
            sincos_rad(dalp1, &sdalp1, &cdalp1);
            const double nsalp1 = salp1 * cdalp1 + calp1 * sdalp1;
            if (nsalp1 > 0) {
              calp1 = calp1 * cdalp1 - salp1 * sdalp1;
              salp1 = nsalp1;
              norm2(&salp1, &calp1);
              // Where the slope -> 0 convergence is not quadratic: test against epsilon.
              tripn = ::fabs(v) <= 16 * kTol0;
              continue;
            }
          }
        }
        // Bisection of the bracket.
        salp1 = (salp1a + salp1b) / 2;
        calp1 = (calp1a + calp1b) / 2;
        norm2(&salp1, &calp1);
        tripn = false;
        tripb = (::fabs(salp1a - salp1) + (calp1a - calp1) < kTolB || ::fabs(salp1 - salp1b) + (calp1 - calp1b) < kTolB);
      }
      salp2 = st.salp2;
      calp2 = st.calp2;
      double unused = 0;
      lengths(st.eps, st.sig12, st.ssig1, st.csig1, dn1, st.ssig2, st.csig2, dn2, true, false, &s12x, &unused);
      s12x *= e.b;
      // omg12 = lam12 - domg12
      double sdomg12, cdomg12;
      sincos_rad(st.domg12, &sdomg12, &cdomg12);
      somg12 = slam12 * cdomg12 - clam12 * sdomg12;
      comg12 = clam12 * cdomg12 + slam12 * sdomg12;
    }
  }

  InverseSolution out{};
  out.s12 = 0.0 + s12x;  // -0 to 0

  // Area: S12 = c2 alp12 + A4 (B42 - B41).
  const double salp0 = salp1 * cbet1;
  const double calp0 = det_hypot(calp1, salp1 * sbet1);  // > 0
  double area = 0;
  if (calp0 != 0 && salp0 != 0) {
    double ssig1 = sbet1, csig1 = calp1 * cbet1;
    double ssig2 = sbet2, csig2 = calp2 * cbet2;
    const double k2 = sq(calp0) * e.ep2;
    const double eps = eps_of(k2);
    const double a4 = sq(e.a) * calp0 * salp0 * e.e2;  // a^2 e^2 cos(alp0) sin(alp0)
    norm2(&ssig1, &csig1);
    norm2(&ssig2, &csig2);
    double c4[kGeodesicOrder];
    c4_coeffs(e, eps, c4);
    const double b41 = sin_cos_series(false, ssig1, csig1, c4, kGeodesicOrder);
    const double b42 = sin_cos_series(false, ssig2, csig2, c4, kGeodesicOrder);
    area = a4 * (b42 - b41);
  }  // else sig1 and sig2 are indeterminate on the equator: the series term is 0
  if (!meridian && somg12 == 2) sincos_rad(omg12, &somg12, &comg12);
  constexpr double kCosThreeQuarterPi = -0.7071;
  constexpr double kMaxSinDiff = 1.75;
  double alp12;
  if (!meridian && comg12 > kCosThreeQuarterPi && sbet2 - sbet1 < kMaxSinDiff) {
    // tan(alp12/2) = tan(omg12/2) (tan(bet1/2) + tan(bet2/2)) / (1 + tan(bet1/2) tan(bet2/2)),
    // with tan(x/2) = sin(x) / (1 + cos(x)).
    const double domg12 = 1 + comg12, dbet1 = 1 + cbet1, dbet2 = 1 + cbet2;
    alp12 = 2 * det_atan2(somg12 * (sbet1 * dbet2 + sbet2 * dbet1), domg12 * (sbet1 * sbet2 + dbet1 * dbet2));
  } else {
    // alp12 = alp2 - alp1
    double salp12 = salp2 * calp1 - calp2 * salp1;
    double calp12 = calp2 * calp1 + salp2 * salp1;
    // alp1 = +/-180 with alp2 = 0 must give alp12 = -180: fix the sign of the zero.
    if (salp12 == 0 && calp12 < 0) {
      salp12 = kTiny * calp1;
      calp12 = -1;
    }
    alp12 = det_atan2(salp12, calp12);
  }
  area += e.c2 * alp12;
  area *= swapp * lonsign * latsign;
  out.S12 = area + 0.0;  // -0 to 0
  return out;
}

}  // namespace qtmv::measure
