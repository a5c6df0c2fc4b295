// The verification of an apply on the realistic simulated cell, as zerocald runs it (the
// configuration's defaults): a calibration at three PSD placements, the only one usable there,
// is verified by re-measuring its own poses at its last placement, where the detector stands
// after it. The zeros must have moved by what was written; the link errors cancel there, so a
// right apply passes, and a write that did not take effect as computed is rolled back.
#include <gtest/gtest.h>
#include <unistd.h>

#include <cmath>
#include <filesystem>
#include <mutex>
#include <nlohmann/json.hpp>

#include "zerocal/daemon/config.h"
#include "zerocal/model/kinematics.h"
#include "zerocal/service/daemon_setup.h"
#include "zerocal/service/session_manager.h"
#include "zerocal/sim/sim_backend.h"
#include "zerocal/sim/sim_controller.h"

namespace zerocal::service {
namespace {

struct TempDir {
  TempDir() {
    char pattern[] = "/tmp/zerocal-verification-XXXXXX";
    if (!::mkdtemp(pattern)) throw std::runtime_error("mkdtemp failed");
    path = pattern;
  }
  ~TempDir() { std::filesystem::remove_all(path); }
  std::string path;
};

// zerocald --sim --seed 3 --set session.placements=3 with its data in `dir`.
DaemonConfig realisticCell(const std::string& dir) {
  DaemonConfig config;
  config.backend.kind = BackendKind::kSim;
  config.backend.sim_seed = 3;
  config.session.data_dir = dir;
  config.session.placements = 3;
  return config;
}

struct Cell {
  explicit Cell(const DaemonConfig& config)
      : backend(makeBackend(config)),
        sim(dynamic_cast<sim::SimBackend&>(*backend)),
        manager(*backend, [&] {
          ManagerSettings s = managerSettingsOf(config);
          s.unattended_placements = true;  // the simulated cell moves its PSD itself
          s.write_reports = nullptr;
          return s;
        }()) {}
  std::unique_ptr<CellBackend> backend;
  sim::SimBackend& sim;
  SessionManager manager;
};

// Every apply event and progress line, in order.
struct ApplyLog {
  std::mutex mutex;
  std::vector<ApplyEvent> ends;
  std::vector<std::string> progress;
  std::function<void(const std::string&)> on_progress;
  SessionControl::EventSink sink() {
    return [this](const SessionEvent& e) {
      std::lock_guard<std::mutex> lock(mutex);
      if (const auto* a = std::get_if<ApplyEvent>(&e)) ends.push_back(*a);
      if (const auto* p = std::get_if<ApplyProgressEvent>(&e)) {
        progress.push_back(p->message);
        if (on_progress) on_progress(p->message);
      }
    };
  }
};

std::string calibrate(SessionManager& manager) {
  const std::string id = manager.start(manager.defaultRequest());
  const SessionStatus end = manager.waitIdle();
  if (end.state != SessionState::kDone) throw std::runtime_error(end.message);
  return id;
}

TEST(ApplyVerification, ASeveralPlacementCalibrationIsVerifiedAtItsLastPlacement) {
  const TempDir dir;
  Cell cell(realisticCell(dir.path));
  ApplyLog log;
  cell.manager.setEventSink(log.sink());
  const std::string id = calibrate(cell.manager);
  const ResultFile calibrated = cell.manager.result(id);
  ASSERT_TRUE(calibrated.report.verdict.usable);

  cell.manager.apply({id, true});
  const SessionStatus end = cell.manager.waitIdle();
  EXPECT_EQ(end.state, SessionState::kDone) << end.message;
  ASSERT_EQ(log.ends.size(), 1u);
  const ApplyEvent& applied = log.ends[0];
  EXPECT_EQ(applied.outcome, ApplyOutcome::kVerified) << applied.message;

  // The technician is told where the PSD must stand.
  bool told = false;
  for (const std::string& line : log.progress)
    told = told || line.find("placement 3: the PSD must stand where it stood") != std::string::npos;
  EXPECT_TRUE(told);

  // The verification compares with the calibration itself, re-measuring only poses of its last
  // placement.
  SessionStore store(dir.path);
  const SessionFile verification = store.readSession(applied.verification);
  EXPECT_EQ(verification.kind, SessionKind::kVerification);
  EXPECT_EQ(verification.verifies, id);
  EXPECT_EQ(verification.reference, id);
  ASSERT_FALSE(verification.reference_poses.empty());
  const SessionFile calibration = store.readSession(id);
  for (const int p : verification.reference_poses)
    EXPECT_EQ(calibration.plan.poses.at(static_cast<std::size_t>(p - 1)).placement, 3) << p;

  // The zeros moved by what was written: the change measured is its opposite, within three of
  // its sigmas, and what the apply reports remaining is that difference.
  const ResultFile measured = cell.manager.result(applied.verification);
  ASSERT_EQ(applied.remaining_deg.size(), 4u);
  for (int k = 0; k < 4; ++k) {
    const ParameterEstimate& change = measured.report.parameters[k];
    const double written = calibrated.report.parameters[k].value;
    EXPECT_NEAR(change.value, -written, 3 * change.sigma) << "delta" << k + 2;
    EXPECT_NEAR(applied.remaining_deg[k], change.value + written, 1e-12);
    EXPECT_NEAR(applied.remaining_sigma_deg[k], change.sigma, 1e-12);
  }
  // On the arm, what is left is the calibration's own error.
  ASSERT_TRUE(measured.truth && calibrated.truth);
  for (int k = 0; k < 4; ++k)
    EXPECT_NEAR(measured.truth->offsets_deg[k],
                calibrated.truth->offsets_deg[k] - calibrated.report.parameters[k].value, 1e-5);
}

// A write that did not move a zero as computed (here joint 3's cal_offset changed again behind
// the apply's back, 0.05 deg on the arm, before the verification) is seen by the verification
// and rolled back, naming the joint.
TEST(ApplyVerification, AZeroThatDidNotMoveByWhatWasWrittenIsRolledBack) {
  const TempDir dir;
  Cell cell(realisticCell(dir.path));
  ApplyLog log;
  const Robot robot = cell.backend->knowledge().cell.robot;
  SimController& controller = cell.sim.cell().controller();
  log.on_progress = [&](const std::string& line) {
    if (line.find("the verification re-measures") == std::string::npos) return;
    const double k = robot.transmission[2];
    double rad = controller.calOffsets()[2] + k * 0.05 * kDegToRad;
    rad = std::fmod(std::fmod(rad, 2 * kPi) + 2 * kPi, 2 * kPi);
    controller.writeCalOffset(3, rad);
  };
  cell.manager.setEventSink(log.sink());
  const std::string id = calibrate(cell.manager);
  ASSERT_TRUE(cell.manager.result(id).report.verdict.usable);
  const std::array<double, 6> before = controller.calOffsets();

  cell.manager.apply({id, true});
  cell.manager.waitIdle();
  ASSERT_EQ(log.ends.size(), 1u);
  const ApplyEvent& applied = log.ends[0];
  EXPECT_EQ(applied.outcome, ApplyOutcome::kRolledBack) << applied.message;
  EXPECT_NE(applied.message.find("delta3"), std::string::npos) << applied.message;
  EXPECT_NEAR(std::abs(applied.remaining_deg.at(1)), 0.05, 0.01);
  // The backup is back in the controller.
  const std::array<double, 6> after = controller.calOffsets();
  for (int j = 0; j < 6; ++j) EXPECT_NEAR(after[j], before[j], 2e-6) << j + 1;
}

}  // namespace
}  // namespace zerocal::service
