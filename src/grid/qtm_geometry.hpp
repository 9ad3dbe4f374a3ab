// QTM geometry: point location, cell centres, vertices and polygons (QTM-SPEC.md, "Geometry").
//
// All angles are in degrees. Each octant is mapped to the planar right triangle
// 0 <= w <= v <= 1 with v = (90 - lat') / 90 and w = (lon' / 90) v, where lon' and lat' are the
// octant's local longitude and latitude; rows and columns are cut in that plane.
#pragma once

#include <cmath>
#include <utility>

#include "qtm_code.hpp"
#include "qtm_math.hpp"

namespace qtmv::grid {

/// A geographic position: longitude and latitude (degrees).
struct LonLat {
  double lon, lat;
};

/// Longitude of octant o (0..7) at local longitude lon_local (degrees), without normalisation:
/// octant 1's lon' = 90 edge is +180 and octant 2's lon' = 0 edge is -180.
QTMV_HD inline double lon_from_local(int octant, double lon_local) {
  switch (octant) {
    case 0: return lon_local;
    case 1: return lon_local + 90.0;
    case 2: return lon_local - 180.0;
    case 3: return lon_local - 90.0;
    case 4: return 90.0 - lon_local;
    case 5: return 180.0 - lon_local;
    case 6: return -90.0 - lon_local;
    default: return -lon_local;
  }
}

QTMV_HD inline double lat_from_local(int octant, double lat_local) { return octant < 4 ? lat_local : -lat_local; }

/// Longitude (degrees) brought into [-180, 180). Exact: fmod is exact, and the one
/// correction step subtracts 360 from a value in [180, 360), which Sterbenz's lemma makes exact.
QTMV_HD inline double normalise_lon(double lon) {
  if (lon >= -180.0 && lon < 180.0) return lon;
  lon = fmod(lon, 360.0);
  if (lon >= 180.0) lon -= 360.0;
  if (lon < -180.0) lon += 360.0;
  return lon;
}

/// The cells along one parallel (latitude, degrees, in [-90, 90]) at a level: lonlat_to_code's
/// steps that depend on the latitude alone (the row, and where the row's squares are cut), done
/// once, and then code(lon) for each longitude. A raster's row of pixel centres is one parallel;
/// along a run of longitudes of one quadrant, column(local_lon(q, lon)) is all that changes.
class ParallelCells {
 public:
  QTMV_HD ParallelCells(double lat, int level) : level_(level), north_(lat >= 0.0) {
    const double lat_local = fabs(lat);
    v_ = (90.0 - lat_local) / 90.0;
    rows_ = static_cast<double>(rows_per_octant(level));
    const double vI = v_ * rows_;
    row_ = static_cast<std::uint64_t>(floor(vI));
    if (row_ > rows_per_octant(level) - 1) row_ = rows_per_octant(level) - 1;
    fv_ = vI - static_cast<double>(row_);
  }

  /// The row (0 .. 2^level - 1) of the parallel's cells in their octant.
  QTMV_HD std::uint64_t row() const { return row_; }
  /// Whether the parallel's cells lie in the northern octants (0..3), else the southern (4..7).
  QTMV_HD bool north() const { return north_; }
  /// The octant of the parallel's cells in quadrant q (0..3, quadrant_of).
  QTMV_HD int octant(int q) const { return north_ ? q : q + 4; }

  /// The quadrant (0..3: the northern octant) of a longitude in [-180, 180) (degrees).
  QTMV_HD static int quadrant_of(double lon) { return lon >= 0.0 ? (lon < 90.0 ? 0 : 1) : (lon < -90.0 ? 2 : 3); }

  /// The octant's local longitude (degrees, 0..90) of longitude lon in [-180, 180) of quadrant q
  /// on this parallel's side of the equator.
  QTMV_HD double local_lon(int q, double lon) const {
    if (north_) {
      const double offset[4] = {0.0, -90.0, 180.0, 90.0};
      return lon + offset[q];
    }
    const double base[4] = {90.0, 180.0, -90.0, 0.0};
    return base[q] - lon;
  }

  /// The column (0 .. 2 row) of the cell at local longitude lon_local (degrees, from local_lon).
  QTMV_HD std::uint64_t column(double lon_local) const {
    const double w = (lon_local / 90.0) * v_;
    // The square [a, a+1] x [i, i+1] of the plane; wI >= 0 (lon_local and v are), where
    // truncation is floor: no call of floor per point.
    const double wI = w * rows_;
    std::uint64_t a = static_cast<std::uint64_t>(wI);
    if (a > row_) a = row_;
    // Which half of the square: up when fw <= fv.
    const double fw = wI - static_cast<double>(a);
    std::uint64_t j = fw <= fv_ ? 2 * a : 2 * a + 1;
    if (j > 2 * row_) j = 2 * row_;
    return j;
  }

