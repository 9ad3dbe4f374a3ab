#include "sites/site_builder.hpp"

#include <cmath>
#include <stdexcept>
#include <utility>

#include "sites/lon_unwrap.hpp"
#include "sites/site_cells.hpp"

namespace qtmv::sites {

SiteBuilder::SiteBuilder(int level, EdgeShape edges, WrapMode wrap)
    : level_(level), edges_(edges), wrap_(wrap), tracer_(level, edges), filler_(level) {
  geometry_.level = level;
}

std::int32_t SiteBuilder::begin_site() {
  if (current_ >= 0) throw std::logic_error("SiteBuilder::begin_site: the previous site is not finished");
  current_ = geometry_.site_count++;
  hits_.clear();
  short_way_edges_ = 0;
  return current_;
}

void SiteBuilder::add_point(const grid::LonLat& point) { tracer_.trace(&point, 1, current_, geometry_.pieces, hits_); }

void SiteBuilder::add_line(const grid::LonLat* vertices, std::size_t count) {
  const UnwrappedPath path = unwrap_longitudes(vertices, count, false, wrap_);
  short_way_edges_ += path.short_way_edges;
  tracer_.trace(path.vertices.data(), path.vertices.size(), current_, geometry_.pieces, hits_, nullptr,
                path.straight.data());
}

void SiteBuilder::add_polygon(const std::vector<LonLatPath>& rings) {
  std::vector<FillRing> fill_rings;
  for (const LonLatPath& input : rings) {
    if (input.empty()) continue;
    const LonLatPath* ring = &input;
    LonLatPath closed;
    if (input.front().lon != input.back().lon || input.front().lat != input.back().lat) {
      closed = input;
      closed.push_back(input.front());
      ring = &closed;
    }
    UnwrappedPath path = unwrap_longitudes(ring->data(), ring->size(), true, wrap_);
    short_way_edges_ += path.short_way_edges;
    FillRing fill_ring;
    fill_ring.winding = path.winding;
    // Geodesic edges are filled along their samples (a quarter cell edge apart).
    tracer_.trace(path.vertices.data(), path.vertices.size(), current_, geometry_.pieces, hits_,
                  edges_ == EdgeShape::geodesic ? &fill_ring.vertices : nullptr, path.straight.data());
    if (edges_ != EdgeShape::geodesic) {
      fill_ring.vertices = std::move(path.vertices);
    } else if (fill_ring.vertices.size() > 1) {  // the geodesics chose their own way round
      fill_ring.winding =
          static_cast<int>(std::lround((fill_ring.vertices.back().lon - fill_ring.vertices.front().lon) / 360.0));
    }
    fill_rings.push_back(std::move(fill_ring));
  }
  fill_cells_.clear();
  fill_nodes_.clear();
  filler_.cover(fill_rings, fill_cells_, fill_nodes_);
  for (grid::Code code : fill_cells_) geometry_.fixed_cells.push_back({code, current_});
  for (const PolygonFiller::CoverNode& n : fill_nodes_) geometry_.fixed_nodes.push_back({n.code, n.level, current_});
}

void SiteBuilder::end_site() {
  append_site_cells(hits_, current_, geometry_.site_cells);
  hits_.clear();
  current_ = -1;
}

SiteGeometry SiteBuilder::take_geometry() {
  SiteGeometry out = std::move(geometry_);
  geometry_ = SiteGeometry{};
  geometry_.level = level_;
  return out;
}

}  // namespace qtmv::sites
