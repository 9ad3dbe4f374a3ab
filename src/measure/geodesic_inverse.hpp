// The inverse geodesic problem (Karney 2013) on an Ellipsoid (geodesic_series.hpp), identical on
// the CPU and on CUDA devices: the lengths, the astroid's start for nearly antipodal lines, the
// Newton iteration on lambda12, and the area S12, in GeographicLib's steps and order.
#pragma once

#include <cmath>

#include "grid/qtm_host_device.hpp"
#include "grid/qtm_math.hpp"
#include "measure/deterministic_math.hpp"
#include "measure/geodesic_series.hpp"

namespace qtmv::measure {

/// Result of the inverse problem.
struct InverseSolution {
  double s12;  ///< geodesic distance (metres)
  double S12;  ///< area between the geodesic and the equator (square metres), signed as GeographicLib's
};

namespace detail {

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

/// The ends of an inverse problem in Karney's canonical form, 0 <= lon12 <= 180,
/// -90 <= lat1 <= -0, lat1 <= lat2 <= -lat1, with the signs that record the transformation
/// (1: none).
struct CanonicalEnds {
  double lam12;           ///< longitude difference (radians)
  double slam12, clam12;  ///< its sine and cosine
  double lon12s;          ///< the supplementary longitude difference (degrees)
  double lat1;            ///< (degrees)
  double sbet1, cbet1, sbet2, cbet2;  ///< the reduced latitudes' sines and cosines
  double dn1, dn2;
  int lonsign, swapp, latsign;
};

/// An inverse problem reduced to Karney's canonical form: all its solution depends on (the
/// latitudes and the longitude difference, each exact) and the signs that undo the reduction.
/// Problems of the same canonical form (mirror images, a shift in longitude) have solutions of
/// the same bits but for those signs.
struct CanonicalProblem {
  double lat1, lat2;     ///< (degrees) -90 <= lat1 <= -0, lat1 <= lat2 <= -lat1
  double lon12, lon12s;  ///< the longitude difference, 0 <= lon12 <= 180, exactly lon12 + lon12s (degrees)
  int lonsign, swapp, latsign;
};

/// (lat1, lon1) to (lat2, lon2) (degrees) as a CanonicalProblem.
QTMV_HD inline CanonicalProblem canonical_problem(double lat1, double lon1, double lat2, double lon2) {
  // Longitude difference, exactly as lon12 + lon12s, made non-negative.
  double lon12s;
  double lon12 = ang_diff(lon1, lon2, &lon12s);
  int lonsign = sign_bit(lon12) ? -1 : 1;
  lon12 *= lonsign;
  lon12s *= lonsign;
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
  return {lat1, lat2, lon12, lon12s, lonsign, swapp, latsign};
}

/// A canonical problem's ends, with their reduced latitudes.
QTMV_HD inline CanonicalEnds canonical_ends(const Ellipsoid& e, const CanonicalProblem& p) {
  const double lon12 = p.lon12;
  const double lam12 = lon12 * grid::kDegree;
  double slam12, clam12;
  sincos_deg_reduced(lon12, p.lon12s, true, &slam12, &clam12);
  const double lon12s = (kHalfTurn - lon12) - p.lon12s;  // the supplementary longitude difference
  const double lat1 = p.lat1, lat2 = p.lat2;

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
  return {lam12, slam12, clam12, lon12s, lat1, sbet1, cbet1, sbet2, cbet2, dn1, dn2, p.lonsign, p.swapp, p.latsign};
}

/// The geodesic between canonical ends: its distance s12x (metres), its azimuths at both ends,
/// and omg12, the longitude difference on the auxiliary sphere, where the area needs it.
struct InverseLine {
  double s12x = 0, salp1 = 0, calp1 = 0, salp2 = 0, calp2 = 0;
  double omg12 = 0, somg12 = 2, comg12 = 0;  // somg12 = 2: still to be computed
  bool meridian = false;  ///< along the meridian of both ends
};

/// Both ends on one full meridian: the geodesic may run along it. Clears line->meridian where
/// the meridian is not a shortest path.
QTMV_HD inline void meridian_line(const Ellipsoid& e, const CanonicalEnds& ends, InverseLine* line) {
  const double sbet1 = ends.sbet1, cbet1 = ends.cbet1, sbet2 = ends.sbet2, cbet2 = ends.cbet2;
  const double dn1 = ends.dn1, dn2 = ends.dn2;
  double &s12x = line->s12x, &salp1 = line->salp1, &calp1 = line->calp1, &salp2 = line->salp2,
         &calp2 = line->calp2;
  calp1 = ends.clam12;
  salp1 = ends.slam12;
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
    line->meridian = false;
  }
}

/// Newton's method on lambda12(alp1) - lam12 = 0, which has one root in (0, pi) with a
/// positive slope, from the start (*salp1_io, *calp1_io), which becomes the root. (alp1a,
/// alp1b) brackets the root; a step that leaves it, or a non-positive slope, falls back to
/// bisection. Returns the line's state at the root.
QTMV_HD inline LineState newton_alp1(const Ellipsoid& e, const CanonicalEnds& ends, double* salp1_io,
                                     double* calp1_io) {
  const double sbet1 = ends.sbet1, cbet1 = ends.cbet1, sbet2 = ends.sbet2, cbet2 = ends.cbet2;
  const double dn1 = ends.dn1, dn2 = ends.dn2, slam12 = ends.slam12, clam12 = ends.clam12;
  double &salp1 = *salp1_io, &calp1 = *calp1_io;
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
  return st;
}

/// A line neither along a meridian nor along the equator: the spherical start (inverse_start),
/// which settles really short lines, else Newton's method (newton_alp1).
QTMV_HD inline void general_line(const Ellipsoid& e, const CanonicalEnds& ends, InverseLine* line) {
  const double sbet1 = ends.sbet1, cbet1 = ends.cbet1, sbet2 = ends.sbet2, cbet2 = ends.cbet2;
  const double dn1 = ends.dn1, dn2 = ends.dn2, lam12 = ends.lam12, slam12 = ends.slam12, clam12 = ends.clam12;
  double &s12x = line->s12x, &salp1 = line->salp1, &calp1 = line->calp1, &salp2 = line->salp2,
         &calp2 = line->calp2;
  double &omg12 = line->omg12, &somg12 = line->somg12, &comg12 = line->comg12;
  double dnm = 0;
  const double sig12 = inverse_start(e, sbet1, cbet1, sbet2, cbet2, lam12, slam12, clam12, &salp1, &calp1,
                                     &salp2, &calp2, &dnm);
  if (sig12 >= 0) {
    // Really short lines: no iteration.
    s12x = sig12 * e.b * dnm;
    omg12 = lam12 / (e.f1 * dnm);
  } else {
    const LineState st = newton_alp1(e, ends, &salp1, &calp1);
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

/// The area S12 (square metres) between the line and the equator, of the canonical problem
/// (the signs not applied).
QTMV_HD inline double inverse_area(const Ellipsoid& e, const CanonicalEnds& ends, const InverseLine& line) {
  const double sbet1 = ends.sbet1, cbet1 = ends.cbet1, sbet2 = ends.sbet2, cbet2 = ends.cbet2;
  const double salp1 = line.salp1, calp1 = line.calp1, salp2 = line.salp2, calp2 = line.calp2;
  const bool meridian = line.meridian;
  double somg12 = line.somg12, comg12 = line.comg12;
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
  if (!meridian && somg12 == 2) sincos_rad(line.omg12, &somg12, &comg12);
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
  return area;  // of the canonical problem: CanonicalProblem's signs still to apply
}

}  // namespace detail

using detail::CanonicalProblem;
using detail::canonical_problem;

/// The solution of a canonical problem before its signs: the distance, and the area as
/// inverse_area leaves it.
struct CanonicalSolution {
  double s12;   ///< (metres)
  double area;  ///< (square metres) of the canonical problem
};

/// Solves a canonical problem (GeographicLib's Geodesic::GenInverse with DISTANCE | AREA, from
/// its canonical form on).
QTMV_HD inline CanonicalSolution solve_canonical(const Ellipsoid& e, const CanonicalProblem& p) {
  using namespace detail;
  const CanonicalEnds ends = canonical_ends(e, p);
  InverseLine line;
  line.meridian = ends.lat1 == -kQuarterTurn || ends.slam12 == 0;
  if (line.meridian) meridian_line(e, ends, &line);
  if (!line.meridian && ends.sbet1 == 0 && (e.f <= 0 || ends.lon12s >= e.f * kHalfTurn)) {
    // Along the equator.
    line.calp1 = line.calp2 = 0;
    line.salp1 = line.salp2 = 1;
    line.s12x = e.a * ends.lam12;
    line.omg12 = ends.lam12 / e.f1;
  } else if (!line.meridian) {
    general_line(e, ends, &line);
  }
  return {line.s12x, inverse_area(e, ends, line)};
}

/// The solution of the problem that `p` is the canonical form of: its signs applied.
QTMV_HD inline InverseSolution signed_solution(const CanonicalProblem& p, const CanonicalSolution& c) {
  InverseSolution out{};
  out.s12 = 0.0 + c.s12;  // -0 to 0
  out.S12 = c.area * (p.swapp * p.lonsign * p.latsign) + 0.0;  // -0 to 0
  return out;
}

/// Inverse geodesic problem between (lat1, lon1) and (lat2, lon2) (degrees, |lat| <= 90, any
/// longitude): the distance s12 (metres) and the area S12 (square metres) between the
/// geodesic and the equator, as GeographicLib's Geodesic::GenInverse with DISTANCE | AREA.
QTMV_HD inline InverseSolution geodesic_inverse(const Ellipsoid& e, double lat1, double lon1, double lat2,
                                                double lon2) {
  const CanonicalProblem p = canonical_problem(lat1, lon1, lat2, lon2);
  return signed_solution(p, solve_canonical(e, p));
}

}  // namespace qtmv::measure
