// A 6R serial arm in standard Denavit-Hartenberg form, as read from a robot YAML file.
//
// Conventions (fixed for the whole project, see docs/maths.md):
//   T_i = Rz(theta_i) * Tz(d_i) * Tx(a_i) * Rx(alpha_i),  theta_i = q_i + theta_offset_i + delta_i
// q_i are controller joint angles (degrees at the interfaces, radians inside the maths); the
// flange (tool0) frame is DH frame 6. Lengths are millimetres.
#pragma once

#include <Eigen/Core>
#include <array>
#include <string>
#include <vector>

namespace zerocal {

constexpr int kJointCount = 6;

// Controller joint angles in degrees (the IRC5's CJointT convention).
using Joints = std::array<double, kJointCount>;

// No industrial arm's joint travels beyond two turns either way: a robot file's limits, and any
// joint angle read back from a file, lie within +-this (deg).
constexpr double kMaxJointTravelDeg = 720;

struct DhRow {
  double a_mm = 0;
  double alpha_rad = 0;
  double d_mm = 0;
  double theta_offset_rad = 0;
};

struct JointLimit {
  double lower_deg = 0;
  double upper_deg = 0;
};

// A lumped mass of the arm for its gravity torques: `kg` at `at_mm` in DH frame `link` (2..6;
// frame j turns with joint j, so the mass is carried by joints 1..j).
struct LumpedMass {
  int link = 0;
  double kg = 0;
  std::array<double, 3> at_mm{};
};

// The compliance of joints 2 and 3 is identified against the gravity torque of these joints.
constexpr int kComplianceCount = 2;

// The link parameters of a robot model: a, d (mm) and alpha (rad) of each joint in turn.
constexpr int kLinkParameterCount = 3 * kJointCount;

// The one-sigma gravity sag of joints 2 and 3 (deg at each one's largest torque); 0: not counted.
using SagTolerances = std::array<double, kComplianceCount>;
inline bool anyCounted(const SagTolerances& sag_deg) { return sag_deg[0] > 0 || sag_deg[1] > 0; }
// As a file or a command gives them: one number for both joints, or those of joints 2 and 3.
// Empty or more than two: none.
// (Inline: the results codec reads it, and the thin client links no model code.)
inline SagTolerances sagTolerancesOf(const std::vector<double>& given) {
  if (given.size() == 1) return {given[0], given[0]};
  if (given.size() == 2) return {given[0], given[1]};
  return {};
}

// What a robot model admits about itself (its file's `model_tolerance` section): the one-sigma
// tolerances of a nominal model's link lengths (a, d) and twists (alpha), and of the gravity sag
// of joints 2 and 3 each at its largest torque (joint 3 carries less of the arm, so it sags
// less); a calibrated model adds the covariance of its link
// parameters' remaining errors, which replaces the two link tolerances. The method does not
// identify these at one PSD placement: every solve and prediction counts their effect on the
// estimates as a consider covariance (docs/maths.md section 5).
struct ModelTolerances {
  double length_mm = 0;
  double angle_deg = 0;
  SagTolerances sag_deg{};
  // The mean of each sag (deg at the largest torque; 0..sag_deg): a compliance is positive, so
  // a sag has gravity's sign, and two sags with means far from 0 are drawn together. 0 and 0:
  // the sags' signs are not stated, and they are counted as independent.
  SagTolerances sag_mean_deg{};
  // kLinkParameterCount square (mm^2, mm rad, rad^2), or empty: a nominal model.
  Eigen::MatrixXd link_covariance;

