#include "sites/polygon_fill.hpp"

#include <algorithm>
#include <cmath>
#include <exception>
#include <utility>

#include "grid/qtm_checks.hpp"

namespace qtmv::sites {

PolygonFiller::PolygonFiller(int level) : level_(level) {
  grid::require_level(level);
  const std::uint64_t rows = grid::rows_per_octant(level);
  // Latitudes come from cell_centre itself so that they are the bits the centres have.
  for (int first_octant : {0, 4}) {
    for (std::uint64_t i = 0; i < rows; ++i) {
      const auto row = static_cast<std::uint32_t>(i);
      scanlines_.push_back({grid::cell_centre(grid::Cell{first_octant, row, 0}, level).lat, first_octant, row, true});
      if (i > 0) {
        scanlines_.push_back({grid::cell_centre(grid::Cell{first_octant, row, 1}, level).lat, first_octant, row, false});
      }
    }
  }
  std::sort(scanlines_.begin(), scanlines_.end(), [](const Scanline& a, const Scanline& b) { return a.lat < b.lat; });
  for (const auto& s : scanlines_) scan_lats_.push_back(s.lat);
  scan_of_.assign(2 * rows * 2, 0);
  for (std::size_t k = 0; k < scanlines_.size(); ++k) {
    const Scanline& s = scanlines_[k];
    scan_of_[(static_cast<std::size_t>(s.first_octant / 4) * rows + s.row) * 2 + (s.up ? 1 : 0)] =
        static_cast<std::uint32_t>(k);
  }
}

namespace {

struct Crossing {
  std::uint32_t scan;
  double lon;
  bool operator<(const Crossing& o) const { return scan != o.scan ? scan < o.scan : lon < o.lon; }
};

// Local longitude range [0, 90] of octant o against a longitude interval, as an interval of lon'.
bool local_interval(int octant, double lo, double hi, double& local_lo, double& local_hi) {
  if (octant < 4) {
    static const double base[4] = {0.0, 90.0, -180.0, -90.0};  // lon = lon' + base
    local_lo = lo - base[octant];
    local_hi = hi - base[octant];
  } else {
    static const double base[4] = {90.0, 180.0, -90.0, 0.0};  // lon = base - lon'
    local_lo = base[octant - 4] - hi;
    local_hi = base[octant - 4] - lo;
  }
  local_lo = std::max(local_lo, 0.0);
  local_hi = std::min(local_hi, 90.0);
  return local_lo < local_hi;
}

}  // namespace

void PolygonFiller::emit_interval(const Scanline& line, double lo, double hi, std::vector<grid::Code>& cells) const {
  const double i = line.row;
  // Up centres: lon' = 90 (3a + 1) / (3i + 2), a = 0..i; down: lon' = 90 (3a + 2) / (3i + 1), a = 0..i-1.
  const double denominator = line.up ? 3.0 * i + 2.0 : 3.0 * i + 1.0;
  const double offset = line.up ? 1.0 : 2.0;
  const std::int64_t a_max = line.up ? line.row : static_cast<std::int64_t>(line.row) - 1;
  for (int octant = line.first_octant; octant < line.first_octant + 4; ++octant) {
    double local_lo, local_hi;
    if (!local_interval(octant, lo, hi, local_lo, local_hi)) continue;
    // A candidate range one wider on each side; the exact test is on the centre's own longitude.
    std::int64_t a0 = static_cast<std::int64_t>(std::floor((local_lo * denominator / 90.0 - offset) / 3.0));
    std::int64_t a1 = static_cast<std::int64_t>(std::ceil((local_hi * denominator / 90.0 - offset) / 3.0));
    a0 = std::max<std::int64_t>(a0, 0);
    a1 = std::min<std::int64_t>(a1, a_max);
    for (std::int64_t a = a0; a <= a1; ++a) {
      const grid::Cell cell{octant, line.row, static_cast<std::uint32_t>(line.up ? 2 * a : 2 * a + 1)};
      const double lon = grid::cell_centre(cell, level_).lon;
      if (lo < lon && lon < hi) cells.push_back(grid::code_of(cell, level_));
    }
  }
}

std::vector<PolygonFiller::Interval> PolygonFiller::inside_intervals(const std::vector<FillRing>& rings) const {
  std::vector<Crossing> toggles;    // ends of the rings' inside intervals, longitudes in [-180, 180]
  std::vector<Crossing> crossings;  // one ring's crossings, unwrapped longitudes
  std::vector<grid::LonLat> closed;
  for (const FillRing& ring : rings) {
    if (ring.vertices.size() < 3) continue;
    const std::vector<grid::LonLat>* vertices = &ring.vertices;
    if (ring.winding != 0) {
      // Close the ring through the pole on its side of the equator.
      double lat_sum = 0;
      for (const auto& v : ring.vertices) lat_sum += v.lat;
      const double pole = lat_sum >= 0 ? 90.0 : -90.0;
      closed = ring.vertices;
      closed.push_back({ring.vertices.back().lon, pole});
      closed.push_back({ring.vertices.front().lon, pole});
      closed.push_back(ring.vertices.front());
      vertices = &closed;
    }
    crossings.clear();
    const auto& v = *vertices;
    for (std::size_t k = 1; k < v.size(); ++k) {
      const grid::LonLat& p = v[k - 1];
      const grid::LonLat& q = v[k];
      if (p.lat == q.lat) continue;
      // Scanlines y with (p.lat > y) != (q.lat > y): y in [min, max).
      const double y0 = std::min(p.lat, q.lat), y1 = std::max(p.lat, q.lat);
      auto s = std::lower_bound(scan_lats_.begin(), scan_lats_.end(), y0) - scan_lats_.begin();
      const auto s_end = std::lower_bound(scan_lats_.begin(), scan_lats_.end(), y1) - scan_lats_.begin();
      for (; s < s_end; ++s) {
        const double y = scan_lats_[s];
        crossings.push_back({static_cast<std::uint32_t>(s), p.lon + (y - p.lat) * (q.lon - p.lon) / (q.lat - p.lat)});
      }
    }
    std::sort(crossings.begin(), crossings.end());
    for (std::size_t k = 0; k + 1 < crossings.size(); k += 2) {
      const std::uint32_t scan = crossings[k].scan;
      if (crossings[k + 1].scan != scan) {  // cannot happen for a closed ring; resynchronise
        --k;
        continue;
      }
      double lo = crossings[k].lon, hi = crossings[k + 1].lon;
      if (hi - lo >= 360.0) {  // the whole parallel
        toggles.push_back({scan, -180.0});
        toggles.push_back({scan, 180.0});
        continue;
      }
      const double shift = 360.0 * std::floor((lo + 180.0) / 360.0);
      lo -= shift;
      hi -= shift;  // lo in [-180, 180)
      if (hi <= 180.0) {
        toggles.push_back({scan, lo});
        toggles.push_back({scan, hi});
      } else {
        toggles.push_back({scan, lo});
        toggles.push_back({scan, 180.0});
        toggles.push_back({scan, -180.0});
        toggles.push_back({scan, hi - 360.0});
      }
    }
  }
  // Even-odd over all rings: between the 2k-th and (2k+1)-th toggle of a parallel is inside.
  std::sort(toggles.begin(), toggles.end());
  std::vector<Interval> inside;
  for (std::size_t k = 0; k + 1 < toggles.size(); k += 2) {
    if (toggles[k + 1].scan != toggles[k].scan) {
      --k;
      continue;
    }
    if (toggles[k].lon < toggles[k + 1].lon) inside.push_back({toggles[k].scan, toggles[k].lon, toggles[k + 1].lon});
  }
  return inside;  // by scanline, then longitude; disjoint
}

void PolygonFiller::fill(const std::vector<FillRing>& rings, std::vector<grid::Code>& cells) const {
  for (const Interval& in : inside_intervals(rings)) emit_interval(scanlines_[in.scan], in.lo, in.hi, cells);
}

namespace {

/// The inside intervals of one scanline: [begin, end) of the sorted intervals.
struct ScanIntervals {
  const PolygonFiller::Interval* begin;
  const PolygonFiller::Interval* end;
  /// Some interval holds every longitude of [m, M] (strictly: centres on an end are outside).
  bool holds_all(double m, double M) const {
    // The last interval starting below m is the only one that can hold it.
    const PolygonFiller::Interval* it =
        std::lower_bound(begin, end, m, [](const PolygonFiller::Interval& in, double x) { return in.lo < x; });
    return it != begin && M < (it - 1)->hi;
  }
  /// No interval meets the open range around [m, M]: no centre in [m, M] is inside.
  bool holds_none(double m, double M) const {
    // The first interval ending above m is the only one that can start below M.
    const PolygonFiller::Interval* it =
        std::upper_bound(begin, end, m, [](double x, const PolygonFiller::Interval& in) { return x < in.hi; });
    return it == end || !(it->lo < M);
  }
};

}  // namespace

/// A polygon of this many inside intervals or more is covered in tasks below the nodes of
/// kSplitLevel (a continent at level 12 has thousands; an island a few).
constexpr std::size_t kSplitIntervals = 2048;
constexpr int kSplitLevel = 4;

void PolygonFiller::cover(const std::vector<FillRing>& rings, std::vector<grid::Code>& cells,
                          std::vector<CoverNode>& nodes) const {
  const std::vector<Interval> inside = inside_intervals(rings);
  if (inside.empty()) return;
  // Per scanline, its intervals; per hemisphere, the rows that have any.
  const std::uint64_t rows = grid::rows_per_octant(level_);
  std::vector<std::uint32_t> scan_first(scanlines_.size() + 1, 0);
  for (const Interval& in : inside) ++scan_first[in.scan + 1];
  for (std::size_t k = 1; k < scan_first.size(); ++k) scan_first[k] += scan_first[k - 1];
  std::uint32_t row_lo[2] = {~0u, ~0u}, row_hi[2] = {0, 0};
  for (const Interval& in : inside) {
    const Scanline& line = scanlines_[in.scan];
    const int h = line.first_octant / 4;
    row_lo[h] = std::min(row_lo[h], line.row);
    row_hi[h] = std::max(row_hi[h], line.row);
  }
  auto intervals_of = [&](int first_octant, std::uint32_t row, bool up) {
    const std::uint32_t scan = scan_of_[(static_cast<std::size_t>(first_octant / 4) * rows + row) * 2 + (up ? 1 : 0)];
    return ScanIntervals{inside.data() + scan_first[scan], inside.data() + scan_first[scan + 1]};
  };
  enum class Side { inside, outside, mixed };
  // Whether every centre below `node` (level l) is inside, none is, or some are: row by row, the
  // up and the down centres of a row run monotonically in longitude, so their ends decide.
  auto classify = [&](const grid::Cell& node, int l) {
    const int k = level_ - l;
    const int h = node.octant / 4;
    const std::uint64_t top = std::uint64_t{node.row} << k, bottom = top + (std::uint64_t{1} << k) - 1;
    if (row_lo[h] == ~0u || bottom < row_lo[h] || top > row_hi[h]) return Side::outside;
    bool all_in = top >= row_lo[h] && bottom <= row_hi[h], none_in = true;
    const std::uint64_t t0 = std::max<std::uint64_t>(top, row_lo[h]) - top;
    const std::uint64_t t1 = std::min<std::uint64_t>(bottom, row_hi[h]) - top;
    for (std::uint64_t t = t0; t <= t1; ++t) {
      const grid::RowCodes codes = grid::row_codes_below(node, k, t, level_);
      const auto row = static_cast<std::uint32_t>(top + t);
      const std::uint64_t jf = codes.first - codes.row_start, jl = codes.last - codes.row_start;
      for (const bool up : {true, false}) {
        // Columns of this parity in [jf, jl].
        const std::uint64_t j0 = (jf % 2 == (up ? 0u : 1u)) ? jf : jf + 1;
        const std::uint64_t j1 = (jl % 2 == (up ? 0u : 1u)) ? jl : jl - 1;
        if (j0 > jl || j1 < jf || j0 > j1) continue;
        const double a = grid::cell_centre(grid::Cell{node.octant, row, static_cast<std::uint32_t>(j0)}, level_).lon;
        const double b = grid::cell_centre(grid::Cell{node.octant, row, static_cast<std::uint32_t>(j1)}, level_).lon;
        const ScanIntervals scan = intervals_of(h * 4, row, up);
        const double m = std::min(a, b), M = std::max(a, b);
        if (all_in && !scan.holds_all(m, M)) all_in = false;
        if (none_in && !scan.holds_none(m, M)) none_in = false;
        if (!all_in && !none_in) return Side::mixed;
      }
    }
    return all_in ? Side::inside : none_in ? Side::outside : Side::mixed;
  };
  // Depth first below `top` (of level top_level): a node wholly inside goes to on_inside(node, l),
  // a mixed one is split, and one of level defer_level goes to on_defer(node) unclassified.
  const auto walk = [&](const grid::Cell& top, int top_level, int defer_level, const auto& on_inside,
                        const auto& on_defer) {
    std::vector<std::pair<grid::Cell, int>> stack{{top, top_level}};
    while (!stack.empty()) {
      const auto [node, l] = stack.back();
      stack.pop_back();
      if (l == defer_level) {
        on_defer(node);
        continue;
      }
      const Side side = classify(node, l);
      if (side == Side::outside) continue;
      if (side == Side::inside) {
        on_inside(node, l);
        continue;
      }
      grid::Cell children[4];
      grid::children(node, children);
      for (int c = 3; c >= 0; --c) stack.push_back({children[c], l + 1});
    }
  };
  // A large polygon's nodes of kSplitLevel are covered as tasks (other threads of the readers'
  // team take them) and the parts joined in the order of one depth-first pass.
  const int split_level = inside.size() >= kSplitIntervals ? std::min(kSplitLevel, level_) : 0;
  struct Part {
    grid::Cell node;
    bool deferred;  // to be covered below node (of split_level), else node is one entry
    std::vector<grid::Code> cells;
    std::vector<CoverNode> nodes;
    std::exception_ptr failure;  // an exception cannot leave a task: rethrown after the wait
  };
  const auto add_entry = [&](Part& part, const grid::Cell& node, int l) {
    if (l == level_) {
      part.cells.push_back(grid::code_of(node, level_));
    } else {
      part.nodes.push_back({grid::code_of(node, l), l});
    }
  };
  std::vector<Part> parts;
  for (int o = 0; o < grid::kOctants; ++o) {
    walk(
        grid::Cell{o, 0, 0}, 0, split_level,
        [&](const grid::Cell& node, int l) {
          parts.push_back({node, false, {}, {}, nullptr});
          add_entry(parts.back(), node, l);
        },
        [&](const grid::Cell& node) { parts.push_back({node, true, {}, {}, nullptr}); });
  }
  for (Part& each : parts) {
    if (!each.deferred) continue;
    Part* const part = &each;
#pragma omp task default(shared) firstprivate(part) if (split_level > 0)
    try {
      walk(
          part->node, split_level, -1, [&](const grid::Cell& node, int l) { add_entry(*part, node, l); },
          [](const grid::Cell&) {});
    } catch (...) {
      part->failure = std::current_exception();
    }
  }
#pragma omp taskwait
  for (Part& part : parts) {
    if (part.failure) std::rethrow_exception(part.failure);
    cells.insert(cells.end(), part.cells.begin(), part.cells.end());
    nodes.insert(nodes.end(), part.nodes.begin(), part.nodes.end());
    part = Part{};  // its memory back before the next part's is copied
  }
}

}  // namespace qtmv::sites
