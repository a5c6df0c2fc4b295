#include "session_fixture.h"

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>

#include "stored_plan.h"
#include "zerocal/calib/experiment.h"
#include "zerocal/calib/format.h"
#include "zerocal/calib/validation.h"
#include "zerocal/store/journal.h"

namespace zerocal::test {

SessionFolder sessionFiles(const FixtureOptions& options) {
  const Table2Scenario sc = table2Scenario();
  // The optimal planner's plan, stored (tests/data/plans), with its prediction as the planner
  // makes it: what is tested here is the report, not the planner.
  Plan plan;
  plan.poses = testing::storedPlan("table2-" + std::to_string(options.poses));
  CalibrationParameters nominal;
  nominal.target_mm = sc.truth.target_mm;
  plan.prediction = predictUncertainty(sc.cell, plan.poses, nominal, PlanOptions{}.noise_mm);
  plan.description = options.plan_description.empty()
                         ? "optimal: the " + std::to_string(options.poses) +
                               " poses that minimise the predicted variance of delta2..delta5"
                         : options.plan_description;
  std::mt19937_64 rng(5);
  const auto recorded = simulateRecording(sc.cell, sc.truth, plan.poses, sc.half_width_mm, rng);
  SolveOptions so;
  so.noise_mm = sc.half_width_mm / std::sqrt(3.0);

  SessionFolder files;
  files.dir = "(in memory)";
  files.session.id = options.id;
  files.session.plan = plan;
  files.session.target_mm = sc.truth.target_mm;
  files.session.noise_mm = *so.noise_mm;
  files.session.config = nlohmann::json::object();
  std::vector<Pose> measured;
  for (std::size_t i = 0; i < recorded.size(); ++i) {
    PoseRecord r;
    r.index = static_cast<int>(i);
    if (std::count(options.skipped.begin(), options.skipped.end(), r.index + 1)) {
      r.skipped = "spot not found";
      files.journal.push_back(r);
      continue;
    }
    measured.push_back(recorded[i]);
    r.joints_deg = recorded[i].q_deg;
    r.reading.spot.u_mm = 0.001 * static_cast<double>(i);
    r.reading.spot.v_mm = -0.002;
    r.reading.se.u_mm = r.reading.se.v_mm = 0.0005;
    r.servo.moves = 3;
    const int pose = static_cast<int>(i) + 1;
    if (std::find(options.poses_without_path.begin(), options.poses_without_path.end(), pose) ==
        options.poses_without_path.end()) {
      // A spot found 2 mm off and servoed in: a decaying spiral to the recorded reading.
      for (int k = 0; k <= 20; ++k) {
        const double a = 0.6 * k + pose, rad = 2.0 * std::exp(-0.3 * k);
        r.servo_path.push_back({0.05 * k, r.reading.spot.u_mm + rad * std::cos(a),
                                r.reading.spot.v_mm + rad * std::sin(a)});
      }
    }
    files.journal.push_back(r);
  }
  // A second measurement of a pose: a line after the plan's, the same pose recorded again.
  for (const int pose : options.remeasured) {
    PoseRecord r = files.journal[pose - 1];
    r.index = static_cast<int>(files.journal.size());
    r.remeasure_of = pose - 1;
    r.servo_path.clear();
    files.journal.push_back(r);
  }
  ResultFile& result = files.result;
  if (options.held_out.empty()) {
    result.report = solve(sc.cell, measured, so);
  } else {
    HoldoutReport h = validateHoldout(sc.cell, recorded, options.held_out, so);
    result.report = h.fit;
    result.validation = std::move(h);
  }
  result.session = options.id;
  result.cell_time_s = 123.4;
  if (!options.remeasured.empty()) result.remeasured = options.remeasured;
  if (options.identity) {
    result.cell = ResultFile::Cell{{"1600-504321", "6.15.01.00", "IRB 1600-10/1.45"},
                                   "/etc/zerocal/psd-map.txt, fingerprint 0123456789abcdef"};
    result.zerocal_version = "0.1.0";
    result.finished_unix_s = 1796137200;  // 2026-12-01 15:00 UTC
  }
  result.truth.emplace();
  for (int k = 0; k < kOffsetCount; ++k)
    result.truth->offsets_deg[k] = sc.truth.delta_rad[k] * kRadToDeg;
  return files;
}

std::string makeSession(const std::string& name, const FixtureOptions& options) {
  namespace fs = std::filesystem;
  // In this build tree, not /tmp: another checkout's tests running at the same time would remove
  // and rewrite a folder of the same name under them.
  const fs::path dir = fs::path(ZEROCAL_REPORT_FIXTURE_DIR) / name;
  fs::remove_all(dir);
  fs::create_directories(dir);
  const SessionFolder files = sessionFiles(options);
  std::ofstream(dir / kSessionFileName) << toJson(files.session).dump(2) << "\n";
  std::ofstream journal(dir / kJournalFileName);
  for (const PoseRecord& line : files.journal) journal << toJson(line).dump() << "\n";
  journal.close();
  std::ofstream(dir / kResultFileName) << toJson(files.result).dump(2) << "\n";
  return dir.string();
}

}  // namespace zerocal::test