  /// The cell holding (lon, lat): lon any finite value (degrees). kInvalidCode for a NaN or
  /// infinite longitude.
  QTMV_HD Code code(double lon) const {
    if (!(lon - lon == 0.0)) return kInvalidCode;
    lon = normalise_lon(lon);
    const int q = quadrant_of(lon);
    const std::uint64_t j = column(local_lon(q, lon));
    return code_of({octant(q), static_cast<std::uint32_t>(row_), static_cast<std::uint32_t>(j)}, level_);
  }

 private:
  int level_;
  bool north_;
  double v_, rows_, fv_;
  std::uint64_t row_;
};

/// The cell that contains the point (lon, lat) (degrees), exactly the steps of the spec in
/// double precision. Longitude may be any finite value; latitude must lie in [-90, 90].
/// Gives kInvalidCode for a NaN or infinite coordinate, a latitude beyond +-90 or a bad level.
QTMV_HD inline Code lonlat_to_code(double lon, double lat, int level) {
  if (!is_valid_level(level) || !(lat >= -90.0 && lat <= 90.0) || !(lon - lon == 0.0)) return kInvalidCode;
  return ParallelCells(lat, level).code(lon);
}

/// Centre of a cell (degrees): the centroid of its planar triangle mapped back to the sphere.
QTMV_HD inline LonLat cell_centre(const Cell& c, int level) {
  const double rows = static_cast<double>(rows_per_octant(level));
  const double a = static_cast<double>(c.col / 2);
  const double i = static_cast<double>(c.row);
  double lon_local, lat_local;
  if (is_up(c)) {
    lon_local = 90.0 * (3.0 * a + 1.0) / (3.0 * i + 2.0);
    lat_local = 90.0 * (1.0 - (3.0 * i + 2.0) / (3.0 * rows));
  } else {
    lon_local = 90.0 * (3.0 * a + 2.0) / (3.0 * i + 1.0);
    lat_local = 90.0 * (1.0 - (3.0 * i + 1.0) / (3.0 * rows));
  }
  return {lon_from_local(c.octant, lon_local), lat_from_local(c.octant, lat_local)};
}

QTMV_HD inline LonLat cell_centre(Code code, int level) { return cell_centre(cell_of(code, level), level); }

/// Unit vector of a cell's centre, computed with the deterministic sincos_deg so that the
/// CPU and CUDA code get the same bits.
QTMV_HD inline Vec3 cell_centre_vector(const Cell& c, int level) {
  const LonLat p = cell_centre(c, level);
  return unit_vector(p.lon, p.lat);
}

QTMV_HD inline Vec3 cell_centre_vector(Code code, int level) { return cell_centre_vector(cell_of(code, level), level); }

/// cell_centre_vector to the same bits, keeping the sine and cosine of the last four latitudes
/// (degrees) met: a row's up cells share one latitude and its down cells another, so a pass
/// along a row computes only its longitudes'; a node's four children have three latitudes. One
/// per thread.
class CentreVectors {
 public:
  Vec3 operator()(const Cell& c, int level) {
    const LonLat p = cell_centre(c, level);
    double slon, clon;
    sincos_deg(p.lon, &slon, &clon);
    const Latitude& lat = latitude(p.lat);
    return {lat.cos * clon, lat.cos * slon, lat.sin};
  }
  Vec3 operator()(Code code, int level) { return (*this)(cell_of(code, level), level); }

