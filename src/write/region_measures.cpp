#include "write/region_measures.hpp"

#include <GeographicLib/Geodesic.hpp>
#include <GeographicLib/Math.hpp>

#include <atomic>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <mutex>

#include "common/first_exception.hpp"
#include "common/huge_page_allocator.hpp"
#include "common/openmp_threads.hpp"
#include "common/parallel_sort.hpp"
#include "grid/qtm.hpp"
#include "measure/edge_solver.hpp"

namespace qtmv::write {

namespace {

using GeographicLib::Math;

/// +1 or -1 when the edge lon1 -> lon2 (degrees) crosses the prime meridian eastwards or
/// westwards, else 0: PolygonArea's rule (its private `transit`), so that the crossings, and
/// hence the areas of rings around a pole, come out as PolygonArea counts them.
int transit(double lon1, double lon2) {
  // Cell vertices lie in [-180, 180]. Off the cut at +-180, an edge shorter than 179 degrees of
  // longitude (every one but a few at level 0) has AngDiff's sign in the plain difference, and
  // AngNormalize leaves its ends as they are: the rule without its three remainders.
  const double d = lon2 - lon1;
  if (std::fabs(lon1) < 180 && std::fabs(lon2) < 180 && std::fabs(d) < 179) {
    return d > 0 && ((lon1 < 0 && lon2 >= 0) || (lon1 > 0 && lon2 == 0)) ? 1 : (d < 0 && lon1 >= 0 && lon2 < 0) ? -1 : 0;
  }
  const double lon12 = Math::AngDiff(lon1, lon2);
  lon1 = Math::AngNormalize(lon1);
  lon2 = Math::AngNormalize(lon2);
  return lon12 > 0 && ((lon1 < 0 && lon2 >= 0) || (lon1 > 0 && lon2 == 0)) ? 1
         : (lon12 < 0 && lon1 >= 0 && lon2 < 0)                              ? -1
                                                                               : 0;
}

/// One edge's terms for the region on its left, in fixed point (wrapping unsigned sums, so that
/// the order of adding does not matter): the geodesic's area to the equator S12 (kAreaUnit),
/// the crossings of the prime meridian, and a rough area (square metres: the trapezoid rule in
/// sin(latitude) on the lon/lat edge, scaled to the ellipsoid) that settles which multiple of the
/// ellipsoid's area the exact sum stands for.
struct EdgeTerms {
  std::uint64_t area = 0, rough = 0, crossings = 0;

  EdgeTerms reversed() const { return {0 - area, 0 - rough, 0 - crossings}; }
};

/// sin(latitude) of the latitudes (degrees) asked for lately, 256 of them by their bits: a cell's
/// vertices lie on two rows, and a thread's steps pass the rows of the 8 octants in turn.
class LatitudeSines {
 public:
  double operator()(double lat) {
    std::uint64_t bits;
    std::memcpy(&bits, &lat, sizeof bits);
    Slot& slot = slots_[(bits * 0x9E3779B97F4A7C15ull) >> (64 - kSlotBits)];
    if (slot.bits != bits) slot = {bits, std::sin(lat * grid::kDegree)};
    return slot.sine;
  }

