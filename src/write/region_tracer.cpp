#include "write/region_tracer.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>

#include "common/openmp_threads.hpp"
#include "grid/qtm_checks.hpp"
#include "common/first_exception.hpp"
#include "write/packed_cell_edges.hpp"

namespace qtmv::write {
namespace {

using grid::Cell;
using grid::Code;

using Edge = RegionTracer::Edge;


/// Angle (radians, in (0, 2 pi]) turned clockwise from direction d to direction t.
double clockwise_angle(double dx, double dy, double tx, double ty) {
  double a = std::atan2(dy, dx) - std::atan2(ty, tx);
  while (a <= 0) a += 2 * grid::kPi;
  while (a > 2 * grid::kPi) a -= 2 * grid::kPi;
  return a;
}

/// Drops vertices in the middle of straight runs along a meridian (exactly equal longitudes),
/// and along a parallel (equal latitudes) unless `parallels` says to keep those: rows of cells
/// make long runs of them.
std::vector<LonLat> drop_straight_runs(const LonLat* ring, std::size_t n, RingVertices parallels) {
  std::vector<LonLat> out;
  out.reserve(n);
  for (std::size_t k = 0; k < n; ++k) {
    // Not %: two integer divisions a vertex, hundreds of vertices a region.
    const LonLat& prev = ring[k == 0 ? n - 1 : k - 1];
    const LonLat& here = ring[k];
    const LonLat& next = ring[k + 1 == n ? 0 : k + 1];
    const bool along_parallel =
        parallels == RingVertices::corners && prev.lat == here.lat && here.lat == next.lat;
    const bool along_meridian = prev.lon == here.lon && here.lon == next.lon;
    if (!along_parallel && !along_meridian) out.push_back(here);
  }
  return out;
}

/// One step of a walk: the vertex, and its id (the index of the first edge leaving it).
struct WalkStep {
  LonLat point;
  std::size_t vertex;
};

/// Cuts a closed walk that passes a vertex more than once into simple rings. Where a region
/// meets itself at a vertex, no pairing of the edges there suits every case: lobes that touch
/// at a point, a hole that touches its shell, holes that touch each other. Each loop cut off
/// here is a shell (counter-clockwise) or a hole (clockwise) of its own: loop(points, count) for
/// each, in the order cut, the rest of the walk last. `position` (indexed by vertex id, all
/// kNone) is scratch, left all kNone again; so is `stack` and `points`.
constexpr std::size_t kNone = ~std::size_t{0};
template <class Loop>
void split_at_repeated_vertices(const std::vector<WalkStep>& walk, std::vector<std::size_t>& position,
                                std::vector<WalkStep>& stack, std::vector<LonLat>& points, const Loop& loop) {
  stack.clear();
  for (const WalkStep& step : walk) {
    const std::size_t first = position[step.vertex];
    if (first == kNone) {
      position[step.vertex] = stack.size();
      stack.push_back(step);
      continue;
    }
    // The walk came back to this vertex: the stretch since its first visit is a closed loop.
    points.clear();
    for (std::size_t k = first; k < stack.size(); ++k) points.push_back(stack[k].point);
    for (std::size_t k = first + 1; k < stack.size(); ++k) position[stack[k].vertex] = kNone;
    stack.resize(first + 1);
    loop(points.data(), points.size());
  }
  points.clear();
  for (const WalkStep& step : stack) {
    points.push_back(step.point);
    position[step.vertex] = kNone;
  }
  loop(points.data(), points.size());
}

/// Even-odd test of a point against a ring that does not pass through it.
bool ring_contains(const std::vector<LonLat>& ring, const LonLat& p) {
  bool inside = false;
  const std::size_t n = ring.size();
  for (std::size_t k = 0, m = n - 1; k < n; m = k++) {
    const LonLat& a = ring[k];
    const LonLat& b = ring[m];
    if ((a.lat > p.lat) != (b.lat > p.lat)) {
      const double lon_at = a.lon + (p.lat - a.lat) / (b.lat - a.lat) * (b.lon - a.lon);
      if (p.lon < lon_at) inside = !inside;
    }
  }
  return inside;
}

struct Box {
  double lon_min = 1e9, lon_max = -1e9, lat_min = 1e9, lat_max = -1e9;
  void add(const LonLat& p) {
    lon_min = std::min(lon_min, p.lon);
    lon_max = std::max(lon_max, p.lon);
    lat_min = std::min(lat_min, p.lat);
    lat_max = std::max(lat_max, p.lat);
  }
  bool contains(const LonLat& p) const {
    return p.lon >= lon_min && p.lon <= lon_max && p.lat >= lat_min && p.lat <= lat_max;
  }
};

/// A point of EdgesFrom's table, by its key, and the first edge leaving it (kNone: an empty slot).
struct PointSlot {
  std::uint64_t key;
  std::size_t first;
};

/// A tracing thread's buffers, kept from one region to the next (a region allocates only its own
/// rings).
struct TraceScratch {
  std::vector<Edge> edges;
  std::vector<PointSlot> table;
  std::vector<std::size_t> next, position;
  std::vector<char> used;
  std::vector<WalkStep> walk, stack;
  std::vector<LonLat> points;
};

/// The edges leaving each point of a site's edges: a hash of the points' keys (grid vertices'
/// keys, the same for a point from every cell around it: one integer compared where the
/// coordinates were two doubles), each point's edges chained in the order given. A point's first
/// edge is its vertex's id.
class EdgesFrom {
 public:
  /// `table` and `next`: the caller's buffers, reused.
  EdgesFrom(const Edge* edges, std::size_t count, std::vector<PointSlot>& table, std::vector<std::size_t>& next)
      : table_(table), next_(next) {
    std::size_t size = 16;
    int bits = 4;
    for (; size < 2 * count; size <<= 1) ++bits;
    mask_ = size - 1;
    shift_ = 64 - bits;
    table_.assign(size, PointSlot{0, kNone});
    next_.assign(count, kNone);
    for (std::size_t k = 0; k < count; ++k) {
      const std::uint64_t key = edges[k].from_key;
      std::size_t h = hash(key);
      while (table_[h].first != kNone && table_[h].key != key) h = (h + 1) & mask_;
      if (table_[h].first == kNone) {
        table_[h] = {key, k};
        continue;
      }
      // Appended to the point's chain: a few edges at most (a region's edges leaving one vertex).
      std::size_t tail = table_[h].first;
      while (next_[tail] != kNone) tail = next_[tail];
      next_[tail] = k;
    }
  }
  /// The first edge leaving the point of `key`, or kNone.
  std::size_t first(std::uint64_t key) const {
    for (std::size_t h = hash(key);; h = (h + 1) & mask_) {
      const PointSlot& slot = table_[h];
      if (slot.first == kNone || slot.key == key) return slot.first;
    }
  }
  /// The edge after k leaving the same point, or kNone.
  std::size_t next(std::size_t k) const { return next_[k]; }

