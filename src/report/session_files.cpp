// Reading a session folder (through the store's types), turning it into a SessionReport, and
// writing the two files.
#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <map>
#include <sstream>

#include "zerocal/calib/cell_model.h"
#include "zerocal/calib/format.h"
#include "zerocal/report/session_report.h"
#include "zerocal/results/placements.h"
#include "zerocal/store/journal.h"

namespace zerocal::report {
namespace {

namespace fs = std::filesystem;

void writeAtomically(const fs::path& path, const std::string& text) {
  const fs::path temporary = path.string() + ".tmp";
  {
    std::ofstream out(temporary, std::ios::binary | std::ios::trunc);
    errno = 0;
    out << text;
    out.flush();
    if (!out) {
      // A full disk: no half-written temporary is left behind beside the session's files.
      const int error = errno;
      out.close();
      std::remove(temporary.c_str());
      throw ReportError(temporary.string() + ": cannot write" +
                        (error ? std::string(": ") + std::strerror(error) : std::string()));
    }
  }
  // A reader (a browser refreshing the page) sees the old file or the new one, never half.
  if (std::rename(temporary.c_str(), path.c_str()) != 0) {
    const int error = errno;
    std::remove(temporary.c_str());
    throw ReportError(path.string() + ": cannot write: " + std::strerror(error));
  }
}

}  // namespace

SessionFolder readSessionFiles(const std::string& session_dir) {
  try {
    return readSessionFolder(session_dir);
  } catch (const JournalError&) {
    throw;
  } catch (const Error& e) {  // a file missing, unreadable, or a member missing or wrong
    throw ReportError(e.what());
  }
}

std::optional<bool> SessionReport::usable() const {
  if (!result.verdict_recorded) return std::nullopt;
  return result.report.verdict.usable;
}

const ResultFile::Cell& SessionReport::cell() const {
  static const ResultFile::Cell kUnknown;
  return result.cell ? *result.cell : kUnknown;
}

const std::vector<int>& SessionReport::remeasured() const {
  static const std::vector<int> kNone;
  return result.remeasured ? *result.remeasured : kNone;
}

SessionReport parseSession(const SessionFolder& files) {
  SessionReport r;
  r.dir = files.dir;
  r.session = files.session;
  r.result = files.result;
  const SolveReport& solve = r.result.report;
  if (!r.result.session.empty() && r.result.session != r.session.id)
    throw ReportError("result.json belongs to session '" + r.result.session +
                      "', session.json to '" + r.session.id + "'");
  const Prediction& prediction = r.session.plan.prediction;
  for (const ParameterEstimate& p : solve.parameters) {
    ParameterRow row;
    static_cast<ParameterEstimate&>(row) = p;
    for (int k = 0; k < kIdentifiedCount; ++k) {
      if (unknownName(k) != p.name) continue;
      if (k < static_cast<int>(prediction.sigma.size()) && std::isfinite(prediction.sigma[k]))
        row.predicted_sigma = prediction.sigma[k];
      if (r.result.truth && k < kOffsetCount && std::isfinite(r.result.truth->offsets_deg[k]))
        row.truth = r.result.truth->offsets_deg[k];
    }
    r.parameters.push_back(row);
  }

  // Poses: every journal line, with the solve's residual where the pose was solved. Held-out
  // poses (validation) are not in the solve, so the residual list skips them.
  std::vector<int> held_out;
  if (r.result.validation)
    for (const HeldOutPose& p : r.result.validation->poses) held_out.push_back(p.pose);
  const std::vector<PoseRecord>& records = files.journal;
  const int journal_poses = static_cast<int>(records.size());
  // Each plan pose's latest line is the one solved (a pose measured again replaces its first
  // measurement).
  const std::vector<const PoseRecord*> latest = latestRecords(records);
  int measured_poses = 0;
  for (const PoseRecord* record : latest)
    if (record && record->measured()) ++measured_poses;
  const int solved_poses = solve.pose_count;
  if (solved_poses + static_cast<int>(held_out.size()) != measured_poses)
    throw ReportError("result.json solved " + std::to_string(solved_poses) + " poses" +
                      (held_out.empty() ? "" : " and held out " + std::to_string(held_out.size())) +
                      ", but journal.jsonl has " + std::to_string(measured_poses) +
                      " measured ones: the files do not belong together");
  if (static_cast<int>(solve.poses.size()) != solved_poses)
    throw ReportError("result.json: " + std::to_string(solve.poses.size()) +
                      " pose_residuals for " + std::to_string(solved_poses) + " poses");
  // Each solved line's residual. The daemon's residuals name their journal lines (posesOf keeps
  // them as the poses' source_line); a result written before they did (every line 0) has them in
  // the solve's order: each plan pose's latest measurement, in plan order, held-out poses left
  // out.
  std::map<const PoseRecord*, int> residual_of;
  const bool lines_named = std::any_of(solve.poses.begin(), solve.poses.end(),
                                       [](const PoseResidual& p) { return p.source_line != 0; });
  if (lines_named) {
    std::map<int, const PoseRecord*> at_line;
    for (const PoseRecord* record : latest)
      if (record && record->measured()) at_line[record->line] = record;
    for (std::size_t k = 0; k < solve.poses.size(); ++k) {
      const auto found = at_line.find(solve.poses[k].source_line);
      if (found == at_line.end())
        throw ReportError("result.json: pose residual " + std::to_string(k + 1) +
                          " is of journal line " + std::to_string(solve.poses[k].source_line) +
                          ", which journal.jsonl has as no pose solved: the files do not "
                          "belong together");
      residual_of[found->second] = static_cast<int>(k);
    }
  } else {
    for (std::size_t plan_index = 0; plan_index < latest.size(); ++plan_index) {
      const PoseRecord* record = latest[plan_index];
      if (!record || !record->measured()) continue;
      if (std::find(held_out.begin(), held_out.end(), static_cast<int>(plan_index) + 1) ==
          held_out.end())
        residual_of[record] = static_cast<int>(residual_of.size());
    }
  }
  const std::vector<Pose>& planned = r.session.plan.poses;
  const bool several_placements = placementCount(planned) > 1;
  for (int i = 0; i < journal_poses; ++i) {
    const PoseRecord& record = records[i];
    PoseRow row;
    row.pose = record.planIndex() + 1;
    row.again = record.remeasure_of >= 0;
    if (several_placements && record.planIndex() < static_cast<int>(planned.size()))
      row.placement = planned[record.planIndex()].placement;
    if (!record.measured()) {
      row.solved = false;
      row.skipped = record.skipped;
      r.poses.push_back(std::move(row));
      continue;
    }
    for (int j = 0; j < 6; ++j) row.joints_deg[j] = record.joints_deg[j];
    row.spot = record.reading.spot;
    // The journal leaves out a path it did not record.
    if (!record.servo_path.empty()) row.servo_path = record.servo_path;
    row.superseded = latest[record.planIndex()] != &record;
    const auto residual = residual_of.find(&record);
    row.solved = residual != residual_of.end();
    if (row.solved) {
      const PoseResidual& p = solve.poses[residual->second];
      row.miss_um = std::hypot(p.miss_mm.x(), p.miss_mm.y()) * 1000;
      row.normalised = p.normalised;
      row.outlier = p.outlier;
      row.standoff_mm = p.standoff_mm;
    }
    r.poses.push_back(std::move(row));
  }
  return r;
}

void writeSessionReport(const std::string& session_dir,
                        const std::vector<record::HistoryEntry>& history) {
  SessionReport report = parseSession(readSessionFiles(session_dir));
  report.history = history;
  report.applied = apply::lastApplyRecord(apply::ApplyJournal(session_dir + "/apply.jsonl"));
  const fs::path dir(session_dir);
  writeAtomically(dir / "summary.txt", summaryText(report));
  writeAtomically(dir / "report.html", reportHtml(report));
}

std::string escapeHtml(const std::string& text) {
  std::string out;
  out.reserve(text.size());
  for (const char c : text) {
    switch (c) {
      case '&':
        out += "&amp;";
        break;
      case '<':
        out += "&lt;";
        break;
      case '>':
        out += "&gt;";
        break;
      case '"':
        out += "&quot;";
        break;
      case '\'':
        out += "&#39;";
        break;
      default:
        out += c;
    }
  }
  return out;
}

}  // namespace zerocal::report