 private:
  static constexpr int kSlotBits = 8;
  struct Slot {
    std::uint64_t bits = ~std::uint64_t{0};  // a NaN: no latitude
    double sine = 0;
  };
  Slot slots_[1 << kSlotBits];
};

/// The terms of the edge from -> to, whose S12 the solver gave (`units`).
EdgeTerms edge_terms(const LonLat& from, const LonLat& to, const measure::EdgeUnits& units, LatitudeSines& sine) {
  static const double m2_per_steradian =
      GeographicLib::Geodesic::WGS84().EllipsoidArea() / (4 * grid::kPi);
  const double rough = (to.lon - from.lon) * grid::kDegree * 0.5 * (sine(from.lat) + sine(to.lat)) * m2_per_steradian;
  EdgeTerms t;
  t.area = static_cast<std::uint64_t>(units.area);
  t.rough = static_cast<std::uint64_t>(std::llround(rough));
  t.crossings = static_cast<std::uint64_t>(static_cast<std::int64_t>(transit(from.lon, to.lon)));
  return t;
}

}  // namespace

/// Every site's sums, shared by the threads.
struct RegionAreaSums::Sums {
  /// A site's three in one cache line, so that a thread adding its slot's sums misses the cache
  /// once, not three times (the sites come in no spatial order).
  struct alignas(32) Site {
    std::atomic<std::uint64_t> area, rough, crossings;
  };
  Sums(std::size_t sites, bool lengths, int cuda_device, std::string* device_problem)
      : site(sites), lengths(lengths), solver(cuda_device, device_problem) {
    // Zeroed on all cores (tens of megabytes: their pages are first touched here).
    const auto count = static_cast<std::int64_t>(sites);
#pragma omp parallel for schedule(static) num_threads(thread_count(0))
    for (std::int64_t s = 0; s < count; ++s) {
      Site& sum = site[static_cast<std::size_t>(s)];
      sum.area.store(0, std::memory_order_relaxed);
      sum.rough.store(0, std::memory_order_relaxed);
      sum.crossings.store(0, std::memory_order_relaxed);
    }
  }
  // In huge pages: a thread's adds land anywhere in tens of megabytes, beyond what the TLB covers
  // in small pages.
  std::vector<Site, HugePageAllocator<Site>> site;
  const bool lengths;
  const measure::EdgeSolver solver;
  std::atomic<std::uint64_t> solve_ns{0};  // the threads' time in solver.solve (the trace's)
  std::mutex pair_lock;
  std::vector<PairLength> pairs;  // the threads' partial sums, any order
};

namespace {

using SiteSums = RegionAreaSums::Sums;

/// A thread's edges, solved in batches (EdgeSolver), and its recent sites' sums, added to the
/// shared ones when a slot is taken by another site and at the end: consecutive outline cells
/// mostly border the same few sites, and a few hundred sites' sums in shared atomics would be
/// fought over by every core.
class SumCache : public RegionEdgeObserver::Local {
 public:
  // A GPU's batches are large (its launch and copies cost tens of microseconds); the CPU's stay
  // in the core's caches between being gathered and solved.
  explicit SumCache(SiteSums& shared)
      : shared_(shared), batch_(shared.solver.on_device() ? measure::EdgeSolver::kBatchEdges : kCpuBatchEdges) {
    pending_.reserve(batch_);
    ends_.reserve(batch_);
  }
  void edge(std::int32_t site, const LonLat& from, const LonLat& to, std::int32_t other) override {
    // A border edge counts for its site; an edge between two sites is solved by the lower
    // site's cell, for both (the gathering passes only those: measured_edge).
    if (!measured_edge(site, other)) return;
    pending_.push_back({site, other});
    ends_.push_back({from, to});
    if (pending_.size() == batch_) solve_pending();
  }
  void finish() override {
    solve_pending();
    for (const Slot& s : slots_) {
      if (s.site >= 0) evict(s);
    }
    flush_evicted();
    if (!shared_.lengths) return;
    for (const PairLength& p : pair_slots_) {
      if (p.units != 0) partial_pairs_.push_back(p);
    }
    const std::lock_guard<std::mutex> hold(shared_.pair_lock);
    shared_.pairs.insert(shared_.pairs.end(), partial_pairs_.begin(), partial_pairs_.end());
  }

