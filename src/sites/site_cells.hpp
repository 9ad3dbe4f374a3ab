// Site cells and fixed cells: from the tracer's hits to the labeller's arrays, and the rules for
// cells that several sites claim.
#pragma once

#include <cstdint>
#include <vector>

#include "sites/path_tracer.hpp"
#include "sites/site_options.hpp"
#include "sites/site_types.hpp"

namespace qtmv::sites {

/// Appends one site's site cells made from its hits (pieces in the order they were added):
/// sorted by code, one entry per run of consecutive pieces in a cell, so a cell the site passes
/// through twice has two entries with disjoint piece ranges. Reorders `hits`.
void append_site_cells(std::vector<CellHit>& hits, std::int32_t site, label::SiteArray<SiteCell>& out);

/// Per site, what it got after resolve_claims.
struct SiteCellCounts {
  std::vector<std::uint64_t> site_cells;   ///< distinct site cells kept
  std::vector<std::uint64_t> fixed_cells;  ///< fixed cells kept (those of its fixed nodes included)
  /// false: every cell of the site went to another site (a lower-id polygon's interior, or
  /// under the cell rule a lower id's site cell); the site cannot win any cell.
  std::vector<bool> has_own_cell;
};

/// Applies the claim rules to g (whose site_count must be set): a fixed cell (or a cell of a fixed
/// node) claimed by several polygons goes to the lowest site id (the labeller applies the same
/// rule to the nodes); under DistanceRule::cell so does a site cell; under
/// DistanceRule::exact every site keeps its site cells and pieces (the labeller decides by
/// distance). Fixed cells come out sorted by code.
SiteCellCounts resolve_claims(SiteGeometry& g, DistanceRule rule);

}  // namespace qtmv::sites
