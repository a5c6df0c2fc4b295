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

namespace zerocal::apply {

// An offset of joints 2..5 as a calibration measured it, deg (arm side).
struct MeasuredOffset {
  double value_deg = 0;
  double sigma_deg = 0;
};
using Offsets = std::array<MeasuredOffset, 4>;  // joints 2..5

struct OnlineApplyOptions {
  // Pass when every remaining offset is within max(3 sigma, required_deg), sigma combining the
  // calibration the change came from and the verification (hypot of the two).
  double required_deg = 0.003;
  // Measures joints 2..5 now (a verification calibration). Throws to abort (then rolled back).
  std::function<Offsets()> verify;
  // For a joint whose new value crosses the seam, after the restart: have its revolution
  // counter updated at its synchronisation mark (the technician on the FlexPendant, or the
  // simulated controller); false when it was not, and the apply is rolled back.
  std::function<bool(int joint, double turn_error_deg)> update_revolution_counter;
  // Progress lines for the terminal.
  std::function<void(const std::string&)> progress;
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
// ratio, with the ratio the numbers imply).
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

// The latest online apply or verification of a session as its journal tells it, for the report.
struct ApplyRecord {
  // "verified", "rolled_back", "recovered", "interrupted" (no end line: the process stopped),
  // "error" (stopped with an error after the backup), "refused" (a measured transmission
  // disagreed with the robot file; nothing written), "pass" / "fail" (a verification alone).
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

struct Recovery {
  bool needed = false;  // the journal ends inside an apply
  std::string message;  // what was found and what was done
};
// Reads the journal; when its last apply did not finish, restores the backed-up values (write,
// restart, read back), journals that, and says so. Throws Error when the controller cannot be
// restored (the message holds the backed-up values to enter by hand).
Recovery recoverApply(ControllerCalibration& store, ApplyJournal& journal);

}  // namespace zerocal::apply
