// The deterministic inverse geodesic solver (measure/geodesic_math.hpp) against GeographicLib's
// Geodesic::GenInverse (DISTANCE | AREA), and its elementary functions against references.
//
// Worst differences measured (g++ 12, glibc 2.36, x86-64, GeographicLib 2.1.2):
//   det_atan2: 1 ulp from std::atan2 (2.9e6 pairs); sincos: 1 ulp, 390 of 2e6 not correctly
//   rounded against long double; hypot: the same bits as glibc's in 1e6 of 1e6.
//   Within the tolerances (s12: 1e-9 m + 1e-15 s12; S12: 1e-6 m^2 + 4e-16 * 5.1e14 m^2 = 0.2 m^2):
//     random, anywhere (1e5):          s12 1.1e-15 s12,                 S12 0.125 m^2
//     random, short (1.5e5):           s12 7.4e-10 m (< 1 km),          S12 0.002 m^2
//     random, nearly antipodal (5e4):  s12 3.7e-16 s12,                 S12 0.203 m^2
//     random, poles (2e4):             s12 3.6e-16 s12,                 S12 0.031 m^2
//     special cases (7651):            s12 7.1e-10 m (< 1 km),          S12 0.141 m^2
//     QTM edges, levels 0-7 (530400):  s12 0 m (< 1 km), 3.4e-10 m,     S12 0.008 m^2
//   Past them, where GeographicLib itself is that uncertain (see Comparer): 23 short lines
//   (up to 1.6e-9 m, its sin or cos of an input off by an ulp), 609 nearly antipodal lines
//   (S12 up to 8.2 m^2, where one ulp of an input moves its S12 by more) and 1 special case.
#include <gtest/gtest.h>

#include <GeographicLib/Geodesic.hpp>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <iomanip>
#include <limits>
#include <random>
#include <vector>

#include "measure/geodesic_math.hpp"

