// zerocal-lab: the engineer's program. The calibration engine on the command line (solve, plan,
// simulate, sensitivity), the PSD chain (psd-sweep, psd-map, psd), the report of a session folder
// (report), the MOC.cfg file apply (apply --moc), and the experiments (experiment ...). The
// technician's client of zerocald is zerocal (src/cli).
// Exit codes: 0 done; 1 unexpected failure; 2 bad input or usage, or no USB-1408FS / no permission
// to open it; 3 the solver did not converge; 4 solved, but some of delta2..delta5 are not
// identifiable from the poses (or not to the required accuracy); 7 (experiments) a requirement
// does not hold; 8 solved, but the verdict refuses the result (stand-off, offset bound, misfit,
// gross errors: the reasons are printed, no correction is). docs/cli.md.
#include <CLI/CLI.hpp>
#include <iostream>

#include "apply_file_command.h"
#include "engine_commands.h"
#include "experiment_commands.h"
#include "lab_exit.h"
#include "psd_commands.h"
#include "report_command.h"
#include "unknown_command.h"
#include "zerocal/error.h"
#include "zerocal/report/session_report.h"
#include "zerocal/store/journal.h"
#include "zerocal/usb1408fs/errors.h"

namespace zerocal::lab {
namespace {

int runPsdCommands(const PsdCommands& psd) {
  if (psd.sweep->parsed()) return runPsdSweep(psd.sweep_args);
  if (psd.map->parsed()) return runPsdMap(psd.map_args);
  if (psd.live->parsed()) return runPsd(psd.live_args);
  return -1;
}

}  // namespace
}  // namespace zerocal::lab

int main(int argc, char** argv) {
  using namespace zerocal;
  using namespace zerocal::lab;
  CLI::App app{
      "zerocal-lab: joint zero-offset calibration of a 6R robot from laser lines aimed at one "
      "point (a PSD), offline: identifies delta2..delta5 and the laser line with their "
      "uncertainty, plans, simulates, reports, and runs the experiments. The technician's client "
      "of zerocald is zerocal.",
      "zerocal-lab"};
  app.require_subcommand(1);
  app.set_version_flag("--version", "zerocal-lab " + std::string(PROJECT_VERSION));

  EngineCommands engine;
  addEngineCommands(app, engine);
  ReportCommand report_cmd;
  addReportCommand(app, report_cmd);
  ExperimentCommands experiments;
  addExperimentCommands(app, experiments);
  PsdCommands psd;
  addPsdCommands(app, psd);
  ApplyFileCommand apply_cmd;
  addApplyFileCommand(app, apply_cmd);

  if (const int rc = cli::answerHelp(app, std::vector<std::string>(argv + 1, argv + argc),
                                     std::cout, std::cerr);
      rc >= 0)
    return rc == 0 ? 0 : kBadInput;
  if (argc > 1 && cli::refuseUnknownCommand(app, argv[1], std::cerr)) return kBadInput;
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    // --help and --version arrive here too, with exit code 0; every real usage error is bad
    // input, so scripts see the same code as for a bad file.
    return app.exit(e) == 0 ? kOk : kBadInput;
  }

  // The file apply reports its own failures (its messages say nothing was written).
  if (const int rc = runApplyFileCommand(apply_cmd, std::cout, std::cerr); rc >= 0) return rc;
  try {
    if (const int rc = runEngineCommands(engine); rc >= 0) return rc;
    if (const int rc = runReportCommand(report_cmd); rc >= 0) return rc;
    if (const int rc = runExperimentCommands(experiments, std::cout, std::cerr); rc >= 0) return rc;
    if (const int rc = runPsdCommands(psd); rc >= 0) return rc;
  } catch (const ConfigError& e) {
    std::cerr << "zerocal-lab: " << e.what() << "\n";
    return kBadInput;
  } catch (const InputError& e) {
    std::cerr << "zerocal-lab: " << e.what() << "\n";
    return kBadInput;
  } catch (const report::ReportError& e) {
    std::cerr << "zerocal-lab: " << e.what() << "\n";
    return kBadInput;
  } catch (const JournalError& e) {
    std::cerr << "zerocal-lab: " << e.what() << "\n";
    return kBadInput;
  } catch (const usb1408fs::DeviceNotFoundError& e) {
    // Absent or forbidden hardware is the engineer's to fix, like a bad file.
    std::cerr << "zerocal-lab: " << e.what() << "\n";
    return kBadInput;
  } catch (const usb1408fs::PermissionError& e) {
    std::cerr << "zerocal-lab: " << e.what() << "\n";
    return kBadInput;
  } catch (const usb1408fs::UsbError& e) {
    std::cerr << "zerocal-lab: USB-1408FS: " << e.what() << "\n";
    return kFailure;
  } catch (const std::exception& e) {
    std::cerr << "zerocal-lab: unexpected failure: " << e.what() << "\n";
    return kFailure;
  }
  return kFailure;
}
