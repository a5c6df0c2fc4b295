#include "record_fixture.h"

#include "zerocal/store/session_files.h"

namespace zerocal::test {

namespace {
constexpr double kRadPerDeg = 0.017453292519943295;
}

ResultFile resultOf(const FinishedSession& s, const std::string& id) {
  ResultFile r;
  r.session = id;
  SolveReport& report = r.report;
  report.converged = true;
  report.pose_count = report.poses_used = 16;
  report.verdict.usable = s.usable;
  report.verdict.reasons = s.reasons;
  for (int k = 0; k < kIdentifiedCount; ++k) {
    ParameterEstimate p;
    p.name = unknownName(k);
    if (k < kOffsetCount) {
      p.identifiable = s.offsets[k].has_value();
      if (s.offsets[k]) {
        p.value = s.offsets[k]->value_deg;
        p.sigma = s.offsets[k]->sigma_deg;
      } else {
        p.reason = "withheld by the test";
      }
    }
    report.parameters.push_back(p);
  }
  if (s.identity) r.cell = ResultFile::Cell{s.robot, "psd.yaml (fingerprint 1)"};
  r.cell_time_s = s.cell_time_s;
  r.cal_offset_rad = s.cal_offset_rad;
  r.model_from = s.model_from;
  r.model_file = s.model_file;
  r.reference = s.reference;
  r.finished_unix_s = 1'800'000'000;
  r.zerocal_version = "test";
  return r;
}

SessionFile plannedSession() {
  SessionFile session;
  // A plan's prediction has a value per identified unknown (toJson indexes them all).
  Prediction& predicted = session.plan.prediction;
  predicted.sigma.assign(kIdentifiedCount, 0.003);
  predicted.identifiable.assign(kIdentifiedCount, true);
  predicted.reason.assign(kIdentifiedCount, "");
  session.plan.description = "the record's test plan";
  return session;
}

std::string makeFinishedSession(SessionStore& store, const FinishedSession& s) {
  SessionFile session = plannedSession();
  session.kind = s.kind;
  session.verifies = s.verifies;
  session.model_from = s.model_from;
  session.reference = s.reference;
  session = store.create(session);
  store.writeResult(session.id, resultOf(s, session.id));
  return session.id;
}

std::array<apply::CalOffsetChange, 4> changesFor(const std::array<double, 4>& offsets_deg,
                                                 const std::array<double, 6>& present) {
  std::array<apply::CalOffsetChange, 4> changes;
  for (int j = 2; j <= 5; ++j)
    changes[j - 2] =
        apply::calOffsetChange(j, offsets_deg[j - 2] * kRadPerDeg, 100, present[j - 1]);
  return changes;
}

apply::OnlineApplyOutcome applyInto(SessionStore& store, const std::string& id,
                                    MemoryCalibration& controller,
                                    const std::array<double, 4>& offsets_deg,
                                    const std::array<double, 4>& remaining_deg) {
  apply::ApplyJournal journal(store.sessionDir(id) + "/" + kApplyJournalFileName);
  apply::Offsets before;
  for (int k = 0; k < 4; ++k) before[k] = {offsets_deg[k], 0.002};
  apply::OnlineApplyOptions options;
  options.required_deg = 0.003;
  options.controller = {"SN-0001", "6.13.02", "IRB 1600-10/1.45"};
  options.verify = [&] {
    journal.append({{"step", "verification"}, {"session", id + "-verification"}});
    apply::Offsets after;
    for (int k = 0; k < 4; ++k) after[k] = {remaining_deg[k], 0.002};
    return after;
  };
  return apply::applyOnline(controller, changesFor(offsets_deg, controller.readCalOffsets()),
                            before, options, journal);
}

}  // namespace zerocal::test
