// The region of a tile job's sites (tile_selection.hpp): caps on the sphere that hold the tile's
// cells and their neighbours, the lon/lat boxes that hold each cap's surroundings to its reach,
// and the check that a cap's nearest site lies within its reach. Pure geometry (no GDAL), in
// float64 with margins larger than its rounding.
#pragma once

#include <cstddef>
#include <cstdint>
#include <utility>
#include <vector>

#include "grid/qtm.hpp"
#include "grid/qtm_code_ranges.hpp"

namespace qtmv::sites {

/// A cell of a coarse level whose rows meet the tile, as a cap.
struct RegionCap {
  grid::Vec3 centre;       ///< the coarse cell's centre
  double lon = 0, lat = 0;  ///< of the centre (degrees)
  /// Angle (radians) within which lie the centres of the tile's cells in the coarse cell, of their
  /// neighbours, and of the cells that hold a site's points near them (the cell rule's distances).
  double radius = 0;
  /// Angle (radians) from the cap within which every site is read.
  double reach = 0;
  bool verified = false;  ///< a site read lies within reach - radius of the centre
  int octant = 0;
  std::uint32_t row = 0;  ///< of the coarse cell in its octant
};

/// A lon/lat box (degrees): lon0 <= lon1 within [-180, 180], lat0 <= lat1 within [-90, 90].
struct LonLatBox {
  double lon0 = -180, lon1 = 180, lat0 = -90, lat1 = 90;
};

/// The coarse level for a tile's caps at `level` when the source holds about `sites` sites: its
/// cells about an eighth of the sites' spacing, at most level 9 and at most `level`.
int coarse_level(int level, double sites);

/// About the spacing of `sites` sites spread over the sphere (radians).
double site_spacing(double sites);

/// The caps of the cells of level `coarse` whose rows meet `range` (whole rows of `level`), each
/// with reach `first_reach` (radians) beyond its radius at least.
std::vector<RegionCap> tile_caps(grid::CodeRange range, int level, int coarse, double first_reach);

/// What a tile's selection has read, slice by slice of latitude: the boxes it reads next hold,
/// with those read before, every point within radius + reach of each cap not yet verified, and
/// read nothing twice but where boxes join (a few per cent) or touch.
class ReadRegion {
 public:
  /// Slices of `step` degrees of latitude (step_for the first round's caps).
  explicit ReadRegion(double step);
  /// Half the thinnest reach of the unverified caps, between 0.05 and 5 degrees.
  static double step_for(const std::vector<RegionCap>& caps);
  /// The boxes to read next (split at +-180); from now on they count as read.
  std::vector<LonLatBox> next_boxes(const std::vector<RegionCap>& caps);

 private:
  using Interval = std::pair<double, double>;  // longitudes (degrees), within [-180, 180]
  void subtract_read(int slice, Interval piece, std::vector<Interval>& out) const;
  void mark_read(int slice, Interval piece);
  double step_;
  int count_;
  std::vector<std::vector<Interval>> read_;  // per slice: sorted, disjoint
};

/// The points of the sites read (degrees), bucketed by latitude and longitude.
class PointIndex {
 public:
  /// `sphere_points`: about how many points the sphere would hold at their density.
  PointIndex(const std::vector<grid::LonLat>& points, double sphere_points);
  /// The angle (radians) from `centre` (at lon, lat degrees) to the nearest point; HUGE_VAL
  /// when there is none. `start`: about where to look first (radians); `enough`: any point
  /// closer than this angle will do (0: the nearest).
  double nearest(const grid::Vec3& centre, double lon, double lat, double start, double enough = 0) const;

 private:
  double nearest_scanned(const grid::Vec3& centre, double lon, double lat, double angle, double enough) const;
  int lat_bucket(double lat) const;
  int lon_bucket(double lon) const;
  double step_ = 1;  // degrees per bucket
  int lats_ = 0, lons_ = 0;
  std::vector<std::uint32_t> first_;  // CSR: bucket b's points are [first_[b], first_[b + 1])
  std::vector<grid::Vec3> points_;
};

/// Marks verified each unverified cap that has a point of `points` closer to its centre than
/// reach - radius (less a margin); the others reach next as far beyond their radius as their
/// nearest point (or twice as far, with none). Returns those left.
std::size_t verify_caps(std::vector<RegionCap>& caps, const PointIndex& points);

}  // namespace qtmv::sites
