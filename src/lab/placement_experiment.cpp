#include "placement_experiment.h"

#include <fmt/format.h>

#include <Eigen/Geometry>
#include <cmath>
#include <cstdio>
#include <iostream>
#include <nlohmann/json.hpp>
#include <random>

#include "cell_experiment.h"
#include "zerocal/calib/planner.h"
#include "zerocal/calib/solver.h"
#include "zerocal/error.h"
#include "zerocal/model/builtin.h"
#include "zerocal/model/kinematics.h"
#include "zerocal/sim/world.h"

namespace zerocal::lab {
namespace {

// One PSD placement of a simulated session: where the detector truly is, and what the session
// is told (the taught centre, the configured orientation).
struct SimPlacement {
  Eigen::Vector3d centre;
  Eigen::Matrix3d rotation;
  Eigen::Vector3d taught;
  Eigen::Matrix3d configured;
};

// Placement 1 is the world's PSD; the others stand where defaultPlacements puts them, 20 mm
// either way, turned and tilted as the world's own (up to 10 deg off level), taught and
// configured with the world's kind of error.
std::vector<SimPlacement> placementsOf(const World& world, int count, std::uint64_t seed,
                                       bool ideal) {
  std::vector<SimPlacement> out{{world.psd_position_mm, world.psd_rotation,
                                 world.psd_centre_taught_mm, world.psd_rotation_configured}};
  std::mt19937_64 rng(seed ^ 0x706c6163656d656eull);
  std::uniform_real_distribution<double> unit(-1.0, 1.0), zero_one(0.0, 1.0);
  std::normal_distribution<double> normal;
  const auto direction = [&] {
    Eigen::Vector3d v;
    do v = Eigen::Vector3d(normal(rng), normal(rng), normal(rng));
    while (v.norm() < 1e-6);
    return v.normalized();
  };
  for (const Eigen::Vector3d& nominal : defaultPlacements(world.psd_position_mm, count)) {
    SimPlacement p;
    p.centre = nominal + 20 * Eigen::Vector3d(unit(rng), unit(rng), unit(rng));
    p.rotation = (Eigen::AngleAxisd(180 * unit(rng) * kDegToRad, Eigen::Vector3d::UnitZ()) *
                  Eigen::AngleAxisd(10 * unit(rng) * kDegToRad, Eigen::Vector3d::UnitY()) *
                  Eigen::AngleAxisd(10 * unit(rng) * kDegToRad, Eigen::Vector3d::UnitX()))
                     .toRotationMatrix();
    const double angle_deg = 1 + 2 * zero_one(rng), taught_mm = 1 + 4 * zero_one(rng);
    p.configured =
        ideal ? p.rotation
              : Eigen::Matrix3d(p.rotation * Eigen::AngleAxisd(angle_deg * kDegToRad, direction()));
    p.taught = ideal ? Eigen::Vector3d(p.centre + Eigen::Vector3d(3, -3, 3))
                     : Eigen::Vector3d(p.centre + taught_mm * direction());
    out.push_back(p);
  }
  return out;
}

// The joints near `start` at which the true beam meets the PSD at its centre (a perfect servo on
// the true arm: offsets, link errors, sag, warming): Gauss-Newton, minimum-norm steps.
Joints servoToCentre(const World& world, const Joints& start, double time_s) {
  Joints q = start;
  for (int iteration = 0; iteration < 50; ++iteration) {
    const auto hit = beamHit(world, q, {}, time_s);
    if (!hit) throw Error("the true beam misses the PSD plane at a planned pose");
    const Eigen::Vector2d r(hit->spot.u_mm, hit->spot.v_mm);
    if (r.norm() < 1e-9) return q;
    Eigen::Matrix<double, 2, kJointCount> jac;
    constexpr double h = 1e-5;  // deg
    for (int j = 0; j < kJointCount; ++j) {
      Joints plus = q, minus = q;
      plus[j] += h;
      minus[j] -= h;
      const auto a = beamHit(world, plus, {}, time_s), b = beamHit(world, minus, {}, time_s);
      if (!a || !b) throw Error("the true beam misses the PSD plane near a planned pose");
      jac.col(j) =
          Eigen::Vector2d(a->spot.u_mm - b->spot.u_mm, a->spot.v_mm - b->spot.v_mm) / (2 * h);
    }
    const Eigen::Matrix<double, kJointCount, 1> step =
        -jac.transpose() * (jac * jac.transpose()).ldlt().solve(r);
    for (int j = 0; j < kJointCount; ++j) q[j] += step[j];
  }
  throw Error("the simulated servo did not bring the spot to the PSD centre");
}

// A session on the world: the planned poses servoed, each recorded with the arm's
// repeatability error and the PSD's noise (no gross errors: the several-placement solve does
// not look for them).
std::vector<Pose> record(const World& world, const std::vector<SimPlacement>& placements,
                         const std::vector<Pose>& planned, std::mt19937_64& rng) {
  std::normal_distribution<double> normal;
  std::vector<Pose> out;
  double time_s = 0;
  int last_placement = planned.empty() ? 1 : planned.front().placement;
  for (const Pose& p : planned) {
    if (p.placement != last_placement) time_s += 120;  // the technician moves the PSD
    last_placement = p.placement;
    World here = world;
    here.psd_position_mm = placements[p.placement - 1].centre;
    here.psd_rotation = placements[p.placement - 1].rotation;
    Pose rec = p;
    rec.q_deg = servoToCentre(here, p.q_deg, time_s);
    Joints error{};
    for (double& e : error) e = world.noise.repeatability_deg * normal(rng);
    const auto hit = beamHit(here, rec.q_deg, error, time_s);
    if (!hit) throw Error("the true beam misses the PSD at a recorded pose");
    rec.spot = PsdSpot{hit->spot.u_mm + world.noise.psd_mm * normal(rng),
                       hit->spot.v_mm + world.noise.psd_mm * normal(rng)};
    out.push_back(rec);
    time_s += 15;
  }
  return out;
}

// One gross error put into a recorded session, at a pose drawn from `rng`: returns its index.
int injectGrossError(std::vector<Pose>& poses, const PlacementExperimentArgs& args,
                     std::mt19937_64& rng) {
  std::uniform_int_distribution<int> which_pose(0, static_cast<int>(poses.size()) - 1),
      which_joint(1, 4);
  std::uniform_real_distribution<double> angle(0, 2 * kPi);
  const int bad = which_pose(rng);
  if (args.gross == "spot") {
    const double a = angle(rng);
    poses[bad].spot->u_mm += args.gross_spot_mm * std::cos(a);
    poses[bad].spot->v_mm += args.gross_spot_mm * std::sin(a);
  } else {
    const int joint = which_joint(rng);
    poses[bad].q_deg[joint] += angle(rng) < kPi ? args.gross_joint_deg : -args.gross_joint_deg;
  }
  return bad;
}

// What the gross-error search made of a session with one gross error at pose `bad`.
struct GrossTally {
  int named = 0;    // the corrupted pose, and only it, left out; verdict usable
  int wrong = 0;    // another pose left out, or more than the corrupted one; verdict usable
  int refused = 0;  // verdict not usable
  int missed = 0;   // nothing left out, verdict usable
  void add(const SolveReport& r, int bad) {
    int left_out = 0;
    bool bad_left_out = false;
    for (std::size_t i = 0; i < r.poses.size(); ++i)
      if (r.poses[i].outlier) ++left_out, bad_left_out = bad_left_out || static_cast<int>(i) == bad;
    if (!r.verdict.usable)
      ++refused;
    else if (bad_left_out && left_out == 1)
      ++named;
    else if (left_out > 0)
      ++wrong;
    else
      ++missed;
  }
  nlohmann::json json() const {
    return {{"named", named}, {"wrong_pose", wrong}, {"refused", refused}, {"missed", missed}};
  }
};

struct Tally {
  std::vector<double> errors_deg;  // every estimate of delta2..delta5
  double worst_sigmas = 0;
  int within = 0, offered = 0, usable = 0, solved = 0;
  int usable_wrong = 0;  // usable results with an offset beyond max_sigmas of its truth
  double noise_scale_sum = 0;
  int compliances = 0;                   // compliance unknowns identified, over the sessions
  std::vector<double> identified_links;  // per session

