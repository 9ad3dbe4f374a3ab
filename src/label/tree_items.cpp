// The octants' items in a spatial order, and the block by block filter (tree_items.hpp).
#include "label/tree_items.hpp"

#include <algorithm>
#include <cmath>

#include "common/radix_sort.hpp"

namespace qtmv::label {

namespace {

/// Margin (chord) of every cap test: far above the float64 rounding of the chords and bounds
/// compared (a few 1e-16), far below any node's size.
constexpr double kCapMargin = 1e-12;
/// Relative margin on a cap's reach (the rounding of its sums and roots).
constexpr double kReachMargin = 1.0 + 1e-12;

/// cap_beyond's answers.
constexpr int kCapUnsure = 0, kCapNoneBeyond = 1, kCapAllBeyond = 2;

/// The 16 low bits of v spread to every third bit.
std::uint64_t spread_bits(std::uint64_t v) {
  v &= 0xffff;
  v = (v | (v << 16)) & 0x0000ff0000ffULL;
  v = (v | (v << 8)) & 0x00f00f00f00fULL;
  v = (v | (v << 4)) & 0x0c30c30c30c3ULL;
  v = (v | (v << 2)) & 0x249249249249ULL;
  return v;
}

/// A Morton key of a unit vector (`bits` <= 16 a coordinate): nearby points get nearby keys,
/// mostly.
std::uint64_t morton_key(const Vec3& p, int bits) {
  const double top = static_cast<double>((1u << bits) - 1);
  auto q = [&](double v) {
    const double s = (v + 1.0) * 0.5 * top + 0.5;
    return static_cast<std::uint64_t>(s < 0.0 ? 0.0 : s > top ? top : s);
  };
  return spread_bits(q(p.x)) | (spread_bits(q(p.y)) << 1) | (spread_bits(q(p.z)) << 2);
}

/// Puts the n distinct non-negative values of `a` in ascending order into `out`. A list leaf's
/// list is short (kMaxLeafList) and its items are spread over the candidates: a counting pass on
/// their top bits leaves them nearly in order, and an insertion pass finishes (a comparison sort
/// mispredicts half its branches on such data).
void sort_short(const std::int32_t* a, std::size_t n, std::int32_t* out) {
  constexpr int kMaxBucketBits = 9;
  if (n >= (std::size_t{1} << (kMaxBucketBits - 2))) {
    std::copy(a, a + n, out);
    std::sort(out, out + n);
    return;
  }
  std::int32_t top = 0;
  for (std::size_t i = 0; i < n; ++i) top |= a[i];
  const int bucket_bits = bits_for(n) + 1;  // about four buckets an item
  const int shift = std::max(0, bits_for(static_cast<std::uint64_t>(top)) - bucket_bits);
  const std::size_t buckets = std::size_t{1} << bucket_bits;
  std::uint32_t bucket[std::size_t{1} << kMaxBucketBits];
  std::fill(bucket, bucket + buckets, 0u);
  for (std::size_t i = 0; i < n; ++i) ++bucket[a[i] >> shift];
  std::uint32_t start = 0;  // each bucket's first place (a running sum: no chain through memory)
  for (std::size_t b = 0; b < buckets; ++b) {
    const std::uint32_t count = bucket[b];
    bucket[b] = start;
    start += count;
  }
  for (std::size_t i = 0; i < n; ++i) out[bucket[a[i] >> shift]++] = a[i];
  for (std::size_t i = 1; i < n; ++i) {
    const std::int32_t v = out[i];
    std::size_t j = i;
    for (; j > 0 && out[j - 1] > v; --j) out[j] = out[j - 1];
    out[j] = v;
  }
}

Vec3 normalised_or(const Vec3& sum, const Vec3& fallback) {
  const double n = sqrt(grid::dot(sum, sum));
  if (!(n > 1e-9)) return fallback;
  return {sum.x / n, sum.y / n, sum.z / n};
}

/// An item's representative point (a point of its first piece, the start of a group's arc) and
/// its extent: a chord within which of that point lie its pieces and arc, widened by a group's
/// reach, so that every lower and upper bound of the item from x is at least |x - rep| - extent,
/// and every lower bound at most |x - rep|.
void item_cap(std::int32_t item, const Piece* pieces, const PieceGroup* groups, Vec3* rep, double* extent) {
  if (!is_group_item(item)) {
    const Piece& p = pieces[item];
    *rep = p.a;
    // The farthest point of a minor arc from its start is its end.
    *extent = (p.flags & kPiecePoint) ? 0.0 : sqrt(grid::chord2(p.a, p.b)) * kReachMargin;
    return;
  }
  const PieceGroup& g = groups[item_group(item)];
  *rep = g.arc.a;
  *extent = (sqrt(grid::chord2(g.arc.a, g.arc.b)) + g.reach) * kReachMargin;
}

}  // namespace

SpatialItems::SpatialItems(const std::vector<std::int32_t>& top_items, const Piece* pieces, const PieceGroup* groups,
                           int threads)
    : pieces_(pieces), groups_(groups) {
  const auto n_top = static_cast<std::int64_t>(top_items.size());
  // Keys: a Morton code of the item's point above its index among the top items (radix_sort is
  // stable, so ties stay in candidate order). Wide items (long lines' runs) stay loose, in
  // candidate order.
  const int index_bits = std::max(1, bits_for(static_cast<std::uint64_t>(n_top)));
  const int axis_bits = std::min(16, (64 - index_bits) / 3);
  auto key = [&](std::int64_t t, bool* wide) {
    Vec3 rep;
    double extent;
    item_cap(top_items[t], pieces, groups, &rep, &extent);
    *wide = extent > kLooseExtent;
    return (morton_key(rep, axis_bits) << index_bits) | static_cast<std::uint64_t>(t);
  };
  DefaultInitVector<std::uint64_t> keyed(top_items.size());
  std::int64_t wide = 0;
#pragma omp parallel for schedule(static) num_threads(threads) reduction(+ : wide)
  for (std::int64_t t = 0; t < n_top; ++t) {
    bool is_wide;
    keyed[t] = key(t, &is_wide);
    wide += is_wide ? 1 : 0;
  }
  if (wide > 0) {
    std::size_t placed = 0;
    for (std::int64_t t = 0; t < n_top; ++t) {
      bool is_wide;
      key(t, &is_wide);
      if (is_wide) {
        loose_.push_back(top_items[t]);
      } else {
        keyed[placed++] = keyed[t];
      }
    }
    keyed.resize(placed);
  }
  radix_sort(keyed, 3 * axis_bits, [&](std::uint64_t k) { return k >> index_bits; });
  place(top_items, keyed, (std::uint64_t{1} << index_bits) - 1, threads);
}

void SpatialItems::place(const std::vector<std::int32_t>& top_items, const DefaultInitVector<std::uint64_t>& keyed,
                         std::uint64_t index_mask, int threads) {
  const auto n = static_cast<std::int64_t>(keyed.size());
  item_.resize(keyed.size());
  site_.resize(keyed.size());
  rep_.resize(keyed.size());
  spread_.resize(keyed.size());
  point_.resize(keyed.size());
  if (n == 0) return;
  // Tier 0: blocks of 8 positions, their items' data read and their caps made in one pass.
  std::int64_t blocks = (n + 7) >> kTier0Bits;
  tiers_.emplace_back(blocks);
  DefaultInitVector<ItemBlock>& base = tiers_.back();
#pragma omp parallel for schedule(static) num_threads(threads)
  for (std::int64_t b = 0; b < blocks; ++b) {
    const std::int64_t first = block_begin(0, b), last = block_end(0, b);
    double extent[8];
    Vec3 sum{0.0, 0.0, 0.0};
    for (std::int64_t k = first; k < last; ++k) {
      const std::int32_t item = top_items[keyed[k] & index_mask];
      item_[k] = item;
      item_cap(item, pieces_, groups_, &rep_[k], &extent[k - first]);
      if (is_group_item(item)) {
        const PieceGroup& g = groups_[item_group(item)];
        site_[k] = g.arc.site;
        spread_[k] = g.spread;
        point_[k] = 0;
      } else {
        site_[k] = pieces_[item].site;
        spread_[k] = 0.0;
        point_[k] = (pieces_[item].flags & kPiecePoint) ? 1 : 0;
      }
      sum = sum + rep_[k];
    }
    ItemBlock blk{normalised_or(sum, rep_[first]), 0.0, 0.0, 0.0, site_[first], site_[first], 1};
    for (std::int64_t k = first; k < last; ++k) {
      const double d = sqrt(grid::chord2(blk.centre, rep_[k]));
      blk.reach = std::max(blk.reach, d + extent[k - first]);
      blk.reach_rep = std::max(blk.reach_rep, d);
      blk.spread = std::max(blk.spread, spread_[k]);
      blk.site_min = std::min(blk.site_min, site_[k]);
      blk.site_max = std::max(blk.site_max, site_[k]);
      blk.points &= point_[k];
    }
    blk.reach *= kReachMargin;
    blk.reach_rep *= kReachMargin;
    base[b] = blk;
  }
  // Tier k: blocks of four tier k - 1 blocks, their caps from the sub-blocks' caps.
  while (blocks > 1) {
    const std::int64_t below = blocks;
    blocks = (below + 3) >> kFanoutBits;
    tiers_.emplace_back(blocks);
    const DefaultInitVector<ItemBlock>& sub = tiers_[tiers_.size() - 2];
    DefaultInitVector<ItemBlock>& tier = tiers_.back();
#pragma omp parallel for schedule(static) num_threads(threads)
    for (std::int64_t b = 0; b < blocks; ++b) {
      const std::int64_t first = b << kFanoutBits, last = std::min(below, first + 4);
      Vec3 sum{0.0, 0.0, 0.0};
      for (std::int64_t k = first; k < last; ++k) sum = sum + sub[k].centre;
      ItemBlock blk{normalised_or(sum, sub[first].centre), 0.0, 0.0, 0.0, sub[first].site_min, sub[first].site_max, 1};
      for (std::int64_t k = first; k < last; ++k) {
        const double d = sqrt(grid::chord2(blk.centre, sub[k].centre));
        blk.reach = std::max(blk.reach, d + sub[k].reach);
        blk.reach_rep = std::max(blk.reach_rep, d + sub[k].reach_rep);
        blk.spread = std::max(blk.spread, sub[k].spread);
        blk.site_min = std::min(blk.site_min, sub[k].site_min);
        blk.site_max = std::max(blk.site_max, sub[k].site_max);
        blk.points &= sub[k].points;
      }
      blk.reach *= kReachMargin;
      blk.reach_rep *= kReachMargin;
      tier[b] = blk;
    }
  }
}

DefaultInitVector<ListBlock> SpatialItems::whole() const {
  if (tiers_.empty()) return {};
  const int top = static_cast<int>(tiers_.size()) - 1;
  return {ListBlock{0, static_cast<std::uint8_t>(top), top == 0 ? full_mask(0) : std::uint8_t{0xff}}};
}

void SpatialItems::nearest_in_block(const Vec3& x, int tier, std::int64_t index, std::uint8_t mask, double d2,
                                    double& best, double& root, BisectorCut& point) const {
  const ItemBlock& b = tiers_[tier][index];
  // Every item's bounds are at least |x - centre| - reach: none below `best` when that is above
  // sqrt(best) (the margin covers the rounding of both sides).
  const double limit = root + b.reach + kCapMargin;
  if (d2 > limit * limit) return;
  if (tier > 0) {
    for_each_child(tier, index, [&](std::int64_t c, std::uint8_t m) {
      nearest_in_block(x, tier - 1, c, m, grid::chord2(x, tiers_[tier - 1][c].centre), best, root, point);
    });
    return;
  }
  const std::int64_t first = block_begin(0, index);
  for (int k = 0; k < 8; ++k) {
    if (!(mask >> k & 1)) continue;
    double lb2, ub2;
    bounds(x, first + k, &lb2, &ub2);
    if (point_[first + k]) point.note(item_[first + k], rep_[first + k], lb2);
    if (ub2 < best) {
      best = ub2;
      root = sqrt(best);
    }
  }
}

void SpatialItems::nearest_point_in_block(const Vec3& x, int tier, std::int64_t index, std::uint8_t mask, double d2,
                                          double limit2, double& root, BisectorCut& cut) const {
  // Every point of the block lies within reach_rep of its centre (as nearest_in_block).
  const double limit = root + tiers_[tier][index].reach_rep + kCapMargin;
  if (d2 > limit * limit) return;
  if (tier > 0) {
    for_each_child(tier, index, [&](std::int64_t c, std::uint8_t m) {
      nearest_point_in_block(x, tier - 1, c, m, grid::chord2(x, tiers_[tier - 1][c].centre), limit2, root, cut);
    });
    return;
  }
  const std::int64_t first = block_begin(0, index);
  for (int k = 0; k < 8; ++k) {
    if (!(mask >> k & 1) || !point_[first + k]) continue;
    double lb2, ub2;
    bounds(x, first + k, &lb2, &ub2);
    if (lb2 <= limit2) {
      cut.note(item_[first + k], rep_[first + k], lb2);
      root = sqrt(std::min(limit2, cut.lb2));
    }
  }
}

void SpatialItems::note_least_point(const Vec3& x, const ListBlock* list, std::uint32_t count, double limit2,
                                    const FilterScratch& s, BisectorCut& cut) const {
  if (count == 0) return;
  std::uint32_t nearest = 0;
  for (std::uint32_t k = 1; k < count; ++k) {
    if (s.chord2[k] < s.chord2[nearest]) nearest = k;
  }
  double root = sqrt(cut.active && cut.lb2 < limit2 ? cut.lb2 : limit2);
  const ListBlock& n = list[nearest];
  nearest_point_in_block(x, n.tier, n.index, n.mask, s.chord2[nearest], limit2, root, cut);
  for (std::uint32_t k = 0; k < count; ++k) {
    if (k != nearest) {
      nearest_point_in_block(x, list[k].tier, list[k].index, list[k].mask, s.chord2[k], limit2, root, cut);
    }
  }
}

void SpatialItems::note_flat_points(const FlatList& f, double threshold, BisectorCut& cut) const {
  for (std::size_t k = 0; k < f.pos.size(); ++k) {
    const std::int32_t pos = f.pos[k];
    if (point_[pos] && f.lb2[k] <= threshold) cut.note(item_[pos], rep_[pos], f.lb2[k]);
  }
}

double SpatialItems::least_upper_bound(const Vec3& x, const ListBlock* list, std::uint32_t count, double best,
                                       FilterScratch& s) const {
  s.chord2.resize(count);
  std::uint32_t nearest = 0;
  for (std::uint32_t k = 0; k < count; ++k) {
    s.chord2[k] = grid::chord2(x, tiers_[list[k].tier][list[k].index].centre);
    if (s.chord2[k] < s.chord2[nearest]) nearest = k;
  }
  if (count == 0) return best;
  // The block nearest first: its items make `best` small, so that most others are passed over.
  double root = sqrt(best);
  const ListBlock& n = list[nearest];
  s.nearest_point = BisectorCut{};
  nearest_in_block(x, n.tier, n.index, n.mask, s.chord2[nearest], best, root, s.nearest_point);
  for (std::uint32_t k = 0; k < count; ++k) {
    if (k != nearest) {
      nearest_in_block(x, list[k].tier, list[k].index, list[k].mask, s.chord2[k], best, root, s.nearest_point);
    }
  }
  return best;
}

void SpatialItems::add_items(std::int64_t index, std::uint8_t mask, KeptList& out) const {
  out.blocks->push_back({static_cast<std::int32_t>(index), 0, mask});
  if (mask == full_mask(index)) {
    const ItemBlock& b = tiers_[0][index];
    out.note_sites(b.site_min, b.site_max);
    out.count += static_cast<std::uint64_t>(block_end(0, index) - block_begin(0, index));
    return;
  }
  const std::int64_t first = block_begin(0, index);
  out.count += static_cast<std::uint64_t>(__builtin_popcount(mask));
  for (unsigned m = mask; m != 0 && !out.several_sites(); m &= m - 1) {
    const std::int32_t site = site_[first + __builtin_ctz(m)];
    out.note_sites(site, site);
  }
}

void SpatialItems::keep_items(const NodeBounds& node, std::int64_t index, std::uint8_t mask, KeptList& out) const {
  const std::int64_t first = block_begin(0, index);
  unsigned kept = 0;
  if (tiers_[0][index].points) {
    // Points: their bounds are their squared chords, and none is split.
    double d2[8];
    for (int k = 0; k < 8; ++k) {
      const Vec3& a = rep_[first + (mask >> k & 1 ? k : 0)];
      const double dx = node.centre.x - a.x, dy = node.centre.y - a.y, dz = node.centre.z - a.z;
      d2[k] = dx * dx + dy * dy + dz * dz;  // as piece_chord2
      kept |= (d2[k] <= node.threshold ? 1u : 0u) << k;
    }
    kept &= mask;
    for (unsigned m = kept; m != 0; m &= m - 1) {
      const int k = __builtin_ctz(m);
      if (node.drops(rep_[first + k], d2[k], item_[first + k])) kept &= ~(1u << k);
    }
    out.count += static_cast<std::uint64_t>(__builtin_popcount(kept));
    for (unsigned m = kept; m != 0 && !out.several_sites(); m &= m - 1) {
      const std::int32_t site = site_[first + __builtin_ctz(m)];
      out.note_sites(site, site);
    }
  } else {
    for (int k = 0; k < 8; ++k) {
      if (!(mask >> k & 1)) continue;
      const std::int64_t pos = first + k;
      double lb2, ub2;
      bounds(node.centre, pos, &lb2, &ub2);
      if (!(lb2 <= node.threshold)) continue;
      if (point_[pos] && node.drops(rep_[pos], lb2, item_[pos])) continue;
      if (spread_[pos] > kGroupSplit * node.radius) {
        keep_split(node, pos, out);
        continue;
      }
      kept |= 1u << k;  // not splits_item: the item itself
      out.note_sites(site_[pos], site_[pos]);
      ++out.count;
    }
  }
  if (kept) out.blocks->push_back({static_cast<std::int32_t>(index), 0, static_cast<std::uint8_t>(kept)});
}

void SpatialItems::keep_split(const NodeBounds& node, std::int64_t pos, KeptList& out) const {
  const std::int32_t item = item_[pos];
  const std::size_t at = out.loose->size();
  const std::int32_t n = refine_kept(node.centre, item, pieces_, groups_, node.radius, node.threshold, nullptr);
  if (n == 0) return;  // none of a loose group's pieces is near the node
  out.loose->resize(at + static_cast<std::size_t>(n));
  refine_kept(node.centre, item, pieces_, groups_, node.radius, node.threshold, out.loose->data() + at);
  out.count += static_cast<std::uint64_t>(n);
  out.note_sites(site_[pos], site_[pos]);
}

void SpatialItems::flatten(const ListBlock* list, std::uint32_t count, std::uint32_t positions, FlatList& f) const {
  f.pos.resize(positions);
  f.site.resize(positions);
  f.x.resize(positions);
  f.y.resize(positions);
  f.z.resize(positions);
  f.lb2.resize(positions);
  f.kept.resize(positions);
  std::size_t n = 0;
  bool points = true;
  for_each_position(list, count, [&](std::int32_t pos) {
    f.pos[n] = pos;
    f.site[n] = site_[pos];
    f.x[n] = rep_[pos].x;
    f.y[n] = rep_[pos].y;
    f.z[n] = rep_[pos].z;
    points &= point_[pos] != 0;
    ++n;
  });
  f.points = points;
}

double SpatialItems::flat_bounds(const Vec3& x, FlatList& f, double best) const {
  const std::size_t n = f.pos.size();
  if (f.points) {
    const double* __restrict px = f.x.data();
    const double* __restrict py = f.y.data();
    const double* __restrict pz = f.z.data();
    double* __restrict lb2 = f.lb2.data();
    const double cx = x.x, cy = x.y, cz = x.z;
#pragma omp simd reduction(min : best)
    for (std::size_t k = 0; k < n; ++k) {
      const double dx = cx - px[k], dy = cy - py[k], dz = cz - pz[k];
      const double d2 = dx * dx + dy * dy + dz * dz;  // grid::chord2(x, a), as piece_chord2
      lb2[k] = d2;
      best = d2 < best ? d2 : best;
    }
    return best;
  }
  for (std::size_t k = 0; k < n; ++k) {
    double ub2;
    bounds(x, f.pos[k], &f.lb2[k], &ub2);
    best = ub2 < best ? ub2 : best;
  }
  return best;
}

void SpatialItems::flat_keep(const NodeBounds& node, FlatList& f, KeptList& out) const {
  const std::size_t n = f.pos.size();
  // The kept items' indices first, without branches (a third or so are kept, at random).
  std::int32_t* __restrict kept = f.kept.data();
  const double* __restrict lb2 = f.lb2.data();
  const double threshold = node.threshold;
  std::size_t m = 0;
  for (std::size_t k = 0; k < n; ++k) {
    kept[m] = static_cast<std::int32_t>(k);
    m += lb2[k] <= threshold ? 1 : 0;
  }
  for (std::size_t j = 0; j < m; ++j) {
    const std::int32_t k = kept[j];
    const std::int32_t pos = f.pos[k];
    if (point_[pos] && node.drops(rep_[pos], lb2[k], item_[pos])) continue;
    if (spread_[pos] > kGroupSplit * node.radius) {
      keep_split(node, pos, out);
      continue;
    }
    // One tier-0 entry a kept position: these lists are short, and spread out again as they are.
    out.blocks->push_back({pos >> kTier0Bits, 0, static_cast<std::uint8_t>(1u << (pos & 7))});
    out.note_sites(f.site[k], f.site[k]);
    ++out.count;
  }
}

void SpatialItems::keep_block(const NodeBounds& node, double root, int tier, std::int64_t index, std::uint8_t mask,
                              double d2, KeptList& out) const {
  const ItemBlock& b = tiers_[tier][index];
  // Every item's lower bound is above the threshold when the cap lies beyond sqrt(threshold).
  const double beyond = root + b.reach + kCapMargin;
  if (d2 > beyond * beyond) return;
  const int cut = cap_beyond(node, b, d2);
  if (cut == kCapAllBeyond) return;
  // Every item's lower bound is within it (and none is split) when the cap lies inside.
  const double inside = root - b.reach_rep - kCapMargin;
  if (cut == kCapNoneBeyond && inside >= 0.0 && d2 <= inside * inside && b.spread <= kGroupSplit * node.radius) {
    if (tier == 0) {
      add_items(index, mask, out);
    } else {
      out.blocks->push_back({static_cast<std::int32_t>(index), static_cast<std::uint8_t>(tier), 0xff});
      out.note_sites(b.site_min, b.site_max);
      out.count += static_cast<std::uint64_t>(block_end(tier, index) - block_begin(tier, index));
    }
    return;
  }
  if (tier > 0) {
    for_each_child(tier, index, [&](std::int64_t c, std::uint8_t m) {
      keep_block(node, root, tier - 1, c, m, grid::chord2(node.centre, tiers_[tier - 1][c].centre), out);
    });
    return;
  }
  keep_items(node, index, mask, out);
}

int SpatialItems::cap_beyond(const NodeBounds& node, const ItemBlock& b, double d2) const {
  const BisectorCut& cut = node.cut;
  if (!cut.active) return kCapNoneBeyond;
  // A block that may hold a, and so a's duplicates (dropped or not by their sites), is tested
  // item by item.
  const double am = sqrt(grid::chord2(cut.a, b.centre));
  if (am <= b.reach_rep + kCapMargin) return kCapUnsure;
  // Every point of the block lies within reach_rep of its centre m: inside the sure ball?
  const double far = sqrt(d2) + b.reach_rep + kCapMargin;
  if (far * far + kCapMargin <= cut.sure2) return kCapNoneBeyond;
  // For such a point p, beyond_bisector's (|c - p|^2 - |c - a|^2) / 2 - k |a - p| (k = r + r^2 /
  // 2), with |c - p| and |a - p| within reach_rep of |c - m| and |a - m|; margins far above the
  // rounding.
  const double rho = b.reach_rep;
  const double k = node.radius + 0.5 * node.radius * node.radius;
  const double dm = sqrt(d2);
  const double near = dm > rho ? dm - rho : 0.0;
  const double hi = 0.5 * ((dm + rho) * (dm + rho) - cut.lb2) - k * (am > rho ? am - rho : 0.0);
  if (hi <= 0.5 * kBisectorMargin) return kCapNoneBeyond;
  const double lo = 0.5 * (near * near - cut.lb2) - k * (am + rho);
  if (b.points && lo >= 2.0 * kBisectorMargin) return kCapAllBeyond;
  return kCapUnsure;
}

void SpatialItems::keep(const NodeBounds& node, const ListBlock* list, std::uint32_t count, FilterScratch& s,
                        KeptList& out) const {
  const double root = sqrt(node.threshold);
  for (std::uint32_t k = 0; k < count; ++k) {
    keep_block(node, root, list[k].tier, list[k].index, list[k].mask, s.chord2[k], out);
  }
}

namespace {

bool same_best(const Best& a, const Best& b) { return a.chord2 == b.chord2 && a.rank == b.rank && a.site == b.site; }
bool better_best(const Best& a, const Best& b) {
  return a.chord2 < b.chord2 || (a.chord2 == b.chord2 && (a.rank < b.rank || (a.rank == b.rank && a.site < b.site)));
}

}  // namespace

void SpatialItems::best_in_block(const Vec3& x, int tier, std::int64_t index, std::uint8_t mask, Best& best,
                                 FilterScratch& s) const {
  const ItemBlock& b = tiers_[tier][index];
  // Every piece is farther than the best so far: none of them can be or tie it.
  if (best.chord2 < kChord2Infinity) {
    const double limit = sqrt(best.chord2) + b.reach + kCapMargin;
    if (grid::chord2(x, b.centre) > limit * limit) return;
  }
  if (tier > 0) {
    for_each_child(tier, index, [&](std::int64_t c, std::uint8_t m) { best_in_block(x, tier - 1, c, m, best, s); });
    return;
  }
  const std::int64_t first = block_begin(0, index);
  for (int k = 0; k < 8; ++k) {
    if (mask >> k & 1) consider_item(x, item_[first + k], best, s);
  }
}

void SpatialItems::consider_item(const Vec3& x, std::int32_t item, Best& best, FilterScratch& s) const {
  std::int32_t won = -1;
  const Best own = best_of_items(x, &item, 1, pieces_, groups_, &won);
  if (better_best(best, own)) return;
  s.achievers.push_back({own, item, won});
  best = own;
}

Best SpatialItems::best_in_list(const Vec3& x, const ListBlock* list, const std::int32_t* points, std::uint32_t count,
                                const std::int32_t* loose, std::uint32_t loose_count, FilterScratch& s,
                                std::int32_t* winner) const {
  // best_of_items' best is the least (distance, rank, site) over all the pieces, whatever their
  // order; its winner is the first piece to reach it in its visit: the items that are pieces in
  // list order, then the groups' pieces, group by group in list order, each in preorder.
  Best best = no_best();
  s.achievers.clear();
  for (std::uint32_t k = 0; k < loose_count; ++k) consider_item(x, loose[k], best, s);
  for (std::uint32_t k = 0; k < count; ++k) {
    if (points) {
      consider_item(x, item_[points[k]], best, s);
    } else {
      best_in_block(x, list[k].tier, list[k].index, list[k].mask, best, s);
    }
  }
  if (winner) {
    std::int32_t piece = -1, group_first = -1;
    *winner = -1;
    for (const FilterScratch::Achiever& a : s.achievers) {
      if (!same_best(a.best, best)) continue;
      if (!is_group_item(a.item)) {
        if (piece < 0 || a.item < piece) piece = a.item;
      } else if (piece < 0) {
        const std::int32_t first = groups_[item_group(a.item)].first;
        if (group_first < 0 || first < group_first) {
          group_first = first;
          *winner = a.winner;
        }
      }
    }
    if (piece >= 0) *winner = piece;
  }
  return best;
}

void SpatialItems::write_in_order(const ListBlock* list, const std::int32_t* points, std::uint32_t count,
                                  std::uint32_t positions, const std::int32_t* loose, std::uint32_t loose_count,
                                  FilterScratch& s, std::int32_t* out) const {
  auto each_position = [&](auto visit) {
    if (points) {
      for (std::uint32_t k = 0; k < count; ++k) visit(points[k]);
    } else {
      for_each_position(list, count, visit);
    }
  };
  // The plain filter keeps its list in the order of the items' first pieces (the octants' list
  // in candidate order, a split group's items in preorder); items never share a first piece.
  if (groups_ == nullptr) {  // every item a piece: its first piece is itself
    std::vector<std::int32_t>& items = s.items;
    items.resize(positions + loose_count);
    std::size_t n = 0;
    each_position([&](std::int32_t pos) { items[n++] = item_[pos]; });
    std::copy(loose, loose + loose_count, items.begin() + static_cast<std::ptrdiff_t>(n));
    sort_short(items.data(), items.size(), out);
    return;
  }
  auto key = [&](std::int32_t item) {
    const std::int32_t first = is_group_item(item) ? groups_[item_group(item)].first : item;
    return (static_cast<std::uint64_t>(static_cast<std::uint32_t>(first)) << 32) | static_cast<std::uint32_t>(item);
  };
  s.keyed.clear();
  each_position([&](std::int32_t pos) { s.keyed.push_back(key(item_[pos])); });
  for (std::uint32_t k = 0; k < loose_count; ++k) s.keyed.push_back(key(loose[k]));
  std::sort(s.keyed.begin(), s.keyed.end());
  for (std::size_t k = 0; k < s.keyed.size(); ++k) {
    out[k] = static_cast<std::int32_t>(static_cast<std::uint32_t>(s.keyed[k]));
  }
}

}  // namespace qtmv::label
