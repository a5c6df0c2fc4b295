#include "robustness_experiment.h"

#include <algorithm>
#include <cstdio>
#include <iostream>
#include <nlohmann/json.hpp>

namespace zerocal::lab {

void addRobustnessExperiments(CLI::App& experiment, RobustnessExperimentArgs& args) {
  args.coverage_cmd = experiment.add_subcommand(
      "coverage",
      "Monte Carlo on the Table II scenario (optimal plan): how often the reported 95% intervals "
      "of delta2..delta5 contain the truth when the noise is larger than the solver is told");
  args.coverage_cmd->add_option("--repeats", args.coverage.repeats, "Monte Carlo repeats")
      ->default_val(args.coverage.repeats)
      ->check(CLI::Range(1, 1000000));
  args.coverage_cmd->add_option("--seed", args.coverage.seed, "random seed")
      ->default_val(args.coverage.seed);
  args.coverage_cmd
      ->add_option("--noise-factor", args.coverage.noise_factor,
                   "the recording's noise over the noise given to the solver")
      ->default_val(args.coverage.noise_factor)
      ->check(CLI::PositiveNumber);
  args.coverage_cmd
      ->add_option("--poses", args.coverage.pose_counts, "pose counts, comma separated")
      ->delimiter(',')
      ->check(CLI::Range(6, 200));
  args.coverage_cmd->add_flag("--json", args.json, "print one JSON object instead of text");

  args.gross_cmd = experiment.add_subcommand(
      "gross-errors",
      "Monte Carlo on the Table II scenario (optimal plan): one gross error per session (a spot "
      "off by --spot-error mm, or one joint of 2..5 read --joint-error deg off) or none; how "
      "often the solve names and leaves out the right pose, per pose count");
  args.gross_cmd->add_option("--repeats", args.gross.repeats, "sessions per pose count and kind")
      ->default_val(args.gross.repeats)
      ->check(CLI::Range(1, 1000000));
  args.gross_cmd->add_option("--seed", args.gross.seed, "random seed")
      ->default_val(args.gross.seed);
  args.gross_cmd->add_option("--poses", args.gross.pose_counts, "pose counts, comma separated")
      ->delimiter(',')
      ->check(CLI::Range(6, 200));
  args.gross_cmd->add_option("--spot-error", args.gross.spot_error_mm, "spot error, mm")
      ->default_val(args.gross.spot_error_mm)
      ->check(CLI::PositiveNumber);
  args.gross_cmd->add_option("--joint-error", args.gross.joint_error_deg, "joint error, deg")
      ->default_val(args.gross.joint_error_deg)
      ->check(CLI::PositiveNumber);
  args.gross_cmd->add_flag("--json", args.json, "print one JSON object instead of text");
}

int runRobustnessExperiment(const RobustnessExperimentArgs& args) {
  using Json = nlohmann::json;
  if (args.coverage_cmd->parsed()) {
    const auto results = runCoverage(args.coverage);
    if (args.json) {
      Json j{{"experiment", "coverage"},
             {"repeats", args.coverage.repeats},
             {"seed", args.coverage.seed},
             {"results", Json::array()}};
      for (const CoverageResult& c : results)
        j["results"].push_back({{"poses", c.poses},
                                {"noise_factor", c.noise_factor},
                                {"estimates", c.estimates},
                                {"coverage", c.coverage},
                                {"coverage_unscaled", c.coverage_unscaled},
                                {"mean_noise_scale", c.mean_noise_scale},
                                {"usable_runs", c.usable_runs}});
      std::cout << j.dump(2) << "\n";
      return 0;
    }
    std::printf(
        "Coverage of the 95%% intervals of delta2..delta5 (Table II scenario, optimal plan), the "
        "noise %.2f x the given one, %d repeats, seed %llu\n",
        args.coverage.noise_factor, args.coverage.repeats,
        static_cast<unsigned long long>(args.coverage.seed));
    std::printf("%6s %10s %17s %19s %17s %12s\n", "poses", "estimates", "coverage (result)",
                "coverage (unscaled)", "mean noise scale", "usable runs");
    for (const CoverageResult& c : results)
      std::printf("%6d %10d %16.1f%% %18.1f%% %17.2f %12d\n", c.poses, c.estimates,
                  100 * c.coverage, 100 * c.coverage_unscaled, c.mean_noise_scale, c.usable_runs);
    return 0;
  }
  if (args.gross_cmd->parsed()) {
    const auto results = runGrossErrors(args.gross);
    if (args.json) {
      Json j{{"experiment", "gross-errors"},
             {"repeats", args.gross.repeats},
             {"seed", args.gross.seed},
             {"spot_error_mm", args.gross.spot_error_mm},
             {"joint_error_deg", args.gross.joint_error_deg},
             {"results", Json::array()}};
      for (const GrossErrorResult& g : results)
        j["results"].push_back({{"poses", g.poses},
                                {"gross_error", grossErrorName(g.kind)},
                                {"runs", g.runs},
                                {"named", g.named},
                                {"wrong", g.wrong},
                                {"refused", g.refused},
                                {"missed", g.missed},
                                {"usable_within_3_sigma", g.usable_within_3_sigma}});
      std::cout << j.dump(2) << "\n";
      return 0;
    }
    std::printf(
        "One gross error per session (Table II scenario, optimal plan): spot %.2f mm off, or one "
        "joint %.3f deg off; %d sessions each, seed %llu\n"
        "named: the corrupted pose alone left out, usable; wrong: another pose left out; refused: "
        "verdict not usable; missed: nothing found (for 'none': the clean pass)\n",
        args.gross.spot_error_mm, args.gross.joint_error_deg, args.gross.repeats,
        static_cast<unsigned long long>(args.gross.seed));
    std::printf("%6s %6s %7s %7s %8s %7s %22s\n", "poses", "error", "named", "wrong", "refused",
                "missed", "usable within 3 sigma");
    for (const GrossErrorResult& g : results)
      std::printf("%6d %6s %6.1f%% %6.1f%% %7.1f%% %6.1f%% %21.1f%%\n", g.poses,
                  grossErrorName(g.kind).c_str(), 100.0 * g.named / g.runs,
                  100.0 * g.wrong / g.runs, 100.0 * g.refused / g.runs, 100.0 * g.missed / g.runs,
                  100.0 * g.usable_within_3_sigma / std::max(1, g.runs - g.refused));
    return 0;
  }
  return -1;
}

}  // namespace zerocal::lab