  bool calibrated() const { return link_covariance.size() > 0; }
  bool linksCounted() const { return calibrated() || length_mm > 0 || angle_deg > 0; }
  bool counted() const { return linksCounted() || anyCounted(sag_deg); }
  // Each link parameter's one-sigma error (mm, rad): the covariance's diagonal, or the
  // tolerances.
  Eigen::VectorXd linkSigmas() const;
  // A square root R of the two sags' second moment (deg): R R^T = E[s s^T], whose diagonal is
  // sag_deg squared and whose off-diagonal is the product of the means (their spreads about the
  // means are independent). Its columns are independent unit draws of both sags at once.
  Eigen::Matrix2d sagRootDeg() const;
};

struct Robot {
  std::string name;
  std::array<DhRow, kJointCount> dh;
  std::array<JointLimit, kJointCount> limits;
  std::array<double, kJointCount> max_speed_deg_s{};
  // Each joint's transmission: the motor angle change per joint angle change, signed (negative:
  // the motor turns backwards when the joint turns forwards). 0: not given in the robot file.
  // It takes an arm-side offset to the motor side, where the controller keeps its calibration.
  std::array<double, kJointCount> transmission{};
  // false: the values above are placeholders to be confirmed on the robot before they are used.
  bool transmission_confirmed = false;
  // The arm's lumped masses (robot file's `gravity` section; empty: no gravity model, and the
  // compliance of joints 2 and 3 is not identified). masses_inferred: the values are estimates,
  // not the manufacturer's data.
  std::vector<LumpedMass> masses;
  bool masses_inferred = false;
  // Identified kinematics (a calibrated model, `zerocal solve --save-model`): the DH errors
  // already added to `dh` (a, d in mm, alpha in rad; kept so that the file can be written back
  // with its nominal rows), and the compliance of joints 2 and 3 in deg per kN m: the true
  // joint angle is the commanded one plus compliance x gravity torque (gravityTorqueKnm).
  std::array<std::array<double, 3>, kJointCount> identified_link_error{};
  std::array<double, kComplianceCount> compliance_deg_per_knm{};
  // What the model admits about its links and sag (required in a robot file: 0 and 0 state a
  // model taken as exact).
  ModelTolerances tolerance;

  bool hasGravityModel() const { return !masses.empty(); }
  bool hasCompliance() const {
    return compliance_deg_per_knm[0] != 0 || compliance_deg_per_knm[1] != 0;
  }

  // True when every joint lies inside its limits shrunk by margin_deg on both sides.
  bool withinLimits(const Joints& q_deg, double margin_deg = 0.0) const;
  // Describes the first joint outside its limits ("joint 3 = 70.000 deg is outside
  // [-245, 65] deg"), or returns an empty string when all are inside.
  std::string limitViolation(const Joints& q_deg, double margin_deg = 0.0) const;
};

// The gravity torque (kN m) about the axes of joints 2 and 3 of the masses at controller joints
// q_deg, on the arm of robot.dh (the base z axis up): positive where it turns the joint
// forwards. A mass counts for joint j when it rides on link j or beyond.
std::array<double, kComplianceCount> gravityTorqueKnm(const Robot& robot,
                                                      const std::vector<LumpedMass>& masses,
                                                      const Joints& q_deg);
// Its bound over every pose: each mass's lever arm at most the sum of the link lengths between
// the joint's axis and the mass (reached with the arm stretched out horizontally).
std::array<double, kComplianceCount> gravityTorqueBoundKnm(const Robot& robot,
                                                           const std::vector<LumpedMass>& masses);
// The joint deflection (deg, joints 1..6) of the robot's identified compliance at q_deg.
Joints complianceDeflectionDeg(const Robot& robot, const Joints& q_deg);

// Reads and validates a robot file. Throws ConfigError listing every problem found
// (missing fields, wrong types, lower >= upper limits, values no arm has: angles beyond +-360 deg,
// lengths beyond +-10 m, limits beyond +-kMaxJointTravelDeg, transmissions outside 1..1000 in
// magnitude, ...), each as "file:line: joint N: key ...".
Robot loadRobot(const std::string& path);
// The same from YAML text; origin names the source in error messages.
Robot parseRobot(const std::string& yaml_text, const std::string& origin);
// The robot as a robot file that parseRobot reads back to the same kinematics: the nominal DH
// rows with the identified errors beside them (da_mm, dd_mm, dalpha_deg), the gravity model
// and the identified compliance, every number to 17 digits. `comment` heads it ('#' lines).
std::string robotYaml(const Robot& robot, const std::string& comment = "");
// robotYaml read back by parseRobot before it is given out: a calibrated model that the loader
// would refuse is never written as if it were one. Throws ConfigError as parseRobot does.
std::string checkedRobotYaml(const Robot& robot, const std::string& comment = "");

}  // namespace zerocal
