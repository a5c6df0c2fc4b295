// The journal of a session (journal.jsonl in its folder; zerocal/store/session_store.h), so that a
// calibration survives a crash or kill -9 without losing or duplicating a pose: one JSON object
// per recorded pose, appended and fsync()ed before the caller moves on; a pose is committed when
// its line, newline included, is on disk. A session without result.json is unfinished and may be
// resumed from its journal. Units: joints in degrees, PSD coordinates and their standard errors in
// millimetres, timestamps in nanoseconds since the Unix epoch (system clock), durations in seconds.
//
// Beside it, faults.jsonl: one JSON object per servo fault latched at a pose, with the samples
// leading to it, appended and fsync()ed; absent until the first fault. No resume reads it: the
// journal alone says what was measured.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <memory>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>
#include <vector>

#include "zerocal/cell/psd_reader.h"
#include "zerocal/error.h"
#include "zerocal/model/robot.h"
#include "zerocal/results/servo_stats.h"
#include "zerocal/servo/servo_sample.h"

namespace zerocal {

// A session folder or journal cannot be written or read back consistently.
class JournalError : public Error {
 public:
  using Error::Error;
};

struct PoseRecord {
  // 0-based position of the line in the journal: lines are 0, 1, 2, ... with no gaps. The plan's
  // poses come first, so for them it is also the position in the plan.
  int index = 0;
  // A second measurement of plan pose `remeasure_of` (0-based), made after the plan's poses
  // because the solve named that pose; -1 for a plan pose's own line. The solve takes each plan
  // pose's latest measurement; the earlier one stays in the journal.
  int remeasure_of = -1;
  Joints joints_deg{};  // controller joint angles at the recorded reading
  // The recorded reading: the servo's converged one. The line keeps its spot and standard errors
  // (JSON u_mm, v_mm, u_se_mm, v_se_mm); a measured line read back is present and in the valid
  // zone, as every recorded reading is, with sum_v and time_s 0 (not journalled).
  PsdReading reading;
  std::int64_t move_started_ns = 0;
  std::int64_t recorded_ns = 0;
  ServoStats servo;
  // The spot's path on the detector during the servo, JSON "servo_path": [[t_s, u_mm, v_mm], ...]
  // with t_s the cell time since the servo's start. Only readings with the spot on the detector,
  // in time order: the first 16 and the last 48 of them when there were more (servo.h,
  // kPathCapacity); outside the map's zone u and v are the chain's coarse estimate. Absent from
  // older journals: empty.
  std::vector<SpotPathPoint> servo_path;
  // Why the pose was skipped, on the technician's request at a resume (its spot was never found,
  // say); empty for a measured pose. A skipped pose's line holds only index, skipped and
  // recorded_ns: it keeps the indices consecutive and says on disk that the pose was given up on
  // purpose, so that no later resume measures it and no solve uses it.
  std::string skipped;
  // The PSD placement (1-based) the pose was measured at, JSON "placement": written only when
  // it is not 1, so that a journal of one placement reads as before and an older one as 1.
  int placement = 1;
  // The record's 1-based line in journal.jsonl, placement lines counted (not written: its
  // position says). Set by readJournal and Journal::append; 0 for a record of neither. A pose
  // solved carries it as its Pose::source_line (posesOf), so the result names its journal lines.
  int line = 0;
  bool measured() const { return skipped.empty(); }
  int planIndex() const { return remeasure_of >= 0 ? remeasure_of : index; }
};

// Each plan pose's latest record, by 0-based plan pose (null where it has none): the one a solve
// takes, since a pose measured again replaces its first measurement (which stays in the
// journal). A skipped pose's latest record is its skipped line.
std::vector<const PoseRecord*> latestRecords(const std::vector<PoseRecord>& records);

nlohmann::json toJson(const PoseRecord& record);
// Throws JournalError when a member is missing or of the wrong type, or holds a value no arm or
// detector can have (a joint beyond +-kMaxJointTravelDeg, a spot or standard error beyond 50 mm,
// a number that is not finite): that line is damaged.
PoseRecord poseRecordFromJson(const nlohmann::json& json);

// The PSD was moved to placement `placement` (2, 3, ...) before the pose lines that follow: a
// line of its own, {"placement": 2, "centre_mm": [x, y, z], "recorded_ns": ...}, with no index
// (pose lines keep theirs). Written when a technician continues a session waiting for the
// placement, before any pose there is measured; until it is on disk the session waits, so a
// daemon restarted meanwhile never measures the next placement's poses with the PSD where it
// was. centre_mm: the placement's centre as taught (base frame, mm), which the servo starts from.
struct PlacementRecord {
  int placement = 2;
  std::array<double, 3> centre_mm{};
  std::int64_t recorded_ns = 0;
  int first_index = 0;  // the index of the next pose line then (not written: its position says)
};

nlohmann::json toJson(const PlacementRecord& record);
// Throws JournalError when a member is missing or of the wrong type.
PlacementRecord placementRecordFromJson(const nlohmann::json& json);

struct JournalContents {
  std::vector<PoseRecord> records;
  std::vector<PlacementRecord> placements;  // in journal order
  std::size_t committed_bytes = 0;          // length of the file up to the last committed line
  std::string dropped;  // empty, or why a torn last line was dropped (for a warning)
  int nextIndex() const { return static_cast<int>(records.size()); }
};

// The placement the PSD is at after these placement lines: the last one's, 1 when none.
int placementInForce(const std::vector<PlacementRecord>& placements);

// Reads a journal back. A last line that has no newline or does not parse is a write cut short by
// a crash: it is dropped and described in `dropped` (and warned about on the "journal" logger).
// A missing file is an empty journal. Throws JournalError for anything else: a bad line before
// the last one, indices that are not 0, 1, 2, ... (never skips, guesses or renumbers), placement
// lines that are not 2, 3, ... in turn, or a measured pose whose placement is not the one in
// force at its line.
JournalContents readJournal(const std::string& path);
// The same from the journal's text; `path` names it in the messages.
JournalContents parseJournal(const std::string& text, const std::string& path);

// The append side of journal.jsonl. Not thread-safe: the session worker owns it.
class Journal {
 public:
  // Opens (creating it if needed, then fsync()ing its folder) the journal at `path` for
  // appending, after reading it back; a torn last line is cut off the file so that the next
  // append starts on a line of its own. Throws JournalError.
  explicit Journal(const std::string& path);
  ~Journal();
  Journal(const Journal&) = delete;
  Journal& operator=(const Journal&) = delete;

