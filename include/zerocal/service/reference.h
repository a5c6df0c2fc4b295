// A robot's reference as checks and restores measure against it (docs/record.md): a finished
// reference session, read from its folder (the source of truth), with what the change since it
// needs (zerocal/calib/change.h).
#pragma once

#include <array>
#include <optional>
#include <string>
#include <vector>

#include "zerocal/calib/change.h"
#include "zerocal/cell/robot_info.h"
#include "zerocal/model/robot.h"
#include "zerocal/store/session_store.h"

namespace zerocal::service {

struct Reference {
  std::string id;
  ReferenceFit fit;             // the poses its solve used, and its solve's parameters
  std::vector<int> plan_poses;  // fit.poses[k]'s 1-based plan pose in the reference session
  RobotInfo robot;              // as its controller named itself
  // The controller's cal_offset values (rad, joints 1..6) while it measured, when recorded.
  std::optional<std::array<double, 6>> cal_offset_rad;
  double noise_mm = 0;  // the measurement sigma it was planned and solved with
  // The PSD placement its poses aimed at, for a calibration of several (0: a reference's poses,
  // at its one placement), and the centres its placements were planned at (session.json).
  int placement = 0;
  std::vector<Eigen::Vector3d> placement_centres_mm;
};

// Reference session `id` of `store`. Throws Refused("bad_request") for an id no session has the
// form of, ("not_found") when there is no such session, ("not_a_reference") when it is not a
// finished reference whose result may be used (its verdict says why not), ("damaged") when its
// files cannot be read.
Reference loadReference(const SessionStore& store, const std::string& id);

// The verification of calibration `id`'s apply compares with it: the poses its solve used at its
// last PSD placement, where the detector stands after it, and that placement's centre. After a
// right apply their zeros have moved by exactly what was written, and the link errors cancel as
// for a reference. Throws as loadReference, and Refused("not_a_calibration") for another kind.
Reference loadAppliedCalibration(const SessionStore& store, const std::string& id);

// What `session` measures its change against: its verified calibration (the verification of a
// calibration's apply names the calibration as its reference), else its reference session.
Reference loadComparedWith(const SessionStore& store, const SessionFile& session);

// The latest finished reference of `store` whose verdict is usable, of the robot with this
// serial when given; empty when there is none.
std::string latestReference(const SessionStore& store, const std::string& serial = "");

// A robot's calibrated model as later calibrations use it (docs/record.md): the kinematics a
// usable calibration at several PSD placements identified, with the covariance of its link
// errors, written beside its result (ResultFile::model_file).
struct CalibratedModel {
  std::string id;    // the calibration that wrote it
  Robot robot;       // as the model file reads
  RobotInfo origin;  // the robot it calibrated, as its controller named itself
};

// The calibrated model of calibration `id`. Throws Refused as loadReference does for an id, and
// ("no_model") when the session wrote none, ("damaged") when its model file cannot be read.
CalibratedModel loadCalibratedModel(const SessionStore& store, const std::string& id);

// The latest finished calibration of `store` whose result wrote a calibrated model, of the robot
// with this serial when given; empty when there is none.
std::string latestCalibratedModel(const SessionStore& store, const std::string& serial = "");

// The kind to run next, in a sentence for the status (SessionStatus::suggestion): a reference
// when `latest` (latestReference's answer) is empty, else a check against it.
std::string suggestedKind(const std::string& latest);

}  // namespace zerocal::service
