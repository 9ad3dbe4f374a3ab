// The deterministic sin/cos against the C library, and unit vectors.
#include <gtest/gtest.h>

#include <cmath>
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
