// zerocal-sim: the simulated IRC5 cell as its own process, so that tests and demos can kill and
// restart the controller from outside.
#include <CLI/CLI.hpp>
#include <cstdio>
#include <fstream>
#include <iostream>

#include "zerocal/error.h"
#include "zerocal/sim/sim_controller.h"
#include "zerocal/sim/world.h"

int main(int argc, char** argv) {
  CLI::App app("Simulated ABB IRC5 controller speaking zerocal's RAPID server protocol");
  app.set_version_flag("--version", "zerocal-sim " + std::string(PROJECT_VERSION));
  zerocal::SimControllerOptions options;
  options.port = 5000;  // the RAPID server's port; 0 picks a free one
  std::string world_file;
  int delay_ms = 0;
  app.add_option("--port", options.port, "TCP port (0: ephemeral, printed on stdout)")
      ->capture_default_str();
  app.add_option("--address", options.address, "address to listen on")->capture_default_str();
  app.add_option("--world", world_file, "world YAML file (default: a random world from --seed)");
  app.add_option("--seed", options.seed, "seed of the random world and of the noise")
      ->capture_default_str();
  bool ideal = false;
  double gross_rate = zerocal::kDefaultGrossRate;
  std::string truth_file;
  app.add_flag("--ideal-world", ideal,
               "the seed's ideal world (exact arm, PSD orientation known, no gross errors) "
               "instead of its realistic one; not with --world");
  app.add_option("--gross-rate", gross_rate,
                 "realistic seeded world: chance per pose of each kind of gross error")
      ->capture_default_str()
      ->check(CLI::Range(0.0, 1.0));
  app.add_option("--write-truth", truth_file,
                 "write the seeded world (every error of the arm and the PSD, the noise) as a "
                 "world file that --world reads");
  app.add_flag(
      "--no-lf", [&](std::int64_t) { options.lf_terminated = false; },
      "end replies with no LF, like upstream open_abb");
  app.add_option("--pace", options.pace,
                 "wall seconds per simulated second of a move (1: real time; default 0: at once)")
      ->check(CLI::Range(0.0, 10.0));
  app.add_option("--move-overhead-s", options.motion.overhead_s,
                 "fixed cost of every move (s): request, reply, the planner's start-up")
      ->capture_default_str()
      ->check(CLI::Range(0.0, 60.0));
  app.add_option("--joint-accel", options.motion.joint_accel_deg_s2,
                 "acceleration and braking of the joints (deg/s^2)")
      ->capture_default_str()
      ->check(CLI::PositiveNumber);
  app.add_option("--settle-s", options.motion.settle_s,
                 "settling at the fine point after every move (s)")
      ->capture_default_str()
      ->check(CLI::Range(0.0, 60.0));
  app.add_flag(
      "--no-search-signal", [&](std::int64_t) { options.search.wired = false; },
      "no PSD light signal at the controller's input: the spot search (49, 47) is refused, as "
      "by a RAPID module whose signal is not configured");
  app.add_option("--restart-s", options.restart_s,
                 "simulated seconds a restart (request 46) takes, connections refused meanwhile "
                 "(wall time: this x --pace); a real IRC5's warm start takes tens of seconds")
      ->capture_default_str()
      ->check(CLI::Range(0.0, 3600.0));
  app.add_option("--drop-after", options.faults.drop_after_requests,
                 "close each connection instead of answering its request N+1");
  app.add_option("--delay-ms", delay_ms, "delay every reply (ms)");
  app.add_flag("--split", options.faults.split_replies, "send each reply in three segments");
  app.add_option("--garbage-code", options.faults.garbage_code,
                 "answer requests with this code with garbage");
  app.add_flag("--stall-moves", options.faults.stall_moves, "never answer a move");
  CLI11_PARSE(app, argc, argv);
  options.faults.reply_delay = std::chrono::milliseconds(delay_ms);

  try {
    if (!world_file.empty() && (ideal || app.count("--gross-rate") > 0 || !truth_file.empty()))
      throw zerocal::ConfigError(
          "zerocal-sim", {"--ideal-world, --gross-rate and --write-truth are for seeded worlds; a "
                          "--world file states its own errors and is its own truth"});
    if (world_file.empty()) {
      options.world = zerocal::randomWorld(
          options.seed, ideal ? zerocal::WorldKind::kIdeal : zerocal::WorldKind::kRealistic);
      if (!ideal)
        options.world.gross.stray_light_rate = options.world.gross.unsettled_rate = gross_rate;
    } else {
      options.world = zerocal::loadWorld(world_file);
    }
    if (!truth_file.empty()) {
      std::ofstream out(truth_file);
      out << zerocal::worldYaml(options.world);
      if (!out) throw zerocal::Error("cannot write " + truth_file);
    }
    zerocal::SimController sim(options);
    std::cout << "zerocal-sim listening on " << options.address << ":" << sim.port() << std::endl;
    sim.run(/*stop_on_signals=*/true);
  } catch (const zerocal::ConfigError& e) {  // a world file or options it cannot run with
    std::cerr << "zerocal-sim: " << e.what() << "\n";
    return 2;
  } catch (const std::exception& e) {
    std::cerr << "zerocal-sim: " << e.what() << "\n";
    return 1;
  }
  return 0;
}
