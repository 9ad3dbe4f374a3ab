// The deterministic sin/cos against the C library, and unit vectors.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdint>
#include <random>

#include "grid/qtm_math.hpp"

namespace qtmv::grid {
namespace {

TEST(GridMath, SinCosDegreesMatchLibmToAnUlpOrTwo) {
  std::mt19937_64 rng(3);
  std::uniform_real_distribution<double> angle(-720.0, 720.0);
  double worst = 0;
  for (int n = 0; n < 200000; ++n) {
    const double x = angle(rng);
    double s, c;
    sincos_deg(x, &s, &c);
    // Reference in long double, reduced in degrees first so the reference itself is exact.
    const long double r = std::fmod(static_cast<long double>(x), 360.0L) * (3.14159265358979323846264338327950288L / 180.0L);
    worst = std::max(worst, static_cast<double>(std::fabs(s - std::sin(r))));
    worst = std::max(worst, static_cast<double>(std::fabs(c - std::cos(r))));
  }
  EXPECT_LT(worst, 4e-16);
}

TEST(GridMath, SinCosSeriesInLanesGiveTheScalarBits) {
  // The CPU's two-lane series against the scalar one that CUDA devices run, over the reduced
  // range and its rounding margin, and through sincos_deg.
  std::mt19937_64 rng(11);
  std::uniform_real_distribution<double> reduced(-0.7854, 0.7854), angle(-720.0, 720.0);
  std::uint64_t differ = 0;
  for (int n = 0; n < 300000; ++n) {
    const double r = n < 1000 ? std::ldexp(1.0, -n % 1075) : reduced(rng);
    double ps, pc, ps_scalar, pc_scalar;
    sincos_series(r * r, &ps_scalar, &pc_scalar);
#if QTMV_SSE2_SERIES
    sincos_series_sse2(r * r, &ps, &pc);
#else
    sincos_series(r * r, &ps, &pc);
#endif
    differ += ps != ps_scalar || pc != pc_scalar;
    const double x = angle(rng);
    double s, c;
    sincos_deg(x, &s, &c);
    const double q = x * (1.0 / 90.0);
    const long long quadrant = static_cast<long long>(q >= 0 ? q + 0.5 : q - 0.5);
    const double rx = (x - 90.0 * static_cast<double>(quadrant)) * kDegree;
    sincos_series(rx * rx, &ps_scalar, &pc_scalar);
    const double sr = rx * ps_scalar, cr = 1.0 - rx * rx * (1.0 / 2.0) * pc_scalar;
    const double sines[4] = {sr, cr, -sr, -cr}, cosines[4] = {cr, -sr, -cr, sr};
    const int k = static_cast<int>(((quadrant % 4) + 4) % 4);
    differ += s != sines[k] || c != cosines[k];
  }
  EXPECT_EQ(differ, 0u);
}

TEST(GridMath, ExactAtQuadrants) {
  const double angles[] = {0, 90, 180, 270, -90, -180, 360, 450};
  const double sines[] = {0, 1, 0, -1, -1, 0, 0, 1};
  const double cosines[] = {1, 0, -1, 0, 0, -1, 1, 0};
  for (int k = 0; k < 8; ++k) {
    double s, c;
    sincos_deg(angles[k], &s, &c);
    EXPECT_EQ(s, sines[k]) << angles[k];
    EXPECT_EQ(c, cosines[k]) << angles[k];
  }
}

TEST(GridMath, UnitVectorsAndChords) {
  const Vec3 north = unit_vector(123.0, 90.0);
  EXPECT_EQ(north.z, 1.0);
  EXPECT_NEAR(north.x, 0.0, 1e-300);
  const Vec3 a = unit_vector(0, 0), b = unit_vector(90, 0);
  EXPECT_DOUBLE_EQ(chord2(a, b), 2.0);  // 90 degrees apart: chord sqrt(2)
  EXPECT_DOUBLE_EQ(chord2(a, unit_vector(180, 0)), 4.0);
  const Vec3 n = cross(a, b);
  EXPECT_DOUBLE_EQ(n.z, 1.0);
  std::mt19937_64 rng(5);
  std::uniform_real_distribution<double> lon(-180, 180), lat(-90, 90);
  for (int k = 0; k < 1000; ++k) {
    const Vec3 v = unit_vector(lon(rng), lat(rng));
    EXPECT_NEAR(dot(v, v), 1.0, 4e-16);
  }
}

}  // namespace
}  // namespace qtmv::grid
