#include "sites/site_cells.hpp"

#include <algorithm>
#include <functional>

#include "common/default_init_allocator.hpp"
#include "common/openmp_threads.hpp"
#include "common/radix_sort.hpp"
#include "grid/qtm_key_ranges.hpp"

namespace qtmv::sites {

void append_site_cells(std::vector<CellHit>& hits, std::int32_t site, label::SiteArray<SiteCell>& out) {
  sort_by_pair(hits, [](const CellHit& h) { return h.code; }, [](const CellHit& h) { return h.piece; });
  for (std::size_t k = 0; k < hits.size(); ++k) {
    const CellHit& h = hits[k];
    if (!out.empty() && out.back().site == site && out.back().code == h.code && out.back().piece_end >= h.piece) {
      out.back().piece_end = std::max(out.back().piece_end, h.piece + 1);
    } else {
      out.push_back({h.code, site, h.piece, h.piece + 1});
    }
  }
}

SiteCellCounts resolve_claims(SiteGeometry& g, DistanceRule rule) {
  const auto sites = static_cast<std::size_t>(g.site_count);
  SiteCellCounts counts;
  counts.site_cells.assign(sites, 0);
  counts.fixed_cells.assign(sites, 0);
  counts.has_own_cell.assign(sites, false);

  auto by_code_site = [](const auto& a, const auto& b) { return a.code != b.code ? a.code < b.code : a.site < b.site; };
  const auto code_of = [](const auto& c) { return c.code; };
  const auto site_of = [](const auto& c) { return static_cast<std::uint32_t>(c.site); };
  sort_by_pair(g.fixed_cells, code_of, site_of);
  g.fixed_cells.erase(std::unique(g.fixed_cells.begin(), g.fixed_cells.end(),
                                  [](const FixedCell& a, const FixedCell& b) { return a.code == b.code; }),
                      g.fixed_cells.end());
  // The cells claimed, cells and nodes alike, each given to its lowest claimant.
  const std::vector<grid::KeyRange> held = label::held_claims(g.input());
  for (const grid::KeyRange& r : held) {
    counts.fixed_cells[r.owner] += r.last - r.first + 1;
    counts.has_own_cell[r.owner] = true;
  }

  if (rule == DistanceRule::cell) {
    std::stable_sort(g.site_cells.begin(), g.site_cells.end(), by_code_site);
    std::size_t kept = 0;
    for (std::size_t k = 0; k < g.site_cells.size(); ++k) {
      const SiteCell& c = g.site_cells[k];
      if (kept > 0 && g.site_cells[kept - 1].code == c.code && g.site_cells[kept - 1].site != c.site) continue;
      g.site_cells[kept++] = c;
    }
    g.site_cells.resize(kept);
  }
  // Distinct codes per site; a site cell is the site's own unless another site's interior holds it.
  struct SiteCode {
    std::int32_t site;
    grid::Code code;
    bool operator==(const SiteCode& o) const { return site == o.site && code == o.code; }
  };
  const auto n = static_cast<std::int64_t>(g.site_cells.size());
  const int threads = thread_count(0);
  std::vector<SiteCode, DefaultInitAllocator<SiteCode>> site_codes(g.site_cells.size());  // filled on all cores
#pragma omp parallel for schedule(static) num_threads(threads)
  for (std::int64_t k = 0; k < n; ++k) site_codes[k] = {g.site_cells[k].site, g.site_cells[k].code};
  // Read in site order, each site's cells by code: sorted already but for shared features and
  // the cell rule.
  const auto by_site_code = [](const SiteCode& a, const SiteCode& b) {
    return a.site != b.site ? a.site < b.site : a.code < b.code;
  };
  if (!std::is_sorted(site_codes.begin(), site_codes.end(), by_site_code)) {
    sort_by_pair(site_codes, [](const SiteCode& c) { return static_cast<std::uint32_t>(c.site); }, [](const SiteCode& c) { return c.code; });
  }
  site_codes.erase(std::unique(site_codes.begin(), site_codes.end()), site_codes.end());
  // Whether each is its site's own: its site holds an interior already, or no other site's
  // interior holds it (looked up on all cores, when there are interiors).
  const auto m = static_cast<std::int64_t>(site_codes.size());
  std::vector<unsigned char, DefaultInitAllocator<unsigned char>> own(held.empty() ? 0 : site_codes.size());
  if (!held.empty()) {
#pragma omp parallel for schedule(static) num_threads(threads)
    for (std::int64_t k = 0; k < m; ++k) {
      const auto [site, code] = site_codes[k];
      if (counts.has_own_cell[site]) {
        own[k] = 1;
        continue;
      }
      const std::uint64_t key = grid::quadtree_key(grid::cell_of(code, g.level), g.level);
      auto r = std::upper_bound(held.begin(), held.end(), key,
                                [](std::uint64_t x, const grid::KeyRange& range) { return x < range.first; });
      own[k] = r == held.begin() || (r - 1)->last < key || (r - 1)->owner == site;
    }
  }
  for (std::size_t k = 0; k < site_codes.size(); ++k) {
    const std::int32_t site = site_codes[k].site;
    ++counts.site_cells[site];
    if (held.empty() || own[k]) counts.has_own_cell[site] = true;
  }
  return counts;
}

}  // namespace qtmv::sites
