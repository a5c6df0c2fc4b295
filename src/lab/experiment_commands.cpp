#include "experiment_commands.h"

#include "lab_exit.h"
#include "zerocal/calib/format.h"

namespace zerocal::lab {

void addExperimentCommands(CLI::App& app, ExperimentCommands& commands) {
  auto* exp = commands.experiment = app.add_subcommand(
      "experiment", "reproduce the paper's experiments, and measure the daemon's calibration");
  exp->require_subcommand(1);
  ExperimentOptions& options = commands.table2_options;
  auto* table2 = commands.table2 = exp->add_subcommand(
      "table2",
      "Monte Carlo of Table II: patterns I, II and optimal with both costs, against "
      "the Cramer-Rao bound and the paper's figures");
  table2->add_option("--repeats", options.repeats, "Monte Carlo repeats")
      ->default_val(options.repeats)
      ->check(CLI::Range(2, 1000000));
  table2->add_option("--seed", options.seed, "random seed")->default_val(options.seed);
  table2->add_flag("--json", commands.table2_json, "print one JSON object instead of text");
  commands.cell = addCellExperiment(*exp, commands.cell_args);
  addRobustnessExperiments(*exp, commands.robustness_args);
  addPlacementExperiment(*exp, commands.placement_args);
  addApplyExperiment(*exp, commands.apply_args);
  addLifeExperiment(*exp, commands.life_args);
  addRemountExperiment(*exp, commands.remount_args);
}

int runExperimentCommands(const ExperimentCommands& commands, std::ostream& out,
                          std::ostream& err) {
  if (commands.table2->parsed()) {
    const auto results = runTable2(commands.table2_options);
    if (commands.table2_json)
      out << toJson(results, commands.table2_options).dump(2) << "\n";
    else
      out << toText(results, commands.table2_options);
    return kOk;
  }
  if (commands.cell->parsed()) return runCellExperiment(commands.cell_args);
  if (commands.placement_args.cmd->parsed()) return runPlacementExperiment(commands.placement_args);
  if (commands.apply_args.cmd->parsed()) return runApplyExperiment(commands.apply_args, out, err);
  if (commands.life_args.cmd->parsed()) return runLifeExperiment(commands.life_args);
  if (commands.remount_args.cmd->parsed()) return runRemountExperiment(commands.remount_args);
  return runRobustnessExperiment(commands.robustness_args);
}

}  // namespace zerocal::lab
