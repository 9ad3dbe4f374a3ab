#include "label/synthetic_sites.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>

#include "grid/qtm_checks.hpp"
#include "label/label_math.hpp"

namespace qtmv::label {

namespace {

grid::Code code_of_vector(const Vec3& v, int level) {
  const double lon = std::atan2(v.y, v.x) / grid::kDegree;
  const double lat = std::asin(std::max(-1.0, std::min(1.0, v.z))) / grid::kDegree;
  return grid::lonlat_to_code(lon, lat, level);
}

void add_site_cell(SiteGeometry& g, grid::Code code, std::int32_t site, std::uint32_t piece) {
  if (!g.site_cells.empty()) {
    SiteCell& last = g.site_cells.back();
    if (last.code == code && last.site == site && last.piece_end >= piece) {
      last.piece_end = std::max(last.piece_end, piece + 1);
      return;
    }
  }
  g.site_cells.push_back({code, site, piece, piece + 1});
}

void note_site(SiteGeometry& g, std::int32_t site) {
  if (site < 0) throw std::invalid_argument("site ids must not be negative");
  g.site_count = std::max(g.site_count, site + 1);
}

}  // namespace

void add_point(SiteGeometry& g, double lon, double lat, std::int32_t site) {
  note_site(g, site);
  const grid::Code code = grid::lonlat_to_code(lon, lat, g.level);
  if (code == grid::kInvalidCode) throw std::invalid_argument("a point site has an invalid coordinate");
  const Vec3 p = grid::unit_vector(lon, lat);
  const auto piece = static_cast<std::uint32_t>(g.pieces.size());
  g.pieces.push_back({p, p, site});
  add_site_cell(g, code, site, piece);
}

void add_arc(SiteGeometry& g, double lon1, double lat1, double lon2, double lat2, std::int32_t site) {
  note_site(g, site);
  const Vec3 a = grid::unit_vector(lon1, lat1), b = grid::unit_vector(lon2, lat2);
  const double angle = chord2_to_angle(grid::chord2(a, b));
  if (!(angle < grid::kPi * (1.0 - 1e-9))) throw std::invalid_argument("an arc site spans 180 degrees or more");
  const double max_piece = max_piece_degrees(g.level) * grid::kDegree;
  const int pieces = std::max(1, static_cast<int>(std::ceil(angle / max_piece)));
  const double sin_angle = std::sin(angle);
  auto at = [&](int k) -> Vec3 {
    if (k == 0) return a;
    if (k == pieces) return b;
    const double t = static_cast<double>(k) / pieces;
    const double wa = std::sin((1.0 - t) * angle) / sin_angle, wb = std::sin(t * angle) / sin_angle;
    Vec3 p{wa * a.x + wb * b.x, wa * a.y + wb * b.y, wa * a.z + wb * b.z};
    const double norm = std::sqrt(grid::dot(p, p));
    return {p.x / norm, p.y / norm, p.z / norm};
  };
  Vec3 from = a;
  for (int k = 1; k <= pieces; ++k) {
    const Vec3 to = at(k);
    const auto piece = static_cast<std::uint32_t>(g.pieces.size());
    g.pieces.push_back({from, to, site});
    Vec3 mid = from + to;
    const double norm = std::sqrt(grid::dot(mid, mid));
    mid = {mid.x / norm, mid.y / norm, mid.z / norm};
    add_site_cell(g, code_of_vector(from, g.level), site, piece);
    add_site_cell(g, code_of_vector(mid, g.level), site, piece);
    add_site_cell(g, code_of_vector(to, g.level), site, piece);
    from = to;
  }
}

void add_fixed_cell(SiteGeometry& g, grid::Code code, std::int32_t site) {
  note_site(g, site);
  grid::require_code(code, g.level);
  g.fixed_cells.push_back({code, site});
}

}  // namespace qtmv::label
