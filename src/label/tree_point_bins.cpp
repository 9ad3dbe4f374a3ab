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

/// Notes the sites of n points in out: the first and the first other one (the node then has
/// several: their least and greatest are apart), or the one site of all.
void note_points_sites(const SpatialItems& items, const std::int32_t* pos, std::size_t n, KeptList& out) {
  if (n == 0) return;
  const std::int32_t* site = items.sites();
  const std::int32_t first = site[pos[0]];
  for (std::size_t k = 1; k < n; ++k) {
    if (site[pos[k]] != first) {
      out.note_sites(std::min(first, site[pos[k]]), std::max(first, site[pos[k]]));
      return;
    }
  }
  out.note_sites(first, first);
}

}  // namespace

double binned_least(const SpatialItems& items, const Vec3& x, const std::int32_t* points, std::uint32_t count,
                    const PointBins* bins, double best, PointScratch& s) {
  const Vec3* rep = items.points();
  s.chord2.resize(count);
  auto search = [&](std::uint32_t begin, std::uint32_t end) {
    for (std::uint32_t k = begin; k < end; ++k) {
      const Vec3& a = rep[points[k]];
      const double dx = x.x - a.x, dy = x.y - a.y, dz = x.z - a.z;
      const double d2 = dx * dx + dy * dy + dz * dz;  // grid::chord2(x, a), as piece_chord2
      s.chord2[k] = d2;
      best = d2 < best ? d2 : best;
    }
  };
  if (!bins) {
    search(0, count);
    s.searched = kPointBins;
    return best;
  }
  const double delta = centre_delta(*bins, x);
  int b = 0;
  for (; b < kPointBins; ++b) {
    if (best < kChord2Infinity && bin_beyond(*bins, b, delta, sqrt(best))) break;
    search(bins->first[b], bins->first[b + 1]);
  }
  s.searched = b;
  return best;
}

