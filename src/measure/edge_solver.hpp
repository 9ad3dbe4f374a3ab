// Batches of cell edges' geodesics (edge_units.hpp) solved on the CPU or on one CUDA device, with
// the same bits either way: the writer's regions' areas and Voronoi edges' lengths.
#pragma once

#include <cstddef>
#include <memory>
#include <string>

#include "measure/edge_units.hpp"

namespace qtmv::measure {

namespace cuda {
class EdgeLanes;
}

class EdgeSolver {
 public:
  /// Edges a caller should gather per solve() call: enough to keep a GPU's launch and copies
  /// (tens of microseconds) small beside the work.
  static constexpr std::size_t kBatchEdges = std::size_t{1} << 16;

  /// The geodesics a CPU thread solved last (a few thousand), by their canonical problem
  /// (geodesic_inverse.hpp: the latitudes and longitude difference, each exact, up to mirror
  /// images): an edge whose problem is one of them takes its solution, the same bits. The cell
  /// edges along a row's parallel share one problem, and so do an edge and its mirror images in
  /// the other octants and across the octant's middle meridian; a caller that passes the
  /// octants' rows in step (RegionTracer) solves each problem about once. One per thread.
  class Recent {
   public:
    Recent();
    ~Recent();
    Recent(const Recent&) = delete;
    Recent& operator=(const Recent&) = delete;
    /// The measures of `edge`, from a slot or solved on `ellipsoid` (and kept).
    EdgeUnits units(const Ellipsoid& ellipsoid, const EdgeEnds& edge);
    /// The same for edges[0, count) into out[0, count), the same bits, each edge's slot fetched
    /// ahead of it.
    void units(const Ellipsoid& ellipsoid, const EdgeEnds* edges, std::size_t count, EdgeUnits* out);

   private:
    struct Slot;
    struct Keyed;
    static Keyed keyed(const EdgeEnds& edge);
    EdgeUnits units(const Ellipsoid& ellipsoid, const Keyed& keyed);
    std::unique_ptr<Slot[]> slots_;
  };

  /// `cuda_device`: the ordinal of the CUDA device that solves the batches; -1: the CPU, each
  /// batch on the thread that passes it. A device that cannot be used (none, no memory left, a
  /// build without CUDA) leaves the batches to the CPU, with the same results: `problem` (may
  /// be null) then gets the reason.
  explicit EdgeSolver(int cuda_device = -1, std::string* problem = nullptr);
  ~EdgeSolver();
  EdgeSolver(const EdgeSolver&) = delete;
  EdgeSolver& operator=(const EdgeSolver&) = delete;

  /// The measures of edges[0, count) into out[0, count). Safe to call from several threads at
  /// once, each with its own `recent` (may be null: the batch's own) for the CPU's solutions.
  /// Throws std::runtime_error on a CUDA error.
  void solve(const EdgeEnds* edges, std::size_t count, EdgeUnits* out, Recent* recent = nullptr) const;

  bool on_device() const { return lanes_ != nullptr; }

 private:
  Ellipsoid ellipsoid_;
  std::unique_ptr<cuda::EdgeLanes> lanes_;
};

}  // namespace qtmv::measure
