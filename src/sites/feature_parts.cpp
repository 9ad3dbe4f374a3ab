#include "sites/feature_parts.hpp"

namespace qtmv::sites {

void FeatureParts::add_curve(const OGRSimpleCurve& curve, Kind kind, int polygon) {
  const int n = curve.getNumPoints();
  if (n == 0) return;
  const std::size_t begin = points.size();
  points.resize(begin + static_cast<std::size_t>(n));
  for (int k = 0; k < n; ++k) points[begin + static_cast<std::size_t>(k)] = {curve.getX(k), curve.getY(k)};
  parts.push_back({kind, begin, points.size(), polygon});
}

void FeatureParts::truncate(std::size_t part_begin, std::size_t point_begin) {
  parts.resize(part_begin);
  points.resize(point_begin);
}

void FeatureParts::clear() {
  points.clear();
  parts.clear();
  polygons = 0;
}

bool gather_parts(const OGRGeometry& geometry, FeatureParts& out, std::string& reason) {
  if (geometry.IsEmpty()) return true;
  switch (wkbFlatten(geometry.getGeometryType())) {
    case wkbPoint: {
      const auto& p = *geometry.toPoint();
      out.points.push_back({p.getX(), p.getY()});
      out.parts.push_back({FeatureParts::kPoint, out.points.size() - 1, out.points.size(), -1});
      return true;
    }
    case wkbLineString:
      out.add_curve(*geometry.toLineString(), FeatureParts::kLine, -1);
      return true;
    case wkbPolygon:
    case wkbTriangle: {
      const auto& polygon = *geometry.toPolygon();
      const int index = out.polygons++;
      if (const OGRLinearRing* ring = polygon.getExteriorRing()) out.add_curve(*ring, FeatureParts::kRing, index);
      for (int k = 0; k < polygon.getNumInteriorRings(); ++k) {
        out.add_curve(*polygon.getInteriorRing(k), FeatureParts::kRing, index);
      }
      return true;
    }
    case wkbMultiPoint:
    case wkbMultiLineString:
    case wkbMultiPolygon:
    case wkbGeometryCollection: {
      const auto& collection = *geometry.toGeometryCollection();
      for (int k = 0; k < collection.getNumGeometries(); ++k) {
        if (!gather_parts(*collection.getGeometryRef(k), out, reason)) return false;
      }
      return true;
    }
    default:
      reason = std::string("unsupported geometry type ") + OGRGeometryTypeToName(geometry.getGeometryType());
      return false;
  }
}

std::size_t point_count(const OGRGeometry& geometry) {
  switch (wkbFlatten(geometry.getGeometryType())) {
    case wkbPolygon:
    case wkbTriangle: {
      const auto& polygon = *geometry.toPolygon();
      std::size_t n = 0;
      for (const OGRLinearRing* ring : polygon) n += static_cast<std::size_t>(ring->getNumPoints());
      return n;
    }
    case wkbLineString:
      return static_cast<std::size_t>(geometry.toLineString()->getNumPoints());
    case wkbMultiPoint:
    case wkbMultiLineString:
    case wkbMultiPolygon:
    case wkbGeometryCollection: {
      std::size_t n = 0;
      for (const OGRGeometry* part : *geometry.toGeometryCollection()) n += point_count(*part);
      return n;
    }
    default:
      return 1;
  }
}

}  // namespace qtmv::sites
