// Distance maths of the labeller, one body for the CPU and the CUDA kernels (QTMV_HD).
//
// Every candidate the labeller compares is a "piece": a point (a == b) or a short great-circle
// arc from a to b, both unit vectors, with the id of the site it belongs to. Distances are
// compared as squared chord lengths (monotone in the great-circle distance, precise when
// small), always in float64, and with the same operations on both sides (no FMA contraction:
// the targets link qtmv::grid), so the CPU and the GPU pick the same site bit for bit.
#pragma once

#include <cstdint>
#include <utility>

#include "grid/qtm.hpp"

namespace qtmv::label {

using grid::Vec3;

/// Radius of the sphere on which distances are reported (metres): the mean Earth radius.
constexpr double kEarthRadiusMetres = 6371008.8;

/// Piece flags.
enum PieceFlag : std::int32_t {
  kPiecePoint = 1,  ///< a point: only `a` is used
  kPieceFixed = 2,  ///< the centre of a fixed cell: wins its own cell at distance 0 (see better())
};

/// One candidate geometry, as the kernels read it.
struct Piece {
  Vec3 a;              ///< first endpoint (unit vector); the point itself for a point piece
  Vec3 b;              ///< second endpoint (unit vector); equal to a for a point piece
  Vec3 n;              ///< (b + a) x (b - a): normal of the arc's plane, not normalised; zero for points
  double n2;           ///< |n|^2
  std::int32_t site;   ///< site id (>= 0)
  std::int32_t flags;  ///< PieceFlag bits
};

QTMV_HD inline Piece make_point_piece(const Vec3& p, std::int32_t site, std::int32_t flags = 0) {
  return {p, p, {0.0, 0.0, 0.0}, 0.0, site, flags | kPiecePoint};
}

/// An arc piece from a to b (unit vectors, shorter than a quarter circle). A degenerate arc
/// (a == b, or n underflows to zero) becomes a point piece at a.
QTMV_HD inline Piece make_arc_piece(const Vec3& a, const Vec3& b, std::int32_t site) {
  // (b + a) x (b - a) = 2 a x b, but loses far less to cancellation when a and b are close.
  const Vec3 n = grid::cross(b + a, b - a);
  const double n2 = grid::dot(n, n);
  if (!(n2 > 0.0)) return make_point_piece(a, site);
  return {a, b, n, n2, site, 0};
}

/// Squared chord between the unit vector x and the nearest point of the piece.
/// For an arc: when x projects inside the arc, the distance to the arc's great circle,
/// angle asin(|x.n| / |n|), whose squared chord 2 - 2 cos is written 2 s^2 / (1 + sqrt(1 - s^2))
/// to keep its precision for short distances; otherwise the nearer endpoint.
QTMV_HD inline double piece_chord2(const Vec3& x, const Piece& p) {
  if (p.flags & kPiecePoint) return grid::chord2(x, p.a);
  // x projects inside the arc iff it lies on the inner side of the planes through the
  // origin, n and each endpoint: (a x x).n >= 0 and (x x b).n >= 0.
  const bool inside = grid::dot(grid::cross(p.a, x), p.n) >= 0.0 && grid::dot(grid::cross(x, p.b), p.n) >= 0.0;
  if (inside) {
    const double t = grid::dot(x, p.n);
    double s2 = t * t / p.n2;  // sin^2 of the angle to the great circle
    if (s2 > 1.0) s2 = 1.0;
    return 2.0 * s2 / (1.0 + sqrt(1.0 - s2));
  }
  const double da = grid::chord2(x, p.a);
  const double db = grid::chord2(x, p.b);
  return da < db ? da : db;
}

/// Great-circle distance (radians) of a squared chord.
QTMV_HD inline double chord2_to_angle(double chord2) {
  double half_chord = sqrt(chord2) * 0.5;
  if (half_chord > 1.0) half_chord = 1.0;
  return 2.0 * asin(half_chord);
}

// Sentinels of squared chords, named as S2 names S1ChordAngle's (Infinity(), kMaxLength2).

/// The largest squared chord between two unit vectors: 4, between antipodes (chord 2).
constexpr double kChord2Max = 4.0;

/// Above every squared chord and bound the labeller computes: the distance of "nothing seen
/// yet" (no_best) and the start of a search for the least upper bound, which any candidate
/// replaces (S2's S1ChordAngle::Infinity()).
constexpr double kChord2Infinity = 1e300;

/// The pruning threshold that keeps every candidate: above kChord2Max by far more than the
/// rounding of a computed squared chord (a few ulps above 4 near the antipode), so that no
/// candidate's distance or lower bound passes it.
constexpr double kChord2KeepAll = kChord2Max + 1.0;  // 5

/// The best candidate seen so far for one cell centre. Order: smaller squared chord first;
/// at distance exactly 0, a fixed cell's own centre first (fixed cells keep their site);
/// then the lower site id (exact ties go to the lower id).
struct Best {
  double chord2;
  std::int32_t rank;  ///< 0: a fixed cell's centre at distance 0; 1: anything else
  std::int32_t site;  ///< -1 while nothing was seen
};

QTMV_HD inline Best no_best() { return {kChord2Infinity, 1, -1}; }

QTMV_HD inline void consider(Best& best, double chord2, const Piece& p) {
  const std::int32_t rank = (chord2 == 0.0 && (p.flags & kPieceFixed)) ? 0 : 1;
  if (chord2 < best.chord2 ||
      (chord2 == best.chord2 && (rank < best.rank || (rank == best.rank && p.site < best.site)))) {
    best = {chord2, rank, p.site};
  }
}

/// Considers `count` pieces for the point x (unit vector): the brute-force step of the
/// float64 reference and of the brute kernels.
QTMV_HD inline void consider_all(Best& best, const Vec3& x, const Piece* pieces, std::int64_t count) {
  for (std::int64_t p = 0; p < count; ++p) consider(best, piece_chord2(x, pieces[p]), pieces[p]);
}

/// Distance (metres) of a squared chord on the sphere of kEarthRadiusMetres.
QTMV_HD inline double chord2_to_metres(double chord2) { return chord2_to_angle(chord2) * kEarthRadiusMetres; }

// ---------------------------------------------------------------------------------------------
// The pruning bound.
//
// Claim: every point of the cell (i, j) at level l (hence every cell centre of its subtree)
// lies within node_radius(l, cell) (radians) of the cell's centre.
//
// Proof. In the octant's plane (w, v), 0 <= w <= v <= 1, a point maps to lat' = 90 (1 - v),
// lon' = 90 rho with rho = w / v (degrees). Along a planar path the spherical arc length element
// is ds^2 = dlat^2 + cos^2(lat) dlon^2 with dlat = (pi/2) dv and
// cos(lat) dlon = sin(pi v / 2) (pi/2) (dw - rho dv) / v. With g(v) = sin(pi v / 2) / v
// (decreasing on (0, 1], g(0+) = pi/2):
//     ds <= (pi/2) sqrt(dv^2 + g(v)^2 (dw - rho dv)^2).
// The cell is a planar triangle of side 1/I (I = 2^l) with rows v in [i/I, (i+1)/I], so on it
// g(v) <= G := g(i/I), and rho lies between the smallest and largest rho of its vertices
// (rho = w / v is linear-fractional, so its extremes on a triangle are at vertices; a pole
// vertex, v = 0, allows all of [0, 1]). Follow the straight planar segment from the centroid to
// a point q of the triangle (it stays inside: the triangle is convex), with constant
// (dw, dv) = q - centroid. Its image on the sphere is no shorter than the great-circle distance,
// and no longer than
//     f(dw, dv) = (pi/2) sqrt(dv^2 + G^2 max(|dw - rho0 dv|, |dw - rho1 dv|)^2)
// for the node's rho range [rho0, rho1] (|dw - rho dv| is linear in rho, so largest at an end).
// f is convex in (dw, dv), so its maximum over the triangle is at a vertex: from the centroid
// the vertices lie at (-1/3, -2/3), (-1/3, 1/3), (2/3, 1/3) (up cells) or (-2/3, -1/3),
// (1/3, -1/3), (1/3, 2/3) (down cells), times 1/I. The radius is the largest f of the three.
// The octant's placement on the globe is an isometry, so this holds in every octant. The
// centres are computed in float64 (error ~1e-16 rad); we add a relative margin of 1e-9 and
// kPruneMarginRadians in the pruning test. tests/label checks the bound on every cell of
// levels 1 to 8 against nodes up to 6 levels above.
///
/// node_radius_stretch(level, row) is G for the cells of one row; node_radius(level, cell, G) the
/// radius from it (the same bits as node_radius(level, cell)).
QTMV_HD inline double node_radius_stretch(int level, std::uint32_t row) {
  const double v0 = static_cast<double>(row) / static_cast<double>(grid::rows_per_octant(level));
  double g = grid::kPi / 2.0;
  if (v0 > 0.0) {
    double s, c;
    grid::sincos_deg(90.0 * v0, &s, &c);
    g = s / v0;
  }
  return g;
}
QTMV_HD inline double node_radius(int level, const grid::Cell& cell, double g) {
  const double rows = static_cast<double>(grid::rows_per_octant(level));
  const double i = static_cast<double>(cell.row), a = static_cast<double>(cell.col / 2);
  const bool up = grid::is_up(cell);
  // rho = k / r of the vertices (r, k); a vertex at the pole (r = 0) allows [0, 1].
  double rho0 = 0.0, rho1 = 1.0;
  if (cell.row > 0) {
    if (up) {
      rho0 = a / (i + 1.0) < a / i ? a / (i + 1.0) : a / i;
      rho1 = (a + 1.0) / (i + 1.0) > a / i ? (a + 1.0) / (i + 1.0) : a / i;
    } else {
      rho0 = a / i < (a + 1.0) / (i + 1.0) ? a / i : (a + 1.0) / (i + 1.0);
      rho1 = (a + 1.0) / i;
    }
  }
  const double dw[3] = {up ? -1.0 / 3 : -2.0 / 3, up ? -1.0 / 3 : 1.0 / 3, up ? 2.0 / 3 : 1.0 / 3};
  const double dv[3] = {up ? -2.0 / 3 : -1.0 / 3, up ? 1.0 / 3 : -1.0 / 3, up ? 1.0 / 3 : 2.0 / 3};
  double worst = 0.0;
  for (int k = 0; k < 3; ++k) {
    const double m0 = fabs(dw[k] - rho0 * dv[k]), m1 = fabs(dw[k] - rho1 * dv[k]);
    const double m = m0 > m1 ? m0 : m1;
    const double f2 = dv[k] * dv[k] + g * g * m * m;
    worst = f2 > worst ? f2 : worst;
  }
  return (grid::kPi / 2.0) / rows * sqrt(worst) * (1.0 + 1e-9);
}
QTMV_HD inline double node_radius(int level, const grid::Cell& cell) {
  return node_radius(level, cell, node_radius_stretch(level, cell.row));
}

/// node_radius_stretch of the last two rows asked for, for a pass over the nodes of one level (a
/// node's four children lie in two rows). One per thread and level.
class RadiusStretches {
 public:
  double operator()(int level, std::uint32_t row) {
    if (row_[0] != row) {
      if (row_[1] != row) {
        row_[1] = row;
        g_[1] = node_radius_stretch(level, row);
      }
      std::swap(row_[0], row_[1]);
      std::swap(g_[0], g_[1]);
    }
    return g_[0];
  }

