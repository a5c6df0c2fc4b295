// Solve time of the identification (everything solve() reports: the fit, identifiability,
// covariance, residuals) for growing pose counts, for both costs.
//   build/bench/bench_solver --benchmark_filter=ML
#include <benchmark/benchmark.h>

#include "zerocal/calib/experiment.h"

namespace zerocal {
namespace {

std::vector<Pose> recording(int n) {
  static const Table2Scenario sc = table2Scenario();
  PlanOptions o;
  o.poses = std::min(n, 40);
  const Plan plan = planPoses(sc.cell, sc.truth.target_mm, o);
  std::vector<Pose> planned;
  for (int i = 0; i < n; ++i) planned.push_back(plan.poses[i % plan.poses.size()]);
  std::mt19937_64 rng(42);
  return simulateRecording(sc.cell, sc.truth, planned, sc.half_width_mm, rng);
}

void solveWith(benchmark::State& state, CostKind cost) {
  const Table2Scenario sc = table2Scenario();
  const auto poses = recording(static_cast<int>(state.range(0)));
  SolveOptions options;
  options.cost = cost;
  options.noise_mm = sc.half_width_mm / std::sqrt(3.0);
  int iterations = 0;
  for (auto _ : state) {
    const SolveReport r = solve(sc.cell, poses, options);
    iterations = r.iterations;
    benchmark::DoNotOptimize(r.estimate.delta_rad);
  }
  state.counters["poses"] = static_cast<double>(poses.size());
  state.counters["lm_iterations"] = iterations;
}

void ML(benchmark::State& state) { solveWith(state, CostKind::kMaximumLikelihood); }
void Pairwise(benchmark::State& state) { solveWith(state, CostKind::kPairwise); }

BENCHMARK(ML)->Arg(8)->Arg(32)->Arg(100)->Arg(1000)->Unit(benchmark::kMillisecond);
// Pairwise: N(N-1)/2 pairs, and its uncertainty propagation is O(N^3).
BENCHMARK(Pairwise)->Arg(8)->Arg(16)->Arg(32)->Arg(64)->Unit(benchmark::kMillisecond);

void PlanOptimal(benchmark::State& state) {
  const Table2Scenario sc = table2Scenario();
  for (auto _ : state)
    benchmark::DoNotOptimize(planPoses(sc.cell, sc.truth.target_mm, PlanOptions{}));
}
BENCHMARK(PlanOptimal)->Unit(benchmark::kMillisecond);

}  // namespace
}  // namespace zerocal

BENCHMARK_MAIN();
