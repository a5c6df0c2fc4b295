// zerocal-lab experiment apply: on seeded simulated cells, calibrate, apply online, verify by a
// second calibration, and (with --wrong-sign J) check that a transmission sign wrong in the
// configuration is caught, rolled back and named. The whole production chain: zerocald's session
// manager and sim backend driving the simulated controller over TCP through Irc5Client.
#include "apply_experiment.h"

#include <fmt/printf.h>
#include <unistd.h>

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <optional>

#include "zerocal/apply/online_apply.h"
#include "zerocal/daemon/config.h"
#include "zerocal/irc5/irc5_client.h"
#include "zerocal/model/builtin.h"
#include "zerocal/service/daemon_setup.h"
#include "zerocal/service/session_manager.h"
#include "zerocal/sim/sim_controller.h"

namespace zerocal::lab {

namespace {

constexpr double kDegPerRad = 57.29577951308232;

std::string f(const char* spec, double a, double b = 0, double c = 0, double d = 0) {
  return fmt::sprintf(spec, a, b, c, d);
}

struct WorldRun {
  std::uint64_t seed = 0;
  apply::OnlineApplyOutcome outcome;
  apply::Offsets before{};
  Joints true_after_deg{};  // the simulated truth after it all
  Joints true_at_verify{};  // the simulated truth while the verification measured
  bool verify_ran = false;
  int seams = 0;
};

WorldRun runWorld(std::uint64_t seed, const ApplyExperimentArgs& args, const std::string& dir,
                  std::ostream& out) {
  SimControllerOptions so;
  // The seed's ideal world: on the realistic one the verdict withholds offsets an 8-pose
  // calibration does not determine to the required accuracy, and nothing is applied
  // (docs/apply.md).
  so.world = randomWorld(seed, WorldKind::kIdeal);
  so.seed = seed;
  SimController sim(so);
  sim.start();

  DaemonConfig config;
  config.backend.kind = BackendKind::kSim;
  config.backend.sim_seed = seed;
  config.backend.sim_ideal_world = true;
  config.backend.sim_host = "127.0.0.1";
  config.backend.sim_port = sim.port();
  config.servo.settle_s = 0.0;
  config.session.data_dir = dir + "/sessions";
  config.session.poses = args.poses;
  const std::unique_ptr<CellBackend> backend = service::makeBackend(config);
  service::SessionManager manager(*backend, service::managerSettingsOf(config));
  // The verification is planned around the PSD centre the calibration found (result.json
  // target_mm), not the taught one, and predicts the spot from the laser line it found, as the
  // daemon's own verification does: it knows the cell better.
  std::optional<CalibrationParameters> found;
  const auto calibrate = [&]() {
    service::StartRequest request = manager.defaultRequest();
    request.poses = args.poses;
    request.even_if_not_usable = true;  // measured whatever its plan predicts
    if (found) {
      request.target_mm = found->target_mm;
      request.found_before = found;
    }
    const std::string id = manager.start(request);
    const service::SessionStatus end = manager.waitIdle();
    if (end.state != service::SessionState::kDone)
      throw Error("world " + std::to_string(seed) + ": calibration " + id +
                  " ended: " + end.message);
    const SolveReport r = manager.result(id).report;
    apply::Offsets o;
    for (int k = 0; k < 4; ++k) {
      const ParameterEstimate& p = r.parameters[k];  // delta2..delta5
      if (!p.identifiable)
        throw Error("world " + std::to_string(seed) + ": delta" + std::to_string(k + 2) +
                    " not identifiable");
      o[k] = {p.value, p.sigma};
    }
    if (!found) found = r.estimate;
    return o;
  };

  WorldRun run;
  run.seed = seed;
  run.before = calibrate();
  Irc5Options link_options;
  link_options.host = "127.0.0.1";
  link_options.port = sim.port();
  link_options.robot = so.world.robot;
  Irc5Client link(link_options);
  link.connect();
  ControllerCalibration& store = link;
  std::array<double, 6> transmission = builtinIrb1600().transmission;
  if (args.wrong_sign_joint > 0) transmission[args.wrong_sign_joint - 1] *= -1;
  const std::array<double, 6> present = link.readCalOffsets();
  std::array<apply::CalOffsetChange, 4> changes;
  for (int j = 2; j <= 5; ++j) {
    changes[j - 2] = apply::calOffsetChange(j, run.before[j - 2].value_deg / kDegPerRad,
                                            transmission[j - 1], present[j - 1]);
    run.seams += changes[j - 2].crossesSeam();
  }
  apply::OnlineApplyOptions options;
  options.required_deg = args.required_deg;
  options.verify = [&]() {
    for (int i = 0; i < kJointCount; ++i)
      run.true_at_verify[i] = so.world.true_offsets_deg[i] + sim.zeroShiftDeg()[i];
    run.verify_ran = true;
    // What remains is the first calibration's error measured by the second: its standard
    // uncertainty combines both.
    apply::Offsets after = calibrate();
    for (int k = 0; k < 4; ++k)
      after[k].sigma_deg = std::hypot(run.before[k].sigma_deg, after[k].sigma_deg);
    return after;
  };
  options.update_revolution_counter = [&](int joint, double) {
    sim.updateRevolutionCounter(joint);  // the technician at the synchronisation mark
    return true;
  };
  apply::ApplyJournal journal(dir + "/apply-" + std::to_string(seed) + ".jsonl");
  run.outcome = apply::applyOnline(store, changes, run.before, options, journal);
  for (int i = 0; i < kJointCount; ++i)
    run.true_after_deg[i] = so.world.true_offsets_deg[i] + sim.zeroShiftDeg()[i];
  out << "world " << seed << ": "
      << (run.outcome.state == apply::ApplyState::kVerified ? "verified" : "rolled back") << " ("
      << run.seams << " seam crossing" << (run.seams == 1 ? "" : "s")
      << "): " << run.outcome.message << "\n";
  for (int k = 0; k < 4; ++k)
    out << "  delta" << k + 2
        << f(": identified %+.4f deg (sigma %.4f); after: measured %+.5f (sigma %.5f)",
             run.before[k].value_deg, run.before[k].sigma_deg, run.outcome.after[k].value_deg,
             run.outcome.after[k].sigma_deg)
        << f(", true then %+.5f, true now %+.5f deg\n", run.true_at_verify[k + 1],
             run.true_after_deg[k + 1]);
  return run;
}

}  // namespace

int runApplyExperiment(const ApplyExperimentArgs& args, std::ostream& out, std::ostream& err) {
  char pattern[] = "/tmp/zerocal-apply-experiment-XXXXXX";
  if (!::mkdtemp(pattern)) {
    err << "zerocal-lab experiment apply: cannot make a temporary folder\n";
    return 1;
  }
  const std::string dir = pattern;
  out << "zerocal-lab experiment apply: " << args.worlds << " seeded simulated worlds from seed "
      << args.seed0 << ", " << args.poses << " poses per calibration, transmission "
      << (args.wrong_sign_joint > 0
              ? "of joint " + std::to_string(args.wrong_sign_joint) + " with its sign WRONG"
              : std::string("as the robot model's"))
      << "; pass: every remaining offset within max(3 sigma, " << args.required_deg << " deg)\n";
  std::vector<WorldRun> runs;
  int failed = 0;
  for (int w = 0; w < args.worlds; ++w) {
    try {
      runs.push_back(runWorld(args.seed0 + w, args, dir + "/" + std::to_string(w), out));
    } catch (const std::exception& e) {
      ++failed;
      out << "world " << args.seed0 + w << ": FAILED: " << e.what() << "\n";
    }
  }
  if (runs.empty()) {
    err << "zerocal-lab experiment apply: no world ran (files kept in " << dir << ")\n";
    return 1;
  }
  bool holds = true;
  double sum_measured = 0, sum_true = 0, sum_z = 0;
  int n = 0, within = 0, named = 0, restored = 0, harmless = 0;
  for (const WorldRun& r : runs) {
    const bool verified = r.outcome.state == apply::ApplyState::kVerified;
    const bool measured = r.outcome.after[0].sigma_deg > 0;  // the verification ran
    for (int k = 0; k < 4 && measured; ++k) {
      const double m = r.outcome.after[k].value_deg, t = r.true_after_deg[k + 1];
      sum_measured += m * m;
      sum_true += t * t;
      // The calibration's own error, in its sigmas: what the verification could at best see.
      const double z = r.true_at_verify[k + 1] / r.before[k].sigma_deg;
      sum_z += z * z;
      ++n;
      within += std::abs(m) <= 3 * std::hypot(r.before[k].sigma_deg, r.outcome.after[k].sigma_deg);
    }
    if (args.wrong_sign_joint > 0) {
      // An offset within its sigma of zero stays there whatever the sign: no measurement can
      // see the wrong sign, and none is needed (world 9's delta2 is -0.0008 deg).
      const int k = args.wrong_sign_joint - 2;
      const double doubled = 2 * std::abs(r.before[k].value_deg);
      if (verified &&
          doubled <= 3 * std::hypot(r.before[k].sigma_deg, r.outcome.after[k].sigma_deg)) {
        ++harmless;
        continue;
      }
      named += !verified &&
               r.outcome.message.find("joint " + std::to_string(args.wrong_sign_joint) + "'s") !=
                   std::string::npos;
      bool back = true;
      for (int i = 0; i < kJointCount; ++i)
        back =
            back && std::abs(r.true_after_deg[i] - randomWorld(r.seed).true_offsets_deg[i]) < 1e-5;
      restored += !verified && back;
    } else {
      holds = holds && verified;
    }
  }
  const double rms_measured = n > 0 ? std::sqrt(sum_measured / n) : 0.0;
  const double rms_true = n > 0 ? std::sqrt(sum_true / n) : 0.0;
  out << "\nremaining offsets after apply (joints 2..5, " << n << " values, as measured by the "
      << "verification): RMS " << f("%.5f deg", rms_measured)
      << "; within 3 sigma of zero: " << within << " of " << n << "\n";
  out << "the simulated truth of those worlds now (after any rollback): RMS "
      << f("%.5f deg", rms_true) << "\n";
  if (args.wrong_sign_joint == 0 && n > 0)
    out << "the first calibration's errors (true offset left while verifying) in units of its "
           "sigma: RMS "
        << f("%.2f", std::sqrt(sum_z / n)) << " (1 when the sigmas are right)\n";
  if (args.wrong_sign_joint > 0) {
    const int judged = static_cast<int>(runs.size()) - harmless;
    out << "rolled back with joint " << args.wrong_sign_joint << " named: " << named << " of "
        << judged << "; controller back to its backed-up values: " << restored << " of " << judged
        << "\n";
    if (harmless > 0)
      out << harmless << " world(s) verified: joint " << args.wrong_sign_joint
          << "'s offset is within 3 sigma of zero, so its sign changes nothing measurable\n";
    holds = named == judged && restored == judged;
  } else {
    out << "verified: " << (holds ? "all" : "NOT all") << " worlds\n";
    // The requirement is on the robot: what remains in it, which the simulation knows. The
    // verification's measurement of it carries the verification's own noise (delta2's sigma is
    // about 0.0035 deg on 8 poses), so its RMS is no bound on the robot's; it must only be
    // consistent with zero.
    holds = holds && rms_true <= args.required_deg && within == n;
  }
  if (failed > 0) out << failed << " world(s) could not be calibrated before the apply\n";
  holds = holds && failed == 0;
  out << (holds ? "requirements hold\n" : "REQUIREMENTS DO NOT HOLD\n");
  std::filesystem::remove_all(dir);
  return holds ? 0 : 7;
}

void addApplyExperiment(CLI::App& experiment, ApplyExperimentArgs& e) {
  e.cmd = experiment.add_subcommand(
      "apply",
      "on seeded simulated cells: calibrate, apply online (backup, write, restart), verify by a "
      "second calibration; with --wrong-sign J, check the rollback names joint J");
  auto* x = e.cmd;
  x->add_option("--worlds", e.worlds, "number of seeded worlds")
      ->default_val(e.worlds)
      ->check(CLI::Range(1, 1000));
  x->add_option("--seed0", e.seed0, "seed of the first world")->default_val(e.seed0);
  e.poses = SessionConfig{}.poses;  // as the daemon calibrates and verifies
  x->add_option("--poses", e.poses, "poses per calibration (the daemon's session.poses)")
      ->default_val(e.poses);
  x->add_option("--wrong-sign", e.wrong_sign_joint,
                "flip joint J's transmission sign in the configuration (2..5)")
      ->check(CLI::Range(2, 5));
  x->add_option("--required", e.required_deg, "required accuracy, deg")
      ->default_val(e.required_deg);
}

}  // namespace zerocal::lab