 private:
  std::uint32_t row_[2] = {~0u, ~0u};  // none yet
  double g_[2] = {0.0, 0.0};
};

/// Slack (radians, about 1.3 m on the Earth) added to every pruning threshold. It covers the
/// rounding of the float64 distances (at most a few 1e-8 rad for squared chords near 0 or 4),
/// so that a candidate the float64 reference would pick is never pruned.
constexpr double kPruneMarginRadians = 2e-7;

/// The pruning threshold (squared chord) of a node with centre c and radius r (radians) whose
/// nearest candidate from c is at squared chord min_chord2: a candidate p can be nearest to
/// some point x of the node only if d(c, p) - r <= d(x, p) <= d(x, q) <= d(c, q) + r for the
/// nearest q, i.e. d(c, p) <= d_min(c) + 2 r. Returns kChord2KeepAll when the angle reaches
/// pi.
QTMV_HD inline double prune_threshold(double min_chord2, double radius) {
  const double limit = chord2_to_angle(min_chord2) + 2.0 * radius + kPruneMarginRadians;
  if (limit >= grid::kPi) return kChord2KeepAll;
  const double half_chord = sin(0.5 * limit);
  return 4.0 * half_chord * half_chord * (1.0 + 1e-12);
}

/// At least prune_threshold(min_chord2, radius), from square roots alone where the node is small
/// (radius up to 0.05 radians) and the nearest candidate not near the antipode: with a the angle
/// of min_chord2 and h = radius + kPruneMarginRadians / 2, sin(a/2 + h) <= sin(a/2) + cos(a/2) h.
/// For callers to whom a larger threshold costs only work (it keeps every candidate that
/// prune_threshold keeps), not for the tree build, whose CPU and GPU trees must agree.
QTMV_HD inline double prune_threshold_above(double min_chord2, double radius) {
  const double h = radius + 0.5 * kPruneMarginRadians;
  if (min_chord2 > 3.9 || h > 0.05) return prune_threshold(min_chord2, radius);
  const double half_chord = 0.5 * sqrt(min_chord2) + sqrt(1.0 - 0.25 * min_chord2) * h;
  return 4.0 * half_chord * half_chord * (1.0 + 1e-12);
}

/// Slack (in x.(a - b), a squared chord's half) by which beyond_bisector must clear the bisector:
/// far above the float64 rounding of the squared chords compared (a few 1e-16), about 6 micrometres
/// on the Earth.
constexpr double kBisectorMargin = 1e-12;

/// True when every point x within `radius` (radians) of the node centre c (unit vector) is nearer
/// to the point a than to the point b (unit vectors), with kBisectorMargin to spare: the node lies
/// wholly on a's side of their bisector, so b is never the nearest in it. This separates points
/// far closer to each other than the node is large, which the distance bounds of prune_threshold
/// cannot: a tight cluster of sites seen from far away. With w = a - b, chord2(x, b) - chord2(x, a)
/// = |b|^2 - |a|^2 + 2 x.w = chord2(c, b) - chord2(c, a) + 2 (x - c).w, and for x within angle r
/// of c, (x - c).w >= -|w| (r + r^2 / 2), since cos(t + r) >= cos t - sin r - (1 - cos r) for
/// cos t >= 0. The squared chords from c, not c.w alone: pieces a few ulps off the unit sphere
/// (exact ties made so in the tests) differ in |a|^2 - |b|^2 by more than the margin. Only + - *
/// and sqrt, correctly rounded in float64 on the host and the device alike, so the two builds
/// decide the same bits.
QTMV_HD inline bool beyond_bisector(const Vec3& c, double radius, const Vec3& a, const Vec3& b) {
  const double wx = a.x - b.x, wy = a.y - b.y, wz = a.z - b.z;
  const double along = 0.5 * (grid::chord2(c, b) - grid::chord2(c, a));
  if (!(along > kBisectorMargin)) return false;
  const double w = sqrt(wx * wx + wy * wy + wz * wz);
  return along > w * (radius + 0.5 * radius * radius) + kBisectorMargin;
}

/// The bisector rule for two point pieces, a the node's nearest (least squared chord from its
/// centre, then least item): b is never the nearest piece anywhere in the node when it lies
/// wholly beyond their bisector, or when it is a's exact duplicate (the same bits, the same
/// fixed-cell flag) of a site no lower than a's, since consider() then gives every tie to a.
/// The duplicates matter: many sites at one point (a geocoder's town centre, the cell rule's
/// cell centres) are otherwise candidates of every node far from them.
QTMV_HD inline bool point_never_nearest(const Vec3& c, double radius, const Piece& a, const Piece& b) {
  if (a.a.x == b.a.x && a.a.y == b.a.y && a.a.z == b.a.z) {
    return (a.flags & kPieceFixed) == (b.flags & kPieceFixed) && a.site <= b.site;
  }
  return beyond_bisector(c, radius, a.a, b.a);
}

}  // namespace qtmv::label
