// zerocal-lab solve, plan, simulate and sensitivity: the calibration engine on a joint set,
// recorded or planned, with no cell and no daemon.
#pragma once

#include <CLI/CLI.hpp>
#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "zerocal/calib/cell_model.h"
#include "zerocal/calib/planner.h"
#include "zerocal/calib/solver.h"

namespace zerocal::lab {

// The cell a command computes for: the robot file and the nominal laser line.
struct CellArgs {
  std::string robot;
  std::vector<double> laser_direction{1, 0, 0};
  std::vector<double> laser_point{0, 0, 0};

  void add(CLI::App* app);
  // Throws ConfigError / InputError for a robot file that cannot be used.
  CellModel cell() const;
};

struct SolveArgs {
  CellArgs cell;
  std::string joints_file, cost = "ml", loss = "none";
  std::optional<double> noise;
  std::optional<double> joint_repeatability, psd_noise;
  std::vector<double> psd_rpy;
  bool ignore_readings = false, json = false;
  double loss_scale = 3.0;
  double required_accuracy = SolveOptions{}.required_accuracy_deg;
  double max_offset = SolveOptions{}.max_offset_deg;
  bool identify_compliance = false;
  std::vector<double> sag_tolerance;  // joints 2 and 3, or one for both; empty: the robot file's
  std::string save_model;
  std::optional<int> holdout_count;
  std::vector<int> holdout_poses;
};

struct PlanArgs {
  CellArgs cell;
  std::vector<double> target;
  std::string pattern = "optimal", out_file;
  PlanOptions options;
  std::vector<double> standoff{options.standoff_min_mm, options.standoff_max_mm};
  std::vector<double> psd_normal{0, 0, 1};
  bool json = false;
  // The planner's own sigma (the PSD's +-0.05 mm read as uniform).
  double noise = options.noise_mm;
  int placements = 1;
  std::vector<std::vector<double>> placement_centres;
};

struct SimulateArgs {
  CellArgs cell;
  std::string plan_file;
  std::vector<double> true_offsets, target;
  double half_width = 0.05;
  std::uint64_t seed = 1;
};

struct SensitivityArgs {
  CellArgs cell;
  std::vector<double> joints;
  double standoff = 600;
  bool json = false;
};

struct EngineCommands {
  CLI::App* solve = nullptr;
  CLI::App* plan = nullptr;
  CLI::App* simulate = nullptr;
  CLI::App* sensitivity = nullptr;
  SolveArgs solve_args;
  PlanArgs plan_args;
  SimulateArgs simulate_args;
  SensitivityArgs sensitivity_args;
};

// Registers the four subcommands; `commands` must outlive the parse.
void addEngineCommands(CLI::App& app, EngineCommands& commands);

// Runs the parsed one and returns its exit code (lab_exit.h), or -1 when none was parsed. Bad
// input throws InputError / ConfigError (main maps them to 2).
int runEngineCommands(const EngineCommands& commands);

}  // namespace zerocal::lab