namespace qtmv::measure {
namespace {

using GeographicLib::Geodesic;

/// Distance in units in the last place between two finite doubles of the same sign (or zeros).
std::int64_t ulp_distance(double a, double b) {
  if (a == b) return 0;
  auto ordered = [](double x) {
    std::int64_t i;
    std::memcpy(&i, &x, sizeof i);
    return i < 0 ? std::numeric_limits<std::int64_t>::min() - i : i;
  };
  const std::int64_t d = ordered(a) - ordered(b);
  return d < 0 ? -d : d;
}

/// The bits of x (NaNs of any payload count as one).
std::uint64_t bits_of(double x) {
  if (std::isnan(x)) return ~std::uint64_t{0};
  std::uint64_t b;
  std::memcpy(&b, &x, sizeof b);
  return b;
}

TEST(RemainderOf, GivesTheCLibrarysBits) {
  // The halves and their neighbours, signed zeros, the turns' multiples, random angles, NaN.
  std::vector<double> xs = {0.0, -0.0, std::nan(""), 1e300, -1e300, std::numeric_limits<double>::denorm_min()};
  for (const double m : {detail::kQuarterTurn, detail::kFullTurn}) {
    for (const double k : {-4.5, -2.0, -1.5, -1.0, -0.5, 0.5, 1.0, 1.5, 2.0, 4.5}) {
      const double x = k * m;
      xs.insert(xs.end(), {x, std::nextafter(x, -1e9), std::nextafter(x, 1e9)});
    }
  }
  std::mt19937_64 random(7);
  std::uniform_real_distribution<double> angle(-1000.0, 1000.0);
  for (int k = 0; k < 200000; ++k) xs.push_back(angle(random));
  for (const double m : {detail::kQuarterTurn, detail::kFullTurn}) {
    for (const double x : xs) {
      ASSERT_EQ(bits_of(detail::remainder_of(x, m)), bits_of(std::remainder(x, m))) << x << " mod " << m;
    }
  }
}

TEST(DetAtan2, WithinTwoUlpOfTheCLibrary) {
  std::int64_t worst = 0;
  long checked = 0;
  auto check = [&](double y, double x) {
    const double mine = det_atan2(y, x), libm = std::atan2(y, x);
    const std::int64_t d = ulp_distance(mine, libm);
    if (d > worst) worst = d;
    ++checked;
    EXPECT_LE(d, 2) << "atan2(" << y << ", " << x << ") = " << mine << " vs " << libm;
  };
  // A dense sweep of directions at magnitudes from 1e-300 to 1e300, in all quadrants.
  constexpr int kDirections = 200000;
  const double magnitudes[] = {1e-300, 3e-160, 1e-20, 1e-5, 1, 7.5, 1e10, 1e150, 1e300};
  for (double r : magnitudes) {
    for (int k = 0; k < kDirections; ++k) {
      const double theta = -grid::kPi + 2 * grid::kPi * (k + 0.5) / kDirections;
      check(r * std::sin(theta), r * std::cos(theta));
    }
  }
  // Random ratios of all sizes, and ratios near the breakpoints of the reduction (j/16, 5/32).
  std::mt19937_64 rng(11);
  std::uniform_real_distribution<double> unit(-1.0, 1.0);
  std::uniform_real_distribution<double> exponent(-60.0, 60.0);
  for (int k = 0; k < 1000000; ++k) {
    const double y = unit(rng) * std::pow(2.0, exponent(rng)), x = unit(rng) * std::pow(2.0, exponent(rng));
    check(y, x);
  }
  for (int j = 2; j <= 33; ++j) {
    const double t = j / 32.0;
    for (int s = -300; s <= 300; ++s) {
      const double u = t + s * 0x1p-52;
      check(u, 1.0);
      check(1.0, -u);
      check(-u, -1.0);
    }
  }
  // Zeros, signs and infinities: exactly as the C library.
  const double inf = std::numeric_limits<double>::infinity();
  const double specials[] = {0.0, -0.0, 1.0, -1.0, 1e-320, -1e-320, inf, -inf};
  for (double y : specials) {
    for (double x : specials) {
      EXPECT_EQ(ulp_distance(det_atan2(y, x), std::atan2(y, x)), 0) << y << ", " << x;
      EXPECT_EQ(std::signbit(det_atan2(y, x)), std::signbit(std::atan2(y, x))) << y << ", " << x;
    }
  }
  EXPECT_TRUE(std::isnan(det_atan2(std::nan(""), 1.0)));
  EXPECT_TRUE(std::isnan(det_atan2(1.0, std::nan(""))));
  std::printf("det_atan2: worst %lld ulp from std::atan2 over %ld pairs\n", static_cast<long long>(worst), checked);
}

/// x rounded to double from long double (x87: 64 bits), i.e. correctly rounded unless the
/// long double falls within 2^-11 ulp of a tie.
double rounded(long double x) { return static_cast<double>(x); }

TEST(SinCosKernel, CorrectlyRoundedButForRareCases) {
  // sin and cos of the latitudes' arguments (as GeographicLib reduces them: |r| <= pi/4),
  // against long double; and of radians up to 4 pi through sincos_rad, within an ulp.
  std::mt19937_64 rng(7);
  std::uniform_real_distribution<double> quarter(-45.0, 45.0), wide(-4 * grid::kPi, 4 * grid::kPi);
  long misrounded = 0, checked = 0;
  std::int64_t worst = 0, worst_rad = 0;
  for (int k = 0; k < 1000000; ++k) {
    // Small arguments as well: the series branch below 1/128.
    const double r = (k % 4 == 0 ? std::pow(2.0, -10.0 * (k % 5)) * 0.01 * quarter(rng) : quarter(rng)) * grid::kDegree;
    double s, c;
    detail::sincos_kernel(r, &s, &c);
    const double s_ref = rounded(std::sin(static_cast<long double>(r)));
    const double c_ref = rounded(std::cos(static_cast<long double>(r)));
    worst = std::max({worst, ulp_distance(s, s_ref), ulp_distance(c, c_ref)});
    misrounded += (s != s_ref) + (c != c_ref);
    checked += 2;
    const double x = wide(rng);
    detail::sincos_rad(x, &s, &c);
    worst_rad = std::max({worst_rad, ulp_distance(s, rounded(std::sin(static_cast<long double>(x)))),
                          ulp_distance(c, rounded(std::cos(static_cast<long double>(x))))});
  }
  std::printf("sincos_kernel: %ld of %ld values not correctly rounded, worst %lld ulp; sincos_rad worst %lld ulp\n",
              misrounded, checked, static_cast<long long>(worst), static_cast<long long>(worst_rad));
  EXPECT_LE(worst, 1);
  EXPECT_LE(misrounded, checked / 2000);
  EXPECT_LE(worst_rad, 2);
  double s, c;
  detail::sincos_kernel(-0.0, &s, &c);
  EXPECT_TRUE(s == 0 && std::signbit(s) && c == 1);
}

/// Whether h is within an ulp of sqrt(x^2 + y^2) (exclusive), and whether it is correctly
/// rounded, checked in binary128 where the squares are exact.
void check_hypot(double h, double x, double y, bool* within_ulp, bool* correctly_rounded) {
  __extension__ typedef __float128 Quad;
  const double down = std::nextafter(h, 0.0), up = std::nextafter(h, 1e300);
  const Quad sum = static_cast<Quad>(x) * x + static_cast<Quad>(y) * y;
  const Quad below = (static_cast<Quad>(h) + down) / 2, above = (static_cast<Quad>(h) + up) / 2;
  *correctly_rounded = below * below <= sum && sum <= above * above;
  *within_ulp = static_cast<Quad>(down) * down < sum && sum < static_cast<Quad>(up) * up;
}

TEST(DetHypot, WithinAnUlp) {
  // Borges' corrected hypot is not always correctly rounded (about 0.6% of cases are off by an
  // ulp); glibc's hypot (2.35 on) is the same algorithm and so far gives the same bits.
  std::mt19937_64 rng(5);
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  long misrounded = 0, same_as_libm = 0;
  constexpr int kPairs = 1000000;
  for (int k = 0; k < kPairs; ++k) {
    // Near 1 as the geodesic uses it, and scaled by 2^-20 and 2^20 (no binary128 overflow).
    const double scale = std::pow(2.0, (k % 3 - 1) * 20.0);
    const double x = unit(rng) * scale, y = unit(rng) * (k % 5 == 0 ? 1e-9 : 1.0) * scale;
    const double h = detail::det_hypot(x, y);
    bool within_ulp, correctly_rounded;
    check_hypot(h, x, y, &within_ulp, &correctly_rounded);
    EXPECT_TRUE(within_ulp) << x << " " << y;
    misrounded += !correctly_rounded;
    same_as_libm += h == std::hypot(x, y);
  }
  std::printf("det_hypot: %ld of %d not correctly rounded (all within an ulp); %ld the same as std::hypot\n",
              misrounded, kPairs, same_as_libm);
  EXPECT_LE(misrounded, kPairs / 50);
  // The scaling far from 1 (against the C library's hypot, correctly rounded or nearly so).
  for (double scale : {0x1p-1060, 0x1p-900, 0x1p-520, 0x1p+520, 0x1p+900, 0x1p+1000}) {
    for (int k = 0; k < 1000; ++k) {
      const double x = unit(rng) * scale, y = unit(rng) * scale;
      EXPECT_LE(ulp_distance(detail::det_hypot(x, y), std::hypot(x, y)), 1) << x << " " << y;
    }
  }
  EXPECT_EQ(detail::det_hypot(0.0, -0.0), 0.0);
  EXPECT_EQ(detail::det_hypot(3.0, -4.0), 5.0);
  EXPECT_EQ(detail::det_hypot(1e-300, 0.0), 1e-300);
  EXPECT_EQ(detail::det_hypot(-std::numeric_limits<double>::infinity(), 1.0), std::numeric_limits<double>::infinity());
}

TEST(DetCbrt, WithinAnUlpOfTheLongDoubleRoot) {
  std::mt19937_64 rng(9);
  std::uniform_real_distribution<double> exponent(-1000.0, 1000.0), unit(-1.0, 1.0);
  std::int64_t worst = 0;
  for (int k = 0; k < 200000; ++k) {
    const double x = unit(rng) * std::pow(2.0, exponent(rng));
    worst = std::max(worst, ulp_distance(detail::det_cbrt(x), rounded(std::cbrt(static_cast<long double>(x)))));
  }
  EXPECT_LE(worst, 1);
  EXPECT_EQ(detail::det_cbrt(-8.0), -2.0);
  EXPECT_EQ(detail::det_cbrt(0x1p-1074), 0x1p-358);
  EXPECT_EQ(detail::det_cbrt(0.0), 0.0);
}

/// Tolerances against GeographicLib: s12 within 1e-9 m + 1e-15 s12; S12 within 1e-6 m^2 + 4e-16
/// times the ellipsoid's area (0.2 m^2).
constexpr double kLengthAbs = 1e-9;
constexpr double kLengthRel = 1e-15;
constexpr double kAreaRelToEllipsoid = 4e-16;
/// How far one ulp of error in the sine or cosine of a (reduced) latitude or of lon12 moves a
/// point: b 2^-53 (0.71 nm).
constexpr double kRoundingMove = 6356752.3142451793 * 0x1p-53;
/// The share of lines allowed past the tolerances for the two reasons that Comparer explains
/// (nearly antipodal lines, where the reference is ill-conditioned, pass their own share).
constexpr double kMaxExplainedShare = 0.005;

/// How many of lat1, lat2 and lon12 GeographicLib turns into other bits than we do: the reduced
/// latitude (sin, cos) normalised with hypot, and the sine and cosine of lon12, as GenInverse
/// takes them. The C library's sin and cos are off by an ulp about once in 400, ours about
/// twice in 10^4 (SinCosKernel); hypot is the same algorithm on both sides with glibc 2.35 on.
/// So a difference is nearly always the reference's rounding.
int input_rounding_differences(double lat1, double lon1, double lat2, double lon2) {
  using GeographicLib::Math;
  const double f1 = 1 - Geodesic::WGS84().Flattening();
  int count = 0;
  for (double lat : {lat1, lat2}) {
    lat = Math::AngRound(lat);
    double s1, c1, s2, c2;
    Math::sincosd(lat, s1, c1);
    s1 *= f1;
    Math::norm(s1, c1);
    detail::sincos_deg_reduced(lat, 0, false, &s2, &c2);
    s2 *= f1;
    detail::norm2(&s2, &c2);
    if (s1 != s2 || c1 != c2) ++count;
  }
  double lon12s;
  double lon12 = Math::AngDiff(lon1, lon2, lon12s);
  if (std::signbit(lon12)) {
    lon12 = -lon12;
    lon12s = -lon12s;
  }
  double s1, c1, s2, c2;
  Math::sincosde(lon12, lon12s, s1, c1);
  detail::sincos_deg_reduced(lon12, lon12s, true, &s2, &c2);
  if (s1 != s2 || c1 != c2) ++count;
  return count;
}

/// Compares lines with GeographicLib and keeps the worst differences. A line past the
/// tolerances passes only where the reference itself is that uncertain:
///   - it rounds an input's sine or cosine otherwise than we do (input_rounding_differences):
///     each such ulp moves a point by up to kRoundingMove; allowed: twice that per input;
///   - its result moves by more than the difference when one input moves by one ulp (nearly
///     antipodal points, where the azimuths and so S12 are ill-conditioned): twice that spread.
/// Such explained lines must stay rare (max_explained_share).
class Comparer {
 public:
  explicit Comparer(double max_explained_share = kMaxExplainedShare)
      : e_(wgs84_ellipsoid()),
        area_tol_(1e-6 + kAreaRelToEllipsoid * Geodesic::WGS84().EllipsoidArea()),
        max_explained_share_(max_explained_share) {}