  void add(const SolveReport& r, const World& world, double max_sigmas) {
    ++solved;
    usable += r.verdict.usable ? 1 : 0;
    int links = 0;
    for (std::size_t k = kIdentifiedCount; k < r.parameters.size(); ++k) {
      const bool compliance = r.parameters[k].name.rfind("compliance", 0) == 0;
      if (r.parameters[k].identifiable) ++(compliance ? compliances : links);
    }
    identified_links.push_back(links);
    noise_scale_sum += r.noise_scale;
    bool wrong = false;
    for (int k = 0; k < kOffsetCount; ++k) {
      const ParameterEstimate& p = r.parameters[k];
      const double error = p.value - world.true_offsets_deg[k + 1];
      errors_deg.push_back(error);
      const double sigmas = std::abs(error) / p.sigma;
      worst_sigmas = std::max(worst_sigmas, sigmas);
      within += sigmas <= max_sigmas ? 1 : 0;
      offered += p.identifiable ? 1 : 0;
      wrong = wrong || (p.identifiable && !(sigmas <= max_sigmas));
    }
    usable_wrong += r.verdict.usable && wrong ? 1 : 0;
  }
  double meanNoiseScale() const { return solved ? noise_scale_sum / solved : NAN; }
  double rms() const {
    double s = 0;
    for (double e : errors_deg) s += e * e;
    return errors_deg.empty() ? NAN : std::sqrt(s / errors_deg.size());
  }
  double meanLinks() const {
    double s = 0;
    for (double l : identified_links) s += l;
    return identified_links.empty() ? 0 : s / identified_links.size();
  }
  nlohmann::json json() const {
    return {{"sessions", solved},
            {"usable", usable},
            {"offsets", errors_deg.size()},
            {"offsets_offered", offered},
            {"within_3_sigma", within},
            {"worst_error_sigmas", worst_sigmas},
            {"rms_error_deg", rms()},
            {"mean_identified_link_errors", meanLinks()},
            {"compliances_identified", compliances},
            {"usable_with_an_offset_beyond_3_sigma", usable_wrong},
            {"mean_noise_scale", meanNoiseScale()}};
  }
};

}  // namespace

void addPlacementExperiment(CLI::App& experiment, PlacementExperimentArgs& args) {
  args.cmd = experiment.add_subcommand(
      "placements",
      "calibrations from several PSD placements (link errors identified) beside one placement "
      "with as many poses, on seeded simulated worlds; exit 0 when the several-placement "
      "sessions' RMS error of delta2..delta5 is within --max-rms and every offset within 3 "
      "reported sigmas, else 7");
  CLI::App* cmd = args.cmd;
  cmd->add_option("--worlds", args.worlds, "number of seeded worlds")
      ->default_val(args.worlds)
      ->check(CLI::Range(1, 10000));
  cmd->add_option("--seed0", args.seed0, "seed of the first world (then seed0+1, ...)")
      ->default_val(args.seed0);
  cmd->add_option("--placements", args.placements, "PSD placements of a session")
      ->default_val(args.placements)
      ->check(CLI::Range(2, kMaxDefaultPlacements));
  cmd->add_option("--poses", args.poses, "poses per placement")
      ->default_val(args.poses)
      ->check(CLI::Range(kMinimumPosesPerPlacement, 40));
  cmd->add_option("--noise", args.noise_mm, "measurement sigma given to the solve, mm")
      ->default_val(args.noise_mm)
      ->check(CLI::PositiveNumber);
  cmd->add_option("--max-rms", args.max_rms_deg,
                  "requirement: RMS error of delta2..delta5 with several placements, deg")
      ->default_val(args.max_rms_deg)
      ->check(CLI::PositiveNumber);
  cmd->add_flag("--ideal-world", args.ideal_world,
                "the seeds' ideal worlds instead of the realistic ones (docs/simulated-cell.md)");
  cmd->add_flag("--without-sag", args.without_sag,
                "the worlds without the gravity sag of joints 2 and 3, which the solve does not "
                "model (to see what it costs)");
  cmd->add_option("--link-scale", args.link_scale,
                  "the realistic worlds' link errors times this (2.5: links 2.5 times worse "
                  "than the robot file's tolerances, which the solve still counts)")
      ->default_val(args.link_scale)
      ->check(CLI::Range(0.0, 10.0));
  cmd->add_option("--sag-tolerance", args.model_sag_deg,
                  "the gravity sag's one-sigma tolerance at the largest torque, deg, of joints 2 "
                  "and 3 (or one for both), counted when the compliance is not identified, their "
                  "signs not stated (realistic worlds with their sag; default: the robot file's)")
      ->expected(1, 2)
      ->check(CLI::Range(0.0, 1.0));
  cmd->add_flag("--identify-compliance", args.identify_compliance,
                "identify the compliance of joints 2 and 3 (robot file's gravity model) instead "
                "of counting the sag as a tolerance");
  cmd->add_option("--gross", args.gross,
                  "one gross error per session at a random pose: spot (the reading 0.5 mm off) "
                  "or joint (one of joints 2..5 recorded 0.05 deg off); counts how often the "
                  "solve names the pose")
      ->default_val(args.gross)
      ->check(CLI::IsMember({"none", "spot", "joint"}));
  cmd->add_flag("--json", args.json, "print one JSON object instead of text");
}

int runPlacementExperiment(const PlacementExperimentArgs& args) {
  const WorldKind kind = args.ideal_world ? WorldKind::kIdeal : WorldKind::kRealistic;
  SolveOptions options;
  options.noise_mm = args.noise_mm;
  options.identify_compliance = args.identify_compliance;
  if (!args.ideal_world) {
    // What the robot file admits (the shipped IRB 1600's tolerances), the sag's as given.
    options.model = builtinIrb1600().tolerance;
    if (!args.model_sag_deg.empty() || args.without_sag) options.model.sag_mean_deg = {};
    if (!args.model_sag_deg.empty()) options.model.sag_deg = sagTolerancesOf(args.model_sag_deg);
    if (args.without_sag) options.model.sag_deg = {};
  }
  Tally several, one;
  GrossTally gross_several, gross_one;
  nlohmann::json per_world = nlohmann::json::array();
  for (int w = 0; w < args.worlds; ++w) {
    const std::uint64_t seed = args.seed0 + static_cast<std::uint64_t>(w);
    World world = randomWorld(seed, kind);
    if (args.without_sag) world.compliance = Compliance{};
    for (DhError& e : world.dh_errors) {
      e.a_mm *= args.link_scale;
      e.d_mm *= args.link_scale;
      e.alpha_deg *= args.link_scale;
    }
    const std::vector<SimPlacement> placements =
        placementsOf(world, args.placements, seed, args.ideal_world);
    // What the session knows: the nominal robot and laser, the taught centres and the
    // configured orientations.
    CellModel known{world.robot,
                    LaserModel(Eigen::Vector3d::UnitX(), Eigen::Vector3d::Zero()),
                    placements[0].configured,
                    {}};
    for (std::size_t p = 1; p < placements.size(); ++p)
      known.placement_rotations.push_back(placements[p].configured);
    PlanOptions plan_options;
    plan_options.poses = args.poses;
    plan_options.noise_mm = args.noise_mm;
    for (std::size_t p = 1; p < placements.size(); ++p)
      plan_options.more_placements.push_back(placements[p].taught);
    const Plan plan = planPoses(known, placements[0].taught, plan_options);
    PlanOptions single_options = plan_options;
    single_options.more_placements.clear();
    single_options.poses = args.poses * args.placements;
    const Plan single_plan = planPoses(known, placements[0].taught, single_options);

    std::mt19937_64 rng(seed * 7919 + 17);
    std::vector<Pose> rec_several = record(world, placements, plan.poses, rng);
    std::vector<Pose> rec_one = record(world, placements, single_plan.poses, rng);
    // Its own stream: the recordings stay those of the clean sessions.
    std::mt19937_64 gross_rng(seed * 104729 + 3);
    const bool inject = args.gross != "none";
    const int bad_several = inject ? injectGrossError(rec_several, args, gross_rng) : -1;
    const int bad_one = inject ? injectGrossError(rec_one, args, gross_rng) : -1;
    const SolveReport r_several = solve(known, rec_several, options);
    const SolveReport r_one = solve(known, rec_one, options);
    several.add(r_several, world, args.max_sigmas);
    one.add(r_one, world, args.max_sigmas);
    if (inject) {
      gross_several.add(r_several, bad_several);
      gross_one.add(r_one, bad_one);
    }
    nlohmann::json row{{"seed", seed},
                       {"several_usable", r_several.verdict.usable},
                       {"one_usable", r_one.verdict.usable}};
    if (inject) {
      row["gross_pose"] = {bad_several + 1, bad_one + 1};
      for (const auto& [key, r] :
           {std::pair<const char*, const SolveReport*>{"several", &r_several}, {"one", &r_one}})
        for (const SuspectPose& sp : r->suspect_poses)
          row[std::string(key) + "_suspects"].push_back(
              {{"pose", sp.pose}, {"chi2_without", sp.chi2_without}});
    }
    for (int k = 0; k < kOffsetCount; ++k) {
      const double truth = world.true_offsets_deg[k + 1];
      row["several_error_deg"].push_back(r_several.parameters[k].value - truth);
      row["several_sigma_deg"].push_back(r_several.parameters[k].sigma);
      row["one_error_deg"].push_back(r_one.parameters[k].value - truth);
      row["one_sigma_deg"].push_back(r_one.parameters[k].sigma);
    }
    if (r_several.chi2_per_dof) row["several_chi2_per_dof"] = *r_several.chi2_per_dof;
    per_world.push_back(row);
  }
  const bool ok = several.rms() <= args.max_rms_deg &&
                  several.within == static_cast<int>(several.errors_deg.size());
  if (args.json) {
    nlohmann::json j{{"worlds", args.worlds},
                     {"seed0", args.seed0},
                     {"world", args.ideal_world ? "ideal" : "realistic"},
                     {"without_sag", args.without_sag},
                     {"link_scale", args.link_scale},
                     {"identify_compliance", args.identify_compliance},
                     {"sag_tolerance_deg", options.model.sag_deg},
                     {"sag_mean_deg", options.model.sag_mean_deg},
                     {"placements", args.placements},
                     {"poses_per_placement", args.poses},
                     {"noise_mm", args.noise_mm},
                     {"several_placements", several.json()},
                     {"one_placement", one.json()},
                     {"requirements_met", ok},
                     {"gross", args.gross},
                     {"per_world", per_world}};
    if (args.gross != "none") {
      j["several_placements"]["gross_errors"] = gross_several.json();
      j["one_placement"]["gross_errors"] = gross_one.json();
    }
    std::cout << j.dump(2) << "\n";
  } else {
    std::printf(
        "%d %s worlds%s from seed %llu; %d placements x %d poses against one placement "
        "with %d poses; noise %.3f mm given%s\n",
        args.worlds, args.ideal_world ? "ideal" : "realistic",
        args.without_sag ? " without gravity sag" : "", static_cast<unsigned long long>(args.seed0),
        args.placements, args.poses, args.placements * args.poses, args.noise_mm,
        args.ideal_world ? "" : ", the robot file's link tolerances counted");
    if (args.link_scale != 1.0)
      std::printf("the worlds' link errors %.2f times their realistic size\n", args.link_scale);
    if (anyCounted(options.model.sag_deg))
      std::printf(
          "gravity sag of joints 2 and 3 counted as tolerances of %.4f and %.4f deg "
          "(means %.4f and %.4f deg)\n",
          options.model.sag_deg[0], options.model.sag_deg[1], options.model.sag_mean_deg[0],
          options.model.sag_mean_deg[1]);
    if (args.identify_compliance) std::printf("compliance of joints 2 and 3 identified\n");
    std::printf("%-22s %8s %8s %10s %14s %12s %14s %12s %12s\n", "session", "usable", "offered",
                "within 3s", "worst (sigma)", "RMS (deg)", "links ident.", "noise scale",
                "usable>3s");
    for (const auto& [name, t] :
         {std::pair<const char*, const Tally*>{"several placements", &several},
          {"one placement", &one}}) {
      std::cout << fmt::format(
                       FMT_STRING("{:<22} {:5d}/{:<2d} {:5d}/{:<3d} {:6d}/{:<3d} {:14.2f} {:12.5f} "
                                  "{:14.1f} {:12.2f} {:12d}"),
                       name, t->usable, t->solved, t->offered, t->errors_deg.size(), t->within,
                       t->errors_deg.size(), t->worst_sigmas, t->rms(), t->meanLinks(),
                       t->meanNoiseScale(), t->usable_wrong)
                << "\n";
    }
    if (args.gross != "none") {
      std::printf("one gross error per session (%s): %-22s %8s %8s %8s %8s\n",
                  args.gross == "spot" ? "the reading 0.5 mm off" : "a joint 0.05 deg off", "",
                  "named", "wrong", "refused", "missed");
      for (const auto& [name, g] :
           {std::pair<const char*, const GrossTally*>{"several placements", &gross_several},
            {"one placement", &gross_one}})
        std::printf("  %-22s %8d %8d %8d %8d\n", name, g->named, g->wrong, g->refused, g->missed);
    }
    std::printf(
        "requirement (several placements: RMS <= %.4f deg, every offset within %.0f "
        "sigma): %s\n",
        args.max_rms_deg, args.max_sigmas, ok ? "met" : "NOT MET");
  }
  return ok ? 0 : kRequirementNotMet;
}

}  // namespace zerocal::lab