 private:
  void add(std::int32_t site, const EdgeTerms& t) {
    Slot& s = slots_[static_cast<std::size_t>(site) % kSiteSlots];
    if (s.site != site) {
      if (s.site >= 0) evict(s);
      s = Slot{site, {}};
    }
    s.sums.area += t.area;
    s.sums.rough += t.rough;
    s.sums.crossings += t.crossings;
  }
  // A pair's sum stays in its slot while the pair's edges come one after another (they mostly
  // do), and goes to the thread's partial sums when another pair takes the slot.
  void add_length(std::uint64_t key, std::uint64_t units) {
    PairLength& slot = pair_slots_[(key ^ (key >> 29)) % kSlots];
    if (slot.key != key) {
      if (slot.units != 0) partial_pairs_.push_back(slot);
      slot = PairLength{key, 0};
    }
    slot.units += units;
  }
  void solve_pending() {
    units_.resize(ends_.size());
    const auto start = std::chrono::steady_clock::now();
    shared_.solver.solve(ends_.data(), ends_.size(), units_.data(), &recent_);
    shared_.solve_ns.fetch_add(static_cast<std::uint64_t>(std::chrono::duration_cast<std::chrono::nanoseconds>(
                                   std::chrono::steady_clock::now() - start).count()),
                               std::memory_order_relaxed);
    for (std::size_t k = 0; k < pending_.size(); ++k) {
      const auto [site, other] = pending_[k];
      const EdgeTerms t = edge_terms(ends_[k].from, ends_[k].to, units_[k], sines_);
      add(site, t);
      if (other == kBorderEdge) continue;
      add(other, t.reversed());
      if (shared_.lengths) {
        add_length(static_cast<std::uint64_t>(site) << 32 | static_cast<std::uint32_t>(other),
                   static_cast<std::uint64_t>(units_[k].length));
      }
    }
    pending_.clear();
    ends_.clear();
  }
  // Slots for the sites of the last few rows of cells of every octant (the thread's 8 octants'
  // rows in turn: OctantSteps), 512 KiB, and for the pairs.
  static constexpr std::size_t kSiteSlots = 16384, kSlots = 512;
  struct Slot {
    std::int32_t site = -1;
    EdgeTerms sums;
  };
  PairLength pair_slots_[kSlots];
  std::vector<PairLength> partial_pairs_;
  // A slot taken by another site: its sums wait, with their site's shared sums fetched ahead
  // (a cache miss each: the sites come in no spatial order), and are added a few dozen at a time,
  // so that the misses overlap rather than each wait behind the last atomic add.
  void evict(const Slot& s) {
    __builtin_prefetch(&shared_.site[static_cast<std::size_t>(s.site)], 1);
    evicted_[evicted_count_++] = s;
    if (evicted_count_ == kEvicted) flush_evicted();
  }
  void flush_evicted() {
    for (std::size_t k = 0; k < evicted_count_; ++k) {
      const Slot& s = evicted_[k];
      SiteSums::Site& to = shared_.site[static_cast<std::size_t>(s.site)];
      to.area.fetch_add(s.sums.area, std::memory_order_relaxed);
      to.rough.fetch_add(s.sums.rough, std::memory_order_relaxed);
      to.crossings.fetch_add(s.sums.crossings, std::memory_order_relaxed);
    }
    evicted_count_ = 0;
  }
  static constexpr std::size_t kEvicted = 32;
  Slot evicted_[kEvicted];
  std::size_t evicted_count_ = 0;
  static constexpr std::size_t kCpuBatchEdges = 1024;
  SiteSums& shared_;
  const std::size_t batch_;  // edges solved at once
  Slot slots_[kSiteSlots];
  struct Sides {
    std::int32_t site, other;
  };
  std::vector<Sides> pending_;  // the edges not solved yet: their sites, and their ends
  std::vector<measure::EdgeEnds> ends_;
  std::vector<measure::EdgeUnits> units_;
  measure::EdgeSolver::Recent recent_;  // the thread's last solutions, from batch to batch
  LatitudeSines sines_;
};

/// A region's area from its sums: PolygonArea's reduction of the S12 sum (modulo the ellipsoid's
/// area A, half of A more for an odd number of crossings; counter-clockwise), then the multiple of
/// A nearest the rough area, within [0, A].
double settle(std::uint64_t area_sum, std::uint64_t rough_sum, std::uint64_t crossings) {
  const double whole = GeographicLib::Geodesic::WGS84().EllipsoidArea();
  double area = std::remainder(static_cast<double>(static_cast<std::int64_t>(area_sum)) * kAreaUnit, whole);
  if (crossings & 1u) area += (area < 0 ? 1 : -1) * whole / 2;
  area = -area;  // S12 sums clockwise areas; the region is on the left of its edges
  const double rough = static_cast<double>(static_cast<std::int64_t>(rough_sum));
  const double nearest = area + whole * std::round((-rough - area) / whole);
  return std::min(whole, std::max(0.0, nearest));
}

}  // namespace

RegionAreaSums::RegionAreaSums(std::int32_t site_count, bool pair_lengths, int cuda_device, std::string* device_problem)
    : sums_(std::make_unique<Sums>(static_cast<std::size_t>(site_count), pair_lengths, cuda_device, device_problem)) {}

RegionAreaSums::~RegionAreaSums() = default;

std::unique_ptr<RegionEdgeObserver::Local> RegionAreaSums::local() { return std::make_unique<SumCache>(*sums_); }

std::vector<double> RegionAreaSums::areas(const std::vector<std::uint64_t>& cells_per_site) const {
  const std::size_t sites = sums_->site.size();
  std::vector<double> out(sites, 0.0);
  for (std::size_t s = 0; s < sites && s < cells_per_site.size(); ++s) {
    if (cells_per_site[s] == 0) continue;
    const SiteSums::Site& sum = sums_->site[s];
    out[s] = settle(sum.area.load(), sum.rough.load(), sum.crossings.load());
  }
  return out;
}

double RegionAreaSums::solve_seconds() const { return static_cast<double>(sums_->solve_ns.load()) * 1e-9; }

std::vector<PairLength> RegionAreaSums::pair_lengths() const {
  std::vector<PairLength> all = sums_->pairs;
  parallel_sort(all.begin(), all.end(), [](const PairLength& a, const PairLength& b) { return a.key < b.key; });
  std::vector<PairLength> out;
  for (const PairLength& p : all) {
    if (!out.empty() && out.back().key == p.key) {
      out.back().units += p.units;
    } else {
      out.push_back(p);
    }
  }
  return out;
}

std::vector<double> region_areas(const label::Outlines& whole_or_tile, int cuda_device) {
  // A tile's regions are cut at its edges (with_range_edges), as RegionTracer cuts them.
  label::Outlines tile;
  const bool part = holds_part(whole_or_tile);
  if (part) tile = with_range_edges(whole_or_tile);
  const label::Outlines& outlines = part ? tile : whole_or_tile;
  const label::OutlineCells& cells = outlines.cells;
  RegionAreaSums sums(outlines.site_count, false, cuda_device);
  FirstException failure;
  const OctantSteps steps(outlines);  // the mirror images of an edge one after another
#pragma omp parallel num_threads(thread_count(0))
  {
    std::unique_ptr<RegionEdgeObserver::Local> cache;
    OutlineWalk walk[8];
    failure.run([&] { cache = sums.local(); });
#pragma omp for schedule(dynamic, 1)
    for (std::int64_t step = 0; step < static_cast<std::int64_t>(steps.count()); ++step) {
      failure.run([&] {
        steps.visit(static_cast<std::size_t>(step), walk, [&](std::size_t k, OutlineWalk& octant_walk) {
          const std::int32_t site = cells[k].site;
          visit_region_edges(outlines, k, octant_walk, [&](int e, std::int32_t other, DrawnCorners& corners) {
            if (measured_edge(site, other)) cache->edge(site, corners.from(e), corners.to(e), other);
          });
        });
      });
    }
    failure.run([&] { cache->finish(); });
  }
  failure.rethrow();
  return sums.areas(outlines.cells_per_site);
}

double geodesic_length(const LonLat& a, const LonLat& b) {
  static const measure::Ellipsoid wgs84 = measure::wgs84_ellipsoid();
  return measure::geodesic_inverse(wgs84, a.lat, a.lon, b.lat, b.lon).s12;
}

}  // namespace qtmv::write
