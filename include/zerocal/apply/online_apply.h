// Online apply: new MOTOR_CALIB cal_offset values written into the controller behind a backup,
// taken by a restart, verified by measurement, rolled back when wrong; every step journalled
// before it is taken, so that a process killed at any step leaves a state recoverApply() brings
// back to a known one (docs/apply.md).
#pragma once

#include <array>
#include <functional>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>
#include <vector>

#include "zerocal/apply/motor_calibration.h"
#include "zerocal/apply/transmission_check.h"
#include "zerocal/cell/controller_calibration.h"
#include "zerocal/cell/controller_link.h"

namespace zerocal::apply {

// An offset of joints 2..5 as a calibration measured it, deg (arm side).
struct MeasuredOffset {
  double value_deg = 0;
  double sigma_deg = 0;
};
using Offsets = std::array<MeasuredOffset, 4>;  // joints 2..5

struct OnlineApplyOptions {
  // Pass when every remaining offset is within max(3 sigma, required_deg).
  double required_deg = 0.003;
  // Measures what remains of joints 2..5's offsets now, each with the whole standard uncertainty
  // of that remainder (a verification that measures the write alone has only its own; one that
  // measures the zeros anew also has the calibration's). Throws to abort (then rolled back).
  std::function<Offsets()> verify;
  // For a joint whose new value crosses the seam, after the restart: have its revolution
  // counter updated at its synchronisation mark (the technician on the FlexPendant, or the
  // simulated controller); false when it was not, and the apply is rolled back.
  std::function<bool(int joint, double turn_error_deg)> update_revolution_counter;
  // Progress lines for the terminal.
  std::function<void(const std::string&)> progress;
  // The controller written to, as it names itself (request 98): journalled with the backup, so
  // that a recovery writes the backup only into the controller it came from.
  RobotInfo controller;
};

enum class ApplyState { kVerified, kRolledBack };

struct OnlineApplyOutcome {
  ApplyState state = ApplyState::kRolledBack;
  std::string message;  // the verdict; for a rollback, why, naming the joints
  Offsets after{};      // what the verification measured (zero when it did not run)
  std::array<double, 6> before_rad{}, written_rad{};
};

// An append-only JSON-lines file, each line flushed and fsync'ed before the step it announces.
class ApplyJournal {
 public:
  explicit ApplyJournal(std::string path) : path_(std::move(path)) {}
  void append(nlohmann::json line);  // adds "time_unix_s"; throws Error when it cannot write
  std::vector<nlohmann::json> read() const;  // a last line cut short by a crash is dropped
  const std::string& path() const { return path_; }

