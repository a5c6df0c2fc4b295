#include "control_commands.h"

#include <fmt/format.h>

#include <cctype>
#include <chrono>
#include <cmath>
#include <cstdlib>
#include <ctime>
#include <limits>
#include <utility>
#include <vector>

#include "record_view.h"
#include "zerocal/calib/pose_count.h"
#include "zerocal/control/client.h"
#include "zerocal/control/token.h"
#include "zerocal/error.h"
#include "zerocal/paths.h"
#include "zerocal/results/result_file.h"

namespace zerocal::cli {

using control::CommandError;
using control::ConnectionError;
using nlohmann::json;

namespace {

const char* const kSigmaNames[] = {"delta2", "delta3", "delta4", "delta5"};

// Planning takes the daemon a second or so of CPU, tens of seconds on a loaded machine: `plan`
// and `start`, which plans before it answers, wait this much beyond --timeout.
constexpr std::chrono::seconds kPlanningAllowance{60};

bool isFinal(const std::string& state) {
  return state == "done" || state == "aborted" || state == "faulted" || state == "idle" ||
         state == "unrecovered";
}

std::string sigmaText(const json& sigmas) {
  std::string text;
  for (std::size_t k = 0; k < sigmas.size() && k < 4; ++k) {
    text += std::string(k ? ", " : "") + kSigmaNames[k] + " ";
    text +=
        sigmas[k].is_number() ? fmt::format("{:.5f}", sigmas[k].get<double>()) : "not identifiable";
  }
  return text.empty() ? "-" : text + " deg";
}

// One line of progress: what a technician at the cell wants at a glance.
std::string progressLine(const json& s) {
  std::string line = s.value("session", std::string("-")) + "  " + s.value("state", "?");
  if (s.value("pose_count", 0) > 0)
    line += "  pose " + std::to_string(s.value("pose", 0)) + " of " +
            std::to_string(s.value("pose_count", 0)) + "  recorded " +
            std::to_string(s.value("recorded", 0));
  const json live = s.value("live_servo_error_um", json(nullptr));
  if (live.is_number())  // servoing now: where the spot is
    line += "  servo error " + fmt::format("{:.1f}", live.get<double>()) + " um now";
  else if (s.value("recorded", 0) > 0)
    line += "  servo error " + fmt::format("{:.1f}", s.value("last_servo_error_um", 0.0)) + " um";
  if (s.value("placement_count", 0) > 1)
    line += "  placement " + std::to_string(s.value("placement", 0)) + " of " +
            std::to_string(s.value("placement_count", 0));
  if (s.value("cell_time_s", 0.0) > 0)
    line += "  " + fmt::format("{:.0f}", s["cell_time_s"].get<double>()) + " s";
  return line;
}

// The terminal's one line, redrawn: pose i of N, a bar, the servo error against its zone, the
// time left at the pace so far.
std::string barLine(const json& s) {
  const int count = s.value("pose_count", 0), recorded = s.value("recorded", 0);
  if (count <= 0 || !s.value("active", false)) return progressLine(s);
  constexpr int kWidth = 20;
  const int filled = std::min(kWidth, recorded * kWidth / count);
  std::string line = "pose " + std::to_string(std::min(count, s.value("pose", 0))) + " of " +
                     std::to_string(count) + " [" + std::string(filled, '#') +
                     std::string(kWidth - filled, '.') + "] " + s.value("state", "?");
  const json live = s.value("live_servo_error_um", json(nullptr));
  if (live.is_number()) line += fmt::format("  {:.0f} um", live.get<double>());
  if (s.value("placement_count", 0) > 1)
    line += "  placement " + std::to_string(s.value("placement", 0)) + " of " +
            std::to_string(s.value("placement_count", 0));
  const double elapsed = s.value("cell_time_s", 0.0);
  if (recorded > 0 && elapsed > 0 && recorded < count) {
    const double left = elapsed / recorded * (count - recorded);
    line += left >= 60 ? fmt::format("  about {:.0f} min left", std::ceil(left / 60))
                       : fmt::format("  about {:.0f} s left", std::ceil(left));
  }
  return line;
}

// A pipe's line for a pose just recorded: its servo error beside the zone it is judged by.
std::string poseLine(const json& s) {
  std::string line = "pose " + std::to_string(s.value("recorded", 0)) + " of " +
                     std::to_string(s.value("pose_count", 0)) + " recorded: spot " +
                     fmt::format("{:.1f} um from its aim", s.value("last_servo_error_um", 0.0));
  // A pose is recorded only this close to the aim (docs/servo.md): what the error is judged by.
  if (s.value("servo_zone_um", 0.0) > 0)
    line += fmt::format(" (recorded within {:.0f} um)", s["servo_zone_um"].get<double>());
  if (s.value("placement_count", 0) > 1)
    line += ", placement " + std::to_string(s.value("placement", 0)) + " of " +
            std::to_string(s.value("placement_count", 0));
  return line;
}

bool isPoseState(const std::string& state) {
  return state == "moving" || state == "servoing" || state == "recording";
}

void printStatus(const json& s, std::ostream& out) {
  out << "state:      " << s.value("state", "?") << (s.value("active", false) ? " (active)" : "")
      << "\n";
  out << "backend:    " << s.value("backend", "") << "\n";
  out << "session:    " << (s.value("session", "").empty() ? "-" : s.value("session", "")) << "\n";
  if (s.value("pose_count", 0) > 0) {
    out << "pose:       " << s.value("pose", 0) << " of " << s.value("pose_count", 0)
        << ", recorded " << s.value("recorded", 0);
    if (s.value("resumed_from", 0) > 0) out << " (resumed from " << s["resumed_from"] << ")";
    out << "\n";
  }
  if (s.value("placement_count", 0) > 1)
    out << "placement:  " << s.value("placement", 0) << " of " << s.value("placement_count", 0)
        << "\n";
  if (s.value("recorded", 0) > 0) {
    out << "servo:      " << fmt::format("{:.2f}", s.value("last_servo_error_um", 0.0))
        << " um from the aim point at the last recorded pose";
    if (s.value("servo_zone_um", 0.0) > 0)
      out << fmt::format(" (recorded within {:.0f} um)", s["servo_zone_um"].get<double>());
    const json live = s.value("live_servo_error_um", json(nullptr));
    if (live.is_number()) out << ", " << fmt::format("{:.2f}", live.get<double>()) << " um now";
    out << "\n";
  }
  out << "predicted:  " << sigmaText(s.value("predicted_sigma_deg", json::array())) << "\n";
  out << "achieved:   " << sigmaText(s.value("achieved_sigma_deg", json::array())) << "\n";
  if (s.contains("message")) out << "message:    " << s["message"].get<std::string>() << "\n";
  if (s.contains("suggestion")) out << "next:       " << s["suggestion"].get<std::string>() << "\n";
}

// The verdict of a result: the solver's own when result.json has one, else what convergence and
// identifiability alone say.
std::pair<bool, std::vector<std::string>> verdictOf(const ResultFile& r) {
  if (r.verdict_recorded) return {r.report.verdict.usable, r.report.verdict.reasons};
  std::vector<std::string> reasons;
  if (!r.report.converged)
    reasons.push_back("the solve did not converge (" + r.report.message + ")");
  for (const ParameterEstimate& p : r.report.parameters)
    if (p.name.rfind("delta", 0) == 0 && !p.identifiable)
      reasons.push_back(p.name.substr(0, 6) + " is not identifiable from these poses");
  if (r.report.parameters.empty()) reasons.push_back("the result carries no offsets");
  return {reasons.empty(), reasons};
}

// What a technician does after a result that is not usable, by the session's kind.
std::string nextStepAfterNotUsable(const ResultFile& r) {
  switch (r.kind) {
    case SessionKind::kCalibration:
      return "nothing was written. To determine every offset absolutely, calibrate at several "
             "PSD placements (`zerocal start --placements 3`, the technician moves the PSD "
             "twice); to bring the robot back to the zeros its programs were taught with, "
             "restore against its reference (`zerocal start --kind restore`); or enter values by "
             "hand only from a usable result";
    case SessionKind::kReference:
      return "this is no reference: take it again with the robot known good and the PSD "
             "undisturbed (`zerocal start --kind reference`)";
    case SessionKind::kCheck:
    case SessionKind::kRestore:
      return "nothing was written: measure again (`zerocal start --kind " +
             std::string(sessionKindName(r.kind)) +
             "`); when it fails again, see whether the PSD or the laser was moved since the "
             "reference (docs/record.md)";
    case SessionKind::kVerification:
      return "the apply was rolled back: its session's result says why (`zerocal result " +
             r.reference + "`)";
  }
  return "";
}

// When a daemon's `time_unix_s` was, in UTC.
std::string utcText(double unix_s) {
  const std::time_t t = static_cast<std::time_t>(unix_s);
  std::tm tm{};
  gmtime_r(&t, &tm);
  char text[32];
  std::strftime(text, sizeof text, "%Y-%m-%d %H:%M UTC", &tm);
  return text;
}

// What became of a result's offsets on the controller (the `result` answer's `apply`): the
// lines that replace "nothing was written" once an apply ran.
void printApplied(const json& a, std::ostream& out) {
  const std::string outcome = a.value("outcome", "");
  const std::string when = utcText(a.value("time_unix_s", 0.0));
  const std::string by = a.contains("verification")
                             ? ", verified by session " + a.value("verification", "")
                             : std::string();
  if (outcome == "verified")
    out << "\nWritten to the controller on " << when << by << ": " << a.value("message", "")
        << "\n  it holds these offsets now: do not enter them again.\n";
  else if (outcome == "rolled_back" || outcome == "recovered" || outcome == "not_written" ||
           outcome == "refused")
    out << "\nApplied on " << when << " and " << (outcome == "refused" ? "refused" : "undone")
        << " (" << outcome << "): " << a.value("message", "")
        << "\n  the controller holds its values from before the apply.\n";
  else
    out << "\nAn apply on " << when << " ended " << outcome << ": " << a.value("message", "")
        << "\n  check the controller's values (zerocal status) before anything runs.\n";
  if (a.contains("later_check"))
    out << "  verified again later by session " << a["later_check"].value("session", "") << ": "
        << a["later_check"].value("outcome", "") << "\n";
}

// What a technician reads: the verdict first, then the offsets and what to do with them.
void printResult(const ResultFile& r, const json& applied, std::ostream& out) {
  const auto [usable, reasons] = verdictOf(r);
  // Against a reference the offsets are changes since it, and the simulated truth (absolute)
  // is not theirs: the reference's result holds the other half.
  const bool against = !r.reference.empty();
  const bool simulated = r.truth.has_value() && !against;
  const bool verification = r.kind == SessionKind::kVerification;
  out << "session " << (r.session.empty() ? "-" : r.session) << ": " << sessionKindName(r.kind)
      << (verification && against ? " of an apply, the change since session " + r.reference
          : against               ? " against reference " + r.reference
                                  : std::string())
      << (simulated ? " (SIMULATED cell: the truth is known)"
          : r.truth ? " (SIMULATED cell: the true change is the reference's truth less this one's)"
                    : "")
      << "\n";
  if (r.check) {
    std::string outcome = checkOutcomeName(r.check->outcome);
    for (char& c : outcome) c = static_cast<char>(std::toupper(static_cast<unsigned char>(c)));
    out << "check: " << outcome << ": " << r.check->summary << "\n";
  }
  for (const Drift& d : r.drift) out << "DRIFT: " << d.summary << "\n";
  if (r.kind == SessionKind::kReference)
    out << "a reference: the robot's zeros as they are now, recorded for later checks and "
           "restores; it claims nothing of the absolute zeros and writes nothing\n";
  if (verification)
    out << "what it measured: the change of each zero since the poses the apply came from; the "
           "apply's verdict, and what remains of each offset, are with the session applied "
           "(`zerocal "
           "result "
        << r.reference << "`)\n";
  out << (verification ? "measurement: " : "verdict: ")
      << (usable ? (verification ? "complete" : "USABLE")
                 : (verification ? "not usable" : "NOT USABLE"));
  if (!r.verdict_recorded) out << " (convergence and identifiability only)";
  out << "\n";
  for (const auto& why : reasons) out << "  - " << why << "\n";
  if (!usable) out << "next: " << nextStepAfterNotUsable(r) << "\n";
  // Whose offsets these are: a value entered on the wrong robot is worse than none.
  if (r.cell && !r.cell->controller.serial.empty())
    out << "robot: " << r.cell->controller.robot_type << ", serial " << r.cell->controller.serial
        << ", RobotWare " << r.cell->controller.software_version << "\n";
  // Joints 2..5, the first four parameters, in the solver's order.
  std::vector<const ParameterEstimate*> offsets;
  for (const ParameterEstimate& p : r.report.parameters)
    if (p.name.rfind("delta", 0) == 0) offsets.push_back(&p);
  if (!offsets.empty()) {
    std::string line;
    line = fmt::format("{:<7} {:>12} {:>11}   {:<26}", "offset",
                       against ? "change deg" : "value deg", "sigma deg", "95% interval deg");
    out << "\n" << line << (simulated ? "  truth deg      error" : "") << "\n";
    for (std::size_t k = 0; k < offsets.size(); ++k) {
      const ParameterEstimate& p = *offsets[k];
      const std::string offset = p.name.substr(0, 6);
      if (!p.identifiable || !std::isfinite(p.value)) {
        out << offset << "  not identifiable: " << (p.reason.empty() ? "-" : p.reason) << "\n";
        continue;
      }
      // A verdict that refused the result offers no value, as summary.txt and report.html say:
      // a number on the terminal is a number someone enters (`--json` keeps the solve's).
      if (r.verdict_recorded && !usable) {
        out << offset << "  withheld: the result is not usable\n";
        continue;
      }
      line = fmt::format("{:<7} {:+12.5f} {:11.5f}   [{:+.5f}, {:+.5f}]", offset.c_str(), p.value,
                         p.sigma, p.ci95_low, p.ci95_high);
      out << line;
      if (simulated && k < r.truth->offsets_deg.size()) {
        const double truth = r.truth->offsets_deg[k];
        line = fmt::format("  {:+9.5f}  {:+9.5f}", truth, p.value - truth);
        out << line;
      }
      out << "\n";
    }
    const bool writes = r.kind == SessionKind::kCalibration || r.kind == SessionKind::kRestore;
    if (!writes) {
      out << "\nNothing is written by a " << sessionKindName(r.kind)
          << (r.kind == SessionKind::kCheck ? "; a restore against its reference finds the values "
                                              "that bring the robot back.\n"
                                            : ".\n");
    } else if (applied.is_object() && !applied.empty()) {
      printApplied(applied, out);
    } else {
      out << "\nOn the controller (arm side, joint angles; nothing was written to it):\n";
      if (against && usable)
        out << "  the values that bring the robot back to reference " << r.reference
            << " (`zerocal apply --confirm` writes them, verifies them by a check, and rolls "
               "back unless it passes):\n";
      if (!usable) out << "  change nothing: the verdict is not usable.\n";
      for (std::size_t k = 0; usable && k < offsets.size(); ++k) {
        const ParameterEstimate& p = *offsets[k];
        if (!p.identifiable || !std::isfinite(p.value)) continue;
        line = fmt::format(
            "  joint {}: the reading grows by {:+.5f} deg (its zero moves {:+.5f} deg)\n",
            p.name[5], p.value, -p.value);
        out << line;
      }
      if (usable) out << "  joints 1 and 6: unchanged (this method cannot determine them).\n";
      out << "summary.txt and report.html in the session folder (`zerocal sessions` lists it) say\n"
             "where the IRC5 keeps the calibration and how to enter it.\n";
    }
  }
  if (r.cell_time_s) {
    std::string line;
    line = fmt::format("cell time {:.1f} s, {} poses\n", *r.cell_time_s, r.report.pose_count);
    out << line;
  }
}

// A result as the port sends it: result.json, read by the results codec the daemon writes it with.
ResultFile resultOf(const json& answer) {
  try {
    return resultFileFromJson(answer);
  } catch (const InputError& e) {
    throw CommandError("bad_result",
                       std::string("the daemon's result cannot be read: ") + e.what());
  }
}

// A watch ends when the session does, or when it waits for the technician to move the PSD (who
// then runs `zerocal continue`).
bool watchEnds(const json& status) {
  return !status.value("active", false) || status.value("state", "") == "awaiting_placement";
}

// What a finished session's result says, as an exit status (docs/cli.md's table): 0 usable
// (a check: passed), 8 not usable, 9 a check that found a zero moved or could not tell.
int exitForOutcome(const ResultFile& r) {
  if (!verdictOf(r).first) return kClientNotUsable;
  if (r.check && r.check->outcome != CheckJudgement::Outcome::kPass) return kClientCheckNotPassed;
  return kClientOk;
}

int exitFor(const std::string& state) {
  return state == "aborted" || state == "faulted" || state == "unrecovered" ? kClientSessionFailed
                                                                            : kClientOk;
}

// Follows the session until it ends. Events drive the display; a status poll every few seconds
// also ends the watch if an event was missed.
int watch(control::ControlClient& client, const ClientArgs& args, std::ostream& out, bool tty) {
  const auto timeout = std::chrono::duration_cast<std::chrono::steady_clock::duration>(
      std::chrono::duration<double>(args.timeout_s));
  json status = client.call("subscribe", json::object(), timeout)["status"];
  // A terminal gets one line, redrawn; a pipe a line per pose recorded and per change of state
  // outside the poses (connecting, planning, solving, awaiting the technician, the end).
  int shown_recorded = status.value("recorded", 0);
  std::string shown_state;
  auto show = [&](const json& s, bool changed) {
    if (args.json) return;
    if (tty) {
      if (changed) out << "\r\033[K" << barLine(s) << std::flush;
      return;
    }
    const std::string state = s.value("state", "");
    const int recorded = s.value("recorded", 0);
    if (recorded > shown_recorded) {
      shown_recorded = recorded;
      out << poseLine(s) << "\n" << std::flush;
    }
    if (state != shown_state && !isPoseState(state)) out << progressLine(s) << "\n" << std::flush;
    if (!isPoseState(state) || shown_state.empty()) shown_state = state;
  };
  std::string last_line = barLine(status);
  show(status, true);
  auto last_poll = std::chrono::steady_clock::now();
  while (!watchEnds(status)) {
    auto event = client.nextEvent(std::chrono::seconds(1));
    if (event) {
      if (args.json) out << event->dump() << "\n" << std::flush;
      const std::string kind = event->value("event", "");
      if (kind == "status") {
        status = (*event)["status"];
      } else if (kind == "state" || kind == "pose") {
        for (const auto& item : event->items())
          if (item.key() != "event")
            status[item.key() == "servo_error_um" ? "last_servo_error_um" : item.key()] =
                item.value();
        if (kind == "state") status["active"] = !isFinal(status.value("state", ""));
        // The live error belongs to the servo; the next status event brings a fresh one.
        if (kind == "pose" || status.value("state", "") != "servoing")
          status.erase("live_servo_error_um");
        if (kind == "pose")
          status["recorded"] = std::max(status.value("recorded", 0), event->value("pose", 0));
      }
    }
    if (!event || std::chrono::steady_clock::now() - last_poll > std::chrono::seconds(5)) {
      status = client.call("status", json::object(), timeout)["status"];
      last_poll = std::chrono::steady_clock::now();
    }
    const auto line = barLine(status);
    show(status, line != last_line);
    last_line = line;
  }
  status = client.call("status", json::object(), timeout)["status"];  // the final figures
  if (tty && !args.json) out << "\r\033[K";
  if (args.json) {
    out << json{{"status", status}}.dump() << "\n";
  } else {
    // Plain lines: the last one shown may already be the final one.
    if (tty || status.value("state", "") != shown_state) out << progressLine(status) << "\n";
    if (status.contains("message")) out << status["message"].get<std::string>() << "\n";
  }
  if (status.value("state", "") != "done") return exitFor(status.value("state", ""));
  // The outcome: the verdict and the offsets, and the exit status a script reads it by.
  try {
    const json answer =
        client.call("result", json{{"session", status.value("session", "")}}, timeout);
    const ResultFile result = resultOf(answer["result"]);
    if (!args.json) {
      out << "\n";
      printResult(result, answer.value("apply", json()), out);
    }
    return exitForOutcome(result);
  } catch (const CommandError& e) {  // done, but its result cannot be read: say so
    if (!args.json)
      out << "the result of session " << status.value("session", "")
          << " cannot be shown: " << e.what() << " (zerocal result)\n";
    return kClientFailure;
  }
}

// The numbers of an apply event, as the technician reads them.
void printApplyEvent(const json& e, std::ostream& out) {
  const auto rad = [](const json& a, int joint) {
    return a.is_array() && a.size() == 6 ? fmt::format("{:.6f}", a[joint - 1].get<double>()) : "?";
  };
  if (e.contains("before_rad") && !e.contains("written_rad")) {
    out << "cal_offset now (rad):";
    for (int j = 2; j <= 5; ++j) out << "  joint " << j << " " << rad(e["before_rad"], j);
    out << "\n";
  } else if (e.contains("before_rad") || e.contains("written_rad")) {
    out << "cal_offset (rad)   before      written\n";
    for (int j = 2; j <= 5; ++j)
      out << "  joint " << j << "         " << rad(e.value("before_rad", json()), j) << "    "
          << (e.contains("written_rad") ? rad(e["written_rad"], j) : std::string("-")) << "\n";
  }
  if (e.contains("remaining_deg")) {
    out << "left after it, as the verification " << e.value("verification", "")
        << " measured (deg):\n";
    for (const auto& item : e["remaining_deg"].items()) {
      std::string line;
      line = fmt::format("  {:<8} {:+.5f}  (sigma {:.5f})\n", item.key().c_str(),
                         item.value().value("value", 0.0), item.value().value("sigma", 0.0));
      out << line;
    }
  }
}

// An apply's or verification's outcome as an exit status: one cause, one code, whether `apply`
// or `verify` met it. A verification that could not complete (the apply then rolled back) is 3,
// one that found the values wrong 8.
int exitForApply(const std::string& outcome, const std::string& message) {
  if (outcome == "verified" || outcome == "pass" || outcome == "recovered" ||
      outcome == "acknowledged")
    return kClientOk;
  // The daemon's words for it (ApplyCoordinator), the same in both.
  const bool incomplete = message.rfind("the verification did not complete", 0) == 0;
  if ((outcome == "rolled_back" || outcome == "fail") && !incomplete)
    return kClientVerificationFailed;
  return kClientSessionFailed;
}

// Sends `apply` or `verify` and follows it to its apply event: progress lines, the verification's
// poses, the outcome. Subscribed before the request, so no event of it is missed.
int followApply(control::ControlClient& client, const std::string& cmd, const json& members,
                const ClientArgs& args, std::ostream& out) {
  const auto timeout = std::chrono::duration_cast<std::chrono::steady_clock::duration>(
      std::chrono::duration<double>(args.timeout_s));
  client.call("subscribe", json::object(), timeout);
  const std::string id = client.call(cmd, members, timeout).value("session", "");
  if (!args.json)
    out << (cmd == "apply"    ? "applying session "
            : cmd == "verify" ? "verifying session "
                              : "acknowledging the interrupted apply of session ")
        << id << "\n"
        << std::flush;
  std::string verification;
  auto last_poll = std::chrono::steady_clock::now();
  for (;;) {
    auto event = client.nextEvent(std::chrono::seconds(1));
    if (event) {
      if (args.json) out << event->dump() << "\n" << std::flush;
      const std::string kind = event->value("event", "");
      const std::string session = event->value("session", "");
      if (kind == "apply_progress" && session == id && !args.json) {
        out << "  " << event->value("message", "") << "\n" << std::flush;
      } else if (kind == "plan" && !args.json) {
        verification = session;
        out << "  verification session " << session << ": " << event->value("pose_count", 0)
            << " poses\n"
            << std::flush;
      } else if (kind == "pose" && session == verification && !args.json) {
        out << "  verification pose " << event->value("pose", 0) << " of "
            << event->value("pose_count", 0) << "\n"
            << std::flush;
      } else if (kind == "apply" && session == id) {
        const std::string outcome = event->value("outcome", "");
        if (!args.json) {
          out << outcome << ": " << event->value("message", "") << "\n";
          printApplyEvent(*event, out);
          if (outcome == "verified")
            out << "Before use:\n"
                   "  - Taught positions (robtargets and jointtargets) move physically by the "
                   "corrected offsets: check them at reduced speed.\n"
                   "  - Absolute Accuracy data (MOC ARM_CALIB) and a later fine calibration at the "
                   "synchronisation marks refer to the old zeros: they no longer match.\n";
        }
        return exitForApply(outcome, event->value("message", ""));
      }
    }
    if (!event || std::chrono::steady_clock::now() - last_poll > std::chrono::seconds(5)) {
      // An event missed (a slow reader is dropped events): the status says how it ended.
      const json status = client.call("status", json::object(), timeout)["status"];
      last_poll = std::chrono::steady_clock::now();
      const std::string apply = status.value("apply", "");
      const std::string prefix = "session " + id + " ";
      if (!status.value("active", false) && apply.rfind(prefix, 0) == 0) {
        if (!args.json) out << apply.substr(prefix.size()) << "\n";
        const std::size_t colon = apply.find(':');
        const std::string outcome = apply.substr(prefix.size(), colon - prefix.size());
        return exitForApply(outcome, colon == std::string::npos ? "" : apply.substr(colon + 2));
      }
    }
  }
}

json startMembers(const ClientArgs& args) {
  json m = json::object();
  if (!args.pattern.empty()) m["plan"] = args.pattern;
  if (args.poses) m["poses"] = *args.poses;
  if (!args.plan_file.empty()) m["plan_file"] = args.plan_file;
  if (!args.target.empty()) m["target_mm"] = args.target;
  if (args.noise_mm) m["noise_mm"] = *args.noise_mm;
  if (args.placements) m["placements"] = *args.placements;
  if (args.even_if_not_usable) m["even_if_not_usable"] = true;
  if (!args.kind.empty()) m["kind"] = args.kind == "calibrate" ? "calibration" : args.kind;
  if (!args.reference.empty()) m["reference"] = args.reference;
  return m;
}

json resumeMembers(const ClientArgs& args) {
  json m = json::object();
  if (!args.session.empty()) m["session"] = args.session;
  if (args.skip_pose > 0) m["skip_pose"] = args.skip_pose;
  return m;
}

// The plan's predicted cell time, and what it is from.
std::string cellTimeText(const json& plan) {
  const json t = plan.value("predicted_cell_time", json(nullptr));
  if (!t.is_object()) return "cell time not predicted: the daemon has no finished session to go by";
  const int sessions = t.value("from_sessions", 0);
  return fmt::format(
      "about {:.0f} s of cell time ({:.1f} s a pose in the daemon's latest {} "
      "session{}){}",
      t.value("seconds", 0.0), t.value("per_pose_s", 0.0), sessions, sessions == 1 ? "" : "s",
      plan.value("placements", 1) > 1 ? ", and the PSD moved by hand between its placements" : "");
}

int printPlan(const json& plan, const ClientArgs& args, std::ostream& out) {
  bool identifiable = true;
  const auto& predicted = plan.value("predicted", json::object());
  for (const char* name : {"delta2_deg", "delta3_deg", "delta4_deg", "delta5_deg"})
    if (predicted.contains(name) && !predicted[name].value("identifiable", true))
      identifiable = false;
  if (args.json) {
    out << plan.dump(2) << "\n";
  } else {
    out << plan.value("description", "") << "\n";
    out << "predicted one-sigma uncertainty before any move:\n";
    for (const auto& item : predicted.items()) {
      std::string line;
      if (item.value().value("identifiable", false) && item.value()["sigma"].is_number())
        line = fmt::format("  {:<19} {:10.5f}\n", item.key().c_str(),
                           item.value()["sigma"].get<double>());
      else
        line = fmt::format("  {:<19} not identifiable: {}\n", item.key().c_str(),
                           item.value().value("reason", std::string()).c_str());
      out << line;
    }
    out << plan.value("poses", json::array()).size() << " poses\n";
    out << cellTimeText(plan) << "\n";
    // The daemon's verdict on the plan, as `start` will apply it.
    const double required = plan.value("required_accuracy_deg", 0.0);
    std::string short_of;
    for (const char* name : {"delta2_deg", "delta3_deg", "delta4_deg", "delta5_deg"})
      if (required > 0 && predicted.contains(name) && predicted[name]["sigma"].is_number() &&
          !(predicted[name]["sigma"].get<double>() <= required))
        short_of += std::string(short_of.empty() ? "" : ", ") + std::string(name).substr(0, 6);
    if (!short_of.empty()) {
      std::string line;
      line = fmt::format("{:.4f}", required);
      out << "short of the required " << line << " deg: " << short_of
          << ". `zerocal start` refuses this plan unless --even-if-not-usable (its result would "
             "withhold them); several PSD placements (--placements 3) would reach it, or a "
             "restore against the robot's reference\n";
    }
  }
  return identifiable ? kClientOk : kClientNotIdentifiable;
}

// This program's version, and the daemon's with its protocol when one answers (no token needed).
int version(const ClientArgs& args, std::ostream& out) {
  json v{{"zerocal", PROJECT_VERSION}, {"zerocald", nullptr}};
  std::string unreachable;
  try {
    control::ControlClient client;
    client.connect(args.host, args.port, std::chrono::seconds(2));
    const json r = client.call("version", json::object(), std::chrono::seconds(5));
    v["zerocald"] = r.value("daemon", std::string("?"));
    v["protocol"] = r.value("protocol", json(nullptr));
  } catch (const std::exception& e) {
    unreachable = e.what();
    v["error"] = unreachable;
  }
  const std::string where = args.host + ":" + std::to_string(args.port);
  if (args.json) {
    v["address"] = where;
    out << v.dump() << "\n";
  } else {
    out << "zerocal " << PROJECT_VERSION << "\n";
    if (unreachable.empty())
      out << "zerocald " << v["zerocald"].get<std::string>() << " at " << where
          << ", control protocol " << v["protocol"].dump() << "\n";
    else
      out << "zerocald: none answers at " << where << " (" << unreachable << ")\n";
  }
  return kClientOk;
}

// The newest args.limit sessions (every one with args.all), newest first, page after page, and
// how many the daemon has.
std::pair<json, std::size_t> listSessions(control::ControlClient& client, const ClientArgs& args,
                                          std::chrono::steady_clock::duration timeout) {
  constexpr std::size_t kPage = 1000;  // the daemon's largest
  const std::size_t wanted =
      args.all ? std::numeric_limits<std::size_t>::max() : static_cast<std::size_t>(args.limit);
  json list = json::array();
  json members{{"limit", std::min(wanted, kPage)}};
  for (;;) {
    const json page = client.call("sessions", members, timeout);
    if (!page.contains("total")) {
      // A daemon from before paging: the whole list, oldest first.
      json all = page["sessions"];
      for (auto s = all.rbegin(); s != all.rend() && list.size() < wanted; ++s) list.push_back(*s);
      return {list, all.size()};
    }
    for (const auto& s : page["sessions"])
      if (list.size() < wanted) list.push_back(s);
    if (list.size() >= wanted || !page.contains("next"))
      return {list, page["total"].get<std::size_t>()};
    members = {{"limit", std::min(wanted - list.size(), kPage)}, {"cursor", page["next"]}};
  }
}

int run(const ClientArgs& args, std::ostream& out, std::ostream& err, bool tty) {
  if (args.command == "version") return version(args, out);
  if (args.command == "acknowledge" && !args.confirm) {
    err << "zerocal: acknowledge closes an interrupted apply on your word that the controller's "
           "cal_offset values were checked on the FlexPendant (zerocal status names them); give "
           "--confirm to do it\n";
    return kClientBadRequest;
  }
  control::ControlClient client;
  client.connect(args.host, args.port, std::chrono::seconds(5));
  const auto timeout = std::chrono::duration_cast<std::chrono::steady_clock::duration>(
      std::chrono::duration<double>(args.timeout_s));
  const std::string token_file = args.token_file.empty() ? defaultTokenFile() : args.token_file;
  std::string token;
  try {
    token = control::loadToken(token_file);
  } catch (const Error& e) {
    err << "zerocal: " << e.what() << " (--token-file or ZEROCAL_TOKEN_FILE)\n";
    return kClientAuthRefused;
  }
  client.authenticate(token);

  const auto& cmd = args.command;
  if (cmd == "status") {
    const auto s = client.call("status", json::object(), timeout)["status"];
    if (args.json)
      out << s.dump(2) << "\n";
    else
      printStatus(s, out);
    return kClientOk;
  }
  if (cmd == "watch") return watch(client, args, out, tty);
  if (cmd == "start" || cmd == "resume" || cmd == "continue") {
    json continued = json::object();
    if (!args.centre.empty()) continued["centre_mm"] = args.centre;
    // What a continue goes on with: a session's next placement, or an apply that waited for a
    // revolution counter.
    const bool counter =
        cmd == "continue" && client.call("status", json::object(), timeout)["status"].value(
                                 "state", "") == "awaiting_counter";
    // A start plans before it answers, as `plan` does (21 s for the optimal plan on a 2-core
    // machine busy with a build): the same room beyond --timeout.
    const auto r = cmd == "start"
                       ? client.call("start", startMembers(args), timeout + kPlanningAllowance)
                   : cmd == "resume" ? client.call("resume", resumeMembers(args), timeout)
                                     : client.call("continue", continued, timeout);
    const std::string id = r.value("session", "");
    if (!args.watch) {
      if (args.json)
        out << json{{"session", id}}.dump() << "\n";
      else
        out << "session " << id
            << (cmd == "start"    ? " started"
                : cmd == "resume" ? " resumed"
                : counter         ? ": the apply goes on with the revolution counter updated"
                                  : " continued at its next PSD placement")
            << "\n";
      return kClientOk;
    }
    return watch(client, args, out, tty);
  }
  if (cmd == "abort") {
    const bool aborted = client.call("abort", json::object(), timeout).value("aborted", false);
    if (args.json)
      out << json{{"aborted", aborted}}.dump() << "\n";
    else
      out << (aborted ? "abort requested; no further move is sent, the robot stops"
                      : "no session was running")
          << "\n";
    return kClientOk;
  }
  if (cmd == "sessions") {
    const auto [list, total] = listSessions(client, args, timeout);
    if (args.json) {
      out << list.dump(2) << "\n";
    } else {
      for (const auto& s : list) {
        std::string line;
        line = fmt::format("{:<24} {:<10} {:3} of {:3} poses  {}\n", s.value("id", "").c_str(),
                           s.contains("damaged")        ? "DAMAGED"
                           : s.value("finished", false) ? "finished"
                                                        : "unfinished",
                           s.value("recorded_poses", 0), s.value("planned_poses", 0),
                           s.value("dir", "").c_str());
        out << line;
        if (s.value("skipped_poses", 0) > 0)
          out << "    " << s.value("skipped_poses", 0) << " of them skipped\n";
        if (s.contains("damaged")) out << "    " << s.value("damaged", "") << "\n";
      }
      if (list.empty()) out << "no sessions\n";
      if (list.size() < total)
        out << "the newest " << list.size() << " of " << total
            << " sessions; --limit N for more, --all for every one\n";
    }
    return kClientOk;
  }
  if (cmd == "robots") {
    const json robots = client.call("robots", json::object(), timeout)["robots"];
    if (args.json)
      out << robots.dump(2) << "\n";
    else
      printRobots(robots, out);
    return kClientOk;
  }
  if (cmd == "history") {
    json members = json::object();
    if (!args.serial.empty()) members["serial"] = args.serial;
    if (!args.robot_type.empty()) members["robot_type"] = args.robot_type;
    const json r = client.call("history", members, timeout);
    const json answer{{"robot", r["robot"]}, {"history", r["history"]}};
    if (args.json)
      out << answer.dump(2) << "\n";
    else if (args.csv)
      printHistoryCsv(answer, out);
    else
      printHistory(answer, out);
    return kClientOk;
  }
  if (cmd == "result") {
    const json answer = client.call(
        "result", args.session.empty() ? json::object() : json{{"session", args.session}}, timeout);
    const ResultFile result = resultOf(answer["result"]);
    if (args.json)
      out << answer["result"].dump(2) << "\n";
    else
      printResult(result, answer.value("apply", json()), out);
    return exitForOutcome(result);
  }
  if (cmd == "apply") {
    json members{{"confirm", args.confirm}};
    if (!args.session.empty()) members["session"] = args.session;
    return followApply(client, "apply", members, args, out);
  }
  if (cmd == "acknowledge") {
    json members{{"confirm", args.confirm}};
    if (!args.session.empty()) members["session"] = args.session;
    return followApply(client, "acknowledge", members, args, out);
  }
  if (cmd == "verify") {
    return followApply(client, "verify",
                       args.session.empty() ? json::object() : json{{"session", args.session}},
                       args, out);
  }
  if (cmd == "plan") {
    const auto r = client.call("plan", startMembers(args), timeout + kPlanningAllowance);
    return printPlan(r["plan"], args, out);
  }
  err << "zerocal: unknown client command '" << cmd << "'\n";
  return kClientBadRequest;
}

}  // namespace

std::string defaultTokenFile() {
  const char* env = std::getenv("ZEROCAL_TOKEN_FILE");
  return env && *env ? env : std::string(kConfigDir) + "/token";
}

void addConnectionOptions(CLI::App* command, ClientArgs& args) {
  command->add_option("--host", args.host, "zerocald's address")->default_val(args.host);
  command->add_option("--port", args.port, "zerocald's control port")->default_val(args.port);
  command->add_option(
      "--token-file", args.token_file,
      "the access token (default $ZEROCAL_TOKEN_FILE, else " + std::string(kConfigDir) + "/token)");
  command
      ->add_option("--timeout", args.timeout_s,
                   "seconds to wait for an answer (start and plan: 60 more, for planning)")
      ->default_val(args.timeout_s)
      ->check(CLI::PositiveNumber);
}

void addClientCommands(CLI::App& app, ClientCommands& commands) {
  auto& a = commands.args;
  auto add = [&](const char* name, const char* help) {
    auto* c = app.add_subcommand(name, help);
    addConnectionOptions(c, a);
    c->add_flag("--json", a.json, "JSON instead of text (watch: one event per line)");
    c->callback([&a, name] { a.command = name; });
    commands.apps.push_back(c);
    return c;
  };
  auto* start = add("start",
                    "start a session on zerocald: a calibration, or a reference, check or restore "
                    "of the robot's zeros (--kind)");
  start
      ->add_option("--kind", a.kind,
                   "calibrate (the absolute zeros; the default), reference (record the zeros "
                   "of a robot known good, for later checks and restores), check (have the "
                   "zeros moved since the reference? a few poses, nothing written) or restore "
                   "(the change since the reference, which `zerocal apply` writes back)")
      ->check(CLI::IsMember({"calibrate", "reference", "check", "restore"}));
  start->add_option("--reference", a.reference,
                    "the reference session a check or restore compares with (default the "
                    "latest usable one)");
  start->add_option("--pattern", a.pattern, "optimal, I, II, mixed or file (default the daemon's)")
      ->check(CLI::IsMember({"optimal", "I", "II", "mixed", "file"}));
  start->add_option("--poses", a.poses, "number of poses (default the daemon's)")
      ->check(CLI::Range(kMinimumPoses, kMaxPlanPoses));
  start->add_option("--plan-file", a.plan_file,
                    "joint-set file on the daemon's host (--pattern file)");
  start->add_option("--target", a.target, "nominal PSD centre X Y Z in mm (default the cell's)")
      ->expected(3);
  start->add_option("--noise", a.noise_mm, "measurement sigma in mm")->check(CLI::PositiveNumber);
  start
      ->add_option("--placements", a.placements,
                   "PSD placements, --poses at each; the session waits for the PSD to be moved "
                   "between them (default the daemon's)")
      ->check(CLI::Range(1, kMaxDefaultPlacements));
  start->add_flag("--even-if-not-usable", a.even_if_not_usable,
                  "start even when the plan is predicted not to determine every offset to the "
                  "daemon's session.required_accuracy_deg (refused otherwise, before anything "
                  "moves); the result then withholds those offsets");
  start->add_flag("--watch", a.watch,
                  "then show its progress until it ends or waits for the PSD to be moved");
  add("status", "the daemon's session state");
  add("watch", "live progress of the running session; exits when it ends");
  add("abort", "stop the running session (the robot stops)");
  auto* resume = add("resume", "resume an unfinished session from its journal");
  resume->add_option("session", a.session, "session id (default the latest unfinished)");
  resume
      ->add_option("--skip-pose", a.skip_pose,
                   "skip this pose, the next one to measure (its spot was never found, say); "
                   "refused unless the plan identifies every offset without it")
      ->check(CLI::PositiveNumber);
  resume->add_flag("--watch", a.watch, "then show its progress until it ends");
  auto* go_on = add("continue",
                    "go on with the session waiting for the PSD at its next placement, once the "
                    "PSD is there, or with the apply waiting for a revolution counter, once the "
                    "technician has updated it at the FlexPendant");
  go_on
      ->add_option("--centre", a.centre,
                   "the placement's centre as taught, X Y Z in mm, robot base frame (default "
                   "its planned centre)")
      ->expected(3);
  go_on->add_flag("--watch", a.watch,
                  "then show its progress until it ends or waits for the PSD to be moved");
  auto* sessions = add("sessions", "the sessions in the daemon's data folder, newest first");
  sessions->add_option("--limit", a.limit, "show the newest this many")
      ->default_val(a.limit)
      ->check(CLI::PositiveNumber);
  sessions->add_flag("--all", a.all, "show every session");
  auto* result =
      add("result", "the verdict and offsets of a finished session (--json: its result.json)");
  result->add_option("session", a.session, "session id (default the latest)");
  auto* verify = add("verify",
                     "measure the offsets left after an apply with a short calibration on zerocald "
                     "and judge them (nothing is written)");
  verify->add_option("session", a.session, "the applied session's id (default the latest applied)");
  auto* acknowledge =
      add("acknowledge",
          "after an interrupted apply the daemon could not recover (state unrecovered): say that "
          "the controller's cal_offset values were checked by hand on the FlexPendant, so that "
          "sessions may run again (journalled with the apply)");
  acknowledge->add_option("session", a.session,
                          "the interrupted apply's session id (default every one)");
  acknowledge->add_flag("--confirm", a.confirm,
                        "the values were checked on the controller and are the ones the robot is "
                        "to run on");
  add("robots", "the robots in the daemon's record: each one's sessions, first and latest");
  auto* history = add("history",
                      "a robot's sessions from the daemon's record, oldest first: date, kind, "
                      "verdict, each offset with its sigma, and each apply, verification and "
                      "rollback with the controller's values");
  history->add_option("serial", a.serial,
                      "the robot's controller serial (default the record's only robot)");
  history->add_option("--type", a.robot_type, "the robot's type, when two robots share a serial");
  history->add_flag("--csv", a.csv, "CSV, a row per session (for a spreadsheet)");
  add("version", "this zerocal's version, and zerocald's and its protocol when one answers");
}

int runClient(const ClientArgs& args, std::ostream& out, std::ostream& err, bool tty) {
  try {
    return run(args, out, err, tty);
  } catch (const CommandError& e) {
    err << "zerocal: " << args.command << " refused (" << e.code() << "): " << e.what() << "\n";
    if (e.code() == "auth_failed" || e.code() == "unauthenticated") return kClientAuthRefused;
    if (e.code() == "not_identifiable" || e.code() == "not_accurate") return kClientNotIdentifiable;
    if (e.code() == "internal") return kClientFailure;
    return kClientBadRequest;
  } catch (const ConnectionError& e) {
    err << "zerocal: " << e.what() << " (is zerocald running? --host, --port)\n";
    return kClientCannotConnect;
  } catch (const std::exception& e) {
    err << "zerocal: unexpected failure: " << e.what() << "\n";
    return kClientFailure;
  }
}

}  // namespace zerocal::cli
