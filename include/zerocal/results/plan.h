// A plan as session.json, the control port's `plan` and `plan --json` hold it (docs/results.md):
// the joint targets and the uncertainty predicted before any move, and its JSON.
// zerocal/calib/planner.h makes it.
#pragma once

#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "zerocal/io/joint_set.h"
#include "zerocal/results/parameters.h"

namespace zerocal {

struct Prediction {
  // One standard deviation per identified parameter (deg for offsets), NaN where not
  // identifiable, for the given measurement sigma.
  std::vector<double> sigma;
  std::vector<bool> identifiable;
  std::vector<std::string> reason;
  double rms_offset_sigma_deg = 0;  // RMS over delta2..delta5 (infinite if any is not identifiable)
  int rank = 0;
  double condition_number = 0;
  // With poses at several PSD placements: how many, and per link error (linkParamName order) its
  // sigma (mm, or deg for a twist; NaN when not identified), whether the poses identify it, and
  // why not. Empty with one placement.
  int placements = 1;
  std::vector<double> link_sigma;
  std::vector<bool> link_identifiable;
  std::vector<std::string> link_reason;
  // The one-sigma accuracy a result must reach, when the daemon's planner judged the plan by it
  // (a session is refused unless every offset's sigma is within it); 0 when not judged.
  double required_accuracy_deg = 0;
  // The cell time the plan should take (s): cell_time_per_pose_s, what a pose cost the daemon's
  // latest cell_time_sessions sessions, times its poses (zerocal/service/cell_time.h). 0 when
  // the daemon had no session to go by.
  double cell_time_s = 0;
  double cell_time_per_pose_s = 0;
  int cell_time_sessions = 0;
};

struct Plan {
  std::vector<Pose> poses;
  Prediction prediction;
  std::string description;
  int candidates_considered = 0;
};

nlohmann::json toJson(const Plan& plan);
// The inverse of toJson; a plan without "predicted" (hand-edited) predicts nothing: every sigma
// NaN, nothing identifiable. Throws InputError.
Plan planFromJson(const nlohmann::json& json, const std::string& where);

}  // namespace zerocal
