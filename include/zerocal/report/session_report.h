// The files a technician reads after a calibration: summary.txt and report.html, written next to
// result.json in a session folder (<data_dir>/<id>/, see zerocal/store/journal.h). Nothing here
// talks to a controller: the ABB section says what to enter, a person enters it.
//
// Units as in result.json (docs/results.md): offsets in degrees (arm side: the joint angle, not
// the motor angle) with radians beside them, lengths in mm, PSD readings in mm, times in s.
#pragma once

#include <array>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>
#include <vector>

#include "zerocal/apply/online_apply.h"
#include "zerocal/error.h"
#include "zerocal/psd/spot.h"
#include "zerocal/record/robot_record.h"
#include "zerocal/store/session_files.h"

namespace zerocal::report {

// A session folder that cannot be reported on: a file missing or unreadable, or files that do
// not belong together (pose counts, session id). The message names the file and the problem.
class ReportError : public Error {
 public:
  using Error::Error;
};

// A parameter of the solve as the report shows it: the estimate, with the plan's prediction and,
// on the simulated cell, the truth beside it.
struct ParameterRow : ParameterEstimate {
  std::optional<double> predicted_sigma;  // the plan's prediction, same unit
  std::optional<double> truth;            // simulated sessions only
};

struct PoseRow {
  int pose = 0;  // 1-based, as in the journal (index + 1)
  std::array<double, 6> joints_deg{};
  PsdSpot spot;             // PSD reading at the recorded moment
  bool solved = true;       // false: held out of the solve (validation), or skipped
  std::string skipped;      // why the pose was skipped at a resume; empty when measured
  bool again = false;       // a second measurement, made because the first solve named the pose
  bool superseded = false;  // measured again later: the solve took the later measurement
  double miss_um = 0;       // line's miss of the hit point (solved poses)
  double normalised = 0;    // miss in what the given noise (and link tolerances) allow
  int placement = 0;        // its PSD placement, with several (0: one placement)
  bool outlier = false;
  double standoff_mm = 0;
  // The spot's path during the servo (journal.jsonl servo_path); absent: not recorded. A
  // coordinate the file leaves null is NaN.
  std::optional<std::vector<SpotPathPoint>> servo_path;
};

// Everything the summary and the report show: the session's files as the store reads them, and
// the rows that join them (parameters with their prediction, journal lines with their residual).
struct SessionReport {
  std::string dir;
  SessionFile session;                   // session.json
  ResultFile result;                     // result.json
  std::vector<ParameterRow> parameters;  // the solve's, offsets first
  std::vector<PoseRow> poses;            // every journal line, in order

  const SolveReport& solve() const { return result.report; }
  // The solve's verdict; unset in results written before verdicts.
  std::optional<bool> usable() const;
  bool simulated() const { return result.truth.has_value(); }  // the truth is known
  // Whose calibration this is: the robot as its controller named itself, the PSD map. Empty in
  // results written before they were recorded.
  const ResultFile::Cell& cell() const;
  // Plan poses (1-based) measured again after the first solve.
  const std::vector<int>& remeasured() const;
  // The latest online apply or verification of these offsets (apply.jsonl), when there was one.
  std::optional<apply::ApplyRecord> applied;
  // The robot's history in the daemon's record, oldest first, for the trend of its zeros; empty
  // when the report is written without a record.
  std::vector<record::HistoryEntry> history;
};

// Reads session.json, journal.jsonl (committed lines, through readJournal's checks) and
// result.json of a session folder (readSessionFolder). Throws ReportError naming the missing or
// unreadable file or the member missing or of the wrong type, or JournalError for an
// inconsistent journal.
SessionFolder readSessionFiles(const std::string& session_dir);

// Interprets the files. Throws ReportError when they disagree (session id, number of poses).
SessionReport parseSession(const SessionFolder& files);

// The plain-text summary (summary.txt) and the self-contained HTML report (report.html: inline
// CSS and SVG, no script, no external resource). Pure functions of the parsed session.
std::string summaryText(const SessionReport& report);
std::string reportHtml(const SessionReport& report);

// Reads the session folder (and its apply.jsonl, when an apply or a verification ran) and
// (re)writes summary.txt and report.html beside result.json,
// each atomically (temporary file, then rename). Throws ReportError
// (missing or inconsistent files, a file that cannot be written) or JournalError.
// With the robot's `history` (from the daemon's record), the report shows its zeros over time
// (docs/results.md).
void writeSessionReport(const std::string& session_dir,
                        const std::vector<record::HistoryEntry>& history = {});

// For text that goes into HTML: & < > " ' replaced by entities.
std::string escapeHtml(const std::string& text);

}  // namespace zerocal::report
