// The robot's record (docs/record.md): each robot a cell has calibrated, by its controller's
// identity, with the history of its sessions and of what was written into its controller. The
// session folders (zerocal/store/session_store.h) stay the source of truth; a record is what they
// say, kept where it can be asked quickly (zerocal/record/from_folders.h makes its entries).
//
// RobotRecord is the seam: the daemon holds its record behind it, so that a database other than
// the cell's own embedded one (zerocal/record/sqlite_record.h), a plant-wide server holding the
// records of many cells, can take its place. It speaks plain values: no SQL, no file, no vendor.
#pragma once

#include <array>
#include <cstdint>
#include <optional>
#include <string>
#include <vector>

namespace zerocal::record {

// A robot as its controller names itself (request 98 of the IRC5). The type and the serial are
// the robot: a new controller software is the same robot, and its history goes on.
struct RobotId {
  std::string robot_type;  // "IRB 1600-10/1.45"
  std::string serial;      // the controller's serial number
  bool operator==(const RobotId& o) const {
    return robot_type == o.robot_type && serial == o.serial;
  }
  bool operator!=(const RobotId& o) const { return !(*this == o); }
};

struct RobotSummary {
  RobotId id;
  std::string software_version;  // of its latest session
  int sessions = 0;
  std::int64_t first_unix_s = 0, last_unix_s = 0;  // its first and latest session's start
};

// One offset as a session measured it, deg (arm side).
struct RecordedOffset {
  double value_deg = 0;
  double sigma_deg = 0;  // one standard deviation
  bool operator==(const RecordedOffset& o) const {
    return value_deg == o.value_deg && sigma_deg == o.sigma_deg;
  }
};
// delta2..delta5; an offset the session could not determine (withheld) is absent.
using RecordedOffsets = std::array<std::optional<RecordedOffset>, 4>;

// A finished session (one with its result.json).
struct SessionEntry {
  std::string session;  // its id: the folder's name, which sorts by age
  RobotId robot;
  std::string software_version;  // the controller's while the session ran
  std::string kind;              // session.json's "kind": "calibration", "verification", ...
  std::string verifies;          // a verification's: the session whose apply it verifies
  // The verdict; absent for a result written before verdicts were recorded.
  std::optional<bool> usable;
  std::vector<std::string> reasons;  // why it is not usable (or what limits it)
  bool converged = false;
  int poses_used = 0;
  RecordedOffsets offsets;
  std::optional<double> cell_time_s;
  std::int64_t started_unix_s = 0;              // session.json's creation time
  std::optional<std::int64_t> finished_unix_s;  // result.json's
  // The controller's MOTOR_CALIB cal_offset values (rad, joints 1..6) while it measured.
  std::optional<std::array<double, 6>> cal_offset_rad;
  // The robot model: the calibration whose calibrated model the solve counted (empty: the
  // daemon's robot file), and the calibrated model this session wrote, its file in the session
  // folder (empty: none).
  std::string model_from;
  std::string model_file;
  // A check's, a restore's or a restore's verification's: the reference it compares with; its
  // offsets are then the change of each zero since it.
  std::string reference;
  bool operator==(const SessionEntry& o) const;
};

// What happened to a controller's values through the daemon, from a session's apply journal.
enum class ControllerEventKind {
  kApply,            // new values written (or refused before writing: outcome "refused")
  kVerification,     // the offsets left after an apply measured, nothing written
  kRollback,         // the values from before an apply written back (a failed verification or
                     // the recovery of an interrupted apply)
  kAcknowledgement,  // an interrupted apply closed on the technician's word
};
const char* controllerEventKindName(ControllerEventKind kind);  // "apply", "verification", ...
// Throws InputError for a name none of them has.
ControllerEventKind controllerEventKindFromName(const std::string& name);

struct ControllerEvent {
  ControllerEventKind kind = ControllerEventKind::kApply;
  double time_unix_s = 0;  // when it began
  // apply: "verified", "rolled_back", "recovered", "not_written", "error", "unrecovered",
  // "acknowledged", "interrupted" (no end yet), "refused"; verification: "pass", "fail";
  // rollback: "restored", "error", "interrupted"; acknowledgement: "acknowledged".
  std::string outcome;
  // The controller's cal_offset values (rad, joints 1..6) before and after it; absent where the
  // journal does not know them (an apply refused before anything was read).
  std::optional<std::array<double, 6>> before_rad, after_rad;
  std::string verification;   // the session that measured, when one did
  RecordedOffsets remaining;  // a verification's measured offsets
  std::string message;
  bool operator==(const ControllerEvent& o) const;
};

// A session and what its apply journal tells of the controller, in the journal's order.
struct HistoryEntry {
  SessionEntry session;
  std::vector<ControllerEvent> events;
  bool operator==(const HistoryEntry& o) const {
    return session == o.session && events == o.events;
  }
};

class RobotRecord {
 public:
  virtual ~RobotRecord() = default;

  // Adds the session, or replaces what the record holds of it (the same id), and its robot.
  // recordSessions does all of them or none. Throw FileError when the record cannot be written.
  virtual void recordSession(const SessionEntry& entry) = 0;
  virtual void recordSessions(const std::vector<SessionEntry>& entries) = 0;
  // Replaces the controller events of `session` (recorded before: else InputError) by `events`,
  // all that its apply journal holds now. Throws FileError when the record cannot be written.
  virtual void recordControllerEvents(const std::string& session,
                                      const std::vector<ControllerEvent>& events) = 0;

  // Every robot, by type then serial. Throw FileError when the record cannot be read.
  virtual std::vector<RobotSummary> robots() const = 0;
  // The robot's sessions, oldest first (none for a robot the record does not know).
  virtual std::vector<HistoryEntry> history(const RobotId& robot) const = 0;
  // The robot's latest session of `kind`, usable only when `usable_only` (a reference to compare
  // with, the calibration in force); nullopt when it has none.
  virtual std::optional<SessionEntry> latest(const RobotId& robot, const std::string& kind,
                                             bool usable_only) const = 0;
};

}  // namespace zerocal::record
