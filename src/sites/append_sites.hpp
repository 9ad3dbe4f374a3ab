// Appending a batch's built sites to the read's geometry, in feature order, on all threads.
#pragma once

#include <cstdint>
#include <vector>

#include "sites/site_types.hpp"

namespace qtmv::sites {

/// Appends a batch's built sites to `out`, `built[k]` (its site id 0) as site `ids[k]`
/// (ascending), its piece indices moved past the pieces before it: the arrays of appending them
/// one by one, each grown once and copied on all threads.
void append_sites(SiteGeometry& out, const std::vector<SiteGeometry>& built, const std::vector<std::int32_t>& ids,
                  int threads);

}  // namespace qtmv::sites
