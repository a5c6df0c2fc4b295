#include "zerocal/apply/online_apply.h"

#include <fcntl.h>
#include <fmt/printf.h>
#include <unistd.h>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <set>

#include "zerocal/error.h"

namespace zerocal::apply {

namespace {

using nlohmann::json;

constexpr double kDeg = 57.29577951308232;

// printf's format, as long as the text is.
std::string printed(const char* format, double a, double b = 0, double c = 0) {
  return fmt::sprintf(format, a, b, c);
}

json offsetsJson(const Offsets& o) {
  json a = json::array();
  for (const auto& m : o) a.push_back({{"value_deg", m.value_deg}, {"sigma_deg", m.sigma_deg}});
  return a;
}

// Writes joints 2..5 of `values`, restarts, and checks the controller reads them back.
void writeAndRestart(ControllerCalibration& store, const std::array<double, 6>& values) {
  for (int j = 2; j <= 5; ++j) store.writeCalOffset(j, values[j - 1]);
  store.restart();
  const std::array<double, 6> now = store.readCalOffsets();
  for (int j = 2; j <= 5; ++j)
    if (std::abs(now[j - 1] - values[j - 1]) > 2e-6)
      throw Error("joint " + std::to_string(j) + ": the controller reads back cal_offset " +
                  printed("%.6f", now[j - 1]) + " after writing " + printed("%.6f", values[j - 1]));
}

}  // namespace

std::string valuesText(const std::array<double, 6>& v) {
  std::string s;
  for (int j = 2; j <= 5; ++j)
    s += "rob1_" + std::to_string(j) + " " + printed("%.6f", v[j - 1]) + " ";
  return s;
}

void ApplyJournal::append(json line) {
  line["time_unix_s"] =
      std::chrono::duration<double>(std::chrono::system_clock::now().time_since_epoch()).count();
  const std::string text = line.dump() + "\n";
  const int fd = ::open(path_.c_str(), O_WRONLY | O_CREAT | O_APPEND | O_CLOEXEC, 0644);
  bool ok = fd >= 0 && ::write(fd, text.data(), text.size()) == static_cast<ssize_t>(text.size());
  ok = ok && ::fsync(fd) == 0;
  if (fd >= 0) ::close(fd);
  if (!ok) throw Error(path_ + ": cannot journal the apply step; nothing more is done");
}

std::vector<json> ApplyJournal::read() const {
  std::vector<json> lines;
  std::ifstream in(path_);
  std::string line;
  while (std::getline(in, line)) {
    if (line.empty()) continue;
    try {
      lines.push_back(json::parse(line));
    } catch (const json::exception&) {
      break;  // a line cut short by a crash: the last one
    }
  }
  return lines;
}

Verdict judge(const std::array<CalOffsetChange, 4>& changes, const Offsets& before,
              const Offsets& after, double required_deg) {
  Verdict v{true, ""};
  std::string reasons;
  for (int k = 0; k < 4; ++k) {
    const int j = k + 2;
    const double a = after[k].value_deg, b = before[k].value_deg;
    const double sigma = after[k].sigma_deg;
    const double bound = std::max(3 * sigma, required_deg);
    if (std::abs(a) <= bound) continue;
    v.pass = false;
    const std::string d = "delta" + std::to_string(j);
    const double turn_deg = kTwoPi / changes[k].transmission * kDeg;
    std::string why;
    if (std::abs(b) > 3 * sigma && std::abs(a / b - 2.0) < 0.25)
      why = d + " doubled (" + printed("%+.4f deg before, %+.4f deg after", b, a) +
            "): the sign of joint " + std::to_string(j) + "'s transmission is wrong";
    else if (std::abs(std::abs(a) - std::abs(turn_deg)) < std::max(bound, 0.02))
      why = "joint " + std::to_string(j) + printed(" is one motor turn (%+.4f deg) off", a) +
            ": its revolution counter was not updated at the synchronisation mark";
    else if (std::abs(b) > 3 * sigma && std::abs(a) > 5 * sigma && std::abs(1 - a / b) > 0.05)
      why = d + printed(" went from %+.4f to %+.4f deg", b, a) + ": joint " + std::to_string(j) +
            "'s transmission looks like " +
            printed("%+.1f", changes[k].transmission / (1 - a / b)) + ", not " +
            printed("%+g", changes[k].transmission);
    else
      why = d + printed(" = %+.4f deg remains, beyond max(3 sigma, required) = %.4f deg", a, bound);
    reasons += (reasons.empty() ? "" : "; ") + why;
  }
  v.message = v.pass ? "every remaining offset of joints 2..5 is within max(3 sigma, " +
                           printed("%.4f", required_deg) + " deg)"
                     : reasons;
  return v;
}

OnlineApplyOutcome applyOnline(ControllerCalibration& store,
                               const std::array<CalOffsetChange, 4>& changes, const Offsets& before,
                               const OnlineApplyOptions& options, ApplyJournal& journal) {
  const auto say = [&](const std::string& s) {
    if (options.progress) options.progress(s);
  };
  OnlineApplyOutcome out;
  out.before_rad = store.readCalOffsets();
  out.written_rad = out.before_rad;
  json changes_json = json::array();
  for (const CalOffsetChange& c : changes) {
    if (std::abs(out.before_rad[c.joint - 1] - c.old_rad) > 2e-6)
      throw Error("joint " + std::to_string(c.joint) + ": the controller holds cal_offset " +
                  printed("%.6f", out.before_rad[c.joint - 1]) +
                  ", the new value was computed from " + printed("%.6f", c.old_rad) +
                  "; nothing was written");
    out.written_rad[c.joint - 1] = c.new_rad;
    changes_json.push_back({{"joint", c.joint},
                            {"delta_rad", c.delta_rad},
                            {"transmission", c.transmission},
                            {"old_rad", c.old_rad},
                            {"new_rad", c.new_rad},
                            {"turns", c.turns},
                            {"formula", formulaText(c)}});
  }
  journal.append({{"step", "begin"},
                  {"controller",
                   {{"robot_type", options.controller.robot_type},
                    {"serial", options.controller.serial},
                    {"software_version", options.controller.software_version}}},
                  {"before_rad", out.before_rad},
                  {"new_rad", out.written_rad},
                  {"changes", changes_json},
                  {"offsets_before", offsetsJson(before)}});
  say("backed up: " + valuesText(out.before_rad));
  std::set<int> counters_updated;
  const auto rollBack = [&](const std::string& reason) {
    journal.append({{"step", "rolling_back"}, {"reason", reason}});
    say("rolling back: " + reason);
    writeAndRestart(store, out.before_rad);
    for (int j : counters_updated) {
      // The counter was moved to the new value's turn: back on the old value it must move back.
      journal.append({{"step", "revolution_counter"}, {"joint", j}});
      if (!options.update_revolution_counter ||
          !options.update_revolution_counter(j, -changes[j - 2].turnErrorRad() * kDeg))
        throw Error("rolled back, but joint " + std::to_string(j) +
                    "'s revolution counter must be updated again at its synchronisation mark");
    }
    journal.append({{"step", "done"}, {"outcome", "rolled_back"}, {"message", reason}});
    out.state = ApplyState::kRolledBack;
    out.message = reason;
    say("restored: " + valuesText(out.before_rad));
  };
  try {
    for (int j = 2; j <= 5; ++j) store.writeCalOffset(j, out.written_rad[j - 1]);
    journal.append({{"step", "written"}});
    say("written: " + valuesText(out.written_rad));
    journal.append({{"step", "restarting"}});
    store.restart();
    journal.append({{"step", "restarted"}});
    const std::array<double, 6> now = store.readCalOffsets();
    for (int j = 2; j <= 5; ++j)
      if (std::abs(now[j - 1] - out.written_rad[j - 1]) > 2e-6) {
        rollBack("joint " + std::to_string(j) + ": the controller reads back " +
                 printed("%.6f", now[j - 1]) + " after the restart, not the " +
                 printed("%.6f", out.written_rad[j - 1]) + " written");
        return out;
      }
    for (const CalOffsetChange& c : changes) {
      if (!c.crossesSeam()) continue;
      say("joint " + std::to_string(c.joint) +
          ": the new value crosses the seam; its revolution counter needs an update at its mark");
      journal.append({{"step", "revolution_counter"}, {"joint", c.joint}});
      if (!options.update_revolution_counter ||
          !options.update_revolution_counter(c.joint, c.turnErrorRad() * kDeg)) {
        rollBack("joint " + std::to_string(c.joint) +
                 "'s revolution counter was not updated after a seam crossing");
        return out;
      }
      counters_updated.insert(c.joint);
    }
    say("verifying by measurement");
    try {
      out.after = options.verify();
    } catch (const std::exception& e) {
      // No measurement, no new values: the backup goes back.
      rollBack(std::string("the verification did not complete: ") + e.what());
      return out;
    }
    const Verdict v = judge(changes, before, out.after, options.required_deg);
    journal.append({{"step", "verified"},
                    {"pass", v.pass},
                    {"offsets_after", offsetsJson(out.after)},
                    {"message", v.message}});
    if (!v.pass) {
      rollBack(v.message);
      return out;
    }
    journal.append({{"step", "done"}, {"outcome", "verified"}, {"message", v.message}});
    out.state = ApplyState::kVerified;
    out.message = v.message;
    return out;
  } catch (const std::exception& e) {
    try {
      journal.append({{"step", "error"}, {"message", e.what()}});
    } catch (...) {
    }
    throw Error(std::string("apply interrupted: ") + e.what() +
                " (recoverApply restores the backed-up values)");
  }
}

void journalTransmissionCheck(ApplyJournal& journal,
                              const std::vector<TransmissionMeasurement>& measurements) {
  json rows = json::array();
  bool agree = true;
  std::string message;
  for (const TransmissionMeasurement& m : measurements) {
    rows.push_back({{"joint", m.joint},
                    {"configured", m.configured},
                    {"measured", m.measured},
                    {"joint_step_deg", m.joint_step_deg},
                    {"motor_change_rad", m.motor_change_rad},
                    {"agrees", m.agrees},
                    {"message", m.message}});
    if (!m.agrees) message += (message.empty() ? "" : "; ") + m.message;
    agree = agree && m.agrees;
  }
  journal.append({{"step", "transmission_check"},
                  {"agree", agree},
                  {"measurements", rows},
                  {"message", agree ? "the robot file's transmissions agree with the cell"
                                    : message + "; nothing was written"}});
}

namespace {

Offsets offsetsFrom(const json& a) {
  Offsets o{};
  for (std::size_t k = 0; k < 4 && k < a.size(); ++k)
    o[k] = {a[k].value("value_deg", 0.0), a[k].value("sigma_deg", 0.0)};
  return o;
}

}  // namespace

std::optional<ApplyRecord> lastApplyRecord(const ApplyJournal& journal) {
  std::optional<ApplyRecord> r;
  // A check that agreed belongs to the apply whose "begin" follows it.
  std::vector<ApplyRecord::Transmission> checked;
  try {
    for (const json& line : journal.read()) {
      const std::string step = line.value("step", "");
      if (step == "transmission_check") {
        checked.clear();
        for (const json& m : line.at("measurements"))
          checked.push_back({m.at("joint").get<int>(), m.at("configured").get<double>(),
                             m.at("measured").get<double>(), m.at("agrees").get<bool>()});
        if (!line.value("agree", false)) {
          r.emplace();
          r->outcome = "refused";
          r->time_unix_s = line.value("time_unix_s", 0.0);
          r->message = line.value("message", "");
          r->transmissions = std::move(checked);
          checked.clear();
        }
      } else if (step == "begin") {
        r.emplace();
        r->transmissions = std::move(checked);
        checked.clear();
        r->outcome = "interrupted";
        r->time_unix_s = line.value("time_unix_s", 0.0);
        r->before_rad = line.at("before_rad").get<std::array<double, 6>>();
        r->written_rad = line.at("new_rad").get<std::array<double, 6>>();
        for (const json& c : line.value("changes", json::array()))
          r->formulas.push_back(c.value("formula", ""));
      } else if (step == "verify" && r && !r->formulas.empty()) {
        // A verification after an apply: the apply stays what the report shows, with it.
        r->later_check = ApplyRecord::LaterCheck{
            line.value("pass", false) ? "pass" : "fail", line.value("session", ""),
            line.value("message", ""), offsetsFrom(line.value("offsets_after", json::array()))};
      } else if (step == "verify") {
        r.emplace();
        r->time_unix_s = line.value("time_unix_s", 0.0);
        r->outcome = line.value("pass", false) ? "pass" : "fail";
        r->verification = line.value("session", "");
        r->remaining = offsetsFrom(line.value("offsets_after", json::array()));
        r->message = line.value("message", "");
      } else if (!r) {
        continue;  // a file apply's record, or a line before any apply
      } else if (step == "verification") {
        r->verification = line.value("session", "");
      } else if (step == "verified") {
        r->remaining = offsetsFrom(line.value("offsets_after", json::array()));
      } else if (step == "error") {
        r->outcome = "error";
        r->message = line.value("message", "");
      } else if (step == "recovery_refused") {
        r->outcome = "unrecovered";
        r->message = line.value("message", "");
      } else if (step == "done") {
        r->outcome = line.value("outcome", "");
        r->message = line.value("message", "");
      }
    }
  } catch (const std::exception&) {
    return std::nullopt;  // a line of another shape: the report says nothing rather than wrong
  }
  return r;
}

const char* recoveryOutcomeName(RecoveryOutcome outcome) {
  switch (outcome) {
    case RecoveryOutcome::kNotNeeded:
      return "not_needed";
    case RecoveryOutcome::kNothingWritten:
      return "not_written";
    case RecoveryOutcome::kRestored:
      return "recovered";
    case RecoveryOutcome::kConflict:
      return "conflict";
    case RecoveryOutcome::kForeign:
      return "foreign";
  }
  return "?";
}

namespace {

// The journal's last apply that has no "done" line: its lines from "begin" on; empty when none.
std::vector<json> openApply(const ApplyJournal& journal) {
  std::vector<json> lines = journal.read();
  int begin = -1;
  for (int i = 0; i < static_cast<int>(lines.size()); ++i) {
    const std::string step = lines[i].value("step", "");
    if (step == "begin") begin = i;
    if (step == "done") begin = -1;
  }
  if (begin < 0) return {};
  return {lines.begin() + begin, lines.end()};
}

bool sameValue(double a, double b) { return std::abs(a - b) <= 2e-6; }

std::string identityText(const std::string& type, const std::string& serial) {
  return "'" + type + "' serial '" + serial + "'";
}

}  // namespace

bool applyInterrupted(const ApplyJournal& journal) { return !openApply(journal).empty(); }

std::string interruptedApplyValues(const ApplyJournal& journal) {
  try {
    const std::vector<json> lines = openApply(journal);
    if (lines.empty()) return "";
    return "The controller's MOC MOTOR_CALIB cal_offset values must be this apply's backup " +
           valuesText(lines.front().at("before_rad").get<std::array<double, 6>>()) +
           "or its written values " +
           valuesText(lines.front().at("new_rad").get<std::array<double, 6>>());
  } catch (const std::exception&) {
    return "";
  }
}

Recovery recoverApply(ControllerCalibration& store, ApplyJournal& journal,
                      const RobotInfo& controller) {
  Recovery r;
  const std::vector<json> lines = openApply(journal);
  if (lines.empty()) return r;
  std::string last = "begin";
  bool restarted = false;
  std::set<int> counters;
  for (const json& line : lines) {
    last = line.value("step", "");
    restarted = restarted || last == "restarting";
    if (last == "revolution_counter") counters.insert(line.value("joint", 0));
  }
  const json& begin = lines.front();
  try {
    r.backup_rad = begin.at("before_rad").get<std::array<double, 6>>();
    r.written_rad = begin.at("new_rad").get<std::array<double, 6>>();
  } catch (const json::exception& e) {
    throw Error(journal.path() + ": the interrupted apply's backup cannot be read (" + e.what() +
                "); nothing was written");
  }
  const auto refuse = [&](RecoveryOutcome outcome, const std::string& why) {
    r.outcome = outcome;
    r.message = "an interrupted apply was not recovered: " + why +
                "; nothing was written. Check the controller's MOC MOTOR_CALIB cal_offset values "
                "on the FlexPendant: backup " +
                valuesText(r.backup_rad) + "; written " + valuesText(r.written_rad) +
                "; the controller holds " + valuesText(r.found_rad);
    // Once per finding: a recovery tried again and again finds the same.
    const json previous = journal.read().back();
    if (previous.value("step", "") != "recovery_refused" ||
        previous.value("message", "") != r.message)
      journal.append({{"step", "recovery_refused"},
                      {"outcome", recoveryOutcomeName(outcome)},
                      {"found_rad", r.found_rad},
                      {"differing_joints", r.differing_joints},
                      {"message", r.message}});
    return r;
  };

  // Only into the controller the backup came from: a session folder copied from another cell
  // carries that cell's values.
  const json recorded = begin.value("controller", json::object());
  const std::string type = recorded.value("robot_type", ""), serial = recorded.value("serial", "");
  r.found_rad = store.readCalOffsets();
  if (serial.empty() && type.empty())
    return refuse(RecoveryOutcome::kForeign,
                  "the apply recorded no controller identity, so it cannot be known that its "
                  "backup belongs to this controller (" +
                      identityText(controller.robot_type, controller.serial) + ")");
  if (type != controller.robot_type || serial != controller.serial)
    return refuse(RecoveryOutcome::kForeign,
                  "the apply was made on the controller of robot " + identityText(type, serial) +
                      ", this one is robot " +
                      identityText(controller.robot_type, controller.serial));

  bool holds_backup = true;
  for (int j = 1; j <= 6; ++j) {
    const double now = r.found_rad[j - 1];
    holds_backup = holds_backup && sameValue(now, r.backup_rad[j - 1]);
    if (!sameValue(now, r.backup_rad[j - 1]) && !sameValue(now, r.written_rad[j - 1]))
      r.differing_joints.push_back(j);
  }
  if (!r.differing_joints.empty()) {
    std::string joints;
    for (int j : r.differing_joints)
      joints += (joints.empty() ? "" : ", ") + std::to_string(j) + " (" +
                printed("%.6f", r.found_rad[j - 1]) + ")";
    // Someone or something changed the calibration since (a later apply, a technician): a
    // backup written over it would undo a calibration nobody asked to undo.
    return refuse(RecoveryOutcome::kConflict,
                  "the controller holds, at joint " + joints +
                      ", neither this apply's backup nor its written value");
  }
  if (holds_backup && !restarted) {
    r.outcome = RecoveryOutcome::kNothingWritten;
    r.message = "an apply was interrupted after step '" + last +
                "' before any value it wrote took effect: the controller holds the backed-up "
                "values " +
                valuesText(r.backup_rad) + "; nothing to restore";
    journal.append({{"step", "recovering"}, {"found_rad", r.found_rad}, {"last_step", last}});
    journal.append(
        {{"step", "done"}, {"outcome", recoveryOutcomeName(r.outcome)}, {"message", r.message}});
    return r;
  }
  journal.append({{"step", "recovering"}, {"found_rad", r.found_rad}, {"last_step", last}});
  // Restore even when the configured values are the backup: the restart that takes them may not
  // have happened.
  try {
    writeAndRestart(store, r.backup_rad);
  } catch (const std::exception& e) {
    throw Error(std::string("an interrupted apply could not be rolled back (") + e.what() +
                "); enter the backed-up values by hand: " + valuesText(r.backup_rad));
  }
  r.outcome = RecoveryOutcome::kRestored;
  r.message = "an apply was interrupted after step '" + last + "' (controller held " +
              (holds_backup ? std::string("the backed-up values") : valuesText(r.found_rad)) +
              "); restored the backed-up values " + valuesText(r.backup_rad);
  for (int j : counters)
    r.message += "; joint " + std::to_string(j) +
                 "'s revolution counter was updated during the apply: update it again at its "
                 "synchronisation mark";
  journal.append(
      {{"step", "done"}, {"outcome", recoveryOutcomeName(r.outcome)}, {"message", r.message}});
  return r;
}

bool acknowledgeApply(ApplyJournal& journal, const std::optional<std::array<double, 6>>& found_rad,
                      const std::string& note) {
  if (openApply(journal).empty()) return false;
  json line{{"step", "acknowledged"}, {"message", note}};
  line["found_rad"] = found_rad ? json(*found_rad) : json(nullptr);
  journal.append(line);
  journal.append({{"step", "done"}, {"outcome", "acknowledged"}, {"message", note}});
  return true;
}

}  // namespace zerocal::apply
