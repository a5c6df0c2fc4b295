#include "zerocal/service/result_assembly.h"

#include <cmath>

namespace zerocal::service {

ResultFile assembleResult(const std::string& session_id, const RunOutcome& outcome,
                          const RunFacts& facts) {
  ResultFile result;
  result.report = *outcome.report;
  result.session = session_id;
  result.kind = facts.kind;
  result.reference = facts.reference;
  result.model_from = facts.model_from;
  result.model_file = facts.model_file;
  result.check = facts.check;
  result.drift = facts.drift;
  result.cell_time_s = facts.cell_time_s;
  result.resumed_from = outcome.resumed_from;
  result.remeasured.emplace();
  for (const int i : outcome.remeasured) result.remeasured->push_back(i + 1);
  result.cell = facts.cell;
  result.cal_offset_rad = facts.cal_offset_rad;
  result.zerocal_version = PROJECT_VERSION;
  result.finished_unix_s = facts.finished_unix_s;
  result.recoveries = ResultFile::Recoveries{outcome.reconnects, outcome.reopens};
  if (facts.truth_deg) {
    result.truth.emplace();
    result.truth->offsets_deg = *facts.truth_deg;
  }
  if (facts.truth_noise_seed) {
    if (!result.truth) result.truth.emplace();
    result.truth->noise_seed = facts.truth_noise_seed;
  }
  if (!facts.truth_world_file.empty()) {
    if (!result.truth) result.truth.emplace();
    result.truth->world_file = facts.truth_world_file;
  }
  result.pose_breakdown.emplace();
  for (const PoseRecord& r : outcome.records) {
    PoseTimes pose;
    pose.pose = r.planIndex() + 1;
    if (!r.measured()) {
      pose.skipped = r.skipped;
    } else {
      pose.servo = r.servo;
      pose.again = r.remeasure_of >= 0;
      if (facts.move_overhead) {
        // Included in the times above: the planned move and every servo move pay them.
        const double moves = r.servo.moves + 1;
        pose.move_overhead_s = moves * facts.move_overhead->fixed_s;
        pose.fine_point_settle_s = moves * facts.move_overhead->settle_s;
      }
    }
    result.pose_breakdown->push_back(pose);
  }
  return result;
}

std::vector<double> achievedSigma(const SolveReport& report) {
  std::vector<double> achieved;
  for (int k = 0; k < kOffsetCount; ++k)
    achieved.push_back(report.parameters[k].identifiable ? report.parameters[k].sigma
                                                         : std::nan(""));
  return achieved;
}

}  // namespace zerocal::service
