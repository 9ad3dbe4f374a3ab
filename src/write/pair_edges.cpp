#include "write/pair_edges.hpp"

#include <algorithm>
#include <cstddef>
#include <utility>

#include "common/first_exception.hpp"
#include "common/openmp_threads.hpp"
#include "measure/edge_solver.hpp"
#include "write/region_measures.hpp"
#include "write/region_tracer.hpp"

namespace qtmv::write {

namespace {

using grid::Code;

struct Segment {
  LonLat from, to;
};

}  // namespace

DefaultInitVector<EdgeRef> gather_edges(const label::Outlines& outlines) {
  const int level = outlines.level;
  const label::OutlineCells& cells = outlines.cells;
  const std::size_t n = cells.size();
  const auto sites = static_cast<std::size_t>(std::max(1, outlines.site_count));
  // Calls emit(edge) for each edge from a cell of the lower site id of its pair, in cell order.
  const auto edges_of = [&](std::size_t c, auto&& emit) {
    const label::OutlineCell& outline = cells[c];
    if (!outline.boundary()) return;
    const Code code = outline.code();
    const std::int32_t site = outline.site;
    Code nb[3];
    grid::neighbours(code, level, nb);
    int across[grid::kMaxPolygonCorners];
    const int corners = drawn_edges(grid::cell_of(code, level), across);
    for (int k = 0; k < corners; ++k) {
      if (across[k] == kAcrossPoleLine) continue;
      const std::int32_t other = label::site_of_near(cells, c, nb[across[k]]);
      if (other > site) {
        emit(EdgeRef{static_cast<std::uint64_t>(site) << 32 | static_cast<std::uint32_t>(other),
                     code << 2 | static_cast<std::uint64_t>(k)});
      }
    }
  };
  // Two passes over the cells, each thread a stretch of them with a count and a next slot per
  // site a of its own (as many threads as keep those tables within a byte an outline cell):
  // the edges counted, then found again and written in place. The edges are held once, where a
  // list of them, its copy and a sort's spare were held before.
  const std::size_t team = std::clamp<std::size_t>(n / (sizeof(std::size_t) * (sites + 1)), 1,
                                                   static_cast<std::size_t>(thread_count(0)));
  std::vector<std::vector<std::size_t>> place(team, std::vector<std::size_t>(sites + 1, 0));
  const auto pass = [&](auto&& emit) {
    FirstException failure;
#pragma omp parallel for schedule(static, 1) num_threads(static_cast<int>(team))
    for (std::int64_t t = 0; t < static_cast<std::int64_t>(team); ++t) {
      std::vector<std::size_t>& mine = place[static_cast<std::size_t>(t)];
      failure.run([&] {
        for (std::size_t c = n * static_cast<std::size_t>(t) / team; c < n * (static_cast<std::size_t>(t) + 1) / team; ++c) {
          edges_of(c, [&](const EdgeRef& e) { emit(mine[static_cast<std::size_t>(e.key >> 32)], e); });
        }
      });
    }
    failure.rethrow();
  };
  pass([](std::size_t& count, const EdgeRef&) { ++count; });
  std::vector<std::size_t> start(sites + 1, 0);
  std::size_t at = 0;
  for (std::size_t s = 0; s < sites; ++s) {
    start[s] = at;
    for (std::size_t t = 0; t < team; ++t) {
      const std::size_t count = place[t][s];
      place[t][s] = at;
      at += count;
    }
  }
  start[sites] = at;
  DefaultInitVector<EdgeRef> all(at);  // every slot written below
  pass([&](std::size_t& next, const EdgeRef& e) { all[next++] = e; });
  // Each site a's edges (in code order) sorted by (pair, edge): the order of one sort of them all.
  const auto site_count = static_cast<std::int64_t>(sites);
#pragma omp parallel for schedule(dynamic, 4096) num_threads(thread_count(0))
  for (std::int64_t s = 0; s < site_count; ++s) {
    std::sort(all.begin() + static_cast<std::ptrdiff_t>(start[static_cast<std::size_t>(s)]),
              all.begin() + static_cast<std::ptrdiff_t>(start[static_cast<std::size_t>(s) + 1]));
  }
  return all;
}

PairLines link_pair(const EdgeRef* begin, const EdgeRef* end, int level, const std::uint64_t* measured) {
  std::vector<Segment> segments;
  segments.reserve(static_cast<std::size_t>(end - begin));
  PairLines out;
  std::uint64_t units = measured ? *measured : 0;
  // The thread's recent geodesics: a pair's edges along a parallel are one problem.
  thread_local measure::EdgeSolver::Recent recent;
  static const measure::Ellipsoid wgs84 = measure::wgs84_ellipsoid();
  for (const EdgeRef* e = begin; e != end; ++e) {
    LonLat ring[grid::kMaxPolygonCorners];
    const int corners = grid::cell_polygon(grid::cell_of(e->edge >> 2, level), level, ring);
    const int k = static_cast<int>(e->edge & 3u);
    const Segment& s = segments.emplace_back(Segment{ring[k], ring[(k + 1) % corners]});
    if (!measured || on_cut(s.from, s.to)) units += static_cast<std::uint64_t>(recent.units(wgs84, {s.from, s.to}).length);
  }
  out.length_m = static_cast<double>(units) * kLengthUnit;
  std::sort(segments.begin(), segments.end(), [](const Segment& a, const Segment& b) {
    return point_less(a.from, b.from) || (same_point(a.from, b.from) && point_less(a.to, b.to));
  });
  std::vector<LonLat> ends;
  ends.reserve(segments.size());
  for (const Segment& s : segments) ends.push_back(s.to);
  std::sort(ends.begin(), ends.end(), point_less);
  const auto has_incoming = [&](const LonLat& p) {
    const auto it = std::lower_bound(ends.begin(), ends.end(), p, point_less);
    return it != ends.end() && same_point(*it, p);
  };
  std::vector<char> used(segments.size(), 0);
  const auto unused_from = [&](const LonLat& p) {
    auto it = std::lower_bound(segments.begin(), segments.end(), p,
                               [](const Segment& s, const LonLat& q) { return point_less(s.from, q); });
    for (; it != segments.end() && same_point(it->from, p); ++it) {
      const auto k = static_cast<std::size_t>(it - segments.begin());
      if (!used[k]) return k;
    }
    return segments.size();
  };
  const auto follow = [&](std::size_t k) {
    std::vector<LonLat> line{segments[k].from};
    while (k < segments.size()) {
      used[k] = 1;
      line.push_back(segments[k].to);
      k = unused_from(segments[k].to);
    }
    out.lines.push_back(std::move(line));
  };
  // Open lines from their starts first, then what is left are closed loops.
  for (std::size_t k = 0; k < segments.size(); ++k) {
    if (!used[k] && !has_incoming(segments[k].from)) follow(k);
  }
  for (std::size_t k = 0; k < segments.size(); ++k) {
    if (!used[k]) follow(k);
  }
  return out;
}

}  // namespace qtmv::write
