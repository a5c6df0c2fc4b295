#include "zerocal/session/calibration_run.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <exception>
#include <iomanip>
#include <sstream>

#include "zerocal/cell/link_error.h"
#include "zerocal/error.h"
#include "zerocal/servo/spot_predictor.h"

namespace zerocal {
namespace {

// Wall time for the journal's timestamps (nanoseconds since the Unix epoch): when a pose was
// measured, for the technician and the logs; durations come from the cell clock.
std::int64_t unixNanoseconds() {
  return std::chrono::duration_cast<std::chrono::nanoseconds>(
             std::chrono::system_clock::now().time_since_epoch())
      .count();
}

enum class Failure { kNone, kLink, kSensor, kAborted, kOther };
enum class Recovery { kDone, kFailed, kAborted };

// Calls `hook` until it returns, at most `attempts` times, waiting `backoff_s` of cell time
// between calls (a board being replugged takes seconds; the link client backs off on its own).
Recovery recover(const std::function<void()>& hook, CellClock& clock,
                 const std::atomic<bool>& abort, int attempts, double backoff_s,
                 std::string& problem) {
  for (int attempt = 1; attempt <= attempts; ++attempt) {
    if (abort.load()) return Recovery::kAborted;
    try {
      hook();
      return Recovery::kDone;
    } catch (const std::exception& e) {
      problem = e.what();
    }
    if (attempt < attempts) clock.waitS(backoff_s);
  }
  return Recovery::kFailed;
}

// A healthy link answers a ping within milliseconds; one that takes this long on each of
// kProbes pings spends the servo's time budget on waiting.
constexpr double kSlowLinkS = 0.1;
constexpr int kProbes = 3;

struct LinkHealth {
  std::string problem;  // empty when healthy; else what is wrong, for the session's message
  bool slow = false;
  LinkError::Kind kind = LinkError::Kind::kTransient;
};

// Pings the controller, timed on the cell clock (the wall on a real cell).
LinkHealth probeLink(ControllerLink& robot, CellClock& clock) {
  LinkHealth health;
  double fastest = 0;
  for (int k = 0; k < kProbes; ++k) {
    const double t0 = clock.nowS();
    try {
      robot.ping();
    } catch (const LinkError& e) {
      health.kind = e.kind();
      health.problem = std::string("failed: ") + e.what();
      return health;
    } catch (const Error& e) {
      health.kind = LinkError::Kind::kFatal;
      health.problem = std::string("failed: ") + e.what();
      return health;
    }
    const double dt = clock.nowS() - t0;
    fastest = k == 0 ? dt : std::min(fastest, dt);
    if (fastest < kSlowLinkS) return health;
  }
  health.slow = true;
  std::ostringstream text;
  text << std::fixed << std::setprecision(2) << "is slow (the fastest of " << kProbes
       << " pings took " << fastest << " s; a healthy link answers within milliseconds)";
  health.problem = text.str();
  return health;
}

// Journal lines of the plan's own poses (measured or skipped), second measurements not counted.
int planLines(const std::vector<PoseRecord>& records) {
  return static_cast<int>(std::count_if(records.begin(), records.end(),
                                        [](const PoseRecord& r) { return r.remeasure_of < 0; }));
}

}  // namespace

std::vector<int> planIndicesOf(const std::vector<PoseRecord>& records) {
  std::vector<int> indices;
  for (const PoseRecord* r : latestRecords(records))
    if (r && r->measured()) indices.push_back(r->planIndex());
  return indices;
}

void CalibrationRun::journalFault(const servo::ServoFault& fault, int plan_index,
                                  bool again) const {
  FaultRecord record;
  record.plan_index = plan_index;
  record.remeasure = again;
  record.status = servo::statusName(fault.status);
  record.message = fault.message;
  record.recorded_ns = unixNanoseconds();
  record.samples.assign(fault.samples.begin(), fault.samples.begin() + fault.sample_count);
  appendFault(faultLogPath(journal_.path()), record);
}

std::vector<Pose> posesOf(const std::vector<PoseRecord>& records) {
  std::vector<Pose> poses;
  for (const PoseRecord* r : latestRecords(records))
    if (r && r->measured())
      poses.push_back({r->joints_deg, r->reading.spot, r->line, r->placement});
  return poses;
}

CalibrationRun::CalibrationRun(CellModel knowledge, Eigen::Vector3d taught_centre_mm,
                               std::vector<Pose> plan, RunSettings settings, Journal& journal)
    : knowledge_(std::move(knowledge)),
      taught_centre_(taught_centre_mm),
      plan_(std::move(plan)),
      settings_(std::move(settings)),
      journal_(journal) {
  if (settings_.recovery_attempts < 1 || settings_.recoveries_per_pose < 0 ||
      !(settings_.recovery_backoff_s >= 0))
    throw InputError(
        "run settings: recovery_attempts must be at least 1, recoveries_per_pose and "
        "recovery_backoff_s not negative");
  const int plan_lines = planLines(journal_.records());
  if (plan_lines > static_cast<int>(plan_.size()))
    throw InputError("the journal holds " + std::to_string(plan_lines) +
                     " poses but the plan only " + std::to_string(plan_.size()));
  // The technician is guided from one placement to the next, never back.
  int placement = 1;
  for (std::size_t i = 0; i < plan_.size(); ++i) {
    const int p = plan_[i].placement;
    if (p != placement && p != placement + 1)
      throw InputError("plan pose " + std::to_string(i + 1) + " is at placement " +
                       std::to_string(p) + " after placement " + std::to_string(placement) +
                       ": a plan's placements must be 1, 2, ... in turn");
    placement = p;
  }
  if (plan_.empty() || plan_.front().placement != 1)
    throw InputError("a plan's first pose must be at placement 1");
  if (plan_lines < static_cast<int>(plan_.size()) &&
      journal_.placement() > plan_[plan_lines].placement)
    throw InputError("the journal has the PSD at placement " +
                     std::to_string(journal_.placement()) + " but its next pose, " +
                     std::to_string(plan_lines + 1) + ", is at placement " +
                     std::to_string(plan_[plan_lines].placement));
}

int CalibrationRun::awaitedPlacement() const {
  const int next = planLines(journal_.records());
  if (next != journal_.nextIndex() || next >= static_cast<int>(plan_.size())) return 0;
  return plan_[next].placement > journal_.placement() ? plan_[next].placement : 0;
}

void CalibrationRun::placeNext(const Eigen::Vector3d& centre_mm) {
  const int placement = awaitedPlacement();
  if (placement == 0) throw InputError("the run does not wait for the PSD to be moved");
  if (!centre_mm.allFinite()) throw InputError("the placement's centre must be finite");
  PlacementRecord record;
  record.placement = placement;
  record.centre_mm = {centre_mm.x(), centre_mm.y(), centre_mm.z()};
  record.recorded_ns = unixNanoseconds();
  journal_.append(record);
}

CellModel CalibrationRun::placementModel(int placement) const {
  CellModel model = knowledge_;
  model.psd_rotation = knowledge_.psdRotation(placement);
  return model;
}

Eigen::Vector3d CalibrationRun::placementCentre(int placement) const {
  for (const PlacementRecord& p : journal_.placements())
    if (p.placement == placement) return Eigen::Vector3d(p.centre_mm.data());
  return taught_centre_;
}

void CalibrationRun::skipNextPose(const std::string& reason) {
  const int plan_lines = planLines(journal_.records());
  if (plan_lines >= static_cast<int>(plan_.size()) || plan_lines != journal_.nextIndex())
    throw InputError("no plan pose is left to skip: every one is recorded");
  PoseRecord record;
  record.index = journal_.nextIndex();
  record.skipped = reason;
  record.recorded_ns = unixNanoseconds();
  const PoseRecord& journalled = journal_.append(record);
  if (on_pose) on_pose(journalled);
}

RunOutcome CalibrationRun::run(ControllerLink& robot, PsdReader& psd, CellClock& clock,
                               const std::atomic<bool>& abort) {
  RunOutcome out;
  out.records = journal_.records();
  out.resumed_from = journal_.nextIndex();
  servo::ServoOptions servo_options = settings_.servo;
  servo_options.abort = &abort;
  // The servo and the predictor know the PSD where it stands now: its placement's orientation
  // and taught centre. The predictor learns from the poses at this placement only, since each
  // placement has a centre of its own.
  const int placement = journal_.placement();
  const CellModel model = placementModel(placement);
  const Eigen::Vector3d centre = placementCentre(placement);
  servo::PsdServo servo(model, centre, servo_options);
  servo::SpotPredictor predictor(model, centre);
  if (found_before) predictor.startFrom(*found_before);
  if (!earlier.empty()) predictor.expectReadingsOf(earlier);
  // Resumed poses teach the predictor where the spot falls, as if they had just been servoed.
  for (const PoseRecord& r : out.records)
    if (r.measured() && r.placement == placement) predictor.addPose(r.joints_deg, r.reading.spot);
  // Once the predictor knows the cell, a pose's move ends where the spot is predicted on the
  // detector's centre rather than at the planned joints: the servo then starts on the detector
  // instead of walking to the prediction in max_step_deg steps (seconds of cell time a pose).
  // The planned joints when that lies beyond the limits less the servo's margin, or more than
  // kMostAimDeg from them (a prediction that far off is not to be trusted with a move).
  constexpr double kMostAimDeg = 6.0;  // about the 100 mm search radius at a 1 m beam
  const auto aimed = [&](const Joints& planned) {
    const Joints q = predictor.aimedJoints(planned, servo_options.damping_mm);
    double change = 0;
    for (int k = 0; k < kJointCount; ++k) change = std::max(change, std::abs(q[k] - planned[k]));
    return change <= kMostAimDeg && model.robot.withinLimits(q, servo_options.limit_margin_deg)
               ? q
               : planned;
  };
  const int n = static_cast<int>(plan_.size());
  const auto phase = [&](int i, RunPhase p) {
    if (on_phase) on_phase(i, p);
  };

  // Measures plan pose i (again, when `again`) and journals it; false when the run must stop,
  // `out` then saying why.
  const auto measure = [&](int i, bool again) -> bool {
    const std::string pose_name = "pose " + std::to_string(i + 1) + " of " + std::to_string(n) +
                                  (again ? " (measured again)" : "");
    int recoveries = 0;
    for (;;) {
      if (abort.load()) {
        out.state = RunState::kAborted;
        out.message = "aborted before " + pose_name;
        return false;
      }
      // One attempt at the pose: the planned move, then the servo. Nothing is journalled until
      // it succeeds, so a failed attempt is simply done again after a recovery.
      Failure failure = Failure::kOther;
      bool pose_at_fault = false;  // the pose itself failed, not the link or the board
      std::string why;
      const Joints target = aimed(plan_[i].q_deg);
      phase(i, RunPhase::kMoving);
      const double move_start = clock.nowS();
      const std::int64_t move_started_ns = unixNanoseconds();
      try {
        robot.moveJoints(target);
        failure = Failure::kNone;
      } catch (const LinkError& e) {
        // Only a transient failure is worth a reconnect; a refused target is never sent again.
        failure = e.kind() == LinkError::Kind::kTransient ? Failure::kLink : Failure::kOther;
        pose_at_fault = e.kind() == LinkError::Kind::kRefused;
        why = std::string("move failed: ") + e.what();
      } catch (const Error& e) {
        why = std::string("move failed: ") + e.what();
      }
      servo::ServoResult r;
      double moved = move_start;
      if (failure == Failure::kNone) {
        moved = clock.nowS();
        phase(i, RunPhase::kServoing);
        // A move aimed into the servo's zone by an earlier reading needs no servo move once
        // the spot lands as predicted (servo::PsdServo::run).
        const PsdSpot expected = predictor.searchCentre(target);
        const bool aimed_move =
            predictor.predictsFromReading(target) &&
            std::hypot(expected.u_mm - servo_options.target.u_mm,
                       expected.v_mm - servo_options.target.v_mm) <= servo_options.hit_zone_mm;
        r = servo.run(robot, psd, clock, target, expected, aimed_move);
        if (!r.ok()) {
          if (r.status != servo::ServoStatus::kAborted) journalFault(servo.fault(), i, again);
          why = std::string("servo ") + servo::statusName(r.status) + ": " + servo.fault().message;
          if (servo.fault().detail[0] != '\0')
            why += std::string(": ") + servo.fault().detail.data();
          const bool transient = servo.fault().link_kind == LinkError::Kind::kTransient;
          pose_at_fault = r.status == servo::ServoStatus::kSpotNotFound ||
                          r.status == servo::ServoStatus::kSpotLost ||
                          r.status == servo::ServoStatus::kNotConverged ||
                          r.status == servo::ServoStatus::kLimit;
          failure = r.status == servo::ServoStatus::kAborted       ? Failure::kAborted
                    : !transient                                   ? Failure::kOther
                    : r.status == servo::ServoStatus::kLinkError   ? Failure::kLink
                    : r.status == servo::ServoStatus::kSensorError ? Failure::kSensor
                                                                   : Failure::kOther;
          // A spot not found or lost, or a servo out of time, may be the link's doing: a link
          // that went down or answers slowly spends the servo's time and its moves. Blaming the
          // pose would offer to skip a good one.
          if (pose_at_fault && r.status != servo::ServoStatus::kLimit) {
            const LinkHealth health = probeLink(robot, clock);
            if (!health.problem.empty()) {
              why += "; but the controller link " + health.problem +
                     ": the link is at fault, not the pose";
              pose_at_fault = false;
              failure = health.kind == LinkError::Kind::kTransient && !health.slow
                            ? Failure::kLink
                            : Failure::kOther;
            }
          }
        }
      }
      if (failure == Failure::kAborted) {
        out.state = RunState::kAborted;
        out.message = pose_name + ": " + why;
        return false;
      }
      if (failure != Failure::kNone) {
        const std::function<void()>& hook =
            failure == Failure::kLink ? settings_.reconnect_link : settings_.reopen_sensor;
        out.stopped_at = i;
        if (failure == Failure::kOther || !hook) {
          out.message = pose_name + ": " + why;
          out.pose_at_fault = pose_at_fault;
          return false;
        }
        if (recoveries == settings_.recoveries_per_pose) {
          out.message = pose_name + ": " + why + " (" + std::to_string(recoveries) +
                        " recoveries already on this pose)";
          return false;
        }
        ++recoveries;
        std::string recovery_problem;
        const Recovery rec = recover(hook, clock, abort, settings_.recovery_attempts,
                                     settings_.recovery_backoff_s, recovery_problem);
        if (rec == Recovery::kAborted) {
          out.state = RunState::kAborted;
          out.message = "aborted while recovering " + pose_name + " from: " + why;
          return false;
        }
        if (rec == Recovery::kFailed) {
          out.message = pose_name + ": " + why + "; " +
                        (failure == Failure::kLink ? "reconnecting" : "reopening the board") +
                        " failed " + std::to_string(settings_.recovery_attempts) +
                        " times: " + recovery_problem;
          return false;
        }
        ++(failure == Failure::kLink ? out.reconnects : out.reopens);
        continue;  // the pose again, from its planned move
      }

      phase(i, RunPhase::kRecording);
      PoseRecord record;
      record.index = journal_.nextIndex();
      if (again) record.remeasure_of = i;
      record.joints_deg = r.q_deg;
      record.reading = r.reading;
      record.placement = placement;
      record.move_started_ns = move_started_ns;
      record.recorded_ns = unixNanoseconds();
      record.servo.moves = r.moves;
      record.servo.search_moves = r.search_moves;
      record.servo.iterations = r.iterations;
      record.servo.move_s = moved - move_start;
      record.servo.acquisition_s = r.acquisitionS();
      record.servo.servo_s = r.servoS();
      record.servo.settle_s = r.settle_s;
      record.servo.final_error_um = r.final_error_um;
      record.servo_path.assign(r.path.begin(),
                               r.path.begin() + static_cast<std::ptrdiff_t>(r.path_count));
      // On disk before the robot moves again.
      const PoseRecord& journalled = journal_.append(record);
      out.records.push_back(journalled);
      predictor.addPose(record.joints_deg, record.reading.spot);
      if (on_pose) on_pose(journalled);
      return true;
    }
  };

  for (int i = journal_.nextIndex(); i < n; ++i) {
    if (plan_[i].placement != placement) {
      // The robot rests at the last pose of this placement; the technician moves the PSD.
      out.state = RunState::kAwaitingPlacement;
      out.next_placement = plan_[i].placement;
      out.stopped_at = i;
      out.message = "waiting for the PSD to be moved to placement " +
                    std::to_string(out.next_placement) + " before pose " + std::to_string(i + 1);
      return out;
    }
    if (!measure(i, false)) return out;
  }

  phase(n, RunPhase::kSolving);
  SolveOptions solve_options = settings_.solve;
  solve_options.cancelled = [&abort] { return abort.load(); };
  const auto solveRecorded = [&] {
    return settings_.solver
               ? settings_.solver(posesOf(out.records), planIndicesOf(out.records), solve_options)
               : solve(knowledge_, posesOf(out.records), solve_options);
  };
  out.report = solveRecorded();
  // The poses the solve names are measured once more and the solve run anew on each pose's
  // latest measurement: a spot disturbed once, or a reading taken before the arm settled, is
  // then replaced, not just left out. Once per session: a journal that has a second measurement
  // already (a resumed session) is solved as it is.
  const bool remeasured_before =
      std::any_of(out.records.begin(), out.records.end(),
                  [](const PoseRecord& r) { return r.remeasure_of >= 0; });
  if (!abort.load() && !remeasured_before && settings_.remeasure_most > 0) {
    const std::vector<int> solved = planIndicesOf(out.records);
    for (const int pose : out.report->remeasure)
      // Only where the PSD stands now: an earlier placement's pose would aim at a PSD gone.
      if (static_cast<int>(out.remeasured.size()) < settings_.remeasure_most &&
          plan_[solved[pose - 1]].placement == placement &&
          std::find(out.remeasured.begin(), out.remeasured.end(), solved[pose - 1]) ==
              out.remeasured.end())
        out.remeasured.push_back(solved[pose - 1]);
  }
  if (!out.remeasured.empty()) {
    if (on_remeasure) on_remeasure(out.remeasured);
    for (const int i : out.remeasured) {
      if (measure(i, true)) continue;
      if (out.state == RunState::kFaulted && out.pose_at_fault) {
        // The pose fails on its own (its spot not found now, say): its first measurement stays,
        // and the solve leaves it out as before.
        out.message.clear();
        out.pose_at_fault = false;
        out.stopped_at = -1;
        continue;
      }
      out.report.reset();
      return out;
    }
    phase(n, RunPhase::kSolving);
    out.report = solveRecorded();
  }
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