  void check(double lat1, double lon1, double lat2, double lon2) {
    double s12, S12;
    reference(lat1, lon1, lat2, lon2, &s12, &S12);
    const InverseSolution mine = geodesic_inverse(e_, lat1, lon1, lat2, lon2);
    ++count_;
    const double ds = std::fabs(mine.s12 - s12), dS = std::fabs(mine.S12 - S12);
    if (std::isnan(mine.s12) || std::isnan(mine.S12) || !(ds <= 1e-3 && dS <= 1e3)) {
      fail(lat1, lon1, lat2, lon2, mine, s12, S12, "far off");
      return;
    }
    const double length_tol = kLengthAbs + kLengthRel * s12;
    if (ds <= length_tol && dS <= area_tol_) {
      keep_worst(ds, dS, s12, lat1, lon1, lat2, lon2, &strict_);
      return;
    }
    // Past the tolerances: how uncertain is the reference here?
    const int rounding = input_rounding_differences(lat1, lon1, lat2, lon2);
    double spread_s = 0, spread_S = 0;
    for (int c = 0; c < 4; ++c) {
      for (double towards : {-1e300, 1e300}) {
        double in[4] = {lat1, lon1, lat2, lon2};
        in[c] = std::nextafter(in[c], towards);
        if (std::fabs(in[0]) > 90 || std::fabs(in[2]) > 90) continue;
        double s, S;
        reference(in[0], in[1], in[2], in[3], &s, &S);
        spread_s = std::max(spread_s, std::fabs(s - s12));
        spread_S = std::max(spread_S, std::fabs(S - S12));
      }
    }
    if (ds <= length_tol + 2 * rounding * kRoundingMove + 2 * spread_s && dS <= area_tol_ + 2 * spread_S) {
      ++explained_;
      keep_worst(ds, dS, s12, lat1, lon1, lat2, lon2, &explained_worst_);
      return;
    }
    fail(lat1, lon1, lat2, lon2, mine, s12, S12, "unexplained");
  }

