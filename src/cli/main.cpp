// zerocal: the calibration engine on the command line (solve, plan, experiment, sensitivity), the
// PSD chain (psd-sweep, psd-map, psd), the report of a session folder (report), and the client of
// zerocald's control port (start, status, watch, abort, resume, sessions, result; plan without
// --robot).
// Exit codes: 0 done; 1 unexpected failure; 2 bad input or usage, or no USB-1408FS / no permission
// to open it; 3 the solver did not converge; 4 solved, but some of delta2..delta5 are not
// identifiable from the poses (or not to the required accuracy); 7 (experiment cell, placements) a
// requirement does not hold; 8 solved, but the verdict refuses the result (stand-off, offset bound,
// misfit, gross errors: the reasons are printed, no correction is). The client commands add 3 (the
// watched session was aborted or faulted), 5 (cannot connect) and 6 (token refused or unusable);
// control_commands.h.
#include <unistd.h>

#include <CLI/CLI.hpp>
#include <Eigen/Geometry>
#include <algorithm>
#include <fstream>
#include <iostream>
#include <sstream>

#include "apply_commands.h"
#include "cell_experiment.h"
#include "control_commands.h"
#include "placement_experiment.h"
#include "psd_commands.h"
#include "robustness_experiment.h"
#include "zerocal/calib/experiment.h"
#include "zerocal/calib/format.h"
#include "zerocal/calib/planner.h"
#include "zerocal/calib/sensitivity.h"
#include "zerocal/calib/solver.h"
#include "zerocal/calib/validation.h"
#include "zerocal/error.h"
#include "zerocal/io/durable_file.h"
#include "zerocal/io/joint_set.h"
#include "zerocal/model/builtin.h"
#include "zerocal/report/session_report.h"
#include "zerocal/store/journal.h"
#include "zerocal/usb1408fs/errors.h"

namespace zerocal {
namespace {

enum ExitCode {
  kOk = 0,
  kFailure = 1,
  kBadInput = 2,
  kNotConverged = 3,
  kNotIdentifiable = 4,
  kRefused = 8,
};

struct CellArgs {
  std::string robot;
  std::vector<double> laser_direction{1, 0, 0};
  std::vector<double> laser_point{0, 0, 0};

