// The robot's record on a cell's lifetime of sessions: 10,000 sessions of 100 robots (one in ten
// applied and verified), in a fresh SQLite record under /tmp.
//   build/bin/bench_record
// history() is what the control port's `history` asks (requirement: < 50 ms on the port, of
// which the record is one part); robots() is `zerocal robots`; Open is the daemon's start (the
// integrity check reads every page).
#include <benchmark/benchmark.h>
#include <stdlib.h>

#include <filesystem>
#include <memory>
#include <stdexcept>

#include "zerocal/record/sqlite_record.h"

namespace zerocal::record {
namespace {

constexpr int kRobots = 100;
constexpr int kSessions = 10'000;

RobotId robot(int r) { return {"IRB 1600-10/1.45", "SN-" + std::to_string(10000 + r)}; }

struct Cell {
  Cell() {
    char pattern[] = "/tmp/zerocal-bench-record-XXXXXX";
    if (::mkdtemp(pattern) == nullptr) throw std::runtime_error("mkdtemp failed");
    dir = pattern;
    path = dir + "/" + kRecordFileName;
    record = std::make_unique<SqliteRecord>(path);
    std::vector<SessionEntry> batch;
    for (int i = 0; i < kSessions; ++i) {
      SessionEntry e;
      e.session = "S" + std::to_string(100000 + i);
      e.robot = robot(i % kRobots);
      e.software_version = "6.13.02";
      e.kind = i % 10 == 9 ? "verification" : "calibration";
      e.usable = i % 3 != 0;
      if (!*e.usable) e.reasons = {"delta5 is beyond 0.01 deg: 0.0123 deg"};
      e.converged = true;
      e.poses_used = 16;
      for (int k = 0; k < 4; ++k) e.offsets[k] = RecordedOffset{0.01 * k - 0.02, 0.003};
      e.cell_time_s = 71.5;
      e.started_unix_s = 1'700'000'000 + 600LL * i;
      e.finished_unix_s = e.started_unix_s + 90;
      e.cal_offset_rad = std::array<double, 6>{1, 2, 3, 3.2, 5, 6};
      batch.push_back(std::move(e));
    }
    record->recordSessions(batch);
    for (int i = 8; i < kSessions; i += 10) {
      ControllerEvent apply;
      apply.time_unix_s = 1'700'000'000 + 600.0 * i + 120;
      apply.outcome = "verified";
      apply.before_rad = std::array<double, 6>{1, 2, 3, 3.2, 5, 6};
      apply.after_rad = std::array<double, 6>{1, 2.001, 3.002, 3.203, 5, 6};
      apply.verification = "S" + std::to_string(100000 + i + 1);
      apply.message = "every remaining offset of joints 2..5 is within max(3 sigma, 0.0030 deg)";
      ControllerEvent check = apply;
      check.kind = ControllerEventKind::kVerification;
      check.outcome = "pass";
      for (int k = 0; k < 4; ++k) check.remaining[k] = RecordedOffset{0.0005, 0.002};
      record->recordControllerEvents("S" + std::to_string(100000 + i), {apply, check});
    }
  }
  ~Cell() {
    record.reset();
    std::filesystem::remove_all(dir);
  }
  std::string dir, path;
  std::unique_ptr<SqliteRecord> record;
};

Cell& cell() {
  static Cell c;
  return c;
}

void History(benchmark::State& state) {
  SqliteRecord& record = *cell().record;
  std::size_t sessions = 0, events = 0;
  for (auto _ : state) {
    const std::vector<HistoryEntry> h = record.history(robot(48));
    sessions = h.size();
    events = 0;
    for (const HistoryEntry& e : h) events += e.events.size();
    benchmark::DoNotOptimize(h.data());
  }
  state.counters["sessions"] = static_cast<double>(sessions);
  state.counters["events"] = static_cast<double>(events);
}
BENCHMARK(History)->Unit(benchmark::kMicrosecond);

void Robots(benchmark::State& state) {
  SqliteRecord& record = *cell().record;
  std::size_t robots = 0;
  for (auto _ : state) {
    const std::vector<RobotSummary> r = record.robots();
    robots = r.size();
    benchmark::DoNotOptimize(r.data());
  }
  state.counters["robots"] = static_cast<double>(robots);
}
BENCHMARK(Robots)->Unit(benchmark::kMicrosecond);

void LatestUsableCalibration(benchmark::State& state) {
  SqliteRecord& record = *cell().record;
  for (auto _ : state) {
    const std::optional<SessionEntry> e = record.latest(robot(48), "calibration", true);
    benchmark::DoNotOptimize(e);
  }
}
BENCHMARK(LatestUsableCalibration)->Unit(benchmark::kMicrosecond);

void Open(benchmark::State& state) {
  const std::string path = cell().path;
  for (auto _ : state) {
    SqliteRecord record(path);
    benchmark::DoNotOptimize(record.openedAtVersion());
  }
  state.counters["file_MiB"] =
      static_cast<double>(std::filesystem::file_size(path)) / (1024.0 * 1024.0);
}
BENCHMARK(Open)->Unit(benchmark::kMillisecond);

}  // namespace
}  // namespace zerocal::record

BENCHMARK_MAIN();
