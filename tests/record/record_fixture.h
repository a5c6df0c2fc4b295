// Finished session folders for the record's tests, made through SessionStore's own API (create,
// writeResult, writeFile) as the daemon makes them, and a controller whose motor calibration
// lives in memory, so that apply journals come from the apply engine itself.
#pragma once

#include <array>
#include <optional>
#include <string>
#include <vector>

#include "zerocal/apply/online_apply.h"
#include "zerocal/record/robot_record.h"
#include "zerocal/store/session_store.h"

namespace zerocal::test {

struct FinishedSession {
  RobotInfo robot{"SN-0001", "6.13.02", "IRB 1600-10/1.45"};  // serial, software, type
  SessionKind kind = SessionKind::kCalibration;
  std::string verifies;
  bool usable = true;
  std::vector<std::string> reasons;
  // delta2..delta5, deg; nullopt: withheld
  std::array<std::optional<record::RecordedOffset>, 4> offsets{
      record::RecordedOffset{0.31, 0.002}, record::RecordedOffset{-0.52, 0.003},
      record::RecordedOffset{0.12, 0.004}, record::RecordedOffset{0.05, 0.005}};
  double cell_time_s = 61.5;
  std::array<double, 6> cal_offset_rad{1, 2, 3, 3.2, 5, 6};
  bool identity = true;                // false: a result that names no robot
  std::string model_from, model_file;  // the robot model it counted and wrote
  std::string reference;               // the reference it compares with
};

// A ResultFile as the daemon writes one for `s` (session `id`).
ResultFile resultOf(const FinishedSession& s, const std::string& id);

// A session.json's contents with a plan's prediction (of no poses), before create().
SessionFile plannedSession();

// Creates the session folder in `store`, writes its result, and returns its id.
std::string makeFinishedSession(SessionStore& store, const FinishedSession& s = {});

// Motor calibration values in memory; restart() takes what was written.
class MemoryCalibration : public ControllerCalibration {
 public:
  explicit MemoryCalibration(std::array<double, 6> values) : values_(values) {}
  std::array<double, 6> readCalOffsets() override { return values_; }
  void writeCalOffset(int joint, double rad) override {
    if (writes_left_ == 0) throw Error("link lost (test)");
    if (writes_left_ > 0) --writes_left_;
    values_[joint - 1] = rad;
  }
  void restart() override {}
  std::array<double, 6> readMotorAngles() override { return {}; }
  int writes_left_ = -1;  // -1: never fails

 private:
  std::array<double, 6> values_;
};

// The changes an apply of `offsets_deg` (delta2..delta5) makes from `present`, transmission 100.
std::array<apply::CalOffsetChange, 4> changesFor(const std::array<double, 4>& offsets_deg,
                                                 const std::array<double, 6>& present);

// Runs an online apply into session `id`'s apply.jsonl, its verification measuring `remaining`
// (deg, sigma 0.002); returns the outcome.
apply::OnlineApplyOutcome applyInto(SessionStore& store, const std::string& id,
                                    MemoryCalibration& controller,
                                    const std::array<double, 4>& offsets_deg,
                                    const std::array<double, 4>& remaining_deg);

}  // namespace zerocal::test
