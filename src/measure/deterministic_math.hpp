// Deterministic elementary functions for the writers' geodesics (geodesic_math.hpp), identical
// on the CPU and on CUDA devices: hypot, atan2, cbrt, sin and cos (of radians, and of degrees
// reduced exactly), and the exact angle arithmetic of GeographicLib's Math.
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

namespace detail {

constexpr double kEpsilon = 0x1p-52;        ///< DBL_EPSILON
constexpr double kTiny = 0x1p-511;          ///< sqrt(DBL_MIN): underflow guard
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

}  // namespace detail

}  // namespace qtmv::measure
