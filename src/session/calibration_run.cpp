#include "zerocal/session/calibration_run.h"

#include <chrono>

#include "zerocal/error.h"
#include "zerocal/servo/spot_predictor.h"

namespace zerocal {
namespace {

std::int64_t nanoseconds(double seconds) { return static_cast<std::int64_t>(seconds * 1e9); }

}  // namespace

std::vector<Pose> posesOf(const std::vector<PoseRecord>& records) {
  std::vector<Pose> poses;
  for (const PoseRecord& r : records)
    poses.push_back({r.joints_deg, Eigen::Vector2d(r.u_mm, r.v_mm), 0});
  return poses;
}

CalibrationRun::CalibrationRun(CellModel knowledge, Eigen::Vector3d taught_centre_mm,
                               std::vector<Pose> plan, RunSettings settings, Journal& journal)
    : knowledge_(std::move(knowledge)),
      taught_centre_(taught_centre_mm),
      plan_(std::move(plan)),
      settings_(std::move(settings)),
      journal_(journal) {
  if (journal_.nextIndex() > static_cast<int>(plan_.size()))
    throw InputError("the journal holds " + std::to_string(journal_.nextIndex()) +
                     " poses but the plan only " + std::to_string(plan_.size()));
}

void CalibrationRun::phase(int pose_index, RunPhase phase) const {
  if (on_phase) on_phase(pose_index, phase);
}

RunOutcome CalibrationRun::run(ControllerLink& robot, servo::PsdReader& psd,
                               servo::CellClock& clock, const std::atomic<bool>& abort) {
  RunOutcome out;
  out.records = journal_.recovered();
  out.resumed_from = journal_.nextIndex();
  servo::PsdServo servo(knowledge_, taught_centre_, settings_.servo);
  servo::SpotPredictor predictor(knowledge_, taught_centre_);
  // Resumed poses teach the predictor where the spot falls, as if they had just been servoed.
  for (const PoseRecord& r : out.records)
    predictor.addPose(r.joints_deg, Eigen::Vector2d(r.u_mm, r.v_mm));

  for (int i = journal_.nextIndex(); i < static_cast<int>(plan_.size()); ++i) {
    if (abort.load()) {
      out.state = RunState::kAborted;
      out.message = "aborted before pose " + std::to_string(i + 1);
      return out;
    }
    const Joints& target = plan_[i].q_deg;
    phase(i, RunPhase::kMoving);
    const double move_start = clock.nowS();
    try {
      robot.moveJoints(target);
    } catch (const Error& e) {
      out.message = "pose " + std::to_string(i + 1) + ": move failed: " + e.what();
      return out;
    }
    const double moved = clock.nowS();
    phase(i, RunPhase::kServoing);
    const servo::ServoResult r = servo.run(robot, psd, target, predictor.searchCentre(target));
    if (!r.ok()) {
      out.message = "pose " + std::to_string(i + 1) + ": servo " + servo::statusName(r.status) +
                    ": " + servo.fault().message;
      return out;
    }
    phase(i, RunPhase::kRecording);
    PoseRecord rec;
    rec.index = i;
    rec.joints_deg = r.q_deg;
    rec.u_mm = r.reading.u_mm;
    rec.v_mm = r.reading.v_mm;
    rec.u_se_mm = r.reading.u_se_mm;
    rec.v_se_mm = r.reading.v_se_mm;
    rec.move_started_ns = nanoseconds(move_start);
    rec.recorded_ns = nanoseconds(r.end_s);
    rec.servo.moves = r.moves;
    rec.servo.iterations = r.iterations;
    rec.servo.move_s = moved - move_start;
    rec.servo.acquisition_s = r.acquisitionS();
    rec.servo.servo_s = r.servoS();
    rec.servo.final_error_um = r.final_error_um;
    journal_.append(rec);  // on disk before the robot moves again
    out.records.push_back(rec);
    predictor.addPose(rec.joints_deg, Eigen::Vector2d(rec.u_mm, rec.v_mm));
    if (on_pose) on_pose(rec);
  }

  phase(static_cast<int>(plan_.size()), RunPhase::kSolving);
  SolveOptions solve_options = settings_.solve;
  solve_options.cancelled = [&abort] { return abort.load(); };
  out.report = solve(knowledge_, posesOf(out.records), solve_options);
  if (abort.load()) {
    out.state = RunState::kAborted;
    out.message = "aborted during the solve";
    out.report.reset();
    return out;
  }
  out.state = RunState::kCompleted;
  return out;
}

}  // namespace zerocal
