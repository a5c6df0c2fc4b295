// The planner of the session service's requests: checks a start or plan request and makes its
// plan, checks a session's plan read back from its session.json (a resume, a continue), and holds
// the one rule for poses given up. Nothing here moves or touches the cell; every method is const
// and may be called from any thread.
//
// The rule for poses given up: a pose may be left out (skipped at a resume, offered as a skip
// after a fault) only when the prediction of what the solve will have once the rest are measured,
// counting the same link and sag tolerances as the solve, still identifies delta2..delta5 -- the
// same prediction a new plan is refused by.
#pragma once

#include <Eigen/Core>
#include <functional>
#include <optional>
#include <string>
#include <vector>

#include "zerocal/calib/planner.h"
#include "zerocal/cell/cell.h"
#include "zerocal/service/reference.h"
#include "zerocal/service/session_control.h"
#include "zerocal/store/journal.h"
#include "zerocal/store/session_files.h"
#include "zerocal/store/session_store.h"

namespace zerocal::service {

struct PlannerSettings {
  // What a request leaves out: the measurement sigma (mm) and the nominal target (base frame,
  // mm; else the cell's taught centre).
  double noise_mm = 0.01;
  std::optional<Eigen::Vector3d> target_mm;
  // What the solve counts beside the noise (its link and sag tolerances), so that every
  // prediction here is the solve's.
  ModelTolerances tolerances;
  // The servo's margin from every joint limit (deg): a plan's pose inside it is refused.
  double limit_margin_deg = 0;
  // The one-sigma accuracy a result must reach (the solve's): a plan predicted short of it
  // starts only when asked for explicitly (StartRequest::even_if_not_usable).
  double required_accuracy_deg = 0.01;
  // How closely the PSD's base puts it back (mm, one sigma per axis per seating): a check's and a
  // restore's change counts it.
  double psd_base_repeatability_mm = 0;
  // The controller's time for a move between two poses (s): a plan is then ordered for travel.
  std::function<double(const Robot& robot, const Joints& from, const Joints& to)> travel_s;
};

// What a run needs of its session: the plan's poses, the nominal target (placement 1's centre),
// the measurement sigma, and with several placements each one's planned centre (the first is the
// target; empty with one placement).
struct RunPlan {
  std::vector<Pose> poses;
  Eigen::Vector3d target = Eigen::Vector3d::Zero();
  double noise_mm = 0;
  std::vector<Eigen::Vector3d> centres;
};

// A request planned and checked for a new session: the plan (for session.json) and its run plan.
struct PlannedSession {
  Plan plan;
  RunPlan run;
  // Measured against a reference: per plan pose, the reference's 1-based plan pose it re-measures.
  std::vector<int> reference_poses;
};

// What a fault at a plan pose lets the technician do: skip it at a resume (skippable_pose, 1-based)
// or plan a new session (0). `advice` goes after the fault's message.
struct SkipAdvice {
  int skippable_pose = 0;
  std::string advice;
};

class RequestPlanner {
 public:
  // `backend` says whether its PSD can be moved between placements; both outlive the planner.
  RequestPlanner(const CellKnowledge& knowledge, const CellBackend& backend,
                 PlannerSettings settings);

  // The plan of a request, with its prediction, as `zerocal plan` shows it; not checked for
  // identifiability. Throws Refused("bad_request") for an invalid request, ("out_of_limits") for
  // a plan file's pose inside the limits' margin, ("unsupported") for placements the cell cannot
  // have. `model`: the calibrated model the session's solve will use, predicted with its
  // covariance in place of the robot file's tolerances (null: the robot file).
  Plan preview(const StartRequest& request, const Robot* model = nullptr) const;
  // The plan of a request for a new session; throws as preview(), Refused("not_identifiable")
  // when the plan does not identify delta2..delta5, and ("not_accurate") when it is predicted
  // short of the required accuracy and the request does not ask for it anyway.
  PlannedSession plan(const StartRequest& request, const Robot* model = nullptr) const;
  // The plan of a session measured against `reference` (a check, a restore, or with
  // request.verifies the verification of a restore's apply): a check and a verification
  // re-measure the fewest of its poses that see a change of the required accuracy's size (each
  // offset's predicted sigma a fifth of it, so that an unchanged robot passes), a restore the
  // fewest whose values are good to write (0.15 of it), each from the joints the reference
  // recorded. Throws Refused("not_accurate") when a
  // restore is predicted short of the required accuracy and the request does not ask for it
  // anyway, ("out_of_limits") for a reference pose inside the limits' margin.
  PlannedSession planChange(const StartRequest& request, const Reference& reference) const;
  // The change's options of this daemon for a session of `kind`: its noise, tolerances and
  // required accuracy; a restore's with the arm's thermal growth an unknown.
  ChangeOptions changeOptions(SessionKind kind) const;
  // Session `id`'s run plan from its session.json, checked exactly as a new plan is (anyone with
  // access may have edited the file). Throws Refused("bad_session"), ("out_of_limits").
  RunPlan runPlanOf(const std::string& id, const SessionFile& session) const;
  // Throws Refused("unsupported") when the plan has several placements and the cell cannot have
  // its PSD moved between them.
  void checkPlaceable(const RunPlan& plan) const;

  // The prediction of the solve once the plan's poses less `skipped` are measured.
  Prediction predictWithout(const std::vector<Pose>& plan, const std::vector<bool>& skipped,
                            const Eigen::Vector3d& target, double noise_mm) const;
  // Whether the plan's poses less `skipped` still identify delta2..delta5 (predictWithout).
  bool identifiesWithout(const RunPlan& plan, const std::vector<bool>& skipped) const;

  // A resume of session `id` (its journal's `records`, `recorded` plan poses of them) asking to
  // skip 1-based pose `skip_pose` (0: none). Returns the 0-based pose to skip, -1 for none.
  // Throws Refused("bad_request") for a pose that is not the next one to measure, and
  // ("not_identifiable") when the plan would not identify every offset without the poses
  // skipped so far and this one.
  int checkResume(const std::string& id, const RunPlan& plan,
                  const std::vector<PoseRecord>& records, int recorded, int skip_pose) const;
  // After a fault of session `id` at 0-based plan pose `stopped_at` (its own fault: measuring it
  // again would fail again), whether the plan can do without it.
  SkipAdvice adviseSkip(const std::string& id, const RunPlan& plan,
                        const std::vector<PoseRecord>& records, int stopped_at) const;

 private:
  Plan makePlan(const StartRequest& request, const Robot* model, Eigen::Vector3d& target,
                double& noise_mm) const;

  const CellKnowledge& knowledge_;
  const CellBackend& backend_;
  PlannerSettings settings_;
};

// The plan poses the journal's records skipped on purpose (a skip asked for at a resume).
std::vector<bool> skippedPoses(const std::vector<PoseRecord>& records, std::size_t plan_size);

// Throws InputError for a target (or placement centre) no robot cell has, or a measurement sigma
// that is not a positive number of millimetres.
void checkPlanInput(const Eigen::Vector3d& target, double noise_mm);

// Session ids are UTC timestamps with an optional clash suffix (20261122T050102Z-001); anything
// else (a path, "..") is refused before it reaches the file system: Refused("bad_request").
void checkSessionId(const std::string& id);

// The result of finished session `requested` (the latest finished one when empty), as the
// `result` request answers it. Throws Refused("not_found", "bad_request"), Error when its
// result.json cannot be read.
ResultFile finishedResult(const SessionStore& store, const std::string& requested);

// A placement's centre for the technician: "(x, y, z) mm".
std::string centreText(const Eigen::Vector3d& centre_mm);

}  // namespace zerocal::service