  void report(const char* what) const {
    print(what, "within the tolerances", count_ - explained_ - failures_, strict_);
    print(what, "past them where the reference is as uncertain", explained_, explained_worst_);
    EXPECT_EQ(failures_, 0) << what;
    EXPECT_LE(explained_, max_explained_share_ * count_) << what;
  }

 private:
  /// Lines below this length (m) are reported by their absolute difference, longer ones by the
  /// relative one.
  static constexpr double kShortLine = 1000;
  struct Worst {
    double short_s12 = 0, long_s12 = 0, S12 = 0;  // m, relative, m^2
    char short_s12_line[128] = "", long_s12_line[128] = "", S12_line[128] = "";
  };

  static void print(const char* what, const char* which, long lines, const Worst& w) {
    std::printf("%s, %ld lines %s: worst |ds12| %.3g m (s12 < 1 km), %.3g s12 (longer); |dS12| %.3g m^2\n", what,
                lines, which, w.short_s12, w.long_s12, w.S12);
    if (lines == 0) return;
    std::printf("  at %s\n     %s\n     %s\n", w.short_s12_line, w.long_s12_line, w.S12_line);
  }

  static void reference(double lat1, double lon1, double lat2, double lon2, double* s12, double* S12) {
    double azi1, azi2, m12, M12, M21;
    Geodesic::WGS84().GenInverse(lat1, lon1, lat2, lon2, Geodesic::DISTANCE | Geodesic::AREA, *s12, azi1, azi2, m12,
                                 M12, M21, *S12);
  }

