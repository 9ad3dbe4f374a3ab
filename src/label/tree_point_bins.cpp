// Point lists binned about their owner (tree_point_bins.hpp).
#include "label/tree_point_bins.hpp"

#include <algorithm>
#include <cmath>

namespace qtmv::label {

namespace {

/// Margins of the bins' tests: a chord far above the rounding of the chords compared, and a
/// relative one on a bin's edge (its index is a rounded product).
constexpr double kBinMargin = 1e-12;
constexpr double kEdgeMargin = 1.0 - 1e-9;

/// True when every point of bin b lies farther than `reach` (chord) from a centre within `delta`
/// of the bins' centre: the bin's inner edge lies beyond reach + delta.
bool bin_beyond(const PointBins& bins, int b, double delta, double reach) {
  const double edge2 = bins.threshold * static_cast<double>(b) / kPointBins * kEdgeMargin;
  const double r = reach + delta + kBinMargin;
  return edge2 > r * r;
}

double centre_delta(const PointBins& bins, const Vec3& x) { return sqrt(grid::chord2(x, bins.centre)) + kBinMargin; }

}  // namespace

double binned_least(const SpatialItems& items, const Vec3& x, const std::int32_t* points, const PointBins& bins,
                    double best, PointScratch& s) {
  const double delta = centre_delta(bins, x);
  const double* px = items.xs();
  const double* py = items.ys();
  const double* pz = items.zs();
  s.chord2.resize(bins.first[kPointBins]);
  int b = 0;
  for (; b < kPointBins; ++b) {
    if (best < kChord2Infinity && bin_beyond(bins, b, delta, sqrt(best))) break;
    for (std::uint32_t k = bins.first[b]; k < bins.first[b + 1]; ++k) {
      const std::int32_t pos = points[k];
      const double dx = x.x - px[pos], dy = x.y - py[pos], dz = x.z - pz[pos];
      const double d2 = dx * dx + dy * dy + dz * dz;  // grid::chord2(x, a), as piece_chord2
      s.chord2[k] = d2;
      best = d2 < best ? d2 : best;
    }
  }
  s.searched = b;
  return best;
}

void binned_keep(const SpatialItems& items, const NodeBounds& node, const std::int32_t* points, const PointBins& bins,
                 PointScratch& s) {
  const Vec3& x = node.centre;
  const double delta = centre_delta(bins, x);
  const double reach = sqrt(node.threshold);
  const double* px = items.xs();
  const double* py = items.ys();
  const double* pz = items.zs();
  s.pos.resize(bins.first[kPointBins]);
  s.kept_chord2.resize(bins.first[kPointBins]);
  std::size_t m = 0;
  for (int b = 0; b < kPointBins; ++b) {
    if (bin_beyond(bins, b, delta, reach)) break;  // and every bin after it
    const std::uint32_t begin = bins.first[b], end = bins.first[b + 1];
    if (b >= s.searched) {
      for (std::uint32_t k = begin; k < end; ++k) {
        const std::int32_t pos = points[k];
        const double dx = x.x - px[pos], dy = x.y - py[pos], dz = x.z - pz[pos];
        s.chord2[k] = dx * dx + dy * dy + dz * dz;
      }
    }
    // Without branches: a point's entry is written and kept only when within the threshold.
    for (std::uint32_t k = begin; k < end; ++k) {
      s.pos[m] = points[k];
      s.kept_chord2[m] = s.chord2[k];
      m += s.chord2[k] <= node.threshold ? 1 : 0;
    }
  }
  s.pos.resize(m);
  s.kept_chord2.resize(m);
}

void flat_points_keep(const FlatList& f, const NodeBounds& node, PointScratch& s) {
  const std::size_t n = f.pos.size();
  s.pos.resize(n);
  s.kept_chord2.resize(n);
  std::size_t m = 0;
  for (std::size_t k = 0; k < n; ++k) {
    s.pos[m] = f.pos[k];
    s.kept_chord2[m] = f.lb2[k];
    m += f.lb2[k] <= node.threshold ? 1 : 0;
  }
  s.pos.resize(m);
  s.kept_chord2.resize(m);
}

void emit_binned(const SpatialItems& items, const NodeBounds& node, const PointScratch& s, KeptList& out,
                 PointBins* bins) {
  const std::size_t n = s.pos.size();
  const std::int32_t* site = items.sites();
  std::int32_t site_min = out.site_min, site_max = out.site_max;
  const std::size_t at = out.points->size();
  out.points->resize(at + n);
  std::int32_t* dest = out.points->data() + at;
  out.count += n;
  if (!bins) {
    for (std::size_t k = 0; k < n; ++k) {
      const std::int32_t pos = s.pos[k];
      dest[k] = pos;
      site_min = site[pos] < site_min ? site[pos] : site_min;
      site_max = site[pos] > site_max ? site[pos] : site_max;
    }
    out.note_sites(site_min, site_max);
    return;
  }
  bins->centre = node.centre;
  bins->threshold = node.threshold;
  std::uint32_t* first = bins->first;
  std::fill(first, first + kPointBins + 1, 0u);
  const double scale = kPointBins / node.threshold;
  auto bin_of = [&](double d2) {
    const int b = static_cast<int>(d2 * scale);
    return b < kPointBins - 1 ? b : kPointBins - 1;
  };
  for (std::size_t k = 0; k < n; ++k) ++first[bin_of(s.kept_chord2[k]) + 1];
  for (int b = 0; b < kPointBins; ++b) first[b + 1] += first[b];
  std::uint32_t next[kPointBins];
  std::copy(first, first + kPointBins, next);
  for (std::size_t k = 0; k < n; ++k) {
    const std::int32_t pos = s.pos[k];
    dest[next[bin_of(s.kept_chord2[k])]++] = pos;
    site_min = site[pos] < site_min ? site[pos] : site_min;
    site_max = site[pos] > site_max ? site[pos] : site_max;
  }
  out.note_sites(site_min, site_max);
}

}  // namespace qtmv::label
