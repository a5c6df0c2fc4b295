#include "zerocal/service/reference.h"

#include "zerocal/service/request_planner.h"
#include "zerocal/session/calibration_run.h"
#include "zerocal/store/session_files.h"

namespace zerocal::service {

Reference loadReference(const SessionStore& store, const std::string& id) {
  checkSessionId(id);
  bool listed = false;
  for (const SessionInfo& s : store.list()) listed = listed || s.id == id;
  if (!listed) throw Refused("not_found", "no session " + id + " in " + store.dataDir());
  SessionFolder folder;
  try {
    folder = readSessionFolder(store.sessionDir(id));
  } catch (const Error& e) {
    throw Refused("damaged", "reference " + id + " cannot be read: " + e.what());
  }
  if (folder.session.kind != SessionKind::kReference)
    throw Refused("not_a_reference", "session " + id + " is a " +
                                         sessionKindName(folder.session.kind) +
                                         ", not a reference: take one with `zerocal start "
                                         "--kind reference`");
  const SolveReport& report = folder.result.report;
  if (!folder.result.report.verdict.usable)
    throw Refused("not_a_reference",
                  "reference " + id + " is not usable: " +
                      (report.verdict.reasons.empty() ? std::string("its verdict says so")
                                                      : report.verdict.reasons.front()));
  const std::vector<Pose> poses = posesOf(folder.journal);
  const std::vector<int> plan = planIndicesOf(folder.journal);
  if (report.poses.size() != poses.size())
    throw Refused("damaged", "reference " + id + ": its result has " +
                                 std::to_string(report.poses.size()) + " poses, its journal " +
                                 std::to_string(poses.size()));
  Reference r;
  r.id = id;
  r.fit.estimate = report.estimate;
  for (std::size_t i = 0; i < poses.size(); ++i)
    if (report.poses[i].used) {
      r.fit.poses.push_back(poses[i]);
      r.plan_poses.push_back(plan[i] + 1);
    }
  if (folder.result.cell) r.robot = folder.result.cell->controller;
  r.cal_offset_rad = folder.result.cal_offset_rad;
  r.noise_mm = folder.session.noise_mm;
  return r;
}

std::string latestReference(const SessionStore& store, const std::string& serial) {
  const std::vector<SessionInfo> sessions = store.list();  // oldest first: ids sort by age
  for (auto s = sessions.rbegin(); s != sessions.rend(); ++s) {
    if (s->kind != SessionKind::kReference || !s->finished) continue;
    try {
      const ResultFile result = store.readResult(s->id);
      if (!result.report.verdict.usable) continue;
      if (!serial.empty() && (!result.cell || result.cell->controller.serial != serial)) continue;
      return s->id;
    } catch (const Error&) {
      continue;  // a damaged result is no reference; loadReference says why when asked for it
    }
  }
  return "";
}

std::string suggestedKind(const std::string& latest) {
  if (latest.empty())
    return "no reference yet: with the robot known good, `zerocal start --kind reference` "
           "records its zeros for later checks and restores; `zerocal start --placements 3` "
           "calibrates them absolutely";
  return "reference " + latest +
         ": `zerocal start --kind check` sees in about 30 s whether a "
         "zero moved; `--kind restore` brings them back after a motor or encoder change";
}

}  // namespace zerocal::service
