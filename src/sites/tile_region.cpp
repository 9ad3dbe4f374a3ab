#include "sites/tile_region.hpp"

#include <algorithm>
#include <cmath>

#include "common/openmp_threads.hpp"

namespace qtmv::sites {

namespace {

constexpr double kRadiansPerDegree = M_PI / 180.0;
constexpr double kSphereSquareDegrees = 41252.96;
/// Far above float64's rounding of the angles below (radians; about a millimetre).
constexpr double kMarginRadians = 1e-9;
/// Boxes grow by this on every side (degrees): above the rounding of their corners.
constexpr double kBoxMarginDegrees = 1e-6;

double angle_between(const grid::Vec3& a, const grid::Vec3& b) {
  const grid::Vec3 c = grid::cross(a, b);
  return std::atan2(std::sqrt(grid::dot(c, c)), grid::dot(a, b));
}

/// A box before it is split at +-180: longitudes may run past it (one octant's span at most
/// beyond), or cover every longitude.
struct RawBox {
  double lon0, lon1, lat0, lat1;
  bool all_lon = false;
  double area() const {
    const double width = all_lon ? 2 * M_PI : (lon1 - lon0) * kRadiansPerDegree;
    return width * (std::sin(lat1 * kRadiansPerDegree) - std::sin(lat0 * kRadiansPerDegree));
  }
};

/// The box of the points within `angle` (radians) of (lon, lat) (degrees).
RawBox cap_box(double lon, double lat, double angle) {
  const double degrees = angle / kRadiansPerDegree + kBoxMarginDegrees;
  RawBox box{lon, lon, std::max(-90.0, lat - degrees), std::min(90.0, lat + degrees)};
  const double cos_lat = std::cos(lat * kRadiansPerDegree);
  // A cap that reaches a pole holds every longitude near it; else its longitudes are within
  // asin(sin(angle) / cos(lat)) of its centre's.
  if (angle >= M_PI / 2 || lat - degrees <= -90.0 || lat + degrees >= 90.0 || std::sin(angle) >= cos_lat) {
    box.all_lon = true;
    return box;
  }
  const double half = std::asin(std::sin(angle) / cos_lat) / kRadiansPerDegree + kBoxMarginDegrees;
  box.lon0 = lon - half;
  box.lon1 = lon + half;
  return box;
}

/// The smallest box holding both (b shifted by 360 degrees where that is narrower).
RawBox join(const RawBox& a, const RawBox& b) {
  RawBox out{0, 0, std::min(a.lat0, b.lat0), std::max(a.lat1, b.lat1)};
  if (a.all_lon || b.all_lon) {
    out.all_lon = true;
    return out;
  }
  double best = 1e300;
  for (const double shift : {-360.0, 0.0, 360.0}) {
    const double lon0 = std::min(a.lon0, b.lon0 + shift), lon1 = std::max(a.lon1, b.lon1 + shift);
    if (lon1 - lon0 < best) {
      best = lon1 - lon0;
      out.lon0 = lon0;
      out.lon1 = lon1;
    }
  }
  out.all_lon = best >= 360.0;
  return out;
}

void split_at_antimeridian(const RawBox& box, std::vector<LonLatBox>& out) {
  if (box.all_lon) {
    out.push_back({-180.0, 180.0, box.lat0, box.lat1});
    return;
  }
  double lon0 = box.lon0, lon1 = box.lon1;
  while (lon0 < -180.0) lon0 += 360.0, lon1 += 360.0;
  while (lon0 >= 180.0) lon0 -= 360.0, lon1 -= 360.0;
  if (lon1 <= 180.0) {
    out.push_back({lon0, lon1, box.lat0, box.lat1});
  } else {
    out.push_back({lon0, 180.0, box.lat0, box.lat1});
    out.push_back({-180.0, std::min(180.0, lon1 - 360.0), box.lat0, box.lat1});
  }
}

}  // namespace

double site_spacing(double sites) {
  return std::sqrt(kSphereSquareDegrees / std::max(1.0, sites)) * kRadiansPerDegree;
}

int coarse_level(int level, double sites) {
  const double spacing_degrees = site_spacing(sites) / kRadiansPerDegree;
  // A cap's reach is its radius plus the distance to its nearest site: cells an eighth of the
  // spacing keep the radius small beside it.
  const int fine = static_cast<int>(std::floor(std::log2(90.0 / spacing_degrees))) + 4;
  return std::max(0, std::min({fine, 9, level}));
}

std::vector<RegionCap> tile_caps(grid::CodeRange range, int level, int coarse, double first_reach) {
  // A cell's diameter at `level` is below 90 / 2^level degrees times 1.5: twice that is room for
  // a neighbour's centre, and for the cell-rule distance between cell centres.
  const double cell = 2.0 * 90.0 / static_cast<double>(grid::rows_per_octant(level)) * kRadiansPerDegree;
  // The coarse cells of the rows that meet the range (a row's cells meet it alike), in code order.
  std::vector<grid::Code> codes;
  for (int octant = 0; octant < grid::kOctants; ++octant) {
    for (std::uint32_t row = 0; row < grid::rows_per_octant(coarse); ++row) {
      const grid::Cell first{octant, row, 0};
      if (!grid::rows_meet(range, first, coarse, level)) continue;
      const grid::Code code = grid::code_of(first, coarse);
      for (std::uint32_t col = 0; col <= 2 * row; ++col) codes.push_back(code + col);
    }
  }
  std::vector<RegionCap> caps(codes.size());
  const auto n = static_cast<std::int64_t>(codes.size());
#pragma omp parallel for schedule(static) num_threads(thread_count(0))
  for (std::int64_t k = 0; k < n; ++k) {
    const grid::Cell c = grid::cell_of(codes[static_cast<std::size_t>(k)], coarse);
    RegionCap& cap = caps[static_cast<std::size_t>(k)];
    const grid::LonLat centre = grid::cell_centre(c, coarse);
    cap.lon = centre.lon;
    cap.lat = centre.lat;
    cap.centre = grid::unit_vector(centre.lon, centre.lat);
    grid::LonLat corners[3];
    grid::cell_vertices(c, coarse, corners);
    double widest = 0;
    for (const grid::LonLat& corner : corners) {
      widest = std::max(widest, angle_between(cap.centre, grid::unit_vector(corner.lon, corner.lat)));
    }
    // The cell's sides are not great circles: a quarter more than its corners' distance holds them.
    cap.radius = 1.25 * widest + 1.5 * cell + kMarginRadians;
    cap.reach = cap.radius + first_reach;
    cap.octant = c.octant;
    cap.row = c.row;
  }
  return caps;
}

namespace {

/// Adds `part` to a slice's boxes (one latitude range, disjoint longitudes): joined with those
/// it meets or nearly meets.
void add_to_slice(std::vector<RawBox>& slice, RawBox part) {
  const double near = 0.25 * (part.all_lon ? 360.0 : part.lon1 - part.lon0);
  for (std::size_t k = 0; k < slice.size();) {
    const RawBox& box = slice[k];
    const RawBox both = join(box, part);
    const double width_both = both.all_lon ? 360.0 : both.lon1 - both.lon0;
    const double widths = (box.all_lon ? 360.0 : box.lon1 - box.lon0) + (part.all_lon ? 360.0 : part.lon1 - part.lon0);
    if (width_both <= widths + near) {
      part = both;
      slice.erase(slice.begin() + static_cast<std::ptrdiff_t>(k));
      k = 0;
    } else {
      ++k;
    }
  }
  slice.push_back(part);
}

}  // namespace

std::vector<LonLatBox> reach_boxes(const std::vector<RegionCap>& caps) {
  // Slices of latitude, each a few boxes that hold the caps' boxes that meet it: disjoint, so
  // that no feature is read twice; thin beside the caps, so that their longitudes waste little.
  double thinnest = 180.0;
  for (const RegionCap& cap : caps) {
    if (!cap.verified) thinnest = std::min(thinnest, (cap.radius + cap.reach) / kRadiansPerDegree);
  }
  const double step = std::max(0.05, std::min(5.0, thinnest / 2));
  const int count = static_cast<int>(std::ceil(180.0 / step));
  std::vector<std::vector<RawBox>> slices(static_cast<std::size_t>(count));
  for (const RegionCap& cap : caps) {
    if (cap.verified) continue;
    const RawBox box = cap_box(cap.lon, cap.lat, cap.radius + cap.reach + kMarginRadians);
    const int first = std::max(0, static_cast<int>(std::floor((box.lat0 + 90.0) / step)));
    const int last = std::min(count - 1, static_cast<int>(std::floor((box.lat1 + 90.0) / step)));
    for (int k = first; k <= last; ++k) {
      RawBox part = box;
      part.lat0 = -90.0 + k * step;
      part.lat1 = std::min(90.0, -90.0 + (k + 1) * step);
      add_to_slice(slices[static_cast<std::size_t>(k)], part);
    }
  }
  // Then a slice's box joins the one of the slice before that it meets while the join's area
  // stays within a tenth of theirs.
  struct Open {
    RawBox box;
    double useful;  // its slices' areas
  };
  std::vector<RawBox> done;
  std::vector<Open> open, next;
  for (const std::vector<RawBox>& slice : slices) {
    next.clear();
    for (const RawBox& box : slice) {
      const double area = box.area();
      bool joined = false;
      for (Open& o : open) {
        const RawBox both = join(o.box, box);
        if (o.useful >= 0 && both.area() <= 1.1 * (o.useful + area)) {
          next.push_back({both, o.useful + area});
          o.useful = -1;  // taken
          joined = true;
          break;
        }
      }
      if (!joined) next.push_back({box, area});
    }
    for (const Open& o : open) {
      if (o.useful >= 0) done.push_back(o.box);
    }
    open.swap(next);
  }
  for (const Open& o : open) done.push_back(o.box);
  std::vector<LonLatBox> out;
  for (const RawBox& box : done) split_at_antimeridian(box, out);
  return out;
}

PointIndex::PointIndex(const std::vector<grid::LonLat>& points, double sphere_points) {
  // About one point a bucket where the points are, between a quarter degree and ten degrees.
  step_ = std::max(0.25, std::min(10.0, std::sqrt(kSphereSquareDegrees / std::max(1.0, sphere_points))));
  lats_ = static_cast<int>(std::ceil(180.0 / step_));
  lons_ = static_cast<int>(std::ceil(360.0 / step_));
  std::vector<std::uint32_t> bucket(points.size());
  first_.assign(static_cast<std::size_t>(lats_) * lons_ + 1, 0);
  for (std::size_t k = 0; k < points.size(); ++k) {
    bucket[k] = static_cast<std::uint32_t>(lat_bucket(points[k].lat) * lons_ + lon_bucket(points[k].lon));
    ++first_[bucket[k] + 1];
  }
  for (std::size_t b = 1; b < first_.size(); ++b) first_[b] += first_[b - 1];
  std::vector<std::uint32_t> fill(first_.begin(), first_.end() - 1);
  points_.resize(points.size());
  for (std::size_t k = 0; k < points.size(); ++k) {
    points_[fill[bucket[k]]++] = grid::unit_vector(grid::normalise_lon(points[k].lon), points[k].lat);
  }
}

int PointIndex::lat_bucket(double lat) const {
  return std::max(0, std::min(lats_ - 1, static_cast<int>(std::floor((lat + 90.0) / step_))));
}

int PointIndex::lon_bucket(double lon) const {
  return std::max(0, std::min(lons_ - 1, static_cast<int>(std::floor((grid::normalise_lon(lon) + 180.0) / step_))));
}

double PointIndex::nearest_scanned(const grid::Vec3& centre, double lon, double lat, double angle, double enough) const {
  // Chords are monotone in the angle: compared as they are, the angle taken once at the end.
  const double enough_chord2 = enough > 0 ? 4.0 * std::pow(std::sin(std::min(enough, M_PI) / 2), 2) : -1.0;
  const RawBox box = cap_box(lon, lat, angle);
  const int row0 = lat_bucket(box.lat0), row1 = lat_bucket(box.lat1);
  // Whole buckets: one more on each side in longitude (the buckets' edges are rounded).
  int col0 = 0, cols = lons_;
  if (!box.all_lon) {
    col0 = static_cast<int>(std::floor((box.lon0 + 180.0) / step_)) - 1;
    cols = std::min(lons_, static_cast<int>(std::floor((box.lon1 + 180.0) / step_)) + 2 - col0);
  }
  double nearest = HUGE_VAL;
  for (int row = row0; row <= row1; ++row) {
    for (int k = 0; k < cols; ++k) {
      const int col = ((col0 + k) % lons_ + lons_) % lons_;
      const std::size_t b = static_cast<std::size_t>(row) * lons_ + col;
      for (std::uint32_t p = first_[b]; p < first_[b + 1]; ++p) nearest = std::min(nearest, grid::chord2(centre, points_[p]));
      if (nearest < enough_chord2) break;
    }
    if (nearest < enough_chord2) break;
  }
  // The chord's angle; float64's rounding of it is far below the callers' margins.
  return nearest == HUGE_VAL ? HUGE_VAL : 2.0 * std::asin(std::min(1.0, std::sqrt(nearest) / 2.0));
}

double PointIndex::nearest(const grid::Vec3& centre, double lon, double lat, double start, double enough) const {
  if (points_.empty()) return HUGE_VAL;
  // Every point within `angle` is in the buckets scanned: a nearest found within it is the nearest.
  for (double angle = std::max(start, step_ * kRadiansPerDegree);; angle *= 2) {
    const double found = nearest_scanned(centre, lon, lat, angle, enough);
    if (found <= angle || angle >= M_PI) return found;
  }
}

std::size_t verify_caps(std::vector<RegionCap>& caps, const PointIndex& points) {
  std::size_t left = 0;
  const auto n = static_cast<std::int64_t>(caps.size());
  // Each cap on its own: the same result whatever the threads.
#pragma omp parallel for schedule(dynamic, 4096) reduction(+ : left) num_threads(thread_count(0))
  for (std::int64_t k = 0; k < n; ++k) {
    RegionCap& cap = caps[static_cast<std::size_t>(k)];
    if (cap.verified) continue;
    const double beyond = cap.reach - cap.radius;  // how far beyond the cap every site was read
    const double nearest = points.nearest(cap.centre, cap.lon, cap.lat, beyond, beyond - 2 * kMarginRadians);
    cap.verified = nearest < beyond - kMarginRadians;
    if (cap.verified) continue;
    // Read next as far as the nearest site read (which then verifies it), or twice as far.
    cap.reach = cap.radius + (nearest < HUGE_VAL ? nearest + 2 * kMarginRadians : 2 * beyond);
    ++left;
  }
  return left;
}

}  // namespace qtmv::sites