 private:
  std::string path_;
};

// The verdict on a verification: pass, or per failing joint what the numbers point to (a doubled
// offset: the transmission's sign; one motor turn: the revolution counter; a part left: the
// ratio, with the ratio the numbers imply). `before` holds the offsets the apply wrote (their
// values name the cause), `after` what remains, with its whole uncertainty (OnlineApplyOptions).
struct Verdict {
  bool pass = false;
  std::string message;
};
Verdict judge(const std::array<CalOffsetChange, 4>& changes, const Offsets& before,
              const Offsets& after, double required_deg);

// Applies `changes` (joints 2..5, computed from `before` against the controller's present
// values): checks the controller still holds the values they were computed from, backs them up
// in the journal, writes, reads back, restarts, has seam crossings' revolution counters updated,
// verifies, and restores the backup (with a restart) when the verification fails. Throws Error
// (after journalling it) when the controller does not hold the expected values or the link
// fails; recoverApply() then restores a known state.
OnlineApplyOutcome applyOnline(ControllerCalibration& store,
                               const std::array<CalOffsetChange, 4>& changes, const Offsets& before,
                               const OnlineApplyOptions& options, ApplyJournal& journal);

// Journals the transmissions measured before an apply (a "transmission_check" line). When one
// disagrees the apply stops there, nothing written: lastApplyRecord() shows it as "refused".
// Throws Error when it cannot write.
void journalTransmissionCheck(ApplyJournal& journal,
                              const std::vector<TransmissionMeasurement>& measurements);

// True when the journal's last online apply has no "done" line (the process stopped inside it):
// recoverApply() has work to do. Reads only the journal.
bool applyInterrupted(const ApplyJournal& journal);
// The open apply's backup and written values, in a sentence for a technician who checks the
// controller by hand; empty when no apply is open (or its values cannot be read).
std::string interruptedApplyValues(const ApplyJournal& journal);
// Joints 2..5's cal_offset values (rad) as the FlexPendant names them: "rob1_2 0.123456 ...".
std::string valuesText(const std::array<double, 6>& rad);

// The latest online apply or verification of a session as its journal tells it, for the report.
struct ApplyRecord {
  // "verified", "rolled_back", "recovered" (restored after an interruption), "not_written" (an
  // interruption before anything took effect), "interrupted" (no end line: the process stopped),
  // "unrecovered" (the recovery found values it must not write over), "acknowledged" (closed
  // by the technician), "error" (stopped with an error after the backup), "refused" (a measured
  // transmission disagreed with the robot file; nothing written), "pass" / "fail" (a
  // verification alone).
  std::string outcome;
  double time_unix_s = 0;                             // when it began
  std::array<double, 6> before_rad{}, written_rad{};  // zero for a verification alone
  std::vector<std::string> formulas;                  // joints 2..5, with their signs
  std::optional<Offsets> remaining;                   // as the verification measured them
  std::string verification;                           // its session id, when one ran
  std::string message;
  // The transmissions measured before writing (empty when the apply did not measure them).
  struct Transmission {
    int joint = 0;
    double configured = 0, measured = 0;
    bool agrees = false;
  };
  std::vector<Transmission> transmissions;
  // A verification run on its own after this apply ("pass" / "fail"), the latest one.
  struct LaterCheck {
    std::string outcome, session, message;
    Offsets remaining{};
  };
  std::optional<LaterCheck> later_check;
};
// Throws nothing: a journal that is absent or holds no online step gives nullopt.
std::optional<ApplyRecord> lastApplyRecord(const ApplyJournal& journal);

enum class RecoveryOutcome {
  kNotNeeded,       // the journal's last apply has ended
  kNothingWritten,  // stopped before any value it wrote took effect; closed, nothing written
  kRestored,        // the backup written back, the controller restarted, the values read back
  // Not recovered, nothing written (the apply stays open, the daemon refuses to run):
  kConflict,  // the controller holds, at some joint, neither the backup nor the written value
  kForeign,   // the apply was made on another controller, or recorded none
};
const char* recoveryOutcomeName(RecoveryOutcome outcome);

struct Recovery {
  RecoveryOutcome outcome = RecoveryOutcome::kNotNeeded;
  bool needed() const { return outcome != RecoveryOutcome::kNotNeeded; }
  // The apply is closed (nothing to do, nothing written, or restored).
  bool resolved() const {
    return outcome != RecoveryOutcome::kConflict && outcome != RecoveryOutcome::kForeign;
  }
  // What was found and what was done; for an unresolved one, the values to check on the
  // controller (the backup, the written ones, what it holds) and the joints that differ.
  std::string message;
  std::array<double, 6> found_rad{}, backup_rad{}, written_rad{};
  std::vector<int> differing_joints;  // 1-based: holding neither the backup nor the written value
};
// Reads the journal; when its last apply did not finish, brings the controller back to a known
// state, by the rules of docs/apply.md ("An interrupted apply"):
// - the apply's recorded controller (robot type and serial) must be `controller`, else kForeign;
// - every joint must hold the apply's backup or its written value, else kConflict (the message
//   gives both sets and the joints that differ);
// - when every joint holds the backup and the controller was never restarted on the new values,
//   nothing was written that took effect: kNothingWritten, closed without a write or restart;
// - otherwise the backup is written, the controller restarted and read back: kRestored.
// Resolved outcomes are journalled with a "done" line; an unresolved one with a
// "recovery_refused" line (once per finding) and the apply stays open. Throws Error when the link
// fails or a restore cannot be completed (the message holds the backed-up values to enter by
// hand); the apply then stays open too.
Recovery recoverApply(ControllerCalibration& store, ApplyJournal& journal,
                      const RobotInfo& controller);

// Closes the journal's open apply on the technician's word that the controller holds the values
// it should (checked by hand on the FlexPendant): an "acknowledged" line with `found_rad` (what the
// controller holds, when it could be read) and `note`, then "done". False when no apply is open.
// Throws Error when it cannot write.
bool acknowledgeApply(ApplyJournal& journal, const std::optional<std::array<double, 6>>& found_rad,
                      const std::string& note);

}  // namespace zerocal::apply
