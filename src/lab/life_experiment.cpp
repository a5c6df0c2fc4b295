// zerocal-lab experiment life: per seeded world, a robot's life as zerocald runs it, each session
// on a backend and a session manager of its own in one data folder (as consecutive `zerocald
// --sim --once` runs are: each its own noise, the arm as warm as configured), the truth of each
// from its result.json.
#include "life_experiment.h"

#include <fmt/format.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <iostream>
#include <nlohmann/json.hpp>
#include <random>

#include "cell_experiment.h"
#include "experiment_sessions.h"
#include "zerocal/error.h"
#include "zerocal/service/daemon_setup.h"
#include "zerocal/sim/world.h"
#include "zerocal/sim/zero_change.h"

namespace zerocal::lab {
namespace {

using Json = nlohmann::json;
constexpr const char* kOrigin = "zerocal-lab experiment life";

DaemonConfig configOf(const LifeExperimentArgs& args) {
  std::vector<std::string> problems;
  const auto range = [&](const char* name, double v, double lo, double hi) {
    if (!(v >= lo && v <= hi))
      problems.push_back(std::string(name) + ": " + std::to_string(v) + " given, must be within " +
                         std::to_string(lo) + ".." + std::to_string(hi));
  };
  range("--reference-warm-s", args.reference_warm_s, 0, kMaxWarmS);
  range("--check-warm-s", args.check_warm_s, 0, kMaxWarmS);
  range("--restore-warm-s", args.restore_warm_s, 0, kMaxWarmS);
  range("--check-change", args.check_change_deg, 1e-6, kMaxZeroChangeDeg);
  range("--restore-change-min", args.restore_min_deg, 1e-6, kMaxZeroChangeDeg);
  range("--restore-change-max", args.restore_max_deg, args.restore_min_deg, kMaxZeroChangeDeg);
  return experimentConfig(
      kOrigin, args.ideal_world, args.overrides,
      {"backend.kind", "backend.sim_seed", "backend.sim_world", "backend.sim_warm_s",
       "backend.sim_zero_change_joint", "backend.sim_zero_change_deg", "session.data_dir"},
      "the world from --seed0 and --worlds, the arm's warm-up from --reference-warm-s, "
      "--check-warm-s and --restore-warm-s, the zeros' changes from --check-change, "
      "--restore-change-min and --restore-change-max",
      problems);
}

// The arm's thermal growth (every length's, relative) when a session starts warm_s into the
// controller's time: ThermalDrift's law, for the table.
double growthAt(const World& world, double warm_s) {
  const ThermalDrift& t = world.thermal;
  if (!(t.time_constant_s > 0)) return 0;
  return t.expansion_per_k * t.rise_k * (1 - std::exp(-warm_s / t.time_constant_s));
}

const char* verdictWord(bool ok) { return ok ? "ok" : "FAIL"; }

}  // namespace

void addLifeExperiment(CLI::App& experiment, LifeExperimentArgs& args) {
  CLI::App* cmd = args.cmd = experiment.add_subcommand(
      "life",
      "a robot's life on the simulated cell, one per seeded world, as zerocald runs it: a "
      "reference (warm), a check with nothing changed, a check with one zero moved by 0.02 deg, "
      "a restore with one zero moved by 0.05..1 deg (cold) and its online apply; exit 0 when "
      "the figures a robot's record must meet hold (restore RMS <= 0.003 deg, each within 3 sigma, "
      "95% coverage 93..97%, usable >= 95%, <= 90 s; checks PASS and named >= 95%, <= 30 s; after "
      "the apply the true zeros within 0.003 deg RMS of the reference's), else 7");
  addSeededWorldOptions(cmd, args.worlds, args.seed0, args.overrides, args.json, args.ideal_world);
  cmd->add_option("--reference-warm-s", args.reference_warm_s,
                  "the arm's warm-up when the reference is taken (backend.sim_warm_s, s)")
      ->default_val(args.reference_warm_s);
  cmd->add_option("--check-warm-s", args.check_warm_s, "... when the checks are taken")
      ->default_val(args.check_warm_s);
  cmd->add_option("--restore-warm-s", args.restore_warm_s, "... when the restore is taken")
      ->default_val(args.restore_warm_s);
  cmd->add_option("--check-change", args.check_change_deg,
                  "deg the second check's zero is moved by (joint 2 + seed % 4)")
      ->default_val(args.check_change_deg);
  cmd->add_option("--restore-change-min", args.restore_min_deg,
                  "smallest change of the restore's zero (deg; its size drawn uniformly up to "
                  "--restore-change-max, its joint and sign drawn too)")
      ->default_val(args.restore_min_deg);
  cmd->add_option("--restore-change-max", args.restore_max_deg,
                  "largest change of the restore's zero (deg)")
      ->default_val(args.restore_max_deg);
}

int runLifeExperiment(const LifeExperimentArgs& args) {
  const DaemonConfig config = configOf(args);
  const ExperimentDir dir("zerocal-life");
  Json worlds = Json::array();
  int failed = 0;  // worlds where a session did not complete
  // Checks.
  int checks_unchanged = 0, passed = 0, checks_changed = 0, named = 0, other_named = 0;
  double max_check_s = 0;
  // Restores: each offset's error against the true change, in deg and in its reported sigmas.
  int restores = 0, usable = 0, estimates = 0, covered = 0, beyond_sigmas = 0;
  double restore_sq = 0, worst_sigmas = 0, max_restore_s = 0;
  // The applies, and the arm's true zeros after them against the reference's.
  int applies = 0, verified = 0, after_count = 0;
  double after_sq = 0, after_worst = 0;
  if (!args.json)
    std::printf("%6s %7s  %-8s %5s  %-18s %5s  %-10s %-48s %6s %6s  %-12s %9s\n", "seed", "dL_ppm",
                "check", "s", "check changed", "s", "restore",
                "error deg (sigmas) of delta2..delta5", "usable", "s", "apply", "after_deg");

  for (int w = 0; w < args.worlds; ++w) {
    const std::uint64_t seed = args.seed0 + static_cast<std::uint64_t>(w);
    DaemonConfig base = config;
    base.backend.kind = BackendKind::kSim;
    base.backend.sim_seed = seed;
    base.session.data_dir = dir.path() + "/" + std::to_string(seed);
    const World world = randomWorld(
        seed, config.backend.sim_ideal_world ? WorldKind::kIdeal : WorldKind::kRealistic);
    // Warmer reference: the restore's arm is shorter by this much (ppm of every length).
    const double growth_ppm =
        1e6 * (growthAt(world, args.reference_warm_s) - growthAt(world, args.restore_warm_s));
    Json row{{"seed", seed}, {"growth_difference_ppm", growth_ppm}};
    const auto sessionConfig = [&](double warm_s, int joint, double deg) {
      DaemonConfig c = base;
      c.backend.sim_warm_s = warm_s;
      c.backend.sim_zero_change_joint = joint;
      c.backend.sim_zero_change_deg = deg;
      return c;
    };
    const int check_joint = 2 + static_cast<int>(seed % 4);
    const double check_deg = (seed / 4) % 2 == 0 ? args.check_change_deg : -args.check_change_deg;
    std::mt19937_64 draw(seed ^ 0x726573746f7265ull);  // "restore"
    const int restore_joint = std::uniform_int_distribution<int>(2, 5)(draw);
    const double restore_deg =
        std::uniform_real_distribution<double>(args.restore_min_deg, args.restore_max_deg)(draw) *
        (std::bernoulli_distribution(0.5)(draw) ? 1 : -1);

    std::string stopped;  // the first session that did not complete
    const ExperimentSession reference = runExperimentSession(
        sessionConfig(args.reference_warm_s, 0, 0), SessionKind::kReference, false);
    if (!reference.completed) stopped = reference.message;
    ExperimentSession unchanged, changed, restore;
    if (stopped.empty()) {
      unchanged =
          runExperimentSession(sessionConfig(args.check_warm_s, 0, 0), SessionKind::kCheck, false);
      if (!unchanged.completed || !unchanged.result.check) stopped = unchanged.message;
    }
    if (stopped.empty()) {
      changed = runExperimentSession(sessionConfig(args.check_warm_s, check_joint, check_deg),
                                     SessionKind::kCheck, false);
      if (!changed.completed || !changed.result.check) stopped = changed.message;
    }
    if (stopped.empty()) {
      restore = runExperimentSession(sessionConfig(args.restore_warm_s, restore_joint, restore_deg),
                                     SessionKind::kRestore, true);
      if (!restore.completed) stopped = restore.message;
    }
    if (!stopped.empty()) {
      ++failed;
      row["message"] = stopped;
      if (!args.json)
        std::printf("%6llu %7.1f  %s\n", static_cast<unsigned long long>(seed), growth_ppm,
                    stopped.c_str());
      worlds.push_back(row);
      continue;
    }
    const std::array<double, kOffsetCount>& reference_truth = reference.result.truth->offsets_deg;

    // The checks: nothing changed should pass; one zero moved should be named.
    const CheckJudgement& c0 = *unchanged.result.check;
    const CheckJudgement& c1 = *changed.result.check;
    ++checks_unchanged;
    passed += c0.outcome == CheckJudgement::Outcome::kPass;
    ++checks_changed;
    const bool named_it =
        c1.outcome == CheckJudgement::Outcome::kChanged &&
        std::find(c1.joints.begin(), c1.joints.end(), check_joint) != c1.joints.end();
    named += named_it;
    other_named +=
        c1.outcome == CheckJudgement::Outcome::kChanged &&
        std::any_of(c1.joints.begin(), c1.joints.end(), [&](int j) { return j != check_joint; });
    max_check_s = std::max({max_check_s, unchanged.cell_time_s, changed.cell_time_s});
    row["check"] = {{"outcome", checkOutcomeName(c0.outcome)},
                    {"joints", c0.joints},
                    {"cell_time_s", unchanged.cell_time_s},
                    {"poses", unchanged.result.report.poses.size()}};
    row["check_changed"] = {{"joint", check_joint},
                            {"change_deg", check_deg},
                            {"outcome", checkOutcomeName(c1.outcome)},
                            {"joints", c1.joints},
                            {"named", named_it},
                            {"cell_time_s", changed.cell_time_s}};

    // The restore: its change against the true change (the truth of its world less the
    // reference's).
    ++restores;
    const SolveReport& r = restore.result.report;
    const bool restore_usable = r.verdict.usable;
    usable += restore_usable;
    max_restore_s = std::max(max_restore_s, restore.cell_time_s);
    const std::array<double, kOffsetCount> truth =
        offsetDifference(restore.result.truth->offsets_deg, reference_truth);
    Json offsets = Json::array();
    std::string errors;
    for (int k = 0; k < kOffsetCount; ++k) {
      const ParameterEstimate& e = r.parameters[k];
      if (!std::isfinite(e.value) || !(e.sigma > 0) || !std::isfinite(e.sigma)) {
        errors += "      n/a    ";
        ++beyond_sigmas;  // no sigma: not within any
        continue;
      }
      const double error = e.value - truth[k];
      const double sigmas = std::abs(error) / e.sigma;
      const bool inside = e.ci95_low <= truth[k] && truth[k] <= e.ci95_high;
      restore_sq += error * error;
      ++estimates;
      covered += inside;
      beyond_sigmas += sigmas > args.max_sigmas;
      worst_sigmas = std::max(worst_sigmas, sigmas);
      offsets.push_back({{"name", unknownName(k)},
                         {"change_deg", e.value},
                         {"true_change_deg", truth[k]},
                         {"error_deg", error},
                         {"sigma_deg", e.sigma},
                         {"model_sigma_deg", e.model_sigma},
                         {"error_sigmas", sigmas},
                         {"covered_95", inside}});
      errors += fmt::format(FMT_STRING(" {:+.4f}({:3.1f})"), error, sigmas);
    }
    row["restore"] = {{"joint", restore_joint},
                      {"change_deg", restore_deg},
                      {"usable", restore_usable},
                      {"reasons", r.verdict.reasons},
                      {"cell_time_s", restore.cell_time_s},
                      {"poses", r.poses.size()},
                      {"noise_scale", r.noise_scale},
                      {"offsets", offsets}};

    // The apply: verified, the arm's zeros are the verification's truth; rolled back or not
    // applied, they are the restore's (the backup written back, or nothing written).
    ++applies;
    verified += restore.verified;
    const std::array<double, kOffsetCount> after =
        restore.verified && restore.verification && restore.verification->truth
            ? restore.verification->truth->offsets_deg
            : restore.result.truth->offsets_deg;
    const std::array<double, kOffsetCount> left = offsetDifference(after, reference_truth);
    double worst_left = 0;
    for (const double d : left) {
      after_sq += d * d;
      ++after_count;
      worst_left = std::max(worst_left, std::abs(d));
    }
    after_worst = std::max(after_worst, worst_left);
    row["apply"] = {{"status", restore.apply},
                    {"verified", restore.verified},
                    {"zeros_after_less_reference_deg", left}};
    if (!args.json) {
      const std::string check_changed =
          fmt::format(FMT_STRING("j{} {:+.3f} {}"), check_joint, check_deg,
                      named_it ? "named" : checkOutcomeName(c1.outcome));
      const std::string change = fmt::format(FMT_STRING("j{} {:+.3f}"), restore_joint, restore_deg);
      std::printf("%6llu %7.1f  %-8s %5.1f  %-18s %5.1f  %-10s %-48s %6s %6.1f  %-12s %9.5f\n",
                  static_cast<unsigned long long>(seed), growth_ppm, checkOutcomeName(c0.outcome),
                  unchanged.cell_time_s, check_changed.c_str(), changed.cell_time_s, change.c_str(),
                  errors.c_str(), restore_usable ? "yes" : "NO", restore.cell_time_s,
                  restore.verified ? "verified" : "NOT verified", worst_left);
    }
    worlds.push_back(row);
  }

  const auto share = [](int n, int of) { return of > 0 ? static_cast<double>(n) / of : 0.0; };
  const double restore_rms = estimates > 0 ? std::sqrt(restore_sq / estimates) : 0.0;
  const double coverage = share(covered, estimates);
  const double after_rms = after_count > 0 ? std::sqrt(after_sq / after_count) : 0.0;
  // A 93..97% band is a statement about many intervals: at 120 (30 worlds) one binomial standard
  // deviation is 2%, at a few it is chance alone. Below 100 the coverage is shown, not judged.
  constexpr int kCoverageJudgedFrom = 100;
  const bool coverage_judged = estimates >= kCoverageJudgedFrom;
  const bool all = failed == 0;
  const bool rms_ok = all && restore_rms <= args.max_restore_rms_deg;
  const bool sigmas_ok = all && beyond_sigmas == 0;
  const bool coverage_ok =
      all && (!coverage_judged || (coverage >= args.min_coverage && coverage <= args.max_coverage));
  const bool usable_ok = all && share(usable, restores) >= args.min_usable_share;
  const bool restore_time_ok = all && max_restore_s <= args.max_restore_cell_time_s;
  const bool pass_ok = all && share(passed, checks_unchanged) >= args.min_pass_share;
  const bool named_ok = all && share(named, checks_changed) >= args.min_named_share;
  const bool check_time_ok = all && max_check_s <= args.max_check_cell_time_s;
  const bool after_ok = all && after_rms <= args.max_after_apply_rms_deg;
  const bool pass = rms_ok && sigmas_ok && coverage_ok && usable_ok && restore_time_ok && pass_ok &&
                    named_ok && check_time_ok && after_ok;

  if (args.json) {
    std::cout << Json{{"worlds", worlds},
                      {"seed0", args.seed0},
                      {"world", config.backend.sim_ideal_world ? "ideal" : "realistic"},
                      {"warm_s",
                       {{"reference", args.reference_warm_s},
                        {"check", args.check_warm_s},
                        {"restore", args.restore_warm_s}}},
                      {"failed_worlds", failed},
                      {"restore",
                       {{"rms_error_deg", restore_rms},
                        {"worst_error_sigmas", worst_sigmas},
                        {"beyond_max_sigmas", beyond_sigmas},
                        {"coverage_95", coverage},
                        {"coverage_judged", coverage_judged},
                        {"estimates", estimates},
                        {"usable_share", share(usable, restores)},
                        {"max_cell_time_s", max_restore_s}}},
                      {"check",
                       {{"pass_share", share(passed, checks_unchanged)},
                        {"named_share", share(named, checks_changed)},
                        {"other_joint_named", other_named},
                        {"max_cell_time_s", max_check_s}}},
                      {"apply",
                       {{"verified_share", share(verified, applies)},
                        {"rms_zeros_after_less_reference_deg", after_rms},
                        {"worst_zero_after_less_reference_deg", after_worst}}},
                      {"requirements",
                       {{"max_restore_rms_deg", args.max_restore_rms_deg},
                        {"max_error_sigmas", args.max_sigmas},
                        {"coverage_95", {args.min_coverage, args.max_coverage}},
                        {"min_usable_share", args.min_usable_share},
                        {"max_restore_cell_time_s", args.max_restore_cell_time_s},
                        {"min_pass_share", args.min_pass_share},
                        {"min_named_share", args.min_named_share},
                        {"max_check_cell_time_s", args.max_check_cell_time_s},
                        {"max_after_apply_rms_deg", args.max_after_apply_rms_deg}}},
                      {"pass", pass}}
                     .dump(2)
              << "\n";
    return pass ? 0 : kRequirementNotMet;
  }
  std::printf(
      "\n%d worlds from seed %llu (%s), %d did not complete; the arm warm for %.0f s at the "
      "reference, %.0f s at the checks, %.0f s at the restore (dL_ppm: how much longer every link "
      "was at the reference than at the restore)\n",
      args.worlds, static_cast<unsigned long long>(args.seed0),
      config.backend.sim_ideal_world ? "ideal" : "realistic", failed, args.reference_warm_s,
      args.check_warm_s, args.restore_warm_s);
  std::printf("restore  RMS error        %.5f deg (<= %.3f)  %s\n", restore_rms,
              args.max_restore_rms_deg, verdictWord(rms_ok));
  std::printf("restore  within 3 sigma   %d of %d offsets beyond %.1f sigma, worst %.2f  %s\n",
              beyond_sigmas, estimates, args.max_sigmas, worst_sigmas, verdictWord(sigmas_ok));
  std::printf("restore  95%% coverage     %.1f%% of %d offsets (%.0f..%.0f%%)  %s\n",
              100 * coverage, estimates, 100 * args.min_coverage, 100 * args.max_coverage,
              coverage_judged ? verdictWord(coverage_ok) : "not judged: fewer than 100 offsets");
  std::printf("restore  usable           %d of %d (%.1f%%, >= %.0f%%)  %s\n", usable, restores,
              100 * share(usable, restores), 100 * args.min_usable_share, verdictWord(usable_ok));
  std::printf("restore  max cell time    %.1f s (<= %.0f)  %s\n", max_restore_s,
              args.max_restore_cell_time_s, verdictWord(restore_time_ok));
  std::printf("check    no change PASS   %d of %d (%.1f%%, >= %.0f%%)  %s\n", passed,
              checks_unchanged, 100 * share(passed, checks_unchanged), 100 * args.min_pass_share,
              verdictWord(pass_ok));
  std::printf(
      "check    %.3f deg named   %d of %d (%.1f%%, >= %.0f%%)  %s; another joint named in "
      "%d\n",
      args.check_change_deg, named, checks_changed, 100 * share(named, checks_changed),
      100 * args.min_named_share, verdictWord(named_ok), other_named);
  std::printf("check    max cell time    %.1f s (<= %.0f)  %s\n", max_check_s,
              args.max_check_cell_time_s, verdictWord(check_time_ok));
  std::printf("apply    verified         %d of %d\n", verified, applies);
  std::printf(
      "apply    true zeros after %.5f deg RMS from the reference's, worst %.5f (<= %.3f)  "
      "%s\n",
      after_rms, after_worst, args.max_after_apply_rms_deg, verdictWord(after_ok));
  return pass ? 0 : kRequirementNotMet;
}

}  // namespace zerocal::lab
