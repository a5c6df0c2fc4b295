// The PSD subcommands of zerocal-lab: psd-sweep (a simulated stage sweep), psd-map (fit the
// voltage->mm map from a sweep) and psd (live readings, simulated or from the board).
#pragma once

#include <CLI/CLI.hpp>
#include <cstdint>
#include <string>
#include <vector>

namespace zerocal::lab {

struct PsdSweepArgs {
  bool sim = false;
  std::uint32_t seed = 1;
  double step_mm = 0.05;
  double extent_mm = 0.8;
};

struct PsdMapArgs {
  std::string sweep_file;
  std::string out_file;
  bool json = false;
  int degree = 7;
  double zone_mm = 0.6;
  double min_sum_v = 0.5;
};

struct PsdArgs {
  bool sim = false;
  std::string config_file;
  std::size_t count = 10;
  bool json = false;
  std::vector<double> sim_spot{0.0, 0.0};
  bool sim_dark = false;
  std::uint32_t seed = 1;
};

struct PsdCommands {
  CLI::App* sweep = nullptr;
  CLI::App* map = nullptr;
  CLI::App* live = nullptr;
  PsdSweepArgs sweep_args;
  PsdMapArgs map_args;
  PsdArgs live_args;
};

// Registers the three subcommands; `commands` must outlive the parse.
void addPsdCommands(CLI::App& app, PsdCommands& commands);

// Each returns the exit code; bad input throws InputError / ConfigError, a board that is absent
// or not permitted throws usb1408fs::DeviceNotFoundError / PermissionError (main maps them to 2).
int runPsdSweep(const PsdSweepArgs& args);
int runPsdMap(const PsdMapArgs& args);
int runPsd(const PsdArgs& args);

}  // namespace zerocal::lab
