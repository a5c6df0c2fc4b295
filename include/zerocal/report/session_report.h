// The files a technician reads after a calibration: summary.txt and report.html, written next to
// result.json in a session folder (<data_dir>/<id>/, see zerocal/daemon/journal.h). Nothing here
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

#include "zerocal/cell/controller_link.h"
#include "zerocal/error.h"
#include "zerocal/store/session_files.h"

namespace zerocal::report {

// A session folder that cannot be reported on: a file missing or unreadable, or files that do
// not belong together (pose counts, session id). The message names the file and the problem.
class ReportError : public Error {
 public:
  using Error::Error;
};

struct ParameterRow {
  std::string name;  // "delta2_deg", "laser_slope_1", ... as in result.json
  bool identifiable = false;
  std::string reason;                     // why not, when not
  double value = 0, sigma = 0;            // the parameter's unit (deg for offsets)
  double ci95_low = 0, ci95_high = 0;     // same unit
  std::optional<double> predicted_sigma;  // the plan's prediction, same unit
  std::optional<double> truth;            // simulated sessions only
};

struct ServoSample {
  double t_s = 0, u_mm = 0, v_mm = 0;
};

struct PoseRow {
  int pose = 0;  // 1-based, as in the journal (index + 1)
  std::array<double, 6> joints_deg{};
  double u_mm = 0, v_mm = 0;  // PSD reading at the recorded moment
  bool solved = true;         // false: held out of the solve (validation), or skipped
  std::string skipped;        // why the pose was skipped at a resume; empty when measured
  bool again = false;         // a second measurement, made because the first solve named the pose
  bool superseded = false;    // measured again later: the solve took the later measurement
  double miss_um = 0;         // line's miss of the hit point (solved poses)
  double normalised = 0;      // miss / noise sigma
  bool outlier = false;
  double standoff_mm = 0;
  std::optional<std::vector<ServoSample>> servo_path;  // absent: not recorded
};

struct HeldOutRow {
  int pose = 0;              // 1-based
  double before_mm = 0;      // nominal model: spot distance on the PSD plane
  double after_mm = 0;       // calibrated model
  double after_miss_mm = 0;  // calibrated line's perpendicular miss
  std::array<double, 2> after_uv_mm{};
};

struct Validation {
  std::vector<HeldOutRow> poses;
  double rms_before_mm = 0, rms_after_mm = 0;
};

// A pose the result does not rest on (result.json suspect_poses).
struct SuspectRow {
  int pose = 0;  // 1-based
  int line = 0;
  std::string reason;
  double chi2_without = 0;
};

// Everything the summary and the report show, taken from the session's files.
struct SessionReport {
  // The solve's verdict (result.json "verdict"); unset in results written before verdicts.
  std::optional<bool> usable;
  std::vector<std::string> refusal_reasons;
  std::vector<SuspectRow> suspect_poses;
  std::string session_id;
  std::string dir;
  bool simulated = false;  // result.json carries the simulated truth
  std::string plan_description;
  bool converged = false;
  std::string message, cost, model, noise_source;
  int solved_poses = 0, rank = 0, dof = 0;
  double condition_number = 0, noise_mm = 0, rms_miss_mm = 0;
  std::optional<double> chi2_per_dof, chi2_p_value, cell_time_s;
  std::vector<ParameterRow> parameters;  // the 8 identified, offsets first
  struct NotIdentifiable {
    std::string name, reason;
  };
  std::vector<NotIdentifiable> not_identifiable;
  std::array<double, 3> target_mm{}, target_sigma_mm{};
  std::vector<PoseRow> poses;   // every journal line, in order
  std::vector<int> remeasured;  // plan poses (1-based) measured again after the first solve
  std::optional<Validation> validation;
  // Whose calibration this is, from result.json's "cell", "zerocal_version" and
  // "finished_unix_s": the robot as its controller identified itself, the PSD map, the zerocal
  // that made the result, and when. Empty or unset in results written before they were recorded.
  RobotInfo robot;
  std::string psd_map, zerocal_version;
  std::optional<std::int64_t> finished_unix_s;
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

// Reads the session folder and (re)writes summary.txt and report.html beside result.json,
// each atomically (temporary file, then rename). Throws ReportError
// (missing or inconsistent files, a file that cannot be written) or JournalError.
void writeSessionReport(const std::string& session_dir);

// For text that goes into HTML: & < > " ' replaced by entities.
std::string escapeHtml(const std::string& text);

}  // namespace zerocal::report
