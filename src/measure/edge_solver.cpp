#include "measure/edge_solver.hpp"

#include <cstdint>
#include <cstring>
#include <stdexcept>

#include "measure/edge_solver_cuda.hpp"

namespace qtmv::measure {

namespace {

/// The measures of the last few hundred distinct edges solved on this thread's batch, looked up
/// by what the solution depends on: geodesic_inverse sees the longitudes only through their
/// difference (ang_diff: exactly lon12 + lon12s), so every edge with the same latitudes and the
/// same difference has the same bits. The cell edges along a parallel of a row of the grid mostly
/// do (a third of a regions' pass at level 10), and they come one after another in code order.
class RecentEdges {
 public:
  /// The measures of `edge`, from a slot or solved (and kept).
  EdgeUnits units(const Ellipsoid& ellipsoid, const EdgeEnds& edge) {
    double lon12s;
    const double lon12 = detail::ang_diff(edge.from.lon, edge.to.lon, &lon12s);
    Key key;
    key.bits[0] = bits(edge.from.lat);
    key.bits[1] = bits(edge.to.lat);
    key.bits[2] = bits(lon12);
    key.bits[3] = bits(lon12s);
    std::uint64_t h = 0;
    for (const std::uint64_t b : key.bits) h = (h ^ b) * 0x9E3779B97F4A7C15ull;
    Slot& slot = slots_[(h ^ (h >> 29)) >> (64 - kSlotBits)];
    if (slot.filled && std::memcmp(slot.key.bits, key.bits, sizeof key.bits) == 0) return slot.units;
    slot = {key, edge_units(ellipsoid, edge), true};
    return slot.units;
  }

 private:
  static std::uint64_t bits(double x) {  // exact bits: -0 and +0 differ
    std::uint64_t b;
    std::memcpy(&b, &x, sizeof b);
    return b;
  }
  struct Key {
    std::uint64_t bits[4];  // latitude from, latitude to, lon12, lon12s
  };
  struct Slot {
    Key key;
    EdgeUnits units;
    bool filled = false;
  };
  static constexpr int kSlotBits = 8;
  Slot slots_[1 << kSlotBits];
};

}  // namespace

EdgeSolver::EdgeSolver(int cuda_device, std::string* problem) : ellipsoid_(wgs84_ellipsoid()) {
  if (cuda_device < 0) return;
  try {
    lanes_ = std::make_unique<cuda::EdgeLanes>(cuda_device, ellipsoid_, kBatchEdges);
  } catch (const std::runtime_error& e) {
    if (problem) *problem = e.what();
  }
}

EdgeSolver::~EdgeSolver() = default;

void EdgeSolver::solve(const EdgeEnds* edges, std::size_t count, EdgeUnits* out) const {
  if (lanes_) {
    lanes_->solve(edges, count, out);
    return;
  }
  RecentEdges recent;
  for (std::size_t k = 0; k < count; ++k) out[k] = recent.units(ellipsoid_, edges[k]);
}

}  // namespace qtmv::measure