void binned_keep(const SpatialItems& items, const NodeBounds& node, const std::int32_t* points, std::uint32_t count,
                 const PointBins* bins, PointScratch& s) {
  const Vec3& x = node.centre;
  const Vec3* rep = items.points();
  std::uint32_t end = count;  // binned_least measured them all when they are plain
  if (bins) {
    // The bins up to the first beyond the node's reach (and every one after it) are one stretch
    // of the list: measured (beyond those binned_least measured) and kept in one pass each.
    const double delta = centre_delta(*bins, x);
    const double reach = sqrt(node.threshold);
    int stop = 0;
    while (stop < kPointBins && !bin_beyond(*bins, stop, delta, reach)) ++stop;
    end = bins->first[stop];
    for (std::uint32_t k = bins->first[std::min(s.searched, stop)]; k < end; ++k) {
      const Vec3& a = rep[points[k]];
      const double dx = x.x - a.x, dy = x.y - a.y, dz = x.z - a.z;
      s.chord2[k] = dx * dx + dy * dy + dz * dz;
    }
  }
  s.pos.resize(end);
  s.kept_chord2.resize(end);
  std::size_t m = 0;
  // Without branches: a point's entry is written and kept only when within the threshold. The
  // least kept one (then least item) is noted on the way: after the first few, seldom replaced.
  const std::int32_t* item = items.items();
  double least = node.threshold;
  std::int32_t least_pos = -1;
  for (std::uint32_t k = 0; k < end; ++k) {
    const double d2 = s.chord2[k];
    s.pos[m] = points[k];
    s.kept_chord2[m] = d2;
    m += d2 <= node.threshold ? 1 : 0;
    if (d2 <= least && (d2 < least || least_pos < 0 || item[points[k]] < item[least_pos])) {
      least = d2;
      least_pos = points[k];
    }
  }
  s.least_pos = least_pos;
  s.least_chord2 = least;
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

bool points_of_blocks(const SpatialItems& items, const Vec3& x, const ListBlock* blocks, std::uint32_t count,
                      PointScratch& s) {
  const std::uint8_t* point = items.point_flags();
  const Vec3* rep = items.points();
  s.pos.clear();
  s.kept_chord2.clear();
  bool points = true;
  items.for_each_position(blocks, count, [&](std::int32_t pos) {
    points = points && point[pos] != 0;
    const double dx = x.x - rep[pos].x, dy = x.y - rep[pos].y, dz = x.z - rep[pos].z;
    s.pos.push_back(pos);
    s.kept_chord2.push_back(dx * dx + dy * dy + dz * dz);  // grid::chord2(x, a), as piece_chord2
  });
  return points;
}

void note_kept_points(const SpatialItems& items, const PointScratch& s, BisectorCut& cut) {
  if (s.least_pos >= 0) cut.note(items.items()[s.least_pos], items.points()[s.least_pos], s.least_chord2);
}

void drop_beyond_bisector(const SpatialItems& items, const NodeBounds& node, PointScratch& s) {
  const BisectorCut& cut = node.cut;
  if (!cut.active) return;
  const Vec3* rep = items.points();
  const std::int32_t* item = items.items();
  const std::size_t n = s.pos.size();
  // beyond_bisector(c, radius, a, b) with its chord2(c, b) given (kept_chord2: the same
  // operations), the same bits, without branches: a third or so of the points go, at random. a's
  // duplicates (and a) take a rare branch. The points within sure2 are kept unread (their
  // coordinates are far in memory) but for those at a's own squared chord, a's duplicates among
  // them.
  const Vec3 a = cut.a;
  const double ca = grid::chord2(node.centre, a);
  const double k_radius = node.radius + 0.5 * node.radius * node.radius;
  std::size_t m = 0;
  for (std::size_t k = 0; k < n; ++k) {
    const std::int32_t pos = s.pos[k];
    const double d2 = s.kept_chord2[k];
    s.pos[m] = pos;
    s.kept_chord2[m] = d2;
    if (d2 <= cut.sure2 && d2 != ca) {
      ++m;
      continue;
    }
    const Vec3& b = rep[pos];
    const double wx = a.x - b.x, wy = a.y - b.y, wz = a.z - b.z;
    const double along = 0.5 * (d2 - ca);
    const double w = sqrt(wx * wx + wy * wy + wz * wz);
    bool dropped = (along > kBisectorMargin) & (along > w * k_radius + kBisectorMargin);
    if (wx == 0.0 && wy == 0.0 && wz == 0.0) dropped = node.drops(b, d2, item[pos]);
    m += dropped ? 0 : 1;
  }
  s.pos.resize(m);
  s.kept_chord2.resize(m);
}

bool emit_points(const SpatialItems& items, const NodeBounds& node, PointScratch& s, KeptList& out, PointBins* bins) {
  const std::size_t n = s.pos.size();
  const std::size_t at = out.points->size();
  out.points->resize(at + n);
  std::int32_t* dest = out.points->data() + at;
  out.count += n;
  note_points_sites(items, s.pos.data(), n, out);
  if (!bins || n <= kPlainPoints) {
    std::copy(s.pos.begin(), s.pos.begin() + static_cast<std::ptrdiff_t>(n), dest);
    return false;
  }
  bins->centre = node.centre;
  bins->threshold = node.threshold;
  std::uint32_t* first = bins->first;
  const double scale = kPointBins / node.threshold;
  s.bin.resize(n);
  for (std::size_t k = 0; k < n; ++k) {
    const int b = static_cast<int>(s.kept_chord2[k] * scale);
    s.bin[k] = static_cast<std::uint8_t>(b < kPointBins - 1 ? b : kPointBins - 1);
  }
  // Two counts a bin, of the even and the odd points: fewer increments of one counter in a row.
  std::uint32_t count[2][kPointBins] = {};
  for (std::size_t k = 0; k < n; ++k) ++count[k & 1][s.bin[k]];
  first[0] = 0;
  for (int b = 0; b < kPointBins; ++b) first[b + 1] = first[b] + count[0][b] + count[1][b];
  // The even points of a bin, then its odd ones: two chains of increments, as in the counts.
  std::uint32_t next[2][kPointBins];
  for (int b = 0; b < kPointBins; ++b) {
    next[0][b] = first[b];
    next[1][b] = first[b] + count[0][b];
  }
  for (std::size_t k = 0; k < n; ++k) dest[next[k & 1][s.bin[k]]++] = s.pos[k];
  return true;
}

}  // namespace qtmv::label