  void add(CLI::App* app, bool required = true) {
    auto* option = app->add_option("--robot", robot,
                                   "robot model YAML (e.g. config/robots/irb1600-10-145.yaml), or "
                                   "'builtin' for the compiled-in IRB 1600-10/1.45" +
                                       std::string(required ? "" : "; without it, zerocald plans"));
    if (required) option->required();
    app->add_option("--laser-direction", laser_direction,
                    "nominal laser direction in the flange frame (default: flange x, 1 0 0)")
        ->expected(3);
    app->add_option("--laser-point", laser_point,
                    "nominal laser point in the flange frame, mm (default: flange origin)")
        ->expected(3);
  }
  CellModel cell() const {
    Robot r = robot == "builtin" ? builtinIrb1600() : loadRobot(robot);
    return CellModel{
        std::move(r),
        LaserModel(Eigen::Vector3d(laser_direction.data()), Eigen::Vector3d(laser_point.data())),
        Eigen::Matrix3d::Identity(),
        {}};
  }
};

Eigen::Matrix3d fromRpyDeg(const std::vector<double>& rpy) {
  return (Eigen::AngleAxisd(rpy[2] * kDegToRad, Eigen::Vector3d::UnitZ()) *
          Eigen::AngleAxisd(rpy[1] * kDegToRad, Eigen::Vector3d::UnitY()) *
          Eigen::AngleAxisd(rpy[0] * kDegToRad, Eigen::Vector3d::UnitX()))
      .toRotationMatrix();
}

void emit(const nlohmann::json& j) { std::cout << j.dump(2) << "\n"; }

// Edits (insert, delete, substitute, swap two neighbours) from one word to the other.
std::size_t editDistance(const std::string& a, const std::string& b) {
  std::vector<std::vector<std::size_t>> d(a.size() + 1, std::vector<std::size_t>(b.size() + 1));
  for (std::size_t i = 0; i <= a.size(); ++i) d[i][0] = i;
  for (std::size_t j = 0; j <= b.size(); ++j) d[0][j] = j;
  for (std::size_t i = 1; i <= a.size(); ++i)
    for (std::size_t j = 1; j <= b.size(); ++j) {
      d[i][j] = std::min(
          {d[i - 1][j] + 1, d[i][j - 1] + 1, d[i - 1][j - 1] + (a[i - 1] == b[j - 1] ? 0 : 1)});
      if (i > 1 && j > 1 && a[i - 1] == b[j - 2] && a[i - 2] == b[j - 1])
        d[i][j] = std::min(d[i][j], d[i - 2][j - 2] + 1);
    }
  return d[a.size()][b.size()];
}

// When the first word is meant as a command and is none: says so, with the nearest command if
// one is close (`sovle` -> solve), and returns true.
bool refuseUnknownCommand(const CLI::App& app, const std::string& word, std::ostream& err) {
  if (word.empty() || word[0] == '-') return false;
  std::string nearest;
  std::size_t best = 3;  // more edits than two: no suggestion
  for (const CLI::App* c : app.get_subcommands([](const CLI::App*) { return true; })) {
    if (c->get_name() == word) return false;
    const std::size_t d = editDistance(word, c->get_name());
    if (d < best) best = d, nearest = c->get_name();
  }
  err << "zerocal: unknown command '" << word << "'";
  if (!nearest.empty()) err << "; did you mean '" << nearest << "'?";
  err << " (zerocal --help lists the commands)\n";
  return true;
}

// Writes a calibrated robot file, after checking that it reads back (a model that the loader
// refuses must not be left behind as if it were one).
void saveCalibratedModel(const std::string& path, const Robot& robot, const std::string& comment) {
  const std::string text = robotYaml(robot, comment);
  parseRobot(text, path);
  // Whole or not at all: a robot file cut short by a crash would be read as another robot.
  writeFileDurably(path, text);
}

}  // namespace
}  // namespace zerocal

