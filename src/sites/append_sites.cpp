#include "sites/append_sites.hpp"

#include <algorithm>
#include <cstdint>
#include <cstring>
#include <type_traits>

namespace qtmv::sites {

namespace {

/// Elements copied as one unit of work.
constexpr std::size_t kCopyUnit = std::size_t{1} << 16;
/// Bytes that are worth a thread when an array moves.
constexpr std::size_t kMoveBytesPerThread = std::size_t{1} << 22;

/// Sizes `array` to `size` elements, the new ones uninitialised; when it must move, it takes
/// twice the room it had (appends to come), its contents copied on all threads.
template <class T>
void grow(label::SiteArray<T>& array, std::size_t size, int threads) {
  static_assert(std::is_trivially_copyable<T>::value, "copied as bytes");
  if (size > array.capacity()) {
    label::SiteArray<T> bigger;
    bigger.reserve(std::max(size, 2 * array.capacity()));
    bigger.resize(array.size());
    const std::size_t bytes = array.size() * sizeof(T);
    const auto pieces = static_cast<std::int64_t>(std::min<std::size_t>(
        static_cast<std::size_t>(std::max(threads, 1)), bytes / kMoveBytesPerThread + 1));
    const auto* from = reinterpret_cast<const unsigned char*>(array.data());
    auto* to = reinterpret_cast<unsigned char*>(bigger.data());
#pragma omp parallel for schedule(static) num_threads(static_cast<int>(pieces)) if (pieces > 1)
    for (std::int64_t k = 0; k < pieces; ++k) {
      const std::size_t first = bytes * static_cast<std::size_t>(k) / static_cast<std::size_t>(pieces);
      const std::size_t last = bytes * static_cast<std::size_t>(k + 1) / static_cast<std::size_t>(pieces);
      if (last > first) std::memcpy(to + first, from + first, last - first);
    }
    array.swap(bigger);
  }
  array.resize(size);
}

std::size_t units_of(const std::vector<std::size_t>& starts) {
  return (starts.back() - starts.front() + kCopyUnit - 1) / kCopyUnit;
}

}  // namespace

void SiteAppend::plan(SiteGeometry& out, const SiteBatch& batch, int threads) {
  out_ = &out;
  batch_ = &batch;
  const std::size_t n = batch.slice_count();
  const std::vector<BuiltSlice>& slices = batch.slices();
  for (auto& starts : starts_) starts.resize(n + 1);
  starts_[0][0] = out.pieces.size();
  starts_[1][0] = out.site_cells.size();
  starts_[2][0] = out.fixed_cells.size();
  starts_[3][0] = out.fixed_nodes.size();
  for (std::size_t k = 0; k < n; ++k) {
    const SiteGeometry& g = slices[k].geometry;
    starts_[0][k + 1] = starts_[0][k] + g.pieces.size();
    starts_[1][k + 1] = starts_[1][k] + g.site_cells.size();
    starts_[2][k + 1] = starts_[2][k] + g.fixed_cells.size();
    starts_[3][k + 1] = starts_[3][k] + g.fixed_nodes.size();
  }
  grow(out.pieces, starts_[0][n], threads);
  grow(out.site_cells, starts_[1][n], threads);
  grow(out.fixed_cells, starts_[2][n], threads);
  grow(out.fixed_nodes, starts_[3][n], threads);
  std::size_t units = 0;
  for (std::size_t a = 0; a < 4; ++a) unit_end_[a] = units += units_of(starts_[a]);
  if (!batch.jobs().empty()) out.site_count = batch.jobs().back().site + 1;
}

/// Calls one(in, out_index, jobs, slice) for the elements [first, last) of an array whose slices
/// start at `starts`, `in` the slice's element.
template <class Copy>
void SiteAppend::copy_range(const std::vector<std::size_t>& starts, std::size_t first, std::size_t last,
                            const Copy& one) const {
  auto k = static_cast<std::size_t>(std::upper_bound(starts.begin(), starts.end(), first) - starts.begin()) - 1;
  for (; k + 1 < starts.size() && starts[k] < last; ++k) {
    const std::size_t from = std::max(first, starts[k]), to = std::min(last, starts[k + 1]);
    const BuiltSlice& slice = batch_->slices()[k];
    const SiteJob* jobs = batch_->jobs().data() + slice.first;  // a slice's site i is its job i
    for (std::size_t i = from; i < to; ++i) one(i, i - starts[k], jobs, k);
  }
}

void SiteAppend::copy(std::size_t u) const {
  const auto array = static_cast<std::size_t>(std::upper_bound(unit_end_.begin(), unit_end_.end(), u) - unit_end_.begin());
  const std::vector<std::size_t>& starts = starts_[array];
  const std::size_t unit = u - (array > 0 ? unit_end_[array - 1] : 0);
  const std::size_t first = starts.front() + unit * kCopyUnit, last = std::min(starts.back(), first + kCopyUnit);
  const std::vector<BuiltSlice>& slices = batch_->slices();
  SiteGeometry& out = *out_;
  switch (array) {
    case 0:
      copy_range(starts, first, last, [&](std::size_t i, std::size_t j, const SiteJob* jobs, std::size_t k) {
        const SitePiece& in = slices[k].geometry.pieces[j];
        out.pieces[i] = in;
        out.pieces[i].site = jobs[in.site].site;
      });
      break;
    case 1:
      copy_range(starts, first, last, [&](std::size_t i, std::size_t j, const SiteJob* jobs, std::size_t k) {
        SiteCell c = slices[k].geometry.site_cells[j];
        const auto piece_offset = static_cast<std::uint32_t>(starts_[0][k]);
        c.site = jobs[c.site].site;
        c.piece_begin += piece_offset;
        c.piece_end += piece_offset;
        out.site_cells[i] = c;
      });
      break;
    case 2:
      copy_range(starts, first, last, [&](std::size_t i, std::size_t j, const SiteJob* jobs, std::size_t k) {
        const FixedCell& in = slices[k].geometry.fixed_cells[j];
        out.fixed_cells[i] = {in.code, jobs[in.site].site};
      });
      break;
    default:
      copy_range(starts, first, last, [&](std::size_t i, std::size_t j, const SiteJob* jobs, std::size_t k) {
        const FixedNode& in = slices[k].geometry.fixed_nodes[j];
        out.fixed_nodes[i] = {in.code, in.level, jobs[in.site].site};
      });
  }
}

}  // namespace qtmv::sites
