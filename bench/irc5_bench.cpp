// Round trips of the real Irc5Client against the simulated controller over loopback: what the
// link itself costs, without a robot. Reports median and 99th-percentile latency per request and
// requests per second.
#include <benchmark/benchmark.h>

#include <algorithm>
#include <chrono>
#include <vector>

#include "zerocal/irc5/irc5_client.h"
#include "zerocal/model/builtin.h"
#include "zerocal/sim/sim_controller.h"

namespace zerocal {
namespace {

void reportLatency(benchmark::State& state, std::vector<double>* us) {
  if (us->empty()) return;
  std::sort(us->begin(), us->end());
  state.counters["median_us"] = (*us)[us->size() / 2];
  state.counters["p99_us"] = (*us)[std::min(us->size() - 1, us->size() * 99 / 100)];
  state.counters["req_per_s"] =
      benchmark::Counter(static_cast<double>(us->size()), benchmark::Counter::kIsRate);
}

template <typename Request>
void roundTrips(benchmark::State& state, bool lf, Request request) {
  SimControllerOptions so;
  so.world = randomWorld(1);
  so.lf_terminated = lf;
  SimController sim(so);
  sim.start();
  Irc5Options o;
  o.host = "127.0.0.1";
  o.port = sim.port();
  o.robot = builtinIrb1600();
  o.lf_terminated = lf;
  Irc5Client client(o);
  client.connect();
  std::vector<double> us;
  us.reserve(1 << 16);
  for (auto _ : state) {
    const auto t0 = std::chrono::steady_clock::now();
    request(client);
    us.push_back(
        std::chrono::duration<double, std::micro>(std::chrono::steady_clock::now() - t0).count());
  }
  reportLatency(state, &us);
}

void BM_ReadJoints(benchmark::State& state) {
  roundTrips(state, true, [](Irc5Client& c) { benchmark::DoNotOptimize(c.readJoints()); });
}
BENCHMARK(BM_ReadJoints)->UseRealTime();

// Upstream's framing: no LF, so the client waits reply_settle for a last field that might grow.
void BM_ReadJointsNoLf(benchmark::State& state) {
  roundTrips(state, false, [](Irc5Client& c) { benchmark::DoNotOptimize(c.readJoints()); });
}
BENCHMARK(BM_ReadJointsNoLf)->UseRealTime()->Iterations(50);

void BM_SmallJointMove(benchmark::State& state) {
  int i = 0;
  roundTrips(state, true, [&i](Irc5Client& c) {
    c.moveJoints({(++i % 2) * 0.01, 0, 0, 0, 30, 0});
  });
}
BENCHMARK(BM_SmallJointMove)->UseRealTime();

}  // namespace
}  // namespace zerocal

BENCHMARK_MAIN();
