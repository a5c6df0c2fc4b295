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
#include "zerocal/daemon/journal.h"
#include "zerocal/report/session_report.h"

namespace zerocal::report {
namespace {

namespace fs = std::filesystem;

void writeAtomically(const fs::path& path, const std::string& text) {
  const fs::path temporary = path.string() + ".tmp";
  {
    std::ofstream out(temporary, std::ios::binary | std::ios::trunc);
    out << text;
    out.flush();
    if (!out) throw ReportError(temporary.string() + ": cannot write");
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

SessionReport parseSession(const SessionFolder& files) {
  SessionReport r;
  r.dir = files.dir;
  const SessionFile& session = files.session;
  const ResultFile& result = files.result;
  const SolveReport& solve = result.report;
  r.session_id = session.id;
  if (!result.session.empty() && result.session != r.session_id)
    throw ReportError("result.json belongs to session '" + result.session + "', session.json to '" +
                      r.session_id + "'");
  r.plan_description = session.plan.description;

  if (result.verdict_recorded) {
    r.usable = solve.verdict.usable;
    r.refusal_reasons = solve.verdict.reasons;
  }
  for (const SuspectPose& s : solve.suspect_poses)
    r.suspect_poses.push_back({s.pose, s.source_line, s.reason, s.chi2_without});
  r.converged = solve.converged;
  r.message = solve.message;
  r.cost = costName(solve.cost);
  r.model = solve.used_readings ? "hit-point" : "point-to-line";
  r.noise_source = solve.noise_estimated ? "estimated from the residuals" : "given";
  r.solved_poses = solve.pose_count;
  r.rank = solve.rank;
  r.dof = solve.dof;
  r.condition_number = solve.condition_number;
  r.noise_mm = solve.noise_mm;
  r.rms_miss_mm = solve.rms_miss_mm;
  r.chi2_per_dof = solve.chi2_per_dof;
  r.chi2_p_value = solve.chi2_p_value;
  r.cell_time_s = result.cell_time_s;
  r.simulated = result.truth.has_value();
  if (result.cell) {
    r.robot = result.cell->controller;
    r.psd_map = result.cell->psd_map;
  }
  r.zerocal_version = result.zerocal_version;
  r.finished_unix_s = result.finished_unix_s;

  for (const ParameterEstimate& p : solve.parameters) {
    ParameterRow row;
    row.name = p.name;
    row.identifiable = p.identifiable;
    row.reason = p.reason;
    row.value = p.value;
    row.sigma = p.sigma;
    row.ci95_low = p.ci95_low;
    row.ci95_high = p.ci95_high;
    for (int k = 0; k < kIdentifiedCount; ++k)
      if (unknownName(k) == p.name && k < static_cast<int>(session.plan.prediction.sigma.size()) &&
          std::isfinite(session.plan.prediction.sigma[k]))
        row.predicted_sigma = session.plan.prediction.sigma[k];
    if (result.truth)
      for (int k = 0; k < kOffsetCount; ++k)
        if (unknownName(k) == p.name && std::isfinite(result.truth->offsets_deg[k]))
          row.truth = result.truth->offsets_deg[k];
    r.parameters.push_back(row);
  }
  for (const auto& n : solve.not_identifiable) r.not_identifiable.push_back({n.name, n.reason});
  for (int k = 0; k < 3; ++k) {
    r.target_mm[k] = solve.estimate.target_mm[k];
    r.target_sigma_mm[k] = solve.target_sigma_mm[k];
  }

  // Poses: every journal line, with the solve's residual where the pose was solved. Held-out
  // poses (validation) are not in the solve, so the residual list skips them.
  std::vector<int> held_out;
  if (result.validation) {
    Validation validation;
    validation.rms_before_mm = result.validation->rms_before_mm;
    validation.rms_after_mm = result.validation->rms_after_mm;
    for (const HeldOutPose& p : result.validation->poses) {
      HeldOutRow row;
      row.pose = p.pose;
      row.before_mm = p.before.on_psd_norm_mm;
      row.after_mm = p.after.on_psd_norm_mm;
      row.after_miss_mm = p.after.miss_mm;
      row.after_uv_mm = {p.after.on_psd_mm.x(), p.after.on_psd_mm.y()};
      held_out.push_back(row.pose);
      validation.poses.push_back(row);
    }
    r.validation = validation;
  }
  const std::vector<PoseRecord>& records = files.journal;
  const int journal_poses = static_cast<int>(records.size());
  // Each plan pose's latest line is the one solved (a pose measured again replaces its first
  // measurement); the residuals are in plan order.
  std::map<int, int> latest;  // plan pose (0-based) -> its latest line
  for (int i = 0; i < journal_poses; ++i) latest[records[i].planIndex()] = i;
  std::map<int, int> residual_of;  // line -> its residual
  int measured_poses = 0;
  for (const auto& [plan_index, line] : latest) {
    if (!records[line].measured()) continue;
    ++measured_poses;
    if (std::find(held_out.begin(), held_out.end(), plan_index + 1) == held_out.end())
      residual_of[line] = static_cast<int>(residual_of.size());
  }
  if (r.solved_poses + static_cast<int>(held_out.size()) != measured_poses)
    throw ReportError("result.json solved " + std::to_string(r.solved_poses) + " poses" +
                      (held_out.empty() ? "" : " and held out " + std::to_string(held_out.size())) +
                      ", but journal.jsonl has " + std::to_string(measured_poses) +
                      " measured ones: the files do not belong together");
  if (static_cast<int>(solve.poses.size()) != r.solved_poses)
    throw ReportError("result.json: " + std::to_string(solve.poses.size()) +
                      " pose_residuals for " + std::to_string(r.solved_poses) + " poses");
  if (result.remeasured) r.remeasured = *result.remeasured;
  for (int i = 0; i < journal_poses; ++i) {
    const PoseRecord& record = records[i];
    PoseRow row;
    row.pose = record.planIndex() + 1;
    row.again = record.remeasure_of >= 0;
    if (!record.measured()) {
      row.solved = false;
      row.skipped = record.skipped;
      r.poses.push_back(std::move(row));
      continue;
    }
    for (int j = 0; j < 6; ++j) row.joints_deg[j] = record.joints_deg[j];
    row.u_mm = record.u_mm;
    row.v_mm = record.v_mm;
    if (!record.servo_path.empty()) {  // the journal leaves out a path it did not record
      row.servo_path.emplace();
      for (const auto& point : record.servo_path)
        row.servo_path->push_back({point[0], point[1], point[2]});
    }
    row.superseded = latest[record.planIndex()] != i;
    const auto residual = residual_of.find(i);
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

void writeSessionReport(const std::string& session_dir) {
  const SessionReport report = parseSession(readSessionFiles(session_dir));
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
