// Geodesic measures of the vector outputs on the WGS84 ellipsoid: the regions' areas (area_m2)
// and the Voronoi edges' lengths (length_m).
//
// A region's area is that of the region whose cell vertices are joined by geodesics: the cells
// then tile the ellipsoid exactly, so the areas add up to its area. It is the area GeographicLib's
// PolygonArea gives for the region's rings, each taken with the region on its left (so a region
// around a pole gets its own area, not the rest of the Earth), holes subtracted; but it is
// summed edge by edge: a ring's area is the sum over its edges of each geodesic's area to the
// equator (S12), reduced modulo the ellipsoid's area with the ring's crossings of the prime
// meridian. Those sums add over all rings of a region, and an edge between two regions counts for
// both with opposite signs, so every cell edge between sites is solved once, straight from the
// outline cells, without the traced rings. The geodesics are solved in batches by
// measure::EdgeSolver, on the CPU or on a GPU with the same bits (measure/geodesic_math.hpp).
#pragma once

#include <cmath>
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "label/outline_cells.hpp"
#include "measure/edge_units.hpp"
#include "write/region_tracer.hpp"

namespace qtmv::write {

/// The resolution (metres) of the sums of edge lengths per pair of sites (PairLength).
using measure::kLengthUnit;

/// `metres` in kLengthUnit, rounded as the edges' lengths are (measure::length_units).
inline std::uint64_t length_units(double metres) { return static_cast<std::uint64_t>(measure::length_units(metres)); }

/// The cell edges between sites a < b (site ids; key = a << 32 | b, as the voronoi_edges layer
/// keys its pairs): their geodesic lengths summed in fixed point (kLengthUnit), so that the sum
/// does not depend on the order of adding.
struct PairLength {
  std::uint64_t key = 0;
  std::uint64_t units = 0;
};

/// The regions' areas summed as their edges are seen, by RegionTracer's gathering pass (or by
/// region_areas): each edge between two sites solved once, from the lower site's side, for both.
class RegionAreaSums : public RegionEdgeObserver {
 public:
  /// With `pair_lengths`, each edge between two sites also gives its geodesic length (the same
  /// solution as its area), summed per pair; not the edges on the cut at +-180, which the pass
  /// sees as borders. `cuda_device`: the CUDA device that solves the geodesics, -1 for the CPU
  /// (the same sums either way; a device that cannot be used leaves them to the CPU, and
  /// `device_problem`, which may be null, gets the reason).
  explicit RegionAreaSums(std::int32_t site_count, bool pair_lengths = false, int cuda_device = -1,
                          std::string* device_problem = nullptr);
  ~RegionAreaSums() override;
  std::unique_ptr<Local> local() override;
  /// Areas (square metres) of the regions, from the edges seen; 0 for a site whose
  /// `cells_per_site` is 0. Call once every Local view is gone.
  std::vector<double> areas(const std::vector<std::uint64_t>& cells_per_site) const;
  /// The pairs' length sums, sorted by key (empty without `pair_lengths`). Call once every
  /// Local view is gone.
  std::vector<PairLength> pair_lengths() const;
  /// The threads' time (seconds, summed over threads) in the geodesics' solves so far: on a GPU,
  /// what the gathering threads wait for.
  double solve_seconds() const;

  struct Sums;

 private:
  std::unique_ptr<Sums> sums_;
};

/// Areas (square metres) of the regions of all sites (outlines.site_count of them; 0 for a site
/// without cells) on all cores, from the outline cells (the whole level, or a tile's: then the
/// areas of the regions cut at its edges). Deterministic: the edges'
/// areas are added in fixed point (kAreaUnit), so the result does not depend on the threads.
/// `cuda_device` as RegionAreaSums'.
std::vector<double> region_areas(const label::Outlines& outlines, int cuda_device = -1);

/// The resolution (square metres) of the sums behind region_areas.
using measure::kAreaUnit;

/// Geodesic length (metres) of the segment between two points (degrees): the solution of the
/// regions' pass (measure::geodesic_inverse).
double geodesic_length(const LonLat& a, const LonLat& b);

}  // namespace qtmv::write
