// Polygon validity: invalid polygons are named where they are read, never silently
// given a meaning.
//
// A feature's polygons are checked as the source gives them (in its CRS, before the
// transformation to WGS84), with GEOS through OGR: the first problem GEOS finds, with its reason
// and location (GEOSisValidDetail), e.g. "Self-intersection at (5, 5)". Two problems GEOS cannot
// take (OGR's export fails on them) are found here first: a ring that is not closed, and a ring
// of fewer than 4 points once closed.
//
// How an invalid polygon is read (what the man page promises): rings are closed, then each
// polygon is filled even-odd over all its rings (a cell centre is inside when a ray from it
// crosses the polygon's rings an odd number of times), the parts of a MultiPolygon are united,
// and every ring is also traced as a line of the site. A hole outside its shell is thus an
// island, a hole in a hole an island, a bow-tie its two triangles, a spike or a zero-area ring
// only the cells its line runs through.
//
// -makevalid replaces the geometry with OGR's MakeValid (GEOS's default "linework" method, as
// ogr2ogr -makevalid), and says what it became. It agrees with the reading above but for
// overlapping parts of a MultiPolygon (linework reads them even-odd: the overlap is a hole) and
// a hole sharing an edge with its shell (filled; its ring kept as a line).
//
// Rings crossing +-180 in uncut lon/lat data (an edge over 180 degrees of longitude, read the
// short way round under -wrap auto) look self-intersecting in flat lon/lat though they are not:
// such a polygon is not checked (nor repaired), under -wrap auto in a geographic CRS.
#pragma once

#include <cstdint>
#include <memory>
#include <optional>
#include <string>

#include <ogr_geometry.h>
#include <ogr_spatialref.h>

#include "sites/site_options.hpp"

namespace qtmv::sites {

/// What is wrong with a polygon: GEOS's reason and, when it gives one, the location (source CRS
/// coordinates, in the source's axis order).
struct PolygonProblem {
  std::string reason;  ///< "Self-intersection", "Hole lies outside shell", "Ring not closed", ...
  bool has_location = false;
  double x = 0, y = 0;
  /// "Self-intersection at (5, 5)".
  std::string describe() const;
};

/// Whether OGR has GEOS (without it nothing can be checked or repaired).
bool have_geos();

/// The first problem of the polygons of `geometry` (Polygon, MultiPolygon, or in a
/// GeometryCollection); nullopt when they are valid, or when it holds no polygon.
std::optional<PolygonProblem> find_polygon_problem(const OGRGeometry& geometry);

/// OGR's MakeValid of `geometry` (rings closed first); nullptr with `error` when it fails.
std::unique_ptr<OGRGeometry> make_valid(const OGRGeometry& geometry, std::string& error);

/// "Polygon of 2 rings", "MultiPolygon of 3 polygons", "GeometryCollection of 2 parts".
std::string describe_shape(const OGRGeometry& geometry);

/// The data axis (0: x, 1: y) that holds longitude when `srs` is geographic; -1 otherwise.
int longitude_axis(const OGRSpatialReference& srs);

/// Whether a ring of `geometry`'s polygons has an edge spanning more than `half_turn` along
/// data axis `axis` (180 degrees in the CRS's angular unit): a ring across +-180.
bool ring_crosses_antimeridian(const OGRGeometry& geometry, int axis, double half_turn);

/// The reader's side: checks each feature's polygons, warns (at most kMostListed lines, then a
/// count at finish()), fails under -strict, and repairs under -makevalid.
class PolygonValidityCheck {
 public:
  static constexpr std::uint64_t kMostListed = 20;

  /// `where_from` names file and layer in messages ("'F', layer 'L'"); `source` is the CRS the
  /// coordinates are in. Throws ReadError for -makevalid when OGR has no GEOS.
  PolygonValidityCheck(const ReadOptions& options, const OGRSpatialReference& source, std::string where_from);

  /// The problem of `geometry`'s polygons: nullopt when they are valid, when it holds none, or
  /// when they are not checked (no GEOS; rings across +-180 under -wrap auto). Changes nothing:
  /// several threads may call it at once, on different features.
  std::optional<PolygonProblem> problem_of(const OGRGeometry& geometry) const;

  /// Reports feature `fid`'s `problem` (from problem_of; called in feature order): a warning, or
  /// ReadError under -strict (unless -makevalid repairs it); under -makevalid `geometry` is
  /// replaced by its repair. Returns true when `geometry` was replaced.
  bool settle(std::int64_t fid, std::unique_ptr<OGRGeometry>& geometry, const std::optional<PolygonProblem>& problem);

  /// The line counting the warnings left out, if any (call once, after the last feature).
  void finish();

  std::uint64_t invalid() const { return invalid_; }    ///< invalid polygons found (features)
  std::uint64_t repaired() const { return repaired_; }  ///< of them, repaired by -makevalid
  /// For the summary line: "; 2 invalid polygon(s) (read by even-odd)", or "" when none.
  std::string summary_text() const;

 private:
  void say(const std::string& message);

  const ReadOptions& options_;
  std::string where_from_;
  bool enabled_ = true, told_no_geos_ = false;
  int lon_axis_ = -1;
  double half_turn_ = 180.0;
  std::uint64_t invalid_ = 0, repaired_ = 0, listed_ = 0;
};

}  // namespace qtmv::sites
