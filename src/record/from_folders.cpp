#include "zerocal/record/from_folders.h"

#include <cmath>
#include <filesystem>

#include "zerocal/apply/online_apply.h"
#include "zerocal/error.h"
#include "zerocal/store/session_files.h"

namespace zerocal::record {
namespace {

using nlohmann::json;

RecordedOffsets offsetsOfJson(const json& offsets) {
  RecordedOffsets o;
  for (std::size_t k = 0; k < o.size() && k < offsets.size(); ++k) {
    const json& m = offsets.at(k);
    o[k] = RecordedOffset{m.at("value_deg").get<double>(), m.at("sigma_deg").get<double>()};
  }
  return o;
}

std::array<double, 6> values(const json& line, const char* member) {
  return line.at(member).get<std::array<double, 6>>();
}

}  // namespace

SessionEntry sessionEntryOf(const SessionFile& session, const ResultFile& result) {
  if (!result.cell ||
      (result.cell->controller.robot_type.empty() && result.cell->controller.serial.empty()))
    throw InputError("session " + session.id +
                     ": its result names no robot (written before the daemon recorded the "
                     "controller's identity, or not by the daemon)");
  SessionEntry e;
  e.session = session.id;
  e.robot = {result.cell->controller.robot_type, result.cell->controller.serial};
  e.software_version = result.cell->controller.software_version;
  e.kind = sessionKindName(session.kind);
  e.verifies = session.verifies;
  const SolveReport& report = result.report;
  if (result.verdict_recorded) e.usable = report.verdict.usable;
  e.reasons = report.verdict.reasons;
  e.converged = report.converged;
  e.poses_used = report.poses_used;
  for (const ParameterEstimate& p : report.parameters)
    for (int k = 0; k < kOffsetCount; ++k)
      if (p.name == unknownName(k) && p.identifiable && std::isfinite(p.value) &&
          std::isfinite(p.sigma))
        e.offsets[k] = RecordedOffset{p.value, p.sigma};
  e.cell_time_s = result.cell_time_s;
  e.started_unix_s = session.created_unix_s;
  e.finished_unix_s = result.finished_unix_s;
  if (result.cal_offset_rad) e.cal_offset_rad = *result.cal_offset_rad;
  e.model_from = result.model_from;
  e.model_file = result.model_file;
  e.reference = result.reference;
  return e;
}

std::vector<ControllerEvent> controllerEventsOf(const std::vector<json>& lines) {
  std::vector<ControllerEvent> events;
  // The open online apply (begin .. done), its rollback under way, and the values a recovery
  // found, by their index in `events`.
  int apply = -1, rollback = -1;
  std::optional<std::array<double, 6>> recovery_found;
  double recovery_time = 0;
  for (std::size_t i = 0; i < lines.size(); ++i) {
    const json& line = lines[i];
    if (!line.is_object() || !line.contains("step")) continue;  // a file apply's record
    try {
      const std::string step = line.at("step").get<std::string>();
      const double time = line.value("time_unix_s", 0.0);
      ControllerEvent e;
      e.time_unix_s = time;
      if (step == "transmission_check") {
        if (line.at("agree").get<bool>()) continue;
        e.kind = ControllerEventKind::kApply;
        e.outcome = "refused";
        e.message = line.value("message", "");
        events.push_back(e);
      } else if (step == "begin") {
        e.kind = ControllerEventKind::kApply;
        e.outcome = "interrupted";  // until its "done"
        e.before_rad = values(line, "before_rad");
        e.after_rad = values(line, "new_rad");
        events.push_back(e);
        apply = static_cast<int>(events.size()) - 1;
        rollback = -1;
        recovery_found.reset();
      } else if (step == "verify") {
        // A verification on its own: the controller holds what it held, nothing is written.
        e.kind = ControllerEventKind::kVerification;
        e.outcome = line.at("pass").get<bool>() ? "pass" : "fail";
        if (line.contains("found_rad")) e.before_rad = e.after_rad = values(line, "found_rad");
        e.verification = line.value("session", "");
        e.remaining = offsetsOfJson(line.value("offsets_after", json::array()));
        e.message = line.value("message", "");
        events.push_back(e);
      } else if (apply < 0) {
        continue;  // a step of no apply this journal began (lastApplyRecord passes it over too)
      } else if (step == "verification") {
        events[apply].verification = line.at("session").get<std::string>();
      } else if (step == "verified") {
        e.kind = ControllerEventKind::kVerification;
        e.outcome = line.at("pass").get<bool>() ? "pass" : "fail";
        e.before_rad = e.after_rad = events[apply].after_rad;  // the values written
        e.verification = events[apply].verification;
        e.remaining = offsetsOfJson(line.value("offsets_after", json::array()));
        e.message = line.value("message", "");
        events.push_back(e);
      } else if (step == "rolling_back") {
        e.kind = ControllerEventKind::kRollback;
        e.outcome = "interrupted";  // until the apply's "done"
        e.before_rad = events[apply].after_rad;
        e.after_rad = events[apply].before_rad;
        e.message = line.value("reason", "");
        events.push_back(e);
        rollback = static_cast<int>(events.size()) - 1;
      } else if (step == "recovering") {
        recovery_found = values(line, "found_rad");
        recovery_time = time;
      } else if (step == "error") {
        events[apply].outcome = "error";
        events[apply].message = line.value("message", "");
        if (rollback >= 0) events[rollback].outcome = "error";
      } else if (step == "recovery_refused") {
        events[apply].outcome = "unrecovered";
        events[apply].message = line.value("message", "");
      } else if (step == "acknowledged") {
        e.kind = ControllerEventKind::kAcknowledgement;
        e.outcome = "acknowledged";
        if (line.contains("found_rad") && !line.at("found_rad").is_null())
          e.before_rad = e.after_rad = values(line, "found_rad");
        e.message = line.value("message", "");
        events.push_back(e);
      } else if (step == "done") {
        ControllerEvent& a = events[apply];
        a.outcome = line.at("outcome").get<std::string>();
        a.message = line.value("message", "");
        if (a.outcome == "not_written") a.after_rad = a.before_rad;  // nothing took effect
        if (rollback >= 0 && a.outcome == "rolled_back") events[rollback].outcome = "restored";
        if (a.outcome == "recovered") {
          // The recovery wrote the backup back over what it found.
          e.kind = ControllerEventKind::kRollback;
          e.time_unix_s = recovery_time;
          e.outcome = "restored";
          e.before_rad = recovery_found;
          e.after_rad = events[apply].before_rad;
          e.message = a.message;
          events.push_back(e);
        }
        apply = rollback = -1;
      }
    } catch (const json::exception& e) {
      throw InputError("apply.jsonl line " + std::to_string(i + 1) + ": " + e.what());
    }
  }
  return events;
}

std::vector<ControllerEvent> controllerEventsOfFolder(const SessionStore& store,
                                                      const std::string& id) {
  const std::string path = store.sessionDir(id) + "/" + kApplyJournalFileName;
  std::error_code ec;
  if (!std::filesystem::exists(path, ec)) return {};
  try {
    return controllerEventsOf(apply::ApplyJournal(path).read());
  } catch (const InputError& e) {
    throw InputError("session " + id + ": " + e.what());
  }
}

void recordFromFolder(RobotRecord& record, const SessionStore& store, const std::string& id) {
  record.recordSession(sessionEntryOf(store.readSession(id), store.readResult(id)));
  record.recordControllerEvents(id, controllerEventsOfFolder(store, id));
}

}  // namespace zerocal::record