 private:
  std::size_t hash(std::uint64_t key) const {
    // Fibonacci hashing: the product's top bits depend on every bit of the key, the row's (bits 30
    // and up) as well as the column's, whatever the table's size.
    return static_cast<std::size_t>((key * 0x9E3779B97F4A7C15ull) >> shift_);
  }
  std::size_t mask_ = 0;
  int shift_ = 64;
  std::vector<PointSlot>& table_;
  std::vector<std::size_t>& next_;
};

/// Links one site's boundary edges into rings and groups them into polygons. The edges come in
/// an order that does not depend on the threads (their cells' code order), and so do the rings.
Region link_rings(const Edge* edges, std::size_t count, RingVertices parallels, TraceScratch& scratch) {
  std::vector<char>& used = scratch.used;
  used.assign(count, 0);
  const EdgesFrom from(edges, count, scratch.table, scratch.next);
  const auto next_edge = [&](std::size_t e, std::size_t first) {
    const LonLat at = edges[e].to;
    std::size_t best = kNone;
    double best_angle = 1e300;
    // Reverse of the incoming edge; the region lies clockwise from it, so the outgoing edge of
    // the same wedge is the first one met turning clockwise.
    std::size_t unused = 0;
    for (std::size_t k = first; k != kNone; k = from.next(k)) {
      if (used[k]) continue;
      if (unused++ == 0) best = k;
    }
    if (unused < 2) return best;  // mostly: no choice to make
    const double dx = edges[e].from.lon - at.lon, dy = edges[e].from.lat - at.lat;
    for (std::size_t k = first; k != kNone; k = from.next(k)) {
      if (used[k]) continue;
      const double angle = clockwise_angle(dx, dy, edges[k].to.lon - at.lon, edges[k].to.lat - at.lat);
      if (angle < best_angle) {
        best_angle = angle;
        best = k;
      }
    }
    return best;
  };

  std::vector<std::size_t>& position = scratch.position;
  position.assign(count, kNone);
  std::vector<std::vector<LonLat>> shells, holes;
  std::vector<WalkStep>& walk = scratch.walk;
  const auto keep = [&](const LonLat* points, std::size_t n) {
    std::vector<LonLat> simple = drop_straight_runs(points, n, parallels);
    if (simple.size() < 3) return;
    (planar_ring_area(simple) > 0 ? shells : holes).push_back(std::move(simple));
  };
  for (std::size_t start = 0; start < count; ++start) {
    if (used[start]) continue;
    walk.clear();
    std::size_t e = start;
    std::size_t vertex = from.first(edges[start].from_key);
    while (e != kNone && !used[e]) {
      used[e] = 1;
      walk.push_back({edges[e].from, vertex});
      vertex = from.first(edges[e].to_key);
      e = next_edge(e, vertex);
    }
    split_at_repeated_vertices(walk, position, scratch.stack, scratch.points, keep);
  }

  Region region(shells.size());
  std::vector<Box> boxes(shells.size());
  std::vector<double> areas(shells.size());
  for (std::size_t s = 0; s < shells.size(); ++s) {
    for (const LonLat& p : shells[s]) boxes[s].add(p);
    areas[s] = planar_ring_area(shells[s]);
    region[s].shell = std::move(shells[s]);
  }
  for (auto& hole : holes) {
    // The middle of an edge of the hole is on no other ring, so it is strictly inside or
    // outside each shell; the smallest shell around it owns the hole.
    const LonLat probe{0.5 * (hole[0].lon + hole[1].lon), 0.5 * (hole[0].lat + hole[1].lat)};
    std::size_t owner = region.size();
    for (std::size_t s = 0; s < region.size(); ++s) {
      if (boxes[s].contains(probe) && ring_contains(region[s].shell, probe) &&
          (owner == region.size() || areas[s] < areas[owner])) {
        owner = s;
      }
    }
    if (owner == region.size()) throw std::logic_error("region tracer: a hole lies in no shell of its region");
    region[owner].holes.push_back(std::move(hole));
  }
  return region;
}

/// A site's slot in one bucketing thread's table.
struct SiteSlot {
  std::size_t place;  // the site's bytes in the thread's stretch, then where its next entry goes
  Code after;         // the code after the site's last cell in the stretch (0: none yet)
};

/// Where each site's bytes start, the threads' stretches of a site one after another in their
/// order (slots[t][s].place: the bytes of site s in stretch t); each slot's place is then where its
/// stretch's bytes of the site go, its `after` reset. Returns the sites' starts and, last, the
/// bytes of all. On all cores (millions of sites times the team's slots): each thread sums a share
/// of the sites, the shares' sums are added up in order, then each thread places its share.
std::vector<std::size_t> place_sites(std::vector<std::vector<SiteSlot>>& slots, std::size_t sites) {
  const std::size_t team = slots.size();
  const std::size_t shares = static_cast<std::size_t>(thread_count(0));
  std::vector<std::size_t> share_start(shares + 1, 0);
  std::vector<std::size_t> start(sites + 1);
#pragma omp parallel for schedule(static, 1) num_threads(static_cast<int>(shares))
  for (std::int64_t j = 0; j < static_cast<std::int64_t>(shares); ++j) {
    const auto share = static_cast<std::size_t>(j);
    std::size_t bytes = 0;
    for (std::size_t s = sites * share / shares; s < sites * (share + 1) / shares; ++s) {
      for (std::size_t t = 0; t < team; ++t) bytes += slots[t][s].place;
    }
    share_start[share + 1] = bytes;
  }
  for (std::size_t j = 0; j < shares; ++j) share_start[j + 1] += share_start[j];
#pragma omp parallel for schedule(static, 1) num_threads(static_cast<int>(shares))
  for (std::int64_t j = 0; j < static_cast<std::int64_t>(shares); ++j) {
    const auto share = static_cast<std::size_t>(j);
    std::size_t at = share_start[share];
    for (std::size_t s = sites * share / shares; s < sites * (share + 1) / shares; ++s) {
      start[s] = at;
      for (std::size_t t = 0; t < team; ++t) {
        SiteSlot& slot = slots[t][s];
        const std::size_t count = slot.place;
        slot = SiteSlot{at, 0};
        at += count;
      }
    }
  }
  start[sites] = share_start[shares];
  return start;
}

}  // namespace

int drawn_ring(const Cell& c, int level, LonLat ring[grid::kMaxPolygonCorners], int across[grid::kMaxPolygonCorners]) {
  drawn_edges(c, across);
  return grid::cell_polygon(c, level, ring);  // 4 corners exactly where drawn_edges says
}

int drawn_edges(const Cell& c, int across[grid::kMaxPolygonCorners]) {
  const int n = c.row == 0 ? 4 : 3;  // an octant's pole cell is drawn as a quadrilateral
  if (n == 4) {  // the pole quadrilateral: left side, bottom, right side, the pole line
    across[0] = grid::kNeighbourLeft;
    across[1] = grid::kNeighbourVertical;
    across[2] = grid::kNeighbourRight;
    across[3] = kAcrossPoleLine;
  } else if (grid::is_up(c)) {  // apex, lower left, lower right
    across[0] = grid::kNeighbourLeft;
    across[1] = grid::kNeighbourVertical;
    across[2] = grid::kNeighbourRight;
  } else {  // upper left, bottom, upper right
    across[0] = grid::kNeighbourLeft;
    across[1] = grid::kNeighbourRight;
    across[2] = grid::kNeighbourVertical;
  }
  return n;
}

double planar_ring_area(const std::vector<LonLat>& ring) {
  double twice = 0;
  const std::size_t n = ring.size();
  for (std::size_t k = 0; k < n; ++k) {
    const LonLat& p = ring[k];
    const LonLat& q = ring[k + 1 == n ? 0 : k + 1];  // not %: a division per vertex
    twice += (p.lon - q.lon) * (p.lat + q.lat);
  }
  return 0.5 * twice;
}

OctantSteps::OctantSteps(const label::Outlines& outlines) {
  // Steps of at least 1024 cells of an octant, at most 1024 of them: tasks enough for any
  // team, few enough to cost nothing.
  const Code per_octant = grid::cells_per_octant(outlines.level);
  steps_ = static_cast<std::size_t>(std::clamp<Code>(per_octant / 1024, 1, 1024));
  bounds_.resize(8 * (steps_ + 1));
  const label::OutlineCells& cells = outlines.cells;
  for (std::size_t octant = 0; octant < 8; ++octant) {
    for (std::size_t j = 0; j <= steps_; ++j) {
      const Code code = octant * per_octant + per_octant / steps_ * j + (j == steps_ ? per_octant % steps_ : 0);
      bounds_[octant * (steps_ + 1) + j] = static_cast<std::size_t>(
          std::lower_bound(cells.begin(), cells.end(), code, [](const label::OutlineCell& c, Code v) { return c.code() < v; }) -
          cells.begin());
    }
  }
}

label::Outlines with_range_edges(const label::Outlines& outlines) {
  const int level = outlines.level;
  grid::require_level(level);
  if (!holds_part(outlines)) return outlines;
  // The cells with a neighbour outside the range: the row ends (their neighbours in the next
  // octants), and the cells of a row whose row above or below may be outside (the range's first
  // and last rows, each octant's first and last: the equator's row faces another octant). Few (a
  // few rows' worth), found here in code order with where they go among the outline cells.
  const label::OutlineCells& cells = outlines.cells;
  const std::size_t n = cells.size();
  struct EdgeCell {
    std::size_t at;  // the first outline cell not below it: itself, or where it goes in
    grid::Code code;
    std::int32_t site;  // its site (label::site_of: here, where its exceptions may be thrown)
    bool listed;        // an outline cell already (flagged), else one to add
  };
  std::vector<EdgeCell> edge_cells;
  const auto code_less = [](const label::OutlineCell& c, grid::Code v) { return c.code() < v; };
  const auto add = [&](grid::Code code) {
    grid::Code nb[3];
    grid::neighbours(code, level, nb);
    if (holds_code(outlines, nb[0]) && holds_code(outlines, nb[1]) && holds_code(outlines, nb[2])) return;
    const std::size_t from = edge_cells.empty() ? 0 : edge_cells.back().at;
    const auto at = static_cast<std::size_t>(
        std::lower_bound(cells.begin() + static_cast<std::ptrdiff_t>(from), cells.end(), code, code_less) - cells.begin());
    const bool listed = at < n && cells[at].code() == code;
    edge_cells.push_back({at, code, listed ? cells[at].site : label::site_of(cells, code), listed});
  };
  const std::uint64_t last_row = grid::rows_per_octant(level) - 1;
  for (grid::Code row = outlines.range.first; row < outlines.range.end;) {
    const grid::Cell c = grid::cell_of(row, level);
    const grid::Code end = row + 2 * std::uint64_t{c.row} + 1;
    if (row == outlines.range.first || end == outlines.range.end || c.row == 0 || c.row == last_row) {
      for (grid::Code code = row; code < end; ++code) add(code);
    } else {
      add(row);
      add(end - 1);
    }
    row = end;
  }
  if (edge_cells.empty()) return outlines;
  // inserted_before[j]: the edge cells before the j-th that are not outline cells yet (added).
  std::vector<std::size_t> inserted_before(edge_cells.size() + 1, 0);
  for (std::size_t j = 0; j < edge_cells.size(); ++j) inserted_before[j + 1] = inserted_before[j] + (edge_cells[j].listed ? 0 : 1);

  // The outline cells copied on all cores (gigabytes at the finer levels), each thread a stretch
  // of them with the edge cells that go in before them (the last the ones after every cell),
  // flagging those already there: the one merge, in code order, whatever the threads.
  label::Outlines out;
  out.level = level;
  out.site_count = outlines.site_count;
  out.range = outlines.range;
  out.cells_per_site = outlines.cells_per_site;
  out.cells.resize(n + inserted_before.back());
  const auto team = static_cast<std::size_t>(thread_count(0));
  const auto first_edge_cell = [&](std::size_t k) {
    return static_cast<std::size_t>(
        std::lower_bound(edge_cells.begin(), edge_cells.end(), k, [](const EdgeCell& e, std::size_t v) { return e.at < v; }) -
        edge_cells.begin());
  };
#pragma omp parallel for schedule(static, 1) num_threads(static_cast<int>(team))
  for (std::int64_t t = 0; t < static_cast<std::int64_t>(team); ++t) {
    const auto stretch = static_cast<std::size_t>(t);
    const std::size_t first = n * stretch / team, end = n * (stretch + 1) / team;
    std::size_t j = first_edge_cell(first);
    const std::size_t j_end = stretch + 1 == team ? edge_cells.size() : first_edge_cell(end);
    label::OutlineCell* to = out.cells.data() + first + inserted_before[j];
    for (std::size_t k = first; k <= end; ++k) {
      // The edge cells that go in before cell k (after the last cell, for the last stretch).
      for (; j < j_end && edge_cells[j].at == k && !edge_cells[j].listed; ++j) {
        *to++ = label::OutlineCell(edge_cells[j].code, edge_cells[j].site, 1);
      }
      if (k == end) break;
      *to = cells[k];
      if (j < j_end && edge_cells[j].at == k) {  // listed: an outline cell already, flagged
        to->mark_boundary();
        ++j;
      }
      ++to;
    }
  }
  return out;
}

RegionTracer::RegionTracer(const label::Outlines& whole_or_tile, RingVertices vertices,
                           const std::function<void(double)>& step_done, RegionEdgeObserver* observer)
    : level_(whole_or_tile.level), vertices_(vertices) {
  const auto done = [&](double fraction) {
    if (step_done) step_done(fraction);
  };
  const int level = whole_or_tile.level;
  grid::require_level(level);
  // A tile's regions are cut at its edges (with_range_edges); the whole level's are traced as given.
  label::Outlines tile;
  const bool part = holds_part(whole_or_tile);
  if (part) tile = with_range_edges(whole_or_tile);
  const label::Outlines& outlines = part ? tile : whole_or_tile;
  const label::OutlineCells& cells = outlines.cells;
  const std::size_t n = cells.size();
  const auto sites = static_cast<std::size_t>(outlines.site_count);

  // Each outline cell's edge mask, written by the one thread that visits it (not zeroed: every
  // cell is visited). A byte a cell, where lists of the cells with edges took 8 bytes each and
  // their bucketed copy 8 more.
  std::vector<std::uint8_t, HugePageAllocator<std::uint8_t>> masks(n);
  FirstException failure;
  const OctantSteps steps(outlines);
#pragma omp parallel num_threads(thread_count(0))
  {
    std::unique_ptr<RegionEdgeObserver::Local> seen;
    OutlineWalk walk[8];
    failure.run([&] {
      if (observer) seen = observer->local();
    });
#pragma omp for schedule(dynamic, 1)  // boundary cells, with their geodesics to solve, come in clusters
    for (std::int64_t step = 0; step < static_cast<std::int64_t>(steps.count()); ++step) {
      failure.run([&] {
        steps.visit(static_cast<std::size_t>(step), walk, [&](std::size_t k, OutlineWalk& octant_walk) {
          const std::int32_t site = cells[k].site;
          std::uint8_t mask = 0;
          const auto add = [&](int e, std::int32_t other, DrawnCorners& corners) {
            mask = static_cast<std::uint8_t>(mask | 1u << e);
            if (seen && measured_edge(site, other)) seen->edge(site, corners.from(e), corners.to(e), other);
          };
          visit_region_edges(outlines, k, octant_walk, add);
          masks[k] = mask;
        });
      });
    }
    failure.run([&] {
      if (seen) seen->finish();
    });
  }
  failure.rethrow();
  done(0.5);

  // Bucketed by site, packed (packed_cell_edges.hpp), each thread taking a stretch of the cells
  // with a slot per site of its own (no atomics; each site's cells come in code order, a
  // thread's first of a site whole): as many threads as keep those tables within two bytes an
  // outline cell, or 128 MiB (the packed lists saved six: a 16-byte slot must not halve the team).
  const std::size_t table_bytes = std::max<std::size_t>(2 * n, std::size_t{128} << 20);
  const std::size_t team = std::clamp<std::size_t>(table_bytes / (sizeof(SiteSlot) * (sites + 1)), 1,
                                                   static_cast<std::size_t>(thread_count(0)));
  // Each zeroed by its thread (megabytes each), not all by this one.
  std::vector<std::vector<SiteSlot>> slots(team);
  // A site's slot is a cache miss (the sites come in no spatial order), and so is where its
  // next entry goes: the slot is fetched kAhead cells before its cell, and fetch_ahead(slot) is
  // called kAhead / 2 cells before, so that the misses overlap.
  constexpr std::size_t kAhead = 16;
  const auto stretch = [&](std::size_t t, auto&& visit, auto&& fetch_ahead) {
    const std::size_t first = n * t / team, end = n * (t + 1) / team;
    SiteSlot* const slot = slots[t].data();
    for (std::size_t k = first; k < end; ++k) {
      if (k + kAhead < end) __builtin_prefetch(slot + cells[k + kAhead].site, 1);
      if (k + kAhead / 2 < end && masks[k + kAhead / 2] != 0) fetch_ahead(slot[cells[k + kAhead / 2].site]);
      if (masks[k] != 0) visit(cells[k].code(), masks[k], slot[static_cast<std::size_t>(cells[k].site)]);
    }
  };
#pragma omp parallel for schedule(static, 1) num_threads(static_cast<int>(team))
  for (std::int64_t t = 0; t < static_cast<std::int64_t>(team); ++t) {
    slots[static_cast<std::size_t>(t)].assign(sites, SiteSlot{0, 0});
    stretch(
        static_cast<std::size_t>(t),
        [](Code code, std::uint8_t, SiteSlot& slot) { slot.place += packed_cell_edges_bytes(code, slot.after); },
        [](const SiteSlot&) {});
  }
  std::vector<std::size_t> start = place_sites(slots, sites);
  const std::size_t at = start[sites];
  // Not zeroed (gigabytes at the finer levels, on one core): every byte is written below, on all cores.
  cells_.resize(at);
#pragma omp parallel for schedule(static, 1) num_threads(static_cast<int>(team))
  for (std::int64_t t = 0; t < static_cast<std::int64_t>(team); ++t) {
    stretch(
        static_cast<std::size_t>(t),
        [&](Code code, std::uint8_t mask, SiteSlot& slot) {
          slot.place = static_cast<std::size_t>(put_packed_cell_edges(cells_.data() + slot.place, code, mask, slot.after) -
                                                cells_.data());
        },
        [&](const SiteSlot& slot) { __builtin_prefetch(cells_.data() + slot.place, 1); });
  }
  start_ = std::move(start);
  done(1.0);
}

Region RegionTracer::trace(std::int32_t site) const {
  const auto s = static_cast<std::size_t>(site);
  // The site's edges drawn again from its cells in code order, so that the rings do not depend on
  // the threads: the bucketing's threads took stretches of the codes in order.
  thread_local TraceScratch scratch;
  std::vector<Edge>& edges = scratch.edges;
  edges.clear();
  PackedCellEdgesReader list(cells_.data() + start_[s], cells_.data() + start_[s + 1]);
  Code code = 0;
  unsigned mask = 0;
  RowWalk rows;  // a site's cells come in code order, many in a row
  while (list.next(code, mask)) {
    LonLat ring[grid::kMaxPolygonCorners];
    std::uint64_t keys[grid::kMaxPolygonCorners];
    const grid::Cell cell = rows.cell(code, level_);
    const int corners = grid::cell_polygon(cell, level_, ring);
    grid::cell_polygon_keys(cell, level_, keys);
    for (int e = 0; e < corners; ++e) {
      const int end = e + 1 < corners ? e + 1 : 0;
      if (mask >> e & 1) edges.push_back({ring[e], ring[end], keys[e], keys[end]});
    }
  }
  return link_rings(edges.data(), edges.size(), vertices_, scratch);
}

std::vector<Region> trace_regions(const label::Outlines& outlines, const std::function<void(double)>& step_done) {
  const auto done = [&](double fraction) {
    if (step_done) step_done(fraction);
  };
  const RegionTracer tracer(outlines, RingVertices::corners, [&](double f) { done(0.7 * f); });
  std::vector<Region> regions(static_cast<std::size_t>(tracer.site_count()));
  FirstException failure;
#pragma omp parallel for schedule(dynamic, 1) num_threads(thread_count(0))
  for (std::int32_t site = 0; site < tracer.site_count(); ++site) {
    failure.run([&] { regions[static_cast<std::size_t>(site)] = tracer.trace(site); });
  }
  failure.rethrow();
  done(1.0);
  return regions;
}

std::vector<Region> trace_regions(int level, const std::int32_t* labels, std::int32_t site_count) {
  grid::require_level(level);
  return trace_regions(label::outlines_of_dense(level, labels, nullptr, site_count));
}

}  // namespace qtmv::write