int main(int argc, char** argv) {
  using namespace zerocal;
  CLI::App app{
      "zerocal: joint zero-offset calibration of a 6R robot from laser lines aimed at one point "
      "(a PSD). Identifies delta2..delta5 and the laser line, with their uncertainty."};
  app.require_subcommand(1);
  app.set_version_flag("--version", std::string(PROJECT_VERSION));

  // solve
  auto* solve_cmd = app.add_subcommand("solve", "identify the offsets from a recorded joint set");
  CellArgs solve_cell;
  solve_cell.add(solve_cmd);
  std::string joints_file, cost = "ml", loss = "none";
  std::optional<double> noise;
  std::vector<double> psd_rpy;
  bool ignore_readings = false, solve_json = false;
  double loss_scale = 3.0;
  solve_cmd->add_option("--joints", joints_file, "joint-set CSV: q1..q6 in deg, optional u,v in mm")
      ->required();
  solve_cmd
      ->add_option("--cost", cost, "ml (maximum likelihood, default) or pairwise (paper eq. 6)")
      ->check(CLI::IsMember({"ml", "pairwise"}));
  solve_cmd->add_option("--noise", noise,
                        "measurement sigma in mm (line miss per axis); when absent it is "
                        "estimated from the residuals");
  solve_cmd
      ->add_option("--psd-rpy", psd_rpy,
                   "PSD orientation in the base frame, roll pitch yaw in deg (needed when "
                   "the joint set has u,v readings)")
      ->expected(3);
  solve_cmd->add_flag("--ignore-readings", ignore_readings,
                      "ignore u,v columns: assume every pose hit the PSD centre");
  solve_cmd->add_option("--loss", loss, "robust loss: none (default), huber or cauchy")
      ->check(CLI::IsMember({"none", "huber", "cauchy"}));
  solve_cmd->add_option("--loss-scale", loss_scale, "where the robust loss bends, in noise sigmas");
  SolveOptions solve_defaults;
  double required_accuracy = solve_defaults.required_accuracy_deg;
  double max_offset = solve_defaults.max_offset_deg;
  solve_cmd
      ->add_option("--required-accuracy", required_accuracy,
                   "the accuracy the calibration is for, deg: an offset whose one-sigma "
                   "uncertainty is larger is not determined and the result is not usable")
      ->default_val(required_accuracy);
  solve_cmd
      ->add_option("--max-offset", max_offset,
                   "largest plausible zero offset, deg; beyond it the result is refused (the "
                   "model is wrong, not the zero)")
      ->default_val(max_offset);
  bool identify_compliance = false;
  double sag_tolerance = 0;
  std::string save_model;
  solve_cmd->add_flag("--identify-compliance", identify_compliance,
                      "several placements: identify the compliance of joints 2 and 3 against the "
                      "robot file's gravity model");
  solve_cmd
      ->add_option("--sag-tolerance", sag_tolerance,
                   "several placements: the gravity sag's one-sigma tolerance at the largest "
                   "torque, deg, counted in every sigma when the compliance is not identified")
      ->check(CLI::Range(0.0, 1.0));
  solve_cmd->add_option("--save-model", save_model,
                        "several placements: write the robot file with the identified link "
                        "errors and compliance (a calibrated model) to this path, when the "
                        "result is usable");
  solve_cmd->add_flag("--json", solve_json, "print one JSON object instead of text");
  std::optional<int> holdout_count;
  std::vector<int> holdout_poses;
  auto* holdout_opt = solve_cmd->add_option(
      "--holdout", holdout_count,
      "validation: hold K poses (spread evenly over the set) out of the solve and report how "
      "well the result predicts them, before and after calibration");
  solve_cmd
      ->add_option("--holdout-poses", holdout_poses,
                   "validation: hold these poses out (1-based, comma separated, e.g. 3,5)")
      ->delimiter(',')
      ->excludes(holdout_opt);

  // report
  auto* report_cmd = app.add_subcommand(
      "report", "(re)write summary.txt and report.html of a session folder and print the summary");
  std::string session_dir;
  bool report_json = false;
  report_cmd->add_option("session-dir", session_dir, "the session folder (<data_dir>/<id>)")
      ->required();
  report_cmd->add_flag("--json", report_json,
                       "print the paths and the offsets as one JSON object instead of the summary");

  // plan
  auto* plan_cmd = app.add_subcommand(
      "plan", "plan poses and predict their uncertainty (with --robot here, else on zerocald)");
  CellArgs plan_cell;
  plan_cell.add(plan_cmd, false);
  cli::ClientArgs plan_client;
  cli::addConnectionOptions(plan_cmd, plan_client);
  std::vector<double> target;
  std::string pattern = "optimal", out_file;
  PlanOptions plan_options;
  std::vector<double> standoff{plan_options.standoff_min_mm, plan_options.standoff_max_mm};
  std::vector<double> psd_normal{0, 0, 1};
  bool plan_json = false;
  // A plan made here predicts with the planner's own sigma (the PSD's +-0.05 mm read as uniform);
  // on the daemon (no --robot) a plan left without --noise gets session.noise_mm instead.
  double plan_noise = plan_options.noise_mm;
  auto* target_option =
      plan_cmd->add_option("--target", target, "nominal target (PSD centre) in the base frame, mm")
          ->expected(3);
  auto* poses_option = plan_cmd->add_option("--poses", plan_options.poses, "number of poses");
  auto* pattern_option =
      plan_cmd->add_option("--pattern", pattern, "I, II, mixed or optimal (default)");
  auto* noise_option =
      plan_cmd->add_option("--noise", plan_noise, "measurement sigma in mm for the prediction")
          ->default_val(plan_noise);
  plan_cmd->add_option("--standoff", standoff, "stand-off range MIN MAX in mm")->expected(2);
  plan_cmd->add_option("--margin", plan_options.margin_deg, "kept from every joint limit, deg")
      ->default_val(plan_options.margin_deg);
  plan_cmd
      ->add_option("--max-incidence", plan_options.max_incidence_deg,
                   "largest beam angle from the PSD normal, deg (optimal)")
      ->default_val(plan_options.max_incidence_deg);
  plan_cmd->add_option("--sweep", plan_options.sweep_deg, "beam tilt range +-deg (patterns)")
      ->default_val(plan_options.sweep_deg);
  plan_cmd->add_option("--psd-normal", psd_normal, "PSD normal in the base frame (default up)")
      ->expected(3);
  plan_cmd->add_flag("--joint1-fixed", plan_options.joint1_fixed,
                     "pattern II: hold joint 1 exactly constant (to show the failure)");
  int plan_placements = 1;
  std::vector<std::vector<double>> placement_centres;
  plan_cmd
      ->add_option("--placements", plan_placements,
                   "PSD placements of the session (the first at --target, the others spread "
                   "over the workspace unless given with --placement); --poses at each")
      ->check(CLI::Range(1, kMaxPlacements));
  plan_cmd
      ->add_option("--placement", placement_centres,
                   "centre of the next placement (2, 3, ...) in the base frame, mm (repeatable)")
      ->expected(3);
  plan_cmd->add_option("--out", out_file, "write the joint targets as a joint-set CSV");
  plan_cmd->add_flag("--json", plan_json, "print one JSON object instead of text");

  // experiment
  auto* exp_cmd = app.add_subcommand("experiment", "reproduce the paper's experiments");
  auto* table2_cmd = exp_cmd->add_subcommand(
      "table2",
      "Monte Carlo of Table II: patterns I, II and optimal with both costs, against "
      "the Cramer-Rao bound and the paper's figures");
  exp_cmd->require_subcommand(1);
  ExperimentOptions exp_options;
  bool exp_json = false;
  table2_cmd->add_option("--repeats", exp_options.repeats, "Monte Carlo repeats")
      ->default_val(exp_options.repeats)
      ->check(CLI::Range(2, 1000000));
  table2_cmd->add_option("--seed", exp_options.seed, "random seed")->default_val(exp_options.seed);
  table2_cmd->add_flag("--json", exp_json, "print one JSON object instead of text");
  cli::CellExperimentArgs cell_exp_args;
  auto* cell_exp_cmd = cli::addCellExperiment(*exp_cmd, cell_exp_args);
  cli::RobustnessExperimentArgs robustness_args;
  cli::addRobustnessExperiments(*exp_cmd, robustness_args);
  cli::PlacementExperimentArgs placement_args;
  cli::addPlacementExperiment(*exp_cmd, placement_args);

  // sensitivity
  auto* sens_cmd = app.add_subcommand(
      "sensitivity", "spot displacement on the PSD per small change of each joint");
  CellArgs sens_cell;
  sens_cell.add(sens_cmd);
  std::vector<double> sens_joints;
  double sens_standoff = 600;
  bool sens_json = false;
  sens_cmd->add_option("--joints", sens_joints, "configuration Q1 .. Q6 in deg")
      ->expected(6)
      ->required();
  sens_cmd->add_option("--standoff", sens_standoff, "laser to PSD distance, mm")->required();
  sens_cmd->add_flag("--json", sens_json, "print JSON instead of text");

  // simulate
  auto* sim_cmd = app.add_subcommand(
      "simulate", "record a planned joint set on a simulated robot with known offsets");
  CellArgs sim_cell;
  sim_cell.add(sim_cmd);
  std::string plan_file;
  std::vector<double> true_offsets, sim_target;
  double sim_half_width = 0.05;
  std::uint64_t sim_seed = 1;
  sim_cmd->add_option("--plan", plan_file, "planned joint-set CSV (from zerocal plan --out)")
      ->required();
  sim_cmd->add_option("--offsets", true_offsets, "true delta2..delta5 in deg")
      ->expected(4)
      ->required();
  sim_cmd->add_option("--target", sim_target, "true target point in the base frame, mm")
      ->expected(3)
      ->required();
  sim_cmd
      ->add_option("--error", sim_half_width,
                   "localisation error, uniform within +-MM on each axis")
      ->default_val(sim_half_width);
  sim_cmd->add_option("--seed", sim_seed, "random seed")->default_val(sim_seed);

  cli::PsdCommands psd_cmds;
  cli::addPsdCommands(app, psd_cmds);
  cli::ClientCommands client_cmds;
  cli::addClientCommands(app, client_cmds);
  cli::ApplyCommands apply_cmds;
  cli::addApplyCommands(app, apply_cmds);

  if (argc > 1 && refuseUnknownCommand(app, argv[1], std::cerr)) return kBadInput;
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    // --help and --version arrive here too, with exit code 0; every real usage error is bad
    // input, so scripts see the same code as for a bad file.
    return app.exit(e) == 0 ? kOk : kBadInput;
  }

  for (auto* c : client_cmds.apps)
    if (c->parsed()) return cli::runClient(client_cmds.args, std::cout, std::cerr, isatty(1));
  if (apply_cmds.parsed()) return cli::runApplyCommands(apply_cmds, std::cout, std::cerr);
  if (plan_cmd->parsed() && plan_cell.robot.empty()) {
    // On the daemon: its cell, its planner; only the options of a session request apply.
    for (const char* local :
         {"--standoff", "--margin", "--max-incidence", "--sweep", "--psd-normal", "--joint1-fixed",
          "--out", "--laser-direction", "--laser-point", "--placement"})
      if (plan_cmd->count(local) > 0) {
        std::cerr << "zerocal: plan " << local << " needs --robot (a plan made here)\n";
        return kBadInput;
      }
    plan_client.command = "plan";
    plan_client.json = plan_json;
    if (pattern_option->count() > 0) plan_client.pattern = pattern;
    if (poses_option->count() > 0) plan_client.poses = plan_options.poses;
    if (target_option->count() > 0) plan_client.target = target;
    if (noise_option->count() > 0) plan_client.noise_mm = plan_noise;
    if (plan_cmd->count("--placements") > 0) plan_client.placements = plan_placements;
    return cli::runClient(plan_client, std::cout, std::cerr, isatty(1));
  }

  try {
    if (plan_cmd->parsed() && (target.empty() || poses_option->count() == 0)) {
      std::cerr << "zerocal: plan --robot needs --target and --poses\n";
      return kBadInput;
    }
    if (solve_cmd->parsed()) {
      CellModel cell = solve_cell.cell();
      const auto poses = readJointSet(joints_file);
      SolveOptions options;
      options.cost = cost == "ml" ? CostKind::kMaximumLikelihood : CostKind::kPairwise;
      options.noise_mm = noise;
      options.loss = loss == "huber"    ? RobustLoss::kHuber
                     : loss == "cauchy" ? RobustLoss::kCauchy
                                        : RobustLoss::kNone;
      options.loss_scale_sigmas = loss_scale;
      options.required_accuracy_deg = required_accuracy;
      options.max_offset_deg = max_offset;
      options.identify_compliance = identify_compliance;
      options.model_sag_deg = sag_tolerance;
      bool has_readings = !poses.empty() && poses.front().spot.has_value();
      options.use_readings = has_readings && !ignore_readings;
      if (options.use_readings) {
        if (psd_rpy.empty())
          throw InputError(joints_file +
                           ": the joint set carries PSD readings u,v; give the PSD orientation "
                           "with --psd-rpy R P Y, or --ignore-readings");
        cell.psd_rotation = fromRpyDeg(psd_rpy);
      }
      std::vector<int> held_out = holdout_poses;
      if (holdout_count) held_out = spreadHoldout(static_cast<int>(poses.size()), *holdout_count);
      std::optional<HoldoutReport> validation;
      if (!held_out.empty()) validation = validateHoldout(cell, poses, held_out, options);
      const SolveReport report = validation ? validation->fit : solve(cell, poses, options);
      if (solve_json) {
        nlohmann::json j = toJson(report);
        if (validation) j["validation"] = toJson(*validation);
        emit(j);
      } else {
        std::cout << toText(report);
        if (validation) std::cout << toText(*validation);
      }
      if (!save_model.empty()) {
        if (report.placements.empty())
          throw InputError(
              "--save-model needs poses at two or more PSD placements: one "
              "placement identifies no link error");
        if (report.verdict.usable) {
          saveCalibratedModel(save_model, calibratedRobot(cell.robot, report.estimate),
                              "calibrated from " + joints_file + " by zerocal solve");
          std::cerr << "zerocal: calibrated robot model written to " << save_model << "\n";
        } else {
          std::cerr << "zerocal: the result is not usable: no robot model written to " << save_model
                    << "\n";
        }
      }
      if (!report.converged) return kNotConverged;
      for (int k = 0; k < kOffsetCount; ++k)
        if (!report.parameters[k].identifiable) return kNotIdentifiable;
      return report.verdict.usable ? kOk : kRefused;
    }
    if (plan_cmd->parsed()) {
      const CellModel cell = plan_cell.cell();
      plan_options.pattern = parsePattern(pattern);
      plan_options.noise_mm = plan_noise;
      plan_options.standoff_min_mm = standoff[0];
      plan_options.standoff_max_mm = standoff[1];
      plan_options.psd_normal = Eigen::Vector3d(psd_normal.data());
      for (const auto& c : placement_centres)
        plan_options.more_placements.emplace_back(c[0], c[1], c[2]);
      const int given = static_cast<int>(placement_centres.size()) + 1;
      if (plan_cmd->count("--placements") > 0 && plan_placements < given)
        throw InputError("--placements " + std::to_string(plan_placements) + " but " +
                         std::to_string(given) + " placements are given (--target and " +
                         std::to_string(given - 1) + " --placement)");
      if (plan_placements > given) {
        // The rest from the default spread, after the ones given.
        const auto spread = defaultPlacements(Eigen::Vector3d(target.data()), plan_placements);
        for (int p = given; p < plan_placements; ++p)
          plan_options.more_placements.push_back(spread[p - 1]);
      }
      const Plan plan = planPoses(cell, Eigen::Vector3d(target.data()), plan_options);
      if (!out_file.empty()) {
        std::ofstream out(out_file);
        out << formatJointSet(plan.poses,
                              "zerocal plan: " + plan.description + "\nrobot: " + cell.robot.name);
        if (!out) throw InputError(out_file + ": cannot write the plan");
      }
      if (plan_json) {
        emit(toJson(plan));
      } else {
        std::cout << toText(plan);
        if (out_file.empty()) std::cout << "\n" << formatJointSet(plan.poses);
      }
      for (int k = 0; k < kOffsetCount; ++k)
        if (!plan.prediction.identifiable[k]) return kNotIdentifiable;
      return kOk;
    }
    if (table2_cmd->parsed()) {
      const auto results = runTable2(exp_options);
      if (exp_json)
        emit(toJson(results, exp_options));
      else
        std::cout << toText(results, exp_options);
      return kOk;
    }
    if (cell_exp_cmd->parsed()) return cli::runCellExperiment(cell_exp_args);
    if (placement_args.cmd->parsed()) return cli::runPlacementExperiment(placement_args);
    if (const int rc = cli::runRobustnessExperiment(robustness_args); rc >= 0) return rc;
    if (sim_cmd->parsed()) {
      const CellModel cell = sim_cell.cell();
      CalibrationParameters truth;
      truth.delta_rad = Eigen::Vector4d(true_offsets.data()) * kDegToRad;
      truth.target_mm = Eigen::Vector3d(sim_target.data());
      if (!(sim_half_width >= 0)) throw InputError("the localisation error must not be negative");
      std::mt19937_64 rng(sim_seed);
      const auto recorded =
          simulateRecording(cell, truth, readJointSet(plan_file), sim_half_width, rng);
      std::ostringstream comment;
      comment << "zerocal simulate: " << cell.robot.name << ", true offsets " << true_offsets[0]
              << " " << true_offsets[1] << " " << true_offsets[2] << " " << true_offsets[3]
              << " deg, target " << sim_target[0] << " " << sim_target[1] << " " << sim_target[2]
              << " mm, error +-" << sim_half_width << " mm, seed " << sim_seed;
      std::cout << formatJointSet(recorded, comment.str());
      return kOk;
    }
    if (report_cmd->parsed()) {
      report::writeSessionReport(session_dir);
      const report::SessionReport r = report::parseSession(report::readSessionFiles(session_dir));
      if (!report_json) {
        std::cout << report::summaryText(r);
        return kOk;
      }
      nlohmann::json j{{"session", r.session.id},
                       {"summary", session_dir + "/summary.txt"},
                       {"report", session_dir + "/report.html"},
                       {"converged", r.solve().converged},
                       {"offsets", nlohmann::json::object()}};
      for (const auto& p : r.parameters) {
        if (p.name.rfind("delta", 0) != 0) continue;
        j["offsets"][p.name] = p.identifiable
                                   ? nlohmann::json{{"value_deg", p.value},
                                                    {"value_rad", p.value * kDegToRad},
                                                    {"sigma_deg", p.sigma},
                                                    {"ci95_deg", {p.ci95_low, p.ci95_high}}}
                                   : nlohmann::json{{"identifiable", false}, {"reason", p.reason}};
      }
      emit(j);
      return kOk;
    }
    if (psd_cmds.sweep->parsed()) return cli::runPsdSweep(psd_cmds.sweep_args);
    if (psd_cmds.map->parsed()) return cli::runPsdMap(psd_cmds.map_args);
    if (psd_cmds.live->parsed()) return cli::runPsd(psd_cmds.live_args);
    if (sens_cmd->parsed()) {
      const CellModel cell = sens_cell.cell();
      Joints q;
      std::copy(sens_joints.begin(), sens_joints.end(), q.begin());
      if (const auto v = cell.robot.limitViolation(q); !v.empty()) throw InputError(v);
      if (!(sens_standoff > 0)) throw InputError("the stand-off must be positive");
      const auto s = spotSensitivity(cell, q, sens_standoff);
      if (sens_json)
        emit(toJson(s));
      else
        std::cout << toText(s);
      return kOk;
    }
  } catch (const ConfigError& e) {
    std::cerr << "zerocal: " << e.what() << "\n";
    return kBadInput;
  } catch (const InputError& e) {
    std::cerr << "zerocal: " << e.what() << "\n";
    return kBadInput;
  } catch (const report::ReportError& e) {
    std::cerr << "zerocal: " << e.what() << "\n";
    return kBadInput;
  } catch (const JournalError& e) {
    std::cerr << "zerocal: " << e.what() << "\n";
    return kBadInput;
  } catch (const usb1408fs::DeviceNotFoundError& e) {
    // Absent or forbidden hardware is the technician's to fix, like a bad file.
    std::cerr << "zerocal: " << e.what() << "\n";
    return kBadInput;
  } catch (const usb1408fs::PermissionError& e) {
    std::cerr << "zerocal: " << e.what() << "\n";
    return kBadInput;
  } catch (const usb1408fs::UsbError& e) {
    std::cerr << "zerocal: USB-1408FS: " << e.what() << "\n";
    return kFailure;
  } catch (const std::exception& e) {
    std::cerr << "zerocal: unexpected failure: " << e.what() << "\n";
    return kFailure;
  }
  return kFailure;
}
