// Polygon validity (see polygon_validity.hpp for what is checked and how invalid polygons are read).
#include "sites/polygon_validity.hpp"

#include <ogr_api.h>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <sstream>
#include <utility>
#include <vector>

#include "gdal/error_capture.hpp"

#ifdef QTMV_HAVE_GEOS_C
#include <geos_c.h>
#endif

namespace qtmv::sites {

namespace {

bool has_polygon(const OGRGeometry& g) {
  const OGRwkbGeometryType type = wkbFlatten(g.getGeometryType());
  if (type == wkbPolygon) return !g.IsEmpty();
  if (type == wkbMultiPolygon || type == wkbGeometryCollection) {
    const auto& c = *g.toGeometryCollection();
    for (int k = 0; k < c.getNumGeometries(); ++k) {
      if (has_polygon(*c.getGeometryRef(k))) return true;
    }
  }
  return false;
}

/// Calls `f` on each ring of each polygon of `g` (members of collections included).
template <typename F>
void for_each_ring(const OGRGeometry& g, F&& f) {
  const OGRwkbGeometryType type = wkbFlatten(g.getGeometryType());
  if (type == wkbPolygon) {
    for (const OGRLinearRing* ring : *g.toPolygon()) f(*ring);
  } else if (type == wkbMultiPolygon || type == wkbGeometryCollection) {
    const auto& c = *g.toGeometryCollection();
    for (int k = 0; k < c.getNumGeometries(); ++k) for_each_ring(*c.getGeometryRef(k), f);
  }
}

/// The rings GEOS cannot take: fewer than 4 points once closed (first found), or not closed.
std::optional<PolygonProblem> ring_problem(const OGRGeometry& g) {
  std::optional<PolygonProblem> too_few, unclosed;
  for_each_ring(g, [&](const OGRLinearRing& ring) {
    const int n = ring.getNumPoints();
    if (n == 0) return;
    const bool closed = ring.getX(0) == ring.getX(n - 1) && ring.getY(0) == ring.getY(n - 1);
    if (n + (closed ? 0 : 1) < 4 && !too_few) too_few = PolygonProblem{"Too few points in ring", true, ring.getX(0), ring.getY(0)};
    if (!closed && !unclosed) unclosed = PolygonProblem{"Ring not closed", true, ring.getX(n - 1), ring.getY(n - 1)};
  });
  return too_few ? too_few : unclosed;
}

#ifdef QTMV_HAVE_GEOS_C
/// GEOS's verdict on one polygonal geometry (a Polygon or a MultiPolygon, rings closed).
std::optional<PolygonProblem> geos_problem(const OGRGeometry& g) {
  GEOSContextHandle_t context = OGRGeometry::createGEOSContext();
  std::optional<PolygonProblem> problem;
  if (GEOSGeom geos = g.exportToGEOS(context)) {
    char* reason = nullptr;
    GEOSGeometry* location = nullptr;
    if (GEOSisValidDetail_r(context, geos, 0, &reason, &location) == 0) {
      problem = PolygonProblem{reason ? reason : "invalid", false, 0, 0};
      if (location && GEOSGeomGetX_r(context, location, &problem->x) == 1 &&
          GEOSGeomGetY_r(context, location, &problem->y) == 1) {
        problem->has_location = true;
      }
    }
    if (reason) GEOSFree_r(context, reason);
    if (location) GEOSGeom_destroy_r(context, location);
    GEOSGeom_destroy_r(context, geos);
  } else {
    problem = PolygonProblem{"GEOS cannot read it", false, 0, 0};
  }
  OGRGeometry::freeGEOSContext(context);
  return problem;
}
#else
// Without GEOS's C headers at build time: OGR's verdict, without reason or location.
std::optional<PolygonProblem> geos_problem(const OGRGeometry& g) {
  if (g.IsValid()) return std::nullopt;
  return PolygonProblem{"invalid (GEOS gives no reason in this build)", false, 0, 0};
}
#endif

/// Checks each polygonal unit: a Polygon or MultiPolygon as a whole (overlapping parts are
/// invalid), the members of a GeometryCollection one by one (they may overlap).
std::optional<PolygonProblem> polygonal_problem(const OGRGeometry& g) {
  const OGRwkbGeometryType type = wkbFlatten(g.getGeometryType());
  if (type == wkbPolygon || type == wkbMultiPolygon) {
    if (g.IsEmpty()) return std::nullopt;
    return geos_problem(g);
  }
  if (type == wkbGeometryCollection) {
    const auto& c = *g.toGeometryCollection();
    for (int k = 0; k < c.getNumGeometries(); ++k) {
      if (auto problem = polygonal_problem(*c.getGeometryRef(k))) return problem;
    }
  }
  return std::nullopt;
}

std::string number(double v) {
  std::ostringstream s;
  s.precision(15);
  s << v;
  return s.str();
}

}  // namespace

std::string PolygonProblem::describe() const {
  return has_location ? reason + " at (" + number(x) + ", " + number(y) + ")" : reason;
}

bool have_geos() { return OGRGeometryFactory::haveGEOS(); }

std::optional<PolygonProblem> find_polygon_problem(const OGRGeometry& geometry) {
  if (!has_polygon(geometry)) return std::nullopt;
  const std::optional<PolygonProblem> rings = ring_problem(geometry);
  if (rings && rings->reason != "Ring not closed") return rings;
  // GEOS's messages (OGR raises them as warnings too) are ours to report, once, by FID.
  gdal::ErrorCapture quiet;
  std::optional<PolygonProblem> problem;
  if (rings) {  // an unclosed ring is read closed: check that, and name the closing if all else is well
    std::unique_ptr<OGRGeometry> closed(geometry.clone());
    closed->closeRings();
    problem = polygonal_problem(*closed);
  } else {
    problem = polygonal_problem(geometry);
  }
  return problem ? problem : rings;
}

std::unique_ptr<OGRGeometry> make_valid(const OGRGeometry& geometry, std::string& error) {
  std::unique_ptr<OGRGeometry> closed(geometry.clone());
  closed->closeRings();
  gdal::ErrorCapture errors;
  std::unique_ptr<OGRGeometry> valid(closed->MakeValid());
  error = errors.take();
  if (!valid && error.empty()) error = "MakeValid gave nothing";
  return valid;
}

std::string describe_shape(const OGRGeometry& geometry) {
  const OGRwkbGeometryType type = wkbFlatten(geometry.getGeometryType());
  std::string name = OGRGeometryTypeToName(type);  // "Multi Polygon": written as in WKT, MultiPolygon
  name.erase(std::remove(name.begin(), name.end(), ' '), name.end());
  if (geometry.IsEmpty()) return "an empty " + name;
  auto count = [](int n, const char* what) { return std::to_string(n) + " " + what + (n == 1 ? "" : "s"); };
  if (type == wkbPolygon) {
    const auto& p = *geometry.toPolygon();
    return name + " of " + count(p.getNumInteriorRings() + (p.getExteriorRing() ? 1 : 0), "ring");
  }
  if (OGR_GT_IsSubClassOf(type, wkbGeometryCollection)) {
    const auto& c = *geometry.toGeometryCollection();
    if (type == wkbGeometryCollection) {
      std::string parts;
      for (int k = 0; k < c.getNumGeometries(); ++k) {
        parts += (k ? ", " : "") + describe_shape(*c.getGeometryRef(k));
      }
      return name + " (" + parts + ")";
    }
    return name + " of " + count(c.getNumGeometries(), type == wkbMultiPolygon ? "polygon" : "part");
  }
  return name;
}

int longitude_axis(const OGRSpatialReference& srs) {
  if (!srs.IsGeographic()) return -1;
  int srs_axis = -1;
  for (int i = 0; i < 2 && srs_axis < 0; ++i) {
    OGRAxisOrientation orientation = OAO_Other;
    srs.GetAxis(nullptr, i, &orientation);
    if (orientation == OAO_East || orientation == OAO_West) srs_axis = i;
  }
  if (srs_axis < 0) srs_axis = 0;
  const std::vector<int>& mapping = srs.GetDataAxisToSRSAxisMapping();
  for (std::size_t d = 0; d < mapping.size() && d < 2; ++d) {
    if (std::abs(mapping[d]) - 1 == srs_axis) return static_cast<int>(d);
  }
  return srs_axis;
}

bool ring_crosses_antimeridian(const OGRGeometry& geometry, int axis, double half_turn) {
  bool crosses = false;
  for_each_ring(geometry, [&](const OGRLinearRing& ring) {
    for (int k = 1; k < ring.getNumPoints() && !crosses; ++k) {
      const double a = axis == 0 ? ring.getX(k - 1) : ring.getY(k - 1);
      const double b = axis == 0 ? ring.getX(k) : ring.getY(k);
      crosses = std::fabs(b - a) > half_turn;
    }
  });
  return crosses;
}

// --- the reader's side ------------------------------------------------------------------------------

PolygonValidityCheck::PolygonValidityCheck(const ReadOptions& options, const OGRSpatialReference& source,
                                           std::string where_from)
    : options_(options), where_from_(std::move(where_from)) {
  enabled_ = have_geos();
  if (!enabled_ && options.make_valid) throw ReadError("-makevalid: this GDAL was built without GEOS");
  if (options.wrap == WrapMode::automatic) {
    lon_axis_ = longitude_axis(source);
    if (lon_axis_ >= 0) {
      const double degrees_per_unit = source.GetAngularUnits(nullptr) / (M_PI / 180.0);
      half_turn_ = 180.0 / (degrees_per_unit > 0 ? degrees_per_unit : 1.0);
    }
  }
}

void PolygonValidityCheck::say(const std::string& message) {
  if (++listed_ <= kMostListed && options_.messages) options_.messages(Severity::warning, message);
}

std::optional<PolygonProblem> PolygonValidityCheck::problem_of(const OGRGeometry& geometry) const {
  if (!enabled_ || !has_polygon(geometry)) return std::nullopt;
  // Read across +-180 by -wrap auto: flat lon/lat would call it self-intersecting.
  if (lon_axis_ >= 0 && ring_crosses_antimeridian(geometry, lon_axis_, half_turn_)) return std::nullopt;
  return find_polygon_problem(geometry);
}

bool PolygonValidityCheck::settle(std::int64_t fid, std::unique_ptr<OGRGeometry>& geometry,
                                  const std::optional<PolygonProblem>& problem) {
  if (!enabled_ && !told_no_geos_ && has_polygon(*geometry)) {
    if (options_.messages) {
      options_.messages(Severity::warning, where_from_ + ": this GDAL was built without GEOS: polygons are not "
                                                         "checked for validity");
    }
    told_no_geos_ = true;
  }
  if (!problem) return false;
  ++invalid_;
  const std::string what = where_from_ + ", FID " + std::to_string(fid) + ": invalid polygon (" + problem->describe() + ")";
  if (options_.make_valid) {
    std::string error;
    std::unique_ptr<OGRGeometry> valid = make_valid(*geometry, error);
    if (!valid) {
      const std::string message = what + "; -makevalid cannot repair it (GDAL: " + error + ")";
      if (options_.strict) throw ReadError(message + " (-strict)");
      say(message + "; read by even-odd over all rings");
      return false;
    }
    ++repaired_;
    say(what + "; repaired by -makevalid: " + describe_shape(*geometry) + " became " + describe_shape(*valid));
    geometry = std::move(valid);
    return true;
  }
  if (options_.strict) throw ReadError(what + " (-strict; -makevalid repairs it)");
  say(what + "; read by even-odd over all rings (-makevalid repairs it)");
  return false;
}

void PolygonValidityCheck::finish() {
  if (listed_ > kMostListed && options_.messages) {
    options_.messages(Severity::warning, where_from_ + ": " + std::to_string(listed_ - kMostListed) +
                                             " more invalid polygon(s) not listed (" + std::to_string(invalid_) +
                                             " in all)");
  }
}

std::string PolygonValidityCheck::summary_text() const {
  if (invalid_ == 0) return "";
  return "; " + std::to_string(invalid_) + " invalid polygon(s) " +
         (repaired_ > 0 ? "(" + std::to_string(repaired_) + " repaired by -makevalid)" : "(read by even-odd)");
}

}  // namespace qtmv::sites
