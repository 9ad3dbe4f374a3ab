// Appending a batch's built slices to the read's geometry, in feature order: planned on one
// thread (the arrays grown, the place of each slice's elements), copied on all threads in units
// of equal size, so that one large slice (a continent's cover) keeps every thread busy.
#pragma once

#include <array>
#include <cstddef>
#include <vector>

#include "sites/site_batch.hpp"
#include "sites/site_types.hpp"

namespace qtmv::sites {

class SiteAppend {
 public:
  /// Plans appending `batch`'s built slices to `out`, each job's site as the job's site id and
  /// its pieces' indices moved past the pieces before them: out's arrays are sized (grown by
  /// twofold or more, their contents copied on up to `threads` threads when they move) and
  /// its site count set. `out` and `batch` must stay until the copies are done.
  void plan(SiteGeometry& out, const SiteBatch& batch, int threads);
  /// The units of the copy (each worth a thread).
  std::size_t unit_count() const { return unit_end_[3]; }
  /// Copies unit `u`: called on any thread, once per unit.
  void copy(std::size_t u) const;

 private:
  template <class Copy>
  void copy_range(const std::vector<std::size_t>& starts, std::size_t first, std::size_t last, const Copy& one) const;

  SiteGeometry* out_ = nullptr;
  const SiteBatch* batch_ = nullptr;
  /// Per array (pieces, site cells, fixed cells, fixed nodes): where each slice's elements go
  /// in out (ascending; the last is the end).
  std::array<std::vector<std::size_t>, 4> starts_;
  std::array<std::size_t, 4> unit_end_{};  // units of the arrays so far
};

}  // namespace qtmv::sites