  static void keep_worst(double ds, double dS, double s12, double lat1, double lon1, double lat2, double lon2,
                         Worst* w) {
    char line[128];
    std::snprintf(line, sizeof line, "%.17g %.17g %.17g %.17g", lat1, lon1, lat2, lon2);
    if (s12 < kShortLine && ds > w->short_s12) {
      w->short_s12 = ds;
      std::snprintf(w->short_s12_line, sizeof w->short_s12_line, "%s", line);
    }
    if (s12 >= kShortLine && ds / s12 > w->long_s12) {
      w->long_s12 = ds / s12;
      std::snprintf(w->long_s12_line, sizeof w->long_s12_line, "%s", line);
    }
    if (dS > w->S12) {
      w->S12 = dS;
      std::snprintf(w->S12_line, sizeof w->S12_line, "%s", line);
    }
  }

  void fail(double lat1, double lon1, double lat2, double lon2, const InverseSolution& mine, double s12, double S12,
            const char* why) {
    if (++failures_ <= 20) {
      ADD_FAILURE() << std::setprecision(17) << why << ": (" << lat1 << ", " << lon1 << ") -> (" << lat2 << ", "
                    << lon2 << "): s12 " << mine.s12 << " vs " << s12 << ", S12 " << mine.S12 << " vs " << S12;
    }
  }