  // Writes the record as one line with one write() and fsync()s the file; when this returns the
  // pose is on disk. record.index must equal nextIndex() and every number must be finite.
  // Throws JournalError (the journal is then unusable if the write itself failed). Returns the
  // record as journalled, its line set.
  const PoseRecord& append(const PoseRecord& record);
  // Writes a placement line likewise: record.placement must be the one in force plus 1, and its
  // first_index is set to nextIndex(). Throws JournalError.
  void append(const PlacementRecord& record);
  int nextIndex() const { return static_cast<int>(records_.size()); }
  const std::vector<PlacementRecord>& placements() const { return placements_; }
  int placement() const { return placementInForce(placements_); }
  // Every committed record: those read back at opening, then those appended since.
  const std::vector<PoseRecord>& records() const { return records_; }
  const std::string& dropped() const { return dropped_; }
  const std::string& path() const { return path_; }

 private:
  // One write() of a whole line, fsync()ed. Throws JournalError (and marks the journal broken).
  void writeLine(const std::string& line);

  std::string path_;
  int fd_ = -1;
  bool broken_ = false;
  std::vector<PoseRecord> records_;
  std::vector<PlacementRecord> placements_;
  std::string dropped_;
};

// One line of faults.jsonl: the servo latched a fault at a plan pose, whether the run then
// recovered (a reconnect, the pose again) or stopped there. An abort is not a fault.
struct FaultRecord {
  int plan_index = 0;      // 0-based plan pose
  bool remeasure = false;  // while measuring the pose a second time (JSON only when true)
  std::string status;      // the servo's status name: "spot not found", "link error", ...
  std::string message;     // the servo's fault message
  std::int64_t recorded_ns = 0;
  // The fault's recent samples, oldest first (at most 32). JSON: [t_s, q1..q6, u_mm, v_mm, sum_v,
  // spot_present, in_valid_zone]; a number that was not finite is null on disk and NaN read back.
  // Each reading's spot, sum_v and flags are kept; its se is not, and its time_s reads back as
  // the sample's.
  std::vector<servo::ServoSample> samples;
};

nlohmann::json toJson(const FaultRecord& record);
// Throws JournalError when a member is missing or of the wrong type.
FaultRecord faultRecordFromJson(const nlohmann::json& json);
// faults.jsonl in the folder of the journal at `journal_path`.
std::string faultLogPath(const std::string& journal_path);
// Appends the record as one line with one write() and fsync()s it (and, when this creates the
// file, its folder): when this returns the fault is on disk. Throws JournalError.
void appendFault(const std::string& path, const FaultRecord& record);
// Every committed line; a missing file has none, a torn last line (a crash mid-write) is dropped.
// Throws JournalError for a bad line before the last.
std::vector<FaultRecord> readFaults(const std::string& path);

}  // namespace zerocal
