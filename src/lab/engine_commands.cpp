#include "engine_commands.h"

#include <Eigen/Geometry>
#include <algorithm>
#include <fstream>
#include <iostream>
#include <random>
#include <sstream>

#include "lab_exit.h"
#include "zerocal/calib/experiment.h"
#include "zerocal/calib/format.h"
#include "zerocal/calib/sensitivity.h"
#include "zerocal/calib/validation.h"
#include "zerocal/error.h"
#include "zerocal/io/durable_file.h"
#include "zerocal/io/joint_set.h"
#include "zerocal/model/builtin.h"

namespace zerocal::lab {
namespace {

Eigen::Matrix3d fromRpyDeg(const std::vector<double>& rpy) {
  return (Eigen::AngleAxisd(rpy[2] * kDegToRad, Eigen::Vector3d::UnitZ()) *
          Eigen::AngleAxisd(rpy[1] * kDegToRad, Eigen::Vector3d::UnitY()) *
          Eigen::AngleAxisd(rpy[0] * kDegToRad, Eigen::Vector3d::UnitX()))
      .toRotationMatrix();
}

void emit(const nlohmann::json& j) { std::cout << j.dump(2) << "\n"; }

// Writes a calibrated robot file, whole or not at all: a robot file cut short by a crash would be
// read as another robot.
void saveCalibratedModel(const std::string& path, const Robot& robot, const std::string& comment) {
  writeFileDurably(path, checkedRobotYaml(robot, comment));
}

void addSolve(CLI::App& app, EngineCommands& commands) {
  SolveArgs& a = commands.solve_args;
  auto* cmd = commands.solve =
      app.add_subcommand("solve", "identify the offsets from a recorded joint set");
  a.cell.add(cmd);
  cmd->add_option("--joints", a.joints_file, "joint-set CSV: q1..q6 in deg, optional u,v in mm")
      ->required();
  cmd->add_option("--cost", a.cost, "ml (maximum likelihood, default) or pairwise (paper eq. 6)")
      ->check(CLI::IsMember({"ml", "pairwise"}));
  cmd->add_option("--noise", a.noise,
                  "measurement sigma in mm (line miss per axis); when absent it is "
                  "estimated from the residuals");
  auto* joint_noise = cmd->add_option(
      "--joint-repeatability", a.joint_repeatability,
      "each joint's repeatability, deg (one sigma per move; the IRB 1600's is about 0.0015): each "
      "pose weighed by its own noise at the PSD, through its joint Jacobian");
  joint_noise->check(CLI::Range(1e-6, 0.1))->excludes("--noise");
  cmd->add_option("--psd-noise", a.psd_noise,
                  "with --joint-repeatability: the PSD's reading noise per axis, mm (default 0)")
      ->check(CLI::Range(0.0, 1.0))
      ->needs(joint_noise);
  cmd->add_option("--psd-rpy", a.psd_rpy,
                  "PSD orientation in the base frame, roll pitch yaw in deg (needed when "
                  "the joint set has u,v readings)")
      ->expected(3);
  cmd->add_flag("--ignore-readings", a.ignore_readings,
                "ignore u,v columns: assume every pose hit the PSD centre");
  cmd->add_option("--loss", a.loss, "robust loss: none (default), huber or cauchy")
      ->check(CLI::IsMember({"none", "huber", "cauchy"}));
  cmd->add_option("--loss-scale", a.loss_scale, "where the robust loss bends, in noise sigmas");
  cmd->add_option("--required-accuracy", a.required_accuracy,
                  "the accuracy the calibration is for, deg: an offset whose one-sigma "
                  "uncertainty is larger is not determined and the result is not usable")
      ->default_val(a.required_accuracy);
  cmd->add_option("--max-offset", a.max_offset,
                  "largest plausible zero offset, deg; beyond it the result is refused (the "
                  "model is wrong, not the zero)")
      ->default_val(a.max_offset);
  cmd->add_flag("--identify-compliance", a.identify_compliance,
                "several placements: identify the compliance of joints 2 and 3 against the "
                "robot file's gravity model");
  cmd->add_option("--sag-tolerance", a.sag_tolerance,
                  "the gravity sag's one-sigma tolerance at the largest torque, deg, of joints 2 "
                  "and 3 (or one for both), counted in every sigma when the compliance is not "
                  "identified, their signs not stated (default: the robot file's "
                  "model_tolerance.sag_deg with its sag_mean_deg)")
      ->expected(1, 2)
      ->check(CLI::Range(0.0, 1.0));
  cmd->add_option("--save-model", a.save_model,
                  "several placements: write the robot file with the identified link "
                  "errors and compliance (a calibrated model) to this path, when the "
                  "result is usable");
  cmd->add_flag("--json", a.json, "print one JSON object instead of text");
  auto* holdout_opt = cmd->add_option(
      "--holdout", a.holdout_count,
      "validation: hold K poses (spread evenly over the set) out of the solve and report how "
      "well the result predicts them, before and after calibration");
  cmd->add_option("--holdout-poses", a.holdout_poses,
                  "validation: hold these poses out (1-based, comma separated, e.g. 3,5)")
      ->delimiter(',')
      ->excludes(holdout_opt);
}

void addPlan(CLI::App& app, EngineCommands& commands) {
  PlanArgs& a = commands.plan_args;
  auto* cmd = commands.plan = app.add_subcommand(
      "plan",
      "plan poses and predict their uncertainty (the plan on zerocald's cell is `zerocal plan`)");
  a.cell.add(cmd);
  cmd->add_option("--target", a.target, "nominal target (PSD centre) in the base frame, mm")
      ->expected(3);
  cmd->add_option("--poses", a.options.poses, "number of poses");
  cmd->add_option("--pattern", a.pattern, "I, II, mixed or optimal (default)");
  cmd->add_option("--noise", a.noise, "measurement sigma in mm for the prediction")
      ->default_val(a.noise);
  cmd->add_option("--standoff", a.standoff, "stand-off range MIN MAX in mm")->expected(2);
  cmd->add_option("--margin", a.options.margin_deg, "kept from every joint limit, deg")
      ->default_val(a.options.margin_deg);
  cmd->add_option("--max-incidence", a.options.max_incidence_deg,
                  "largest beam angle from the PSD normal, deg (optimal)")
      ->default_val(a.options.max_incidence_deg);
  cmd->add_option("--sweep", a.options.sweep_deg, "beam tilt range +-deg (patterns)")
      ->default_val(a.options.sweep_deg);
  cmd->add_option("--psd-normal", a.psd_normal, "PSD normal in the base frame (default up)")
      ->expected(3);
  cmd->add_flag("--joint1-fixed", a.options.joint1_fixed,
                "pattern II: hold joint 1 exactly constant (to show the failure)");
  cmd->add_option("--placements", a.placements,
                  "PSD placements of the session (the first at --target, the others spread "
                  "over the workspace unless given with --placement); --poses at each")
      ->check(CLI::Range(1, kMaxPlacements));
  cmd->add_option("--placement", a.placement_centres,
                  "centre of the next placement (2, 3, ...) in the base frame, mm (repeatable)")
      ->expected(3);
  cmd->add_option("--out", a.out_file, "write the joint targets as a joint-set CSV");
  cmd->add_flag("--json", a.json, "print one JSON object instead of text");
}

void addSimulate(CLI::App& app, EngineCommands& commands) {
  SimulateArgs& a = commands.simulate_args;
  auto* cmd = commands.simulate = app.add_subcommand(
      "simulate", "record a planned joint set on a simulated robot with known offsets");
  a.cell.add(cmd);
  cmd->add_option("--plan", a.plan_file, "planned joint-set CSV (from zerocal-lab plan --out)")
      ->required();
  cmd->add_option("--offsets", a.true_offsets, "true delta2..delta5 in deg")
      ->expected(4)
      ->required();
  cmd->add_option("--target", a.target, "true target point in the base frame, mm")
      ->expected(3)
      ->required();
  cmd->add_option("--error", a.half_width, "localisation error, uniform within +-MM on each axis")
      ->default_val(a.half_width);
  cmd->add_option("--seed", a.seed, "random seed")->default_val(a.seed);
}

void addSensitivity(CLI::App& app, EngineCommands& commands) {
  SensitivityArgs& a = commands.sensitivity_args;
  auto* cmd = commands.sensitivity = app.add_subcommand(
      "sensitivity", "spot displacement on the PSD per small change of each joint");
  a.cell.add(cmd);
  cmd->add_option("--joints", a.joints, "configuration Q1 .. Q6 in deg")->expected(6)->required();
  cmd->add_option("--standoff", a.standoff, "laser to PSD distance, mm")->required();
  cmd->add_flag("--json", a.json, "print JSON instead of text");
}

int runSolve(const SolveArgs& a) {
  CellModel cell = a.cell.cell();
  if (a.joint_repeatability) cell.noise = {*a.joint_repeatability, a.psd_noise.value_or(0.0)};
  const auto poses = readJointSet(a.joints_file);
  SolveOptions options;
  options.cost = a.cost == "ml" ? CostKind::kMaximumLikelihood : CostKind::kPairwise;
  options.noise_mm = a.noise;
  options.loss = a.loss == "huber"    ? RobustLoss::kHuber
                 : a.loss == "cauchy" ? RobustLoss::kCauchy
                                      : RobustLoss::kNone;
  options.loss_scale_sigmas = a.loss_scale;
  options.required_accuracy_deg = a.required_accuracy;
  options.max_offset_deg = a.max_offset;
  options.identify_compliance = a.identify_compliance;
  // What the robot file admits about its model (a nominal one's tolerances, a calibrated one's
  // covariance), the sag's tolerance as given here when it is (its sign then not stated).
  options.model = cell.robot.tolerance;
  if (!a.sag_tolerance.empty()) {
    options.model.sag_deg = sagTolerancesOf(a.sag_tolerance);
    options.model.sag_mean_deg = {};
  }
  bool has_readings = !poses.empty() && poses.front().spot.has_value();
  options.use_readings = has_readings && !a.ignore_readings;
  if (options.use_readings) {
    if (a.psd_rpy.empty())
      throw InputError(a.joints_file +
                       ": the joint set carries PSD readings u,v; give the PSD orientation "
                       "with --psd-rpy R P Y, or --ignore-readings");
    cell.psd_rotation = fromRpyDeg(a.psd_rpy);
  }
  std::vector<int> held_out = a.holdout_poses;
  if (a.holdout_count) held_out = spreadHoldout(static_cast<int>(poses.size()), *a.holdout_count);
  std::optional<HoldoutReport> validation;
  if (!held_out.empty()) validation = validateHoldout(cell, poses, held_out, options);
  const SolveReport report = validation ? validation->fit : solve(cell, poses, options);
  if (a.json) {
    nlohmann::json j = toJson(report);
    if (validation) j["validation"] = toJson(*validation);
    emit(j);
  } else {
    std::cout << toText(report);
    if (validation) std::cout << toText(*validation);
  }
  if (!a.save_model.empty()) {
    if (report.placements.empty())
      throw InputError(
          "--save-model needs poses at two or more PSD placements: one "
          "placement identifies no link error");
    if (report.verdict.usable) {
      saveCalibratedModel(a.save_model, calibratedRobot(cell.robot, report),
                          "calibrated from " + a.joints_file + " by zerocal solve");
      std::cerr << "zerocal-lab: calibrated robot model written to " << a.save_model << "\n";
    } else {
      std::cerr << "zerocal-lab: the result is not usable: no robot model written to "
                << a.save_model << "\n";
    }
  }
  if (!report.converged) return kNotConverged;
  for (int k = 0; k < kOffsetCount; ++k)
    if (!report.parameters[k].identifiable) return kNotIdentifiable;
  return report.verdict.usable ? kOk : kRefused;
}

int runPlan(const CLI::App& cmd, const PlanArgs& a) {
  if (a.target.empty() || cmd.count("--poses") == 0) {
    std::cerr << "zerocal-lab: plan --robot needs --target and --poses\n";
    return kBadInput;
  }
  const CellModel cell = a.cell.cell();
  PlanOptions options = a.options;
  options.pattern = parsePattern(a.pattern);
  options.noise_mm = a.noise;
  options.standoff_min_mm = a.standoff[0];
  options.standoff_max_mm = a.standoff[1];
  options.psd_normal = Eigen::Vector3d(a.psd_normal.data());
  for (const auto& c : a.placement_centres) options.more_placements.emplace_back(c[0], c[1], c[2]);
  const int given = static_cast<int>(a.placement_centres.size()) + 1;
  if (cmd.count("--placements") > 0 && a.placements < given)
    throw InputError("--placements " + std::to_string(a.placements) + " but " +
                     std::to_string(given) + " placements are given (--target and " +
                     std::to_string(given - 1) + " --placement)");
  if (a.placements > given) {
    // The rest from the default spread, after the ones given.
    const auto spread = defaultPlacements(Eigen::Vector3d(a.target.data()), a.placements);
    for (int p = given; p < a.placements; ++p) options.more_placements.push_back(spread[p - 1]);
  }
  const Plan plan = planPoses(cell, Eigen::Vector3d(a.target.data()), options);
  if (!a.out_file.empty()) {
    std::ofstream out(a.out_file);
    // The comment keeps the name the joint sets were always written with.
    out << formatJointSet(plan.poses,
                          "zerocal plan: " + plan.description + "\nrobot: " + cell.robot.name);
    if (!out) throw InputError(a.out_file + ": cannot write the plan");
  }
  if (a.json) {
    emit(toJson(plan));
  } else {
    std::cout << toText(plan);
    if (a.out_file.empty()) std::cout << "\n" << formatJointSet(plan.poses);
  }
  for (int k = 0; k < kOffsetCount; ++k)
    if (!plan.prediction.identifiable[k]) return kNotIdentifiable;
  return kOk;
}

int runSimulate(const SimulateArgs& a) {
  const CellModel cell = a.cell.cell();
  CalibrationParameters truth;
  truth.delta_rad = Eigen::Vector4d(a.true_offsets.data()) * kDegToRad;
  truth.target_mm = Eigen::Vector3d(a.target.data());
  if (!(a.half_width >= 0)) throw InputError("the localisation error must not be negative");
  std::mt19937_64 rng(a.seed);
  const auto recorded =
      simulateRecording(cell, truth, readJointSet(a.plan_file), a.half_width, rng);
  std::ostringstream comment;
  comment << "zerocal simulate: " << cell.robot.name << ", true offsets " << a.true_offsets[0]
          << " " << a.true_offsets[1] << " " << a.true_offsets[2] << " " << a.true_offsets[3]
          << " deg, target " << a.target[0] << " " << a.target[1] << " " << a.target[2]
          << " mm, error +-" << a.half_width << " mm, seed " << a.seed;
  std::cout << formatJointSet(recorded, comment.str());
  return kOk;
}

int runSensitivity(const SensitivityArgs& a) {
  const CellModel cell = a.cell.cell();
  Joints q;
  std::copy(a.joints.begin(), a.joints.end(), q.begin());
  if (const auto v = cell.robot.limitViolation(q); !v.empty()) throw InputError(v);
  if (!(a.standoff > 0)) throw InputError("the stand-off must be positive");
  const auto s = spotSensitivity(cell, q, a.standoff);
  if (a.json)
    emit(toJson(s));
  else
    std::cout << toText(s);
  return kOk;
}

}  // namespace

void CellArgs::add(CLI::App* app) {
  app->add_option("--robot", robot,
                  "robot model YAML (e.g. config/robots/irb1600-10-145.yaml), or "
                  "'builtin' for the compiled-in IRB 1600-10/1.45")
      ->required();
  app->add_option("--laser-direction", laser_direction,
                  "nominal laser direction in the flange frame (default: flange x, 1 0 0)")
      ->expected(3);
  app->add_option("--laser-point", laser_point,
                  "nominal laser point in the flange frame, mm (default: flange origin)")
      ->expected(3);
}

CellModel CellArgs::cell() const {
  Robot r = robot == "builtin" ? builtinIrb1600() : loadRobot(robot);
  return CellModel{
      std::move(r),
      LaserModel(Eigen::Vector3d(laser_direction.data()), Eigen::Vector3d(laser_point.data())),
      Eigen::Matrix3d::Identity(),
      {}};
}

void addEngineCommands(CLI::App& app, EngineCommands& commands) {
  addSolve(app, commands);
  addPlan(app, commands);
  addSimulate(app, commands);
  addSensitivity(app, commands);
}

int runEngineCommands(const EngineCommands& commands) {
  if (commands.solve->parsed()) return runSolve(commands.solve_args);
  if (commands.plan->parsed()) return runPlan(*commands.plan, commands.plan_args);
  if (commands.simulate->parsed()) return runSimulate(commands.simulate_args);
  if (commands.sensitivity->parsed()) return runSensitivity(commands.sensitivity_args);
  return -1;
}

}  // namespace zerocal::lab
