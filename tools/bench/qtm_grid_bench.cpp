// Grid micro-benchmark: lon/lat -> code and code -> centre, on one core.
// Run: build/tools/bench/qtm_grid_bench --benchmark_repetitions=5 --benchmark_report_aggregates_only=true
#include <benchmark/benchmark.h>

#include <cmath>
#include <random>
#include <vector>

#include "grid/qtm.hpp"

namespace {

using namespace qtmv::grid;

constexpr std::size_t kSamples = 1 << 16;

std::vector<LonLat> random_points() {
  std::mt19937_64 rng(1);
  std::uniform_real_distribution<double> lon(-180.0, 180.0), z(-1.0, 1.0);
  std::vector<LonLat> points(kSamples);
  for (auto& p : points) p = {lon(rng), std::asin(z(rng)) / kDegree};
  return points;
}

std::vector<Code> random_codes(int level) {
  std::mt19937_64 rng(2);
  std::uniform_int_distribution<Code> pick(0, cell_count(level) - 1);
  std::vector<Code> codes(kSamples);
  for (auto& c : codes) c = pick(rng);
  return codes;
}

void BM_LonLatToCode(benchmark::State& state) {
  const int level = static_cast<int>(state.range(0));
  const auto points = random_points();
  for (auto _ : state) {
    for (const LonLat& p : points) benchmark::DoNotOptimize(lonlat_to_code(p.lon, p.lat, level));
  }
  state.SetItemsProcessed(static_cast<std::int64_t>(state.iterations()) * kSamples);
}

void BM_CellCentre(benchmark::State& state) {
  const int level = static_cast<int>(state.range(0));
  const auto codes = random_codes(level);
  for (auto _ : state) {
    for (Code c : codes) benchmark::DoNotOptimize(cell_centre(c, level));
  }
  state.SetItemsProcessed(static_cast<std::int64_t>(state.iterations()) * kSamples);
}

void BM_CellCentreVector(benchmark::State& state) {
  const int level = static_cast<int>(state.range(0));
  const auto codes = random_codes(level);
  for (auto _ : state) {
    for (Code c : codes) benchmark::DoNotOptimize(cell_centre_vector(c, level));
  }
  state.SetItemsProcessed(static_cast<std::int64_t>(state.iterations()) * kSamples);
}

void BM_Neighbours(benchmark::State& state) {
  const int level = static_cast<int>(state.range(0));
  const auto codes = random_codes(level);
  Code out[3];
  for (auto _ : state) {
    for (Code c : codes) {
      neighbours(c, level, out);
      benchmark::DoNotOptimize(out);
    }
  }
  state.SetItemsProcessed(static_cast<std::int64_t>(state.iterations()) * kSamples);
}

BENCHMARK(BM_LonLatToCode)->Arg(9)->Arg(16)->Arg(24);
BENCHMARK(BM_CellCentre)->Arg(9)->Arg(16)->Arg(24);
BENCHMARK(BM_CellCentreVector)->Arg(9)->Arg(16)->Arg(24);
BENCHMARK(BM_Neighbours)->Arg(9)->Arg(24);

}  // namespace

BENCHMARK_MAIN();
