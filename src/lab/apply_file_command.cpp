#include "apply_file_command.h"

#include <fmt/printf.h>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <regex>

#include "zerocal/apply/moc_file.h"
#include "zerocal/apply/motor_calibration.h"
#include "zerocal/error.h"
#include "zerocal/model/builtin.h"
#include "zerocal/model/robot.h"
#include "zerocal/report/session_report.h"
#include "zerocal/store/journal.h"

namespace zerocal::lab {

namespace {

namespace fs = std::filesystem;
using apply::CalOffsetChange;

constexpr double kRadToDegree = 57.29577951308232;

enum ApplyExit {
  kApplyOk = 0,
  kApplyRefused = 2,
  kApplyNotConverged = 3,
  kApplyNotIdentifiable = 4
};

std::string format(const char* spec, double a, double b = 0, double c = 0, double d = 0) {
  return fmt::sprintf(spec, a, b, c, d);
}

// "ABB IRB 1600-10/1.45" -> {1600, 10, 1.45}; "ROB1_1600_1.45_10" -> the same. Empty when the
// text does not follow the pattern.
struct ModelId {
  std::string model;
  double payload_kg = 0, reach_m = 0;
};
std::optional<ModelId> fromRobotName(const std::string& name) {
  static const std::regex re(R"(IRB\s*([0-9A-Za-z]+)-([0-9.]+)/([0-9.]+))");
  std::smatch m;
  if (!std::regex_search(name, m, re)) return std::nullopt;
  return ModelId{m[1], std::stod(m[2]), std::stod(m[3])};
}
std::optional<ModelId> fromMocRobotType(const std::string& type) {
  static const std::regex re(R"(ROB[0-9]+_([0-9A-Za-z]+)_([0-9.]+)_([0-9.]+)(_.*)?)");
  std::smatch m;
  if (!std::regex_match(type, m, re)) return std::nullopt;
  return ModelId{m[1], std::stod(m[3]), std::stod(m[2])};
}

Robot sessionRobot(const ApplyFileArgs& args, const SessionFolder& files, std::string* source) {
  std::string robot = args.robot;
  if (robot.empty()) {
    // zerocald's snapshot of its configuration keeps the robot file under controller.robot.
    const nlohmann::json& config = files.session.config;
    const auto controller = config.find("controller");
    if (controller == config.end() || !controller->is_object() || !controller->contains("robot") ||
        !(*controller)["robot"].is_string())
      throw InputError(args.session_dir +
                       "/session.json: no config.controller.robot; give the robot file with "
                       "--robot");
    robot = (*controller)["robot"].get<std::string>();
  }
  *source = robot == "builtin" ? "the built-in IRB 1600-10/1.45 (config/robots/irb1600-10-145.yaml)"
                               : robot;
  return robot == "builtin" ? builtinIrb1600() : loadRobot(robot);
}

void writeAtomically(const std::string& path, const std::string& text) {
  const std::string tmp = path + ".tmp";
  {
    std::ofstream out(tmp, std::ios::binary | std::ios::trunc);
    out << text;
    out.flush();
    if (!out) throw InputError(path + ": cannot write it");
  }
  std::error_code ec;
  fs::rename(tmp, path, ec);
  if (ec) throw InputError(path + ": cannot write it: " + ec.message());
}

int run(const ApplyFileArgs& args, std::ostream& out, std::ostream& err) {
  // The session: converged, every offset of joints 2..5 identified.
  const SessionFolder files = report::readSessionFiles(args.session_dir);
  const report::SessionReport session = report::parseSession(files);
  if (!session.solve().converged) {
    err << "zerocal-lab apply: session " << session.session.id
        << ": the solve did not converge; there is nothing to apply\n";
    return kApplyNotConverged;
  }
  std::array<const report::ParameterRow*, 4> offsets{};
  for (int j = 2; j <= 5; ++j) {
    for (const auto& p : session.parameters)
      if (p.name == "delta" + std::to_string(j) + "_deg") offsets[j - 2] = &p;
    if (!offsets[j - 2])
      throw InputError(args.session_dir + "/result.json: no delta" + std::to_string(j) + "_deg");
    if (!offsets[j - 2]->identifiable) {
      err << "zerocal-lab apply: delta" << j << " is not identifiable in this session ("
          << offsets[j - 2]->reason << "); re-plan and calibrate again, nothing was written\n";
      return kApplyNotIdentifiable;
    }
  }

  std::string robot_source;
  const Robot robot = sessionRobot(args, files, &robot_source);
  const apply::MocFile moc = apply::readMocFile(args.moc_file);

  // The backup must be of this robot model.
  const std::optional<std::string> moc_type = apply::robotType(moc);
  if (!moc_type)
    throw apply::MocFormatError(args.moc_file, {"no ROBOT instance with -use_robot_type: cannot "
                                                "tell which robot this backup belongs to"});
  const auto mine = fromRobotName(robot.name), theirs = fromMocRobotType(*moc_type);
  if (mine && theirs &&
      (mine->model != theirs->model || std::abs(mine->payload_kg - theirs->payload_kg) > 1e-9 ||
       std::abs(mine->reach_m - theirs->reach_m) > 1e-9)) {
    err << "zerocal-lab apply: " << args.moc_file << " is the backup of a " << *moc_type
        << ", the session's robot is " << robot.name << "; nothing was written\n";
    return kApplyRefused;
  }

  // The transmission: given, confirmed or explicitly accepted, and not contradicted by the backup.
  std::vector<std::string> problems;
  for (int j = 2; j <= 5; ++j) {
    const double k = robot.transmission[j - 1];
    const std::string inst = "rob1_" + std::to_string(j);
    if (k == 0) {
      problems.push_back("joint " + std::to_string(j) + ": the robot file (" + robot_source +
                         ") gives no transmission");
      continue;
    }
    if (const auto in_moc = apply::transmissionOf(moc, inst); in_moc && *in_moc != k)
      problems.push_back("joint " + std::to_string(j) + ": the backup's TRANSMISSION \"" + inst +
                         "\" -transm_joint is " + format("%+g", *in_moc) +
                         ", the robot file says " + format("%+g", k));
  }
  if (!problems.empty()) throw ConfigError("transmission", problems);
  if (!robot.transmission_confirmed && !args.unconfirmed_transmission) {
    err << "zerocal-lab apply: the transmissions of " << robot.name << " in " << robot_source
        << " are placeholders to be confirmed (transmission_confirmed: false). A wrong sign "
           "doubles an offset instead of removing it, a wrong ratio leaves part of it. Confirm "
           "them and set transmission_confirmed: true, or accept them with "
           "--unconfirmed-transmission and verify by a calibration after loading the file "
           "(docs/apply.md). Nothing was written\n";
    return kApplyRefused;
  }

  std::error_code ec;
  if (fs::exists(args.out_file, ec)) {
    err << "zerocal-lab apply: " << args.out_file
        << " exists; give a new file name (the backup is never overwritten)\n";
    return kApplyRefused;
  }

  std::vector<CalOffsetChange> changes;
  std::vector<apply::CalOffsetEdit> edits;
  for (int j = 2; j <= 5; ++j) {
    const std::string inst = "rob1_" + std::to_string(j);
    const double delta_rad = offsets[j - 2]->value / kRadToDegree;
    changes.push_back(apply::calOffsetChange(j, delta_rad, robot.transmission[j - 1],
                                             apply::presentCalOffset(moc, inst)));
    edits.push_back({inst, changes.back().new_rad});
  }
  std::vector<apply::MocChange> moc_changes;
  const std::string text = apply::withCalOffsets(moc, edits, &moc_changes);

  out << "zerocal-lab apply: session " << session.session.id
      << (session.simulated() ? " (simulated)" : "") << ", robot " << robot.name << ", backup "
      << args.moc_file << " (" << *moc_type << ")\n";
  out << "Transmission k (motor angle per joint angle, signed) from " << robot_source
      << (robot.transmission_confirmed ? ""
                                       : ": NOT CONFIRMED, placeholders accepted with "
                                         "--unconfirmed-transmission")
      << "\n";
  out << "Model: q = (phi - cal_offset) / k, theta = q + delta, so\n"
         "  cal_offset_new = wrap(cal_offset_old - k x delta), wrapped into [0, 2 pi)\n\n";
  std::vector<std::string> warnings;
  for (std::size_t i = 0; i < changes.size(); ++i) {
    const CalOffsetChange& c = changes[i];
    const report::ParameterRow& p = *offsets[i];
    out << "joint " << c.joint << ": delta" << c.joint << " = "
        << format("%+.5f deg = %+.8f rad (sigma %.5f deg)", p.value, c.delta_rad, p.sigma);
    if (p.ci95_low <= 0 && 0 <= p.ci95_high) out << ", not distinguishable from zero";
    out << "\n  " << apply::formulaText(c) << "\n  MOC.cfg rob1_" << c.joint << ": "
        << (moc_changes[i].old_rad ? apply::mocNumber(*moc_changes[i].old_rad)
                                   : std::string("absent (the default 0)"))
        << " -> " << apply::mocNumber(c.new_rad) << "\n";
    if (c.crossesSeam())
      warnings.push_back(
          "Joint " + std::to_string(c.joint) +
          "'s new value crosses the resolver's 0 / 2 pi seam: after the restart its revolution "
          "counter still counts from the old motor turn: until it is updated the joint's true "
          "angle is its reading " +
          format("%+.4f deg", c.turnErrorRad() * kRadToDegree) +
          " (one motor turn). Update its revolution counter with the joint at its "
          "synchronisation mark, then verify (inferred; docs/apply.md).");
  }
  writeAtomically(args.out_file, text);
  out << "\nWritten " << args.out_file << ": only these lines differ from the backup\n"
      << apply::diffText(moc_changes);
  warnings.push_back(
      "The session does not record the controller's cal_offset: the backup must hold the values "
      "the robot had during the calibration (no calibration change in between), which zerocal "
      "cannot check.");
  warnings.push_back(
      "Load the file into the controller as ABB's procedure says (system parameters, MOC; a "
      "restart), keep the backup to restore, then run a verification calibration: every new "
      "delta must lie within its uncertainty of zero, a doubled one means a wrong sign.");
  warnings.push_back(
      "Taught positions (robtargets and jointtargets) move physically by the corrected offsets: "
      "check them at reduced speed.");
  warnings.push_back(
      "Absolute Accuracy data (MOC ARM_CALIB) and a later fine calibration at the "
      "synchronisation marks refer to the old zeros: they no longer match.");
  out << "\nBefore use:\n";
  for (const auto& w : warnings) out << "  - " << w << "\n";

  // The record, beside the session's result: what was computed from what, and when.
  nlohmann::json record{
      {"format", "zerocal-apply-file/1"},
      {"time_unix_s",
       std::chrono::duration<double>(std::chrono::system_clock::now().time_since_epoch()).count()},
      {"moc", args.moc_file},
      {"out", args.out_file},
      {"robot", robot.name},
      {"transmission_confirmed", robot.transmission_confirmed},
      {"joints", nlohmann::json::array()}};
  for (const CalOffsetChange& c : changes)
    record["joints"].push_back({{"joint", c.joint},
                                {"delta_rad", c.delta_rad},
                                {"transmission", c.transmission},
                                {"old_rad", c.old_rad},
                                {"new_rad", c.new_rad},
                                {"written", apply::mocNumber(c.new_rad)},
                                {"turns", c.turns},
                                {"formula", apply::formulaText(c)}});
  std::ofstream log(args.session_dir + "/apply.jsonl", std::ios::app);
  log << record.dump() << "\n";
  log.flush();
  if (!log)
    err << "zerocal-lab apply: warning: could not append the record to " << args.session_dir
        << "/apply.jsonl\n";
  return kApplyOk;
}

}  // namespace

void addApplyFileCommand(CLI::App& app, ApplyFileCommand& command) {
  ApplyFileArgs& a = command.args;
  command.apply = app.add_subcommand(
      "apply",
      "turn a session's offsets into MOC MOTOR_CALIB cal_offset values and write them into a "
      "copy of the controller's MOC.cfg (only cal_offset and its valid flag of joints 2..5 "
      "change)");
  auto* c = command.apply;
  c->add_option("session", a.session_dir, "the session folder (<data_dir>/<id>)")->required();
  c->add_option("--moc", a.moc_file, "MOC.cfg from the controller's backup (SYSPAR/MOC.cfg)");
  c->add_option("--out", a.out_file, "the new MOC.cfg to write (must not exist)");
  c->add_option("--robot", a.robot,
                "robot model YAML with each joint's transmission, or 'builtin' (default: the "
                "session's)");
  c->add_flag("--unconfirmed-transmission", a.unconfirmed_transmission,
              "accept transmissions the robot file marks as not confirmed (then verify by "
              "measurement after loading)");
}

int runApplyFileCommand(const ApplyFileCommand& command, std::ostream& out, std::ostream& err) {
  if (!command.apply->parsed()) return -1;
  const ApplyFileArgs& a = command.args;
  if (a.moc_file.empty()) {
    err << "zerocal-lab apply: " << (a.out_file.empty() ? "" : "--out needs --moc MOC.cfg: ")
        << "give the backup to start from and the file to write, --moc MOC.cfg --out NEW.cfg "
           "(the online apply through zerocald is `zerocal apply ID --confirm`)\n";
    return kApplyRefused;
  }
  if (a.out_file.empty()) {
    err << "zerocal-lab apply: --moc needs --out NEW.cfg (the file to write)\n";
    return kApplyRefused;
  }
  return runApplyFile(a, out, err);
}

int runApplyFile(const ApplyFileArgs& args, std::ostream& out, std::ostream& err) {
  try {
    return run(args, out, err);
  } catch (const ConfigError& e) {
    err << "zerocal-lab apply: " << e.what() << "\nNothing was written\n";
  } catch (const InputError& e) {
    err << "zerocal-lab apply: " << e.what() << "\nNothing was written\n";
  } catch (const report::ReportError& e) {
    err << "zerocal-lab apply: " << e.what() << "\n";
  } catch (const JournalError& e) {
    err << "zerocal-lab apply: " << e.what() << "\n";
  } catch (const std::exception& e) {
    err << "zerocal-lab apply: unexpected failure: " << e.what() << "\n";
    return 1;
  }
  return kApplyRefused;
}

}  // namespace zerocal::lab