 private:
  struct Latitude {
    double lat = 1000.0;  // none yet
    double sin = 0.0, cos = 0.0;
  };
  static constexpr int kLatitudes = 4;
  /// The latitude's entry; a new one replaces the one made longest ago.
  const Latitude& latitude(double lat) {
    for (const Latitude& l : last_) {
      if (l.lat == lat) return l;
    }
    Latitude& made = last_[oldest_];
    oldest_ = (oldest_ + 1) % kLatitudes;
    made.lat = lat;
    sincos_deg(lat, &made.sin, &made.cos);
    return made;
  }
  int oldest_ = 0;
  Latitude last_[kLatitudes];
};

/// Grid vertex (r, k), 0 <= k <= r <= 2^L, of an octant (degrees). The pole (r = 0) gets the
/// longitude of the octant's lon' = 0 side.
QTMV_HD inline LonLat grid_vertex(int octant, std::uint64_t r, std::uint64_t k, int level) {
  const double rows = static_cast<double>(rows_per_octant(level));
  const double lat_local = 90.0 * (1.0 - static_cast<double>(r) / rows);
  const double lon_local = r == 0 ? 0.0 : 90.0 * static_cast<double>(k) / static_cast<double>(r);
  return {lon_from_local(octant, lon_local), lat_from_local(octant, lat_local)};
}

/// The three vertices of a cell in the spec's order (degrees): up (i, a), (i+1, a), (i+1, a+1);
/// down (i, a), (i, a+1), (i+1, a+1).
QTMV_HD inline void cell_vertices(const Cell& c, int level, LonLat out[3]) {
  const std::uint64_t i = c.row, a = c.col / 2;
  out[0] = grid_vertex(c.octant, i, a, level);
  if (is_up(c)) {
    out[1] = grid_vertex(c.octant, i + 1, a, level);
  } else {
    out[1] = grid_vertex(c.octant, i, a + 1, level);
  }
  out[2] = grid_vertex(c.octant, i + 1, a + 1, level);
}

/// Most corners of a cell polygon.
constexpr int kMaxPolygonCorners = 4;

/// The cell as a ring in lon/lat (degrees), counter-clockwise, not closed; returns the number
/// of corners (3, or 4 for the pole cell of an octant, which is drawn as a quadrilateral with
/// two corners on latitude +-90). Edges are straight lines in lon/lat.
QTMV_HD inline int cell_polygon(const Cell& c, int level, LonLat out[kMaxPolygonCorners]) {
  if (c.row == 0) {
    const LonLat row1_start = grid_vertex(c.octant, 1, 0, level);
    const LonLat row1_end = grid_vertex(c.octant, 1, 1, level);
    out[0] = {row1_start.lon, c.octant < 4 ? 90.0 : -90.0};
    out[1] = row1_start;
    out[2] = row1_end;
    out[3] = {row1_end.lon, out[0].lat};
    return 4;
  }
  LonLat v[3];
  cell_vertices(c, level, v);
  // The spec's order is counter-clockwise for up cells and clockwise for down cells.
  out[0] = v[0];
  out[1] = is_up(c) ? v[1] : v[2];
  out[2] = is_up(c) ? v[2] : v[1];
  return 3;
}

/// Keys of grid vertices and of cell_polygon's corners: two corners of any cells of a level have
/// the same key exactly when they are the same point (shared across octants' sides, the equator
/// and the poles' lines; +-180 are two points, as the drawn cells are), so that edges are linked
/// by integers rather than by their coordinates' bits. Layout: bits 62-63 a tag (kVertexKey*),
/// bits 30-61 the row line r (on a pole's line: 0 north, 1 south), bits 0-29 the column g along
/// the row line from -180, lon = 90 g / r - 180 (on a pole's line: g = 0 to 4, the sides from
/// -180 to 180). Fits every level: r <= 2^kMaxLevel, g <= 4 r.
constexpr int kVertexKeyTagShift = 62;
constexpr int kVertexKeyRowShift = 30;
constexpr std::uint64_t kVertexKeyNorth = 0, kVertexKeySouth = 1, kVertexKeyEquator = 2, kVertexKeyPoleLine = 3;
static_assert(kMaxLevel + 3 <= kVertexKeyRowShift, "a vertex key's column fits below its row");
static_assert(kVertexKeyRowShift + kMaxLevel + 1 <= kVertexKeyTagShift, "a vertex key's row fits below its tag");

/// The key of grid vertex (r, k) of an octant (grid_vertex's), 0 < r <= 2^L, 0 <= k <= r.
QTMV_HD inline std::uint64_t vertex_key(int octant, std::uint64_t r, std::uint64_t k, int level) {
  const auto quarter = static_cast<std::uint64_t>((octant + 2) & 3);  // the octant's quarter of longitude from -180
  const bool north = octant < 4;  // south octants run their columns from east to west
  const std::uint64_t g = quarter * r + (north ? k : r - k);
  const std::uint64_t tag = r == rows_per_octant(level) ? kVertexKeyEquator : north ? kVertexKeyNorth : kVertexKeySouth;
  return tag << kVertexKeyTagShift | r << kVertexKeyRowShift | g;
}

/// The key of a pole cell's corner on its pole's line (cell_polygon's), on the octant's side
/// `side` (0: lon' = 0, 1: lon' = 90).
QTMV_HD inline std::uint64_t pole_line_key(int octant, std::uint64_t side) {
  const auto quarter = static_cast<std::uint64_t>((octant + 2) & 3);
  const bool north = octant < 4;
  return kVertexKeyPoleLine << kVertexKeyTagShift | std::uint64_t{north ? 0u : 1u} << kVertexKeyRowShift |
         (quarter + (north ? side : 1 - side));
}

/// The keys of cell_polygon's corners, in its order; returns their number.
QTMV_HD inline int cell_polygon_keys(const Cell& c, int level, std::uint64_t out[kMaxPolygonCorners]) {
  if (c.row == 0) {
    out[0] = pole_line_key(c.octant, 0);
    out[1] = vertex_key(c.octant, 1, 0, level);
    out[2] = vertex_key(c.octant, 1, 1, level);
    out[3] = pole_line_key(c.octant, 1);
    return 4;
  }
  const std::uint64_t i = c.row, a = c.col / 2;
  out[0] = vertex_key(c.octant, i, a, level);
  out[1] = vertex_key(c.octant, i + 1, is_up(c) ? a : a + 1, level);
  out[2] = is_up(c) ? vertex_key(c.octant, i + 1, a + 1, level) : vertex_key(c.octant, i, a + 1, level);
  return 3;
}

}  // namespace qtmv::grid
