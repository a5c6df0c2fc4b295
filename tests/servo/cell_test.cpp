// System tests on the simulated cell: the real Irc5Client over loopback TCP to the simulated
// controller, the real USB-1408FS protocol code over FakeTransport to the simulated board, the
// PSD model at the world's true beam hit, and the servo between them. Simulated time only.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <optional>
#include <vector>

#include "stored_plan.h"
#include "zerocal/calib/planner.h"
#include "zerocal/calib/solver.h"
#include "zerocal/irc5/irc5_client.h"
#include "zerocal/irc5/motion_time.h"
#include "zerocal/servo/servo.h"
#include "zerocal/servo/spot_predictor.h"
#include "zerocal/sim/simulated_rig.h"
#include "zerocal/sim/world.h"
#include "zerocal/sim/zero_change.h"

namespace zerocal::servo {
namespace {

using Knowledge = sim::SessionKnowledge;
using sim::knowledgeOf;
using Rig = sim::SimulatedRig;

sim::SimulatedCellOptions cellOptions(std::uint64_t seed, double repeatability_deg,
                                      WorldKind kind = WorldKind::kRealistic) {
  sim::SimulatedCellOptions o = sim::seededCellOptions(seed, kind);
  o.world.noise.repeatability_deg = repeatability_deg;
  return o;
}

// The optimal planner's 8 poses for a world's knowledge, stored (tests/data/plans): these tests
// are about the servo on the cell, not the planner. `world` names the kind and seed: "ideal-24".
std::vector<Pose> planFor(const std::string& world) { return testing::storedPlan(world); }

struct PoseFigures {
  double move_s = 0, acquisition_s = 0, servo_s = 0;
  int moves = 0, search_moves = 0;
};

// Moves to each planned pose and servoes; returns the recorded poses (hit-point readings).
// These tests run the servo without a cell clock (the rig's moves are instant), so no reading
// waits to settle.
ServoOptions withoutClock(ServoStop stop) {
  ServoOptions o;
  o.stop = stop;
  o.settle_s = 0;
  return o;
}

std::vector<Pose> record(Rig& rig, const Knowledge& k, const std::vector<Pose>& plan,
                         const ServoOptions& o, std::vector<PoseFigures>* figures) {
  PsdServo servo(k.cell, k.taught_centre, o);
  SpotPredictor predictor(k.cell, k.taught_centre);
  std::vector<Pose> poses;
  for (const Pose& planned : plan) {
    const double t0 = rig.cell.nowS();
    rig.client.moveJoints(planned.q_deg);
    const double t1 = rig.cell.nowS();
    const ServoResult r =
        servo.run(rig.client, rig.psd, planned.q_deg, predictor.searchCentre(planned.q_deg));
    EXPECT_TRUE(r.ok()) << statusName(r.status) << ": " << servo.fault().message;
    if (!r.ok()) break;
    Pose p;
    p.q_deg = r.q_deg;
    p.spot = r.reading.spot;
    poses.push_back(p);
    predictor.addPose(p.q_deg, *p.spot);
    if (figures)
      figures->push_back(
          {t1 - t0, r.acquired_s - t1, rig.cell.nowS() - r.acquired_s, r.moves, r.search_moves});
  }
  return poses;
}

TEST(SimulatedCell, ServoConvergesToTwoMicrometresOfTheCentre) {
  // No repeatability noise: every move lands where asked, so the centre is reachable.
  Rig rig(cellOptions(11, 0.0));
  const Knowledge k = knowledgeOf(rig.cell.world());
  const std::vector<Pose> plan = planFor("realistic-11");
  PsdServo servo(k.cell, k.taught_centre, withoutClock(ServoStop::kCentre));
  SpotPredictor predictor(k.cell, k.taught_centre);
  for (std::size_t i = 0; i < plan.size(); ++i) {
    const Joints& planned = plan[i].q_deg;
    rig.client.moveJoints(planned);
    const ServoResult r = servo.run(rig.client, rig.psd, planned, predictor.searchCentre(planned));
    ASSERT_TRUE(r.ok()) << statusName(r.status) << ": " << servo.fault().message;
    EXPECT_LE(r.final_error_um, 2.0);
    const auto hit = rig.cell.controller().beamHitNow();
    ASSERT_TRUE(hit);
    // The map's own error (under 2 um) adds to the servo's tolerance.
    EXPECT_LE(std::hypot(hit->spot.u_mm, hit->spot.v_mm), 0.004);
    std::printf("pose %zu: %d moves (%d searching), %d iterations, %.2f um, %.2f s\n", i, r.moves,
                r.search_moves, r.iterations, r.final_error_um, r.end_s - r.start_s);
    predictor.addPose(r.q_deg, r.reading.spot);
  }
}

// What a pose records is the reading after the servo's last move, and the solver weighs its miss
// as the whole scatter of the arm's repeatability (zerocal/calib/cell_model.h MissNoise). A servo
// that stopped on the first reading inside its zone kept only the draws that fell towards the
// zone: the recorded misses came out at 0.74 of that variance here (0.97 now). Here every pose of a
// plan is servoed again and again on an ideal world (no model error: the true beam for the recorded
// joints is known), and each miss is weighed by its own covariance, J_q J_q^T sigma_q^2 through
// the true beam plus the PSD's noise: its mean square is 1 per axis when nothing selects the draws.
TEST(SimulatedCell, TheRecordedMissIsTheArmsWholeScatterNotTheDrawsThatFellInTheZone) {
  constexpr double kRepeatabilityDeg = 1.5e-3;
  Rig rig(cellOptions(24, kRepeatabilityDeg, WorldKind::kIdeal));
  const World& world = rig.cell.world();
  const Knowledge k = knowledgeOf(world);
  const std::vector<Pose> plan = planFor("ideal-24");
  PsdServo servo(k.cell, k.taught_centre, withoutClock(ServoStop::kZone));
  SpotPredictor predictor(k.cell, k.taught_centre);
  const auto trueSpot = [&](const Joints& q, const Joints& extra) {
    const auto hit = beamHit(world, q, extra, rig.cell.nowS());
    EXPECT_TRUE(hit);
    return hit ? Eigen::Vector2d(hit->spot.u_mm, hit->spot.v_mm) : Eigen::Vector2d::Zero();
  };
  constexpr int kRunsPerPose = 150;
  double sum = 0;
  int count = 0;
  for (const Pose& planned : plan) {
    Eigen::Matrix<double, 2, kJointCount> jq;
    constexpr double h = 1e-4;  // deg
    for (int j = 0; j < kJointCount; ++j) {
      Joints plus{}, minus{};
      plus[j] = h;
      minus[j] = -h;
      jq.col(j) = (trueSpot(planned.q_deg, plus) - trueSpot(planned.q_deg, minus)) / (2 * h);
    }
    const Eigen::Matrix2d sigma =
        kRepeatabilityDeg * kRepeatabilityDeg * jq * jq.transpose() +
        world.noise.psd_mm * world.noise.psd_mm * Eigen::Matrix2d::Identity();
    const Eigen::Matrix2d information = sigma.inverse();
    for (int run = 0; run < kRunsPerPose; ++run) {
      rig.client.moveJoints(planned.q_deg);  // a new draw of the arm's repeatability
      const ServoResult r =
          servo.run(rig.client, rig.psd, planned.q_deg, predictor.searchCentre(planned.q_deg));
      ASSERT_TRUE(r.ok()) << statusName(r.status) << ": " << servo.fault().message;
      const Eigen::Vector2d miss =
          Eigen::Vector2d(r.reading.spot.u_mm, r.reading.spot.v_mm) - trueSpot(r.q_deg, Joints{});
      sum += miss.dot(information * miss) / 2;
      ++count;
      if (run == 0) predictor.addPose(r.q_deg, r.reading.spot);
    }
  }
  const double mean = sum / count;
  std::printf("%d servoed readings: mean square miss %.3f of the arm's scatter per axis\n", count,
              mean);
  // 1200 readings: the mean of a chi-square of 2 over 2 has a standard error of 0.029.
  EXPECT_NEAR(mean, 1.0, 0.12);
}

// A check re-measures its reference's poses: at the reference's joints the spot is expected
// where the reference read it, moved by what the check's own poses show the zeros to have
// changed by. Unchanged, every pose's move lands the spot where it was and the reading is
// recorded without a search or a servo move; with one zero moved by 0.02 deg (0.3 mm at the
// detector) the first poses teach the change and the later ones land as predicted.
TEST(SimulatedCell, ACheckFindsTheSpotWhereItsReferenceReadItAndLearnsAChange) {
  const ServoOptions o = withoutClock(ServoStop::kZone);
  const std::vector<Pose> plan = planFor("realistic-11");
  std::vector<Pose> reference;
  {
    Rig rig(cellOptions(11, 1.5e-3));
    reference = record(rig, knowledgeOf(rig.cell.world()), plan, o, nullptr);
    ASSERT_EQ(reference.size(), plan.size());
  }
  for (const double change_deg : {0.0, 0.02}) {
    sim::SimulatedCellOptions options = cellOptions(11, 1.5e-3);
    options.controller_seed = 1011;  // the check's own draws of the arm's repeatability
    if (change_deg != 0) applyZeroChange({3, change_deg}, &options.world);
    Rig rig(options);
    const Knowledge k = knowledgeOf(rig.cell.world());
    PsdServo servo(k.cell, k.taught_centre, o);
    SpotPredictor predictor(k.cell, k.taught_centre);
    predictor.expectReadingsOf(reference);
    int servo_moves = 0, search_moves = 0;
    double worst_late_miss_mm = 0;
    for (std::size_t i = 0; i < reference.size(); ++i) {
      const Joints target = predictor.aimedJoints(reference[i].q_deg, o.damping_mm);
      // Unchanged, every prediction is the reference's reading; 0.02 deg of joint 3 moves the
      // spot by more than kNearReadingMm at the longer beams, and those are servoed.
      if (change_deg == 0) EXPECT_TRUE(predictor.predictsFromReading(target)) << "pose " << i + 1;
      const PsdSpot expected = predictor.predict(target);
      rig.client.moveJoints(target);
      const ServoResult r = servo.run(rig.client, rig.psd, target, expected,
                                      std::hypot(expected.u_mm, expected.v_mm) <= o.hit_zone_mm);
      ASSERT_TRUE(r.ok()) << statusName(r.status) << ": " << servo.fault().message;
      const double miss =
          std::hypot(r.reading.spot.u_mm - expected.u_mm, r.reading.spot.v_mm - expected.v_mm);
      if (r.moves == 0) {
        // Recorded where the move ended: the reading the prediction was made for.
        EXPECT_LE(std::hypot(r.reading.spot.u_mm, r.reading.spot.v_mm), o.recordedWithinMm());
      }
      if (i >= 2) worst_late_miss_mm = std::max(worst_late_miss_mm, miss);
      servo_moves += r.moves - r.search_moves;
      search_moves += r.search_moves;
      predictor.addPose(r.q_deg, r.reading.spot);
    }
    std::printf(
        "zero of joint 3 changed by %.3f deg: %d servo moves, %d search moves for %zu "
        "poses; the predictions from pose 3 on within %.3f mm\n",
        change_deg, servo_moves, search_moves, reference.size(), worst_late_miss_mm);
    EXPECT_EQ(search_moves, 0) << change_deg;
    // The arm's scatter in both sessions: about 0.06 mm at the detector, 0.2 mm at 3 sigma.
    EXPECT_LE(worst_late_miss_mm, 0.2) << change_deg;
    // Two readings of 0.06 mm scatter per axis each (the reference's and the check's): the
    // recorded bound of 0.2 mm is about 3 sigma of their difference; 2 of 8 poses may miss it.
    if (change_deg == 0) EXPECT_LE(servo_moves, 2);
  }
}

TEST(SimulatedCell, ANeighbourhoodOfPosesDoesNotMisleadThePredictionFarAway) {
  // The realistic arm's link errors leave misses of tenths of a millimetre that the predictor's
  // model cannot explain. Weighed as if they were the robot's 0.02 mm of repeatability, a few
  // neighbouring poses (the daemon's 16-pose plan, visited in the order of least travel) were
  // fitted with offsets and a laser far from the truth, and the next pose across the workspace
  // was predicted 87 mm off (seed 2, pose 6: the spot then not found in 40 search moves).
  Rig rig(sim::seededCellOptions(2, WorldKind::kRealistic));
  const Knowledge k = knowledgeOf(rig.cell.world());
  PlanOptions o;
  o.poses = 16;
  o.noise_mm = 0.02;
  o.psd_normal = k.cell.psd_rotation.col(2);
  o.travel_s = [&k](const Joints& from, const Joints& to) {
    return irc5::jointMoveTime(k.cell.robot, from, to, 250, 100, irc5::MotionCosts{}).motion_s;
  };
  const std::vector<Pose> plan = planPoses(k.cell, k.taught_centre, o).poses;
  PsdServo servo(k.cell, k.taught_centre, withoutClock(ServoStop::kZone));
  SpotPredictor predictor(k.cell, k.taught_centre);
  double worst = 0;
  for (std::size_t i = 0; i < plan.size(); ++i) {
    rig.client.moveJoints(plan[i].q_deg);
    const ServoResult r =
        servo.run(rig.client, rig.psd, plan[i].q_deg, predictor.searchCentre(plan[i].q_deg));
    ASSERT_TRUE(r.ok()) << "pose " << i + 1 << ": " << statusName(r.status);
    if (predictor.confident()) {
      const PsdSpot p = predictor.predict(r.q_deg);
      const double miss = std::hypot(p.u_mm - r.reading.spot.u_mm, p.v_mm - r.reading.spot.v_mm);
      std::printf("pose %zu: predicted %.2f mm off\n", i + 1, miss);
      worst = std::max(worst, miss);
    }
    predictor.addPose(r.q_deg, r.reading.spot);
  }
  EXPECT_LT(worst, 30.0);  // under a third of the search's radius
}

TEST(SimulatedCell, SpotNeverFoundLeavesTheRobotAtThePlannedPose) {
  Rig rig(cellOptions(12, 0.0));
  Knowledge k = knowledgeOf(rig.cell.world());
  // The session believes the PSD is 100 mm from where it is: the spot is nowhere near.
  k.taught_centre += Eigen::Vector3d(100, 0, 0);
  ServoOptions o = withoutClock(ServoStop::kZone);
  o.search_radius_mm = 10;
  PsdServo servo(k.cell, k.taught_centre, o);
  // Aim well away from the detector by planning against the wrong centre.
  const Joints planned = planFor("realistic-12-taught-100mm-off")[0].q_deg;
  rig.client.moveJoints(planned);
  const ServoResult r = servo.run(rig.client, rig.psd, planned);
  EXPECT_EQ(r.status, ServoStatus::kSpotNotFound);
  EXPECT_TRUE(servo.faulted());
  const Joints now = rig.client.readJoints();
  for (int i = 0; i < kJointCount; ++i) EXPECT_NEAR(now[i], planned[i], 1e-4);
}

// The continuous search (the PSD's light signal wired to the controller) finds the spot of the
// first pose, which has no prediction, in a few search moves; without the signal the same pose
// takes the point-by-point spiral's many. Both end converged.
TEST(SimulatedCell, ContinuousSearchFindsTheSpotInAFewMoves) {
  int continuous_moves = 0, discrete_moves = 0;
  for (bool wired : {true, false}) {
    sim::SimulatedCellOptions options = cellOptions(13, 1.5e-3);
    options.search_signal = wired;
    Rig rig(options);
    const Knowledge k = knowledgeOf(rig.cell.world());
    const Joints planned = planFor("realistic-13")[0].q_deg;
    rig.client.moveJoints(planned);
    ASSERT_FALSE(rig.psd.read().spot_present) << "the test needs a pose that misses the detector";
    PsdServo servo(k.cell, k.taught_centre, withoutClock(ServoStop::kZone));
    const ServoResult r = servo.run(rig.client, rig.psd, planned);
    ASSERT_TRUE(r.ok()) << statusName(r.status) << ": " << servo.fault().message;
    (wired ? continuous_moves : discrete_moves) = r.search_moves;
    EXPECT_EQ(rig.cell.controller().motionTotals().search_moves > 0, wired);
  }
  std::printf("search moves: continuous %d, point by point %d\n", continuous_moves, discrete_moves);
  EXPECT_LE(continuous_moves, 20);
  EXPECT_GT(discrete_moves, 3 * continuous_moves);
}

// The spiral of the continuous search for a planned pose: the servo's own mapping.
SpotSearch spiralAt(const Knowledge& k, const Joints& planned) {
  const Eigen::Matrix<double, kJointCount, 2> pinv =
      dampedPseudoInverse(imageJacobian(k.cell, k.taught_centre, planned), 1e-3);
  SpotSearch search;
  search.centre_deg = planned;
  for (int i = 0; i < kJointCount; ++i) {
    search.per_u_mm[i] = pinv(i, 0);
    search.per_v_mm[i] = pinv(i, 1);
  }
  return search;
}

// A run latches the joints where the light rose (the edge of the lit disk, ~5.7 mm from the
// detector's centre, plus what the input's latency carries it), and the robot rests within a
// waypoint or two beyond.
TEST(SimulatedCell, SearchRunLatchesTheJointsWhereTheLightRose) {
  Rig rig(cellOptions(11, 0.0));
  const Knowledge k = knowledgeOf(rig.cell.world());
  const Joints planned = planFor("realistic-11")[0].q_deg;
  rig.client.moveJoints(planned);
  ASSERT_FALSE(rig.psd.read().spot_present) << "the test needs a pose that misses the detector";
  ASSERT_TRUE(rig.client.startSpotSearch(spiralAt(k, planned)));
  const double t0 = rig.cell.nowS();
  const std::optional<Joints> hit = rig.client.searchRun({0, 60, 100});
  ASSERT_TRUE(hit);
  const double run_s = rig.cell.nowS() - t0;
  EXPECT_EQ(rig.cell.controller().motionTotals().search_moves, 1);
  const auto rest = rig.cell.controller().beamHitNow();
  ASSERT_TRUE(rest);
  rig.client.moveJoints(*hit);
  const auto latched = rig.cell.controller().beamHitNow();
  ASSERT_TRUE(latched);
  const double from_centre = std::hypot(latched->spot.u_mm, latched->spot.v_mm);
  EXPECT_GT(from_centre, 4.0);
  EXPECT_LT(from_centre, 9.0);
  EXPECT_LT(std::hypot(rest->spot.u_mm - latched->spot.u_mm, rest->spot.v_mm - latched->spot.v_mm),
            16.0);
  // One move's fixed cost and its settling at least.
  const MotionTotals totals = rig.cell.controller().motionTotals();
  EXPECT_GT(run_s, (totals.overhead_s + totals.settle_s) / totals.moves);
}

// A run with a waypoint outside the limits less the margin, too fast, or before a spiral was
// given, is refused by the client before anything is sent.
TEST(SimulatedCell, SearchRunsAreCheckedBeforeTheyAreSent) {
  Rig rig(cellOptions(11, 0.0), [](Irc5Options& o) { o.limit_margin_deg = 1.0; });
  const Knowledge k = knowledgeOf(rig.cell.world());
  const Joints planned = planFor("realistic-11")[0].q_deg;
  rig.client.moveJoints(planned);
  EXPECT_THROW(rig.client.searchRun({0, 10, 100}), RequestRefusedError);
  SpotSearch wild = spiralAt(k, planned);
  wild.per_u_mm[0] = 10;  // 10 deg of joint 1 per mm: out of its range within the spiral
  ASSERT_TRUE(rig.client.startSpotSearch(wild));
  const long requests = rig.cell.controller().requestCount();
  EXPECT_THROW(rig.client.searchRun({0, 60, 100}), RequestRefusedError);
  ASSERT_TRUE(rig.client.startSpotSearch(spiralAt(k, planned)));
  const long after_start = rig.cell.controller().requestCount();
  EXPECT_THROW(rig.client.searchRun({0, 60, 1e6}), RequestRefusedError);
  EXPECT_EQ(rig.cell.controller().requestCount(), after_start);
  EXPECT_GT(after_start, requests);
  EXPECT_EQ(rig.cell.controller().motionTotals().search_moves, 0);
}

// A controller without the light signal refuses the spiral; the client says so.
TEST(SimulatedCell, NoLightSignalMeansNoContinuousSearch) {
  sim::SimulatedCellOptions options = cellOptions(11, 0.0);
  options.search_signal = false;
  Rig rig(options);
  const Knowledge k = knowledgeOf(rig.cell.world());
  EXPECT_FALSE(rig.client.startSpotSearch(spiralAt(k, planFor("realistic-11")[0].q_deg)));
  EXPECT_TRUE(rig.client.connected());
}

// The controller connection drops mid-servo, then the board is unplugged: each is latched as a
// fault with its samples, never thrown.
TEST(SimulatedCell, LinkDropAndUnpluggedBoardAreLatchedFaults) {
  Rig rig(cellOptions(13, 0.0));
  const Knowledge k = knowledgeOf(rig.cell.world());
  PsdServo servo(k.cell, k.taught_centre, withoutClock(ServoStop::kZone));
  const Joints planned = planFor("realistic-13")[0].q_deg;
  rig.client.moveJoints(planned);
  SimFaults faults;
  faults.drop_after_requests = 8;  // setup (6), the joint read-back, one move
  rig.cell.controller().setFaults(faults);
  rig.client.reconnect();
  ServoResult r = servo.run(rig.client, rig.psd, planned);
  EXPECT_EQ(r.status, ServoStatus::kLinkError);
  EXPECT_TRUE(servo.faulted());
  EXPECT_STRNE(servo.fault().message, "");

  rig.cell.controller().setFaults(SimFaults{});
  rig.client.reconnect();
  rig.client.moveJoints(planned);
  rig.cell.board().unplug();
  r = servo.run(rig.client, rig.psd, planned);
  EXPECT_EQ(r.status, ServoStatus::kSensorError);
  EXPECT_EQ(servo.fault().status, ServoStatus::kSensorError);
}

// Records the optimal 8-pose plan by servoing on noisy cells (repeatability, PSD noise, float32
// joints, 5 decimals) and solves: delta2..delta5 within 3 reported sigma of the truth. The ideal
// world: this checks the chain from servo to solver, exactly; what the realistic world's model
// errors do to the figures is measured by `zerocal-lab experiment cell` (docs/simulated-cell.md).
TEST(SimulatedCell, EightServoedPosesCalibrateWithinThreeSigma) {
  double sum_sq = 0, worst_sigmas = 0, worst_cell_s = 0;
  int count = 0;
  for (std::uint64_t seed = 21; seed <= 30; ++seed) {
    Rig rig(cellOptions(seed, 5e-4, WorldKind::kIdeal));
    const Knowledge k = knowledgeOf(rig.cell.world());
    const std::vector<Pose> plan = planFor("ideal-" + std::to_string(seed));
    const ServoOptions o = withoutClock(ServoStop::kZone);
    std::vector<PoseFigures> figures;
    const std::vector<Pose> poses = record(rig, k, plan, o, &figures);
    ASSERT_EQ(poses.size(), plan.size());
    // The measurement sigma a session configures: the robot's repeatability (5e-4 deg per joint,
    // about 0.01 mm per axis at the PSD, chi2/dof near 1 here) dwarfs the PSD's ~0.5 um. Estimating
    // it from 5 degrees of freedom instead makes the reported sigmas themselves scatter by a factor
    // of two.
    SolveOptions so;
    so.noise_mm = 0.010;
    const SolveReport report = solve(k.cell, poses, so);
    std::printf("seed %d: chi2/dof %.2f\n", static_cast<int>(seed),
                report.chi2_per_dof.value_or(-1));
    ASSERT_TRUE(report.converged) << report.message;
    const Joints truth = rig.cell.world().true_offsets_deg;
    double cell_s = 0;
    int moves = 0;
    std::printf("seed %d: pose  move_s  acquisition_s  servo_s  moves  search_moves\n",
                static_cast<int>(seed));
    for (std::size_t i = 0; i < figures.size(); ++i) {
      const PoseFigures& f = figures[i];
      cell_s += f.move_s + f.acquisition_s + f.servo_s;
      moves += f.moves;
      std::printf("        %4zu  %6.2f  %13.2f  %7.2f  %5d  %12d\n", i, f.move_s, f.acquisition_s,
                  f.servo_s, f.moves, f.search_moves);
    }
    worst_cell_s = std::max(worst_cell_s, cell_s);
    std::printf("seed %d: cell time %.1f s, servo moves per pose %.1f\n", static_cast<int>(seed),
                cell_s, static_cast<double>(moves) / figures.size());
    for (int i = 0; i < kOffsetCount; ++i) {
      const ParameterEstimate& e = report.parameters[i];
      const double error = e.value - truth[i + 1];
      EXPECT_LE(std::abs(error), 3 * e.sigma) << e.name << " seed " << seed;
      std::printf("  %s = %.5f, truth %.5f, error %.5f, sigma %.5f\n", e.name.c_str(), e.value,
                  truth[i + 1], error, e.sigma);
      sum_sq += error * error;
      worst_sigmas = std::max(worst_sigmas, std::abs(error) / e.sigma);
      ++count;
    }
  }
  std::printf(
      "RMS error of delta2..delta5: %.5f deg over %d worlds, worst %.2f sigma, "
      "longest calibration %.1f s of cell time\n",
      std::sqrt(sum_sq / count), count / kOffsetCount, worst_sigmas, worst_cell_s);
  EXPECT_LE(std::sqrt(sum_sq / count), 0.005);
}

// After an apply the verification knows the cell as the calibration found it: started from that
// estimate, the prediction puts the search at the spot from the first pose on, where an
// unstarted one (nominal laser, taught centre) is tens of millimetres off and makes no
// prediction at all before two poses. The apply is simulated on the world: its offsets of
// joints 2..5 are what the calibration left.
TEST(SimulatedCell, APredictionStartedFromTheCalibrationFindsTheSpotAfterAnApply) {
  constexpr std::uint64_t kSeed = 21;
  Rig rig(cellOptions(kSeed, 5e-4, WorldKind::kIdeal));
  const Knowledge k = knowledgeOf(rig.cell.world());
  const std::vector<Pose> plan = planFor("ideal-21");
  const std::vector<Pose> poses = record(rig, k, plan, withoutClock(ServoStop::kZone), nullptr);
  ASSERT_EQ(poses.size(), plan.size());
  SolveOptions so;
  so.noise_mm = 0.010;
  const SolveReport report = solve(k.cell, poses, so);
  ASSERT_TRUE(report.converged) << report.message;

  sim::SimulatedCellOptions applied = cellOptions(kSeed, 5e-4, WorldKind::kIdeal);
  for (int i = 0; i < kOffsetCount; ++i)
    applied.world.true_offsets_deg[i + 1] -= report.parameters[i].value;
  Rig after(applied);
  SpotPredictor started(k.cell, k.taught_centre), unstarted(k.cell, k.taught_centre);
  started.startFrom(report.estimate);
  ASSERT_TRUE(started.confident());
  double worst_started = 0, worst_unstarted = 0;
  for (const Pose& p : plan) {
    after.client.moveJoints(p.q_deg);
    const auto hit = after.cell.controller().beamHitNow();
    ASSERT_TRUE(hit);
    const auto miss = [&](const SpotPredictor& predictor) {
      const PsdSpot s = predictor.predict(p.q_deg);
      return std::hypot(s.u_mm - hit->spot.u_mm, s.v_mm - hit->spot.v_mm);
    };
    worst_started = std::max(worst_started, miss(started));
    worst_unstarted = std::max(worst_unstarted, miss(unstarted));
  }
  std::printf("worst prediction error: %.3f mm started from the calibration, %.1f mm without\n",
              worst_started, worst_unstarted);
  EXPECT_LT(worst_started, 0.5);
  EXPECT_GT(worst_unstarted, 5.0);
  EXPECT_EQ(unstarted.searchCentre(plan[0].q_deg), PsdSpot{});
}

}  // namespace
}  // namespace zerocal::servo
