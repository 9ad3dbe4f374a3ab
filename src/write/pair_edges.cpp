#include "write/pair_edges.hpp"

#include <algorithm>
#include <cstddef>
#include <utility>

#include "common/first_exception.hpp"
#include "common/openmp_threads.hpp"
#include "common/radix_sort.hpp"
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
  const auto n = static_cast<std::int64_t>(cells.size());
  // Thread t of the team takes the t-th run of cells, so its edges come in cell order, k after
  // k: joined in thread order they are sorted by `edge`, and a stable radix sort by pair leaves
  // them sorted by (key, edge).
  std::vector<std::vector<EdgeRef>> parts(static_cast<std::size_t>(thread_count(0)));
  FirstException failure;
#pragma omp parallel num_threads(thread_count(0))
  {
    const auto team = static_cast<std::int64_t>(team_size()), t = static_cast<std::int64_t>(thread_index());
    std::vector<EdgeRef>& local = parts[static_cast<std::size_t>(t)];
    for (std::int64_t c = n * t / team; c < n * (t + 1) / team; ++c) {
      const label::OutlineCell& outline = cells[static_cast<std::size_t>(c)];
      if (!outline.boundary()) continue;
      const Code code = outline.code();
      const std::int32_t site = outline.site;
      failure.run([&] {
        Code nb[3];
        grid::neighbours(code, level, nb);
        int across[grid::kMaxPolygonCorners];
        const int corners = drawn_edges(grid::cell_of(code, level), across);
        for (int k = 0; k < corners; ++k) {
          if (across[k] == kAcrossPoleLine) continue;
          const std::int32_t other = label::site_of_near(cells, static_cast<std::size_t>(c), nb[across[k]]);
          if (other > site) {
            local.push_back({static_cast<std::uint64_t>(site) << 32 | static_cast<std::uint32_t>(other),
                             code << 2 | static_cast<std::uint64_t>(k)});
          }
        }
      });
    }
  }
  failure.rethrow();
  std::vector<std::size_t> at(parts.size() + 1, 0);
  for (std::size_t t = 0; t < parts.size(); ++t) at[t + 1] = at[t] + parts[t].size();
  DefaultInitVector<EdgeRef> all(at.back());  // every slot copied below
#pragma omp parallel for schedule(static, 1) num_threads(thread_count(0))
  for (std::int64_t t = 0; t < static_cast<std::int64_t>(parts.size()); ++t) {
    std::copy(parts[static_cast<std::size_t>(t)].begin(), parts[static_cast<std::size_t>(t)].end(),
              all.begin() + static_cast<std::ptrdiff_t>(at[static_cast<std::size_t>(t)]));
    std::vector<EdgeRef>().swap(parts[static_cast<std::size_t>(t)]);
  }
  // Pairs (a, b) as a * sites + b: one key of the fewest bits.
  const auto sites = static_cast<std::uint64_t>(std::max(1, outlines.site_count));
  radix_sort(all, bits_for(sites * sites - 1),
             [sites](const EdgeRef& e) { return (e.key >> 32) * sites + (e.key & 0xffffffffu); });
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
