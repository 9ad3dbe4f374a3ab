#include "sites/tile_region.hpp"

#include <algorithm>
#include <cmath>

#include "common/openmp_threads.hpp"
#include "label/label_math.hpp"

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

/// The part of cap_box(lon, lat, angle) between latitudes lat0 and lat1 (degrees): only the
/// longitudes that the cap reaches there, which near a pole are far fewer than the whole cap's.
RawBox cap_slice(double lon, double lat, double angle, double lat0, double lat1) {
  RawBox box = cap_box(lon, lat, angle);
  box.lat0 = lat0;
  box.lat1 = lat1;
  if (box.all_lon && angle >= M_PI / 2) return box;
  // The half-width at latitude p: acos((cos a - sin p sin c) / (cos p cos c)), largest at
  // asin(sin c / cos a) and falling away from it on either side (every longitude where the cap
  // holds a pole there); so its largest in [lat0, lat1] is at one of these.
  const double c = lat * kRadiansPerDegree, a = angle;
  const double top = asin(std::min(1.0, std::sin(c) / std::cos(a))) / kRadiansPerDegree;
  double half = 0;
  for (const double p_deg : {lat0, lat1, std::max(lat0, std::min(lat1, top))}) {
    const double p = std::max(lat - angle / kRadiansPerDegree, std::min(lat + angle / kRadiansPerDegree, p_deg)) * kRadiansPerDegree;
    const double across = std::cos(p) * std::cos(c);
    if (across < 1e-12) return box;  // at a pole: the whole cap's longitudes
    const double g = (std::cos(a) - std::sin(p) * std::sin(c)) / across;
    if (g <= -1.0) return RawBox{0, 0, lat0, lat1, true};
    half = std::max(half, std::acos(std::min(1.0, g)));
  }
  // acos is steep near 1: far more than its rounding there.
  half = half / kRadiansPerDegree + 1e-5;
  if (half >= 180.0) return RawBox{0, 0, lat0, lat1, true};
  return RawBox{lon - half, lon + half, lat0, lat1};
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

double ReadRegion::step_for(const std::vector<RegionCap>& caps) {
  double thinnest = 180.0;
  for (const RegionCap& cap : caps) {
    if (!cap.verified) thinnest = std::min(thinnest, (cap.radius + cap.reach) / kRadiansPerDegree);
  }
  return std::max(0.05, std::min(5.0, thinnest / 2));
}

ReadRegion::ReadRegion(double step)
    : step_(step), count_(static_cast<int>(std::ceil(180.0 / step))), read_(static_cast<std::size_t>(count_)) {}

void ReadRegion::subtract_read(int slice, Interval piece, std::vector<Interval>& out) const {
  for (const Interval& done : read_[static_cast<std::size_t>(slice)]) {  // sorted, disjoint
    if (done.second < piece.first) continue;
    if (done.first > piece.second) break;
    if (done.first > piece.first) out.push_back({piece.first, done.first});
    piece.first = std::max(piece.first, done.second);
    if (piece.first >= piece.second) return;
  }
  out.push_back(piece);
}

void ReadRegion::mark_read(int slice, Interval piece) {
  std::vector<Interval>& done = read_[static_cast<std::size_t>(slice)];
  done.push_back(piece);
  std::sort(done.begin(), done.end());
  std::size_t kept = 0;
  for (const Interval& i : done) {
    if (kept > 0 && i.first <= done[kept - 1].second) {
      done[kept - 1].second = std::max(done[kept - 1].second, i.second);
    } else {
      done[kept++] = i;
    }
  }
  done.resize(kept);
}

std::vector<LonLatBox> ReadRegion::next_boxes(const std::vector<RegionCap>& caps) {
  // Each slice's part of the caps' boxes (joined where they nearly meet), less what was read.
  std::vector<std::vector<RawBox>> needed(static_cast<std::size_t>(count_));
  for (const RegionCap& cap : caps) {
    if (cap.verified) continue;
    const double angle = cap.radius + cap.reach + kMarginRadians;
    const RawBox box = cap_box(cap.lon, cap.lat, angle);
    const int first = std::max(0, static_cast<int>(std::floor((box.lat0 + 90.0) / step_)));
    const int last = std::min(count_ - 1, static_cast<int>(std::floor((box.lat1 + 90.0) / step_)));
    // A narrow cap's slices are about its box: worth their trigonometry only for a wide one.
    const bool wide = box.all_lon || box.lon1 - box.lon0 > 5.0;
    for (int k = first; k <= last; ++k) {
      const double lat0 = -90.0 + k * step_, lat1 = std::min(90.0, -90.0 + (k + 1) * step_);
      add_to_slice(needed[static_cast<std::size_t>(k)], wide ? cap_slice(cap.lon, cap.lat, angle, lat0, lat1) : box);
    }
  }
  // Then a slice's new box joins the one of the slice before that it meets while the join's
  // area stays within a tenth of theirs.
  struct Open {
    RawBox box;
    double useful;  // its slices' areas
  };
  std::vector<RawBox> done;
  std::vector<Open> open, next;
  std::vector<LonLatBox> split;
  std::vector<Interval> fresh;
  for (int k = 0; k < count_; ++k) {
    const double lat0 = -90.0 + k * step_, lat1 = std::min(90.0, -90.0 + (k + 1) * step_);
    fresh.clear();
    for (const RawBox& box : needed[static_cast<std::size_t>(k)]) {
      split.clear();
      split_at_antimeridian(box, split);
      for (const LonLatBox& part : split) subtract_read(k, {part.lon0, part.lon1}, fresh);
    }
    next.clear();
    for (const Interval& lon : fresh) {
      const RawBox box{lon.first, lon.second, lat0, lat1};
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
  // What is read now counts as read: slice by slice of each box.
  for (const LonLatBox& box : out) {
    // Its latitudes are slices' edges (the last one's is 90).
    const int first = std::max(0, static_cast<int>(std::floor((box.lat0 + 90.0) / step_ + 0.5)));
    const int last = box.lat1 >= 90.0 ? count_ : std::min(count_, static_cast<int>(std::floor((box.lat1 + 90.0) / step_ + 0.5)));
    for (int k = first; k < last; ++k) mark_read(k, {box.lon0, box.lon1});
  }
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
  return nearest == HUGE_VAL ? HUGE_VAL : label::chord2_to_angle(nearest);
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