  Ellipsoid e_;
  double area_tol_, max_explained_share_;
  Worst strict_, explained_worst_;
  long count_ = 0, failures_ = 0, explained_ = 0;
};

TEST(GeodesicInverse, RandomPairsOfAllLengthsMatchGeographicLib) {
  std::mt19937_64 rng(2013);
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  auto random_lat = [&] { return std::asin(2 * unit(rng) - 1) / grid::kDegree; };
  auto random_lon = [&] { return 360 * unit(rng) - 180; };
  auto offset = [&](double min_exp, double max_exp) {
    const double size = std::pow(10.0, min_exp + (max_exp - min_exp) * unit(rng));
    return unit(rng) < 0.5 ? -size : size;
  };
  Comparer anywhere;
  for (int k = 0; k < 100000; ++k) anywhere.check(random_lat(), random_lon(), random_lat(), random_lon());
  anywhere.report("random, anywhere");
  Comparer short_lines;  // 1e-9 to 10 degrees apart (0.1 mm to 1100 km)
  for (int k = 0; k < 150000; ++k) {
    const double lat1 = random_lat(), lon1 = random_lon();
    const double lat2 = std::clamp(lat1 + offset(-9, 1), -90.0, 90.0);
    short_lines.check(lat1, lon1, lat2, lon1 + offset(-9, 1));
  }
  short_lines.report("random, short");
  Comparer antipodal(0.03);  // within 1e-8 to 3 degrees of the antipode
  for (int k = 0; k < 50000; ++k) {
    const double lat1 = random_lat(), lon1 = random_lon();
    const double lat2 = std::clamp(-lat1 + offset(-8, 0.5), -90.0, 90.0);
    antipodal.check(lat1, lon1, lat2, lon1 + 180 + offset(-8, 0.5));
  }
  antipodal.report("random, nearly antipodal");
  Comparer poles;  // from at and near the poles to near the equator or anywhere
  for (int k = 0; k < 20000; ++k) {
    const double from_pole = unit(rng) < 0.1 ? 0 : std::pow(10.0, -12 * unit(rng));
    const double lat1 = (unit(rng) < 0.5 ? 1 : -1) * (90 - from_pole);
    const double lat2 = unit(rng) < 0.5 ? offset(-14, 0) : random_lat();
    poles.check(lat1, random_lon(), lat2, random_lon());
  }
  poles.report("random, poles");
}

TEST(GeodesicInverse, SpecialCasesMatchGeographicLib) {
  Comparer cmp;
  const double lats[] = {-90, -89.999999, -60, -45, -1e-10, -0.0, 0, 1e-10, 0.5, 30, 45, 89.9999999, 90};
  const double lons[] = {-180, -179.99999, -135, -90, -1e-9, -0.0, 0, 1e-9, 0.001, 90, 179.5, 180, 360, -540};
  // Every combination: meridians, the equator, poles, coincident points, antipodes, lon12 < 0.
  for (double lat1 : lats)
    for (double lat2 : lats)
      for (double lon2 : lons) {
        cmp.check(lat1, 0, lat2, lon2);
        cmp.check(lat2, lon2, lat1, 0);  // swapped
      }
  // Along the equator, short and up to (and past) the point where the geodesic leaves it.
  for (double lon2 = -180; lon2 <= 180; lon2 += 0.37) cmp.check(0, 0, 0, lon2);
  for (double d = 0; d < 1; d += 0.01) cmp.check(0, 10, 0, 10 + 179 + d);
  // Pole to equator, nearly antipodal, and lines of 1 cm to 1 m everywhere.
  for (double lon = -180; lon <= 180; lon += 7.5) cmp.check(90, 0, 0, lon);
  for (double lat = -80; lat <= 80; lat += 10) {
    for (double d = 1e-9; d < 1; d *= 3) {
      cmp.check(lat, 20, -lat + d, 200 - d);
      cmp.check(lat, 20, -lat, 200 - d);
      cmp.check(lat, 20, -lat - d, 200);
    }
    const double metre = 1 / 111000.0;  // degrees, about
    for (double len = 0.01; len <= 1; len *= 1.5) {
      cmp.check(lat, 3, lat + len * metre, 3);
      cmp.check(lat, 3, lat, 3 - len * metre);
      cmp.check(lat, 3, lat + 0.6 * len * metre, 3 + 0.8 * len * metre);
      cmp.check(lat + 0.6 * len * metre, 3 + 0.8 * len * metre, lat, 3);
    }
  }
  // GeographicLib's own hard cases (its geodtest's regression list).
  cmp.check(52.784459512564, 0, -52.784459512563990912, 179.634407464943777557);
  cmp.check(48.522876735459, 0, -48.52287673545898293, 179.599720456223079643);
  cmp.check(20.001, 0, 20.001, 0);
  cmp.check(90, 0, 90, 180);
  cmp.check(0, 0, 0, 179.5);
  cmp.check(0, 0, 0, 179.7);
  cmp.check(-0.000000000000000003, 0, 0.000000000000000003, 179.9999999999999);
  cmp.check(36.530042355041, 0, -36.529614281056, 179.9999999999);
  cmp.check(0.07476, 0, -0.07476, 180);
  cmp.check(0.1, 0, -0.1, 180);
  cmp.check(-45, 0, 45, 179.98);
  cmp.check(89.333123580033, 0, -89.333123580032997687, 179.99999999999999);
  cmp.report("special cases");
}

/// lon of a QTM vertex from its octant's local longitude (../shared/QTM-SPEC.md, "Octants").
double octant_lon(int octant, double lon_local) {
  switch (octant) {
    case 0: return lon_local;
    case 1: return lon_local + 90;
    case 2: return lon_local - 180;
    case 3: return lon_local - 90;
    case 4: return 90 - lon_local;
    case 5: return 180 - lon_local;
    case 6: return -90 - lon_local;
    default: return -lon_local;
  }
}

TEST(GeodesicInverse, QtmGridEdgesOfLevels0To7MatchGeographicLib) {
  Comparer cmp;
  for (int level = 0; level <= 7; ++level) {
    const int rows = 1 << level;
    for (int octant = 0; octant < 8; ++octant) {
      // Vertex (r, k): lat' = 90 (1 - r/I), lon' = 90 k / r.
      auto vertex = [&](int r, int k, double* lat, double* lon) {
        const double lat_local = 90.0 * (1.0 - static_cast<double>(r) / rows);
        const double lon_local = r == 0 ? 0.0 : 90.0 * k / r;
        *lat = octant < 4 ? lat_local : -lat_local;
        *lon = octant_lon(octant, lon_local);
      };
      for (int r = 0; r <= rows; ++r) {
        for (int k = 0; k <= r; ++k) {
          double lat1, lon1, lat2, lon2;
          vertex(r, k, &lat1, &lon1);
          if (k < r) {
            vertex(r, k + 1, &lat2, &lon2);
            cmp.check(lat1, lon1, lat2, lon2);
            cmp.check(lat2, lon2, lat1, lon1);
          }
          if (r < rows) {
            vertex(r + 1, k, &lat2, &lon2);
            cmp.check(lat1, lon1, lat2, lon2);
            cmp.check(lat2, lon2, lat1, lon1);
            vertex(r + 1, k + 1, &lat2, &lon2);
            cmp.check(lat1, lon1, lat2, lon2);
            cmp.check(lat2, lon2, lat1, lon1);
          }
        }
      }
    }
  }
  cmp.report("QTM edges");
}

TEST(GeodesicInverse, EllipsoidCoefficientsMatchGeographicLibsConstants) {
  const Ellipsoid e = wgs84_ellipsoid();
  EXPECT_EQ(e.a, Geodesic::WGS84().EquatorialRadius());
  EXPECT_EQ(e.f, Geodesic::WGS84().Flattening());
  // The authalic sphere's area 4 pi c2 against GeographicLib's ellipsoid area.
  EXPECT_NEAR(4 * grid::kPi * e.c2, Geodesic::WGS84().EllipsoidArea(), 1.0);
}

}  // namespace
}  // namespace qtmv::measure
