#include "zerocal/service/reference.h"

#include "zerocal/results/placements.h"
#include "zerocal/service/request_planner.h"
#include "zerocal/session/calibration_run.h"
#include "zerocal/store/session_files.h"

namespace zerocal::service {

namespace {

// The folder of session `id`, its id checked and the session listed.
SessionFolder readListed(const SessionStore& store, const std::string& id) {
  checkSessionId(id);
  bool listed = false;
  for (const SessionInfo& s : store.list()) listed = listed || s.id == id;
  if (!listed) throw Refused("not_found", "no session " + id + " in " + store.dataDir());
  try {
    return readSessionFolder(store.sessionDir(id));
  } catch (const Error& e) {
    throw Refused("damaged", "session " + id + " cannot be read: " + e.what());
  }
}

// The poses the result's solve used at `placement` (every placement when 0), with the fit.
Reference referenceOf(const std::string& id, const SessionFolder& folder, int placement) {
  const SolveReport& report = folder.result.report;
  const std::vector<Pose> poses = posesOf(folder.journal);
  const std::vector<int> plan = planIndicesOf(folder.journal);
  if (report.poses.size() != poses.size())
    throw Refused("damaged", "session " + id + ": its result has " +
                                 std::to_string(report.poses.size()) + " poses, its journal " +
                                 std::to_string(poses.size()));
  Reference r;
  r.id = id;
  r.fit.estimate = report.estimate;
  for (std::size_t i = 0; i < poses.size(); ++i)
    if (report.poses[i].used && (placement == 0 || poses[i].placement == placement)) {
      r.fit.poses.push_back(poses[i]);
      r.fit.poses.back().placement = 1;  // the change is measured at one placement
      r.plan_poses.push_back(plan[i] + 1);
    }
  if (placement > 0) {
    r.placement = placement;
    r.placement_centres_mm = folder.session.placement_centres_mm;
    for (const SolveReport::PlacementCentre& c : report.placements)
      if (c.placement == placement) r.fit.estimate.target_mm = c.target_mm;
  }
  if (folder.result.cell) r.robot = folder.result.cell->controller;
  r.cal_offset_rad = folder.result.cal_offset_rad;
  r.noise_mm = folder.session.noise_mm;
  return r;
}

// The latest finished session of `kind` whose result `wanted` accepts, of the robot with this
// serial when given; empty when there is none.
std::string latestFinished(const SessionStore& store, SessionKind kind, const std::string& serial,
                           bool (*wanted)(const ResultFile&)) {
  const std::vector<SessionInfo> sessions = store.list();  // oldest first: ids sort by age
  for (auto s = sessions.rbegin(); s != sessions.rend(); ++s) {
    if (s->kind != kind || !s->finished) continue;
    try {
      const ResultFile result = store.readResult(s->id);
      if (!wanted(result)) continue;
      if (!serial.empty() && (!result.cell || result.cell->controller.serial != serial)) continue;
      return s->id;
    } catch (const Error&) {
      continue;  // a damaged result counts for nothing; loading the session says why
    }
  }
  return "";
}

}  // namespace

Reference loadReference(const SessionStore& store, const std::string& id) {
  const SessionFolder folder = readListed(store, id);
  if (folder.session.kind != SessionKind::kReference)
    throw Refused("not_a_reference", "session " + id + " is a " +
                                         sessionKindName(folder.session.kind) +
                                         ", not a reference: take one with `zerocal start "
                                         "--kind reference`");
  const SolveReport& report = folder.result.report;
  if (!report.verdict.usable)
    throw Refused("not_a_reference",
                  "reference " + id + " is not usable: " +
                      (report.verdict.reasons.empty() ? std::string("its verdict says so")
                                                      : report.verdict.reasons.front()));
  return referenceOf(id, folder, 0);
}

Reference loadAppliedCalibration(const SessionStore& store, const std::string& id) {
  const SessionFolder folder = readListed(store, id);
  if (folder.session.kind != SessionKind::kCalibration)
    throw Refused(
        "not_a_calibration",
        "session " + id + " is a " + sessionKindName(folder.session.kind) + ", not a calibration");
  const std::vector<int> placements = placementsOf(posesOf(folder.journal));
  if (placements.empty()) throw Refused("damaged", "session " + id + " recorded no pose");
  return referenceOf(id, folder, placements.back());
}

Reference loadComparedWith(const SessionStore& store, const SessionFile& session) {
  if (session.kind == SessionKind::kVerification && session.reference == session.verifies)
    return loadAppliedCalibration(store, session.reference);
  return loadReference(store, session.reference);
}

std::string latestReference(const SessionStore& store, const std::string& serial) {
  return latestFinished(store, SessionKind::kReference, serial,
                        [](const ResultFile& r) { return r.report.verdict.usable; });
}

CalibratedModel loadCalibratedModel(const SessionStore& store, const std::string& id) {
  const SessionFolder folder = readListed(store, id);
  if (folder.result.model_file.empty())
    throw Refused("no_model", "session " + id +
                                  " wrote no calibrated model: a usable calibration at several "
                                  "PSD placements writes one");
  CalibratedModel model;
  model.id = id;
  try {
    model.robot = loadRobot(store.sessionDir(id) + "/" + folder.result.model_file);
  } catch (const Error& e) {
    throw Refused("damaged",
                  "the calibrated model of session " + id + " cannot be read: " + e.what());
  }
  if (folder.result.cell) model.origin = folder.result.cell->controller;
  return model;
}

std::string latestCalibratedModel(const SessionStore& store, const std::string& serial) {
  return latestFinished(store, SessionKind::kCalibration, serial,
                        [](const ResultFile& r) { return !r.model_file.empty(); });
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
