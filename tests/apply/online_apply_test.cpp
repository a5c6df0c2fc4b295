// Online apply against the simulated controller through the real client (requests 41, 45, 46):
// verified when the transmission is right, rolled back naming the joint when a sign is wrong,
// and an apply interrupted at any step recovered to the backed-up values.
#include "zerocal/apply/online_apply.h"

#include <gtest/gtest.h>

#include <chrono>
#include <cstdio>
#include <filesystem>
#include <fstream>

#include "zerocal/error.h"
#include "zerocal/irc5/irc5_client.h"
#include "zerocal/model/builtin.h"
#include "zerocal/model/kinematics.h"
#include "zerocal/sim/sim_controller.h"

namespace zerocal::apply {
namespace {

class ClientStore : public ControllerCalibration {
 public:
  explicit ClientStore(Irc5Client& c) : c_(c) {}
  std::array<double, 6> readCalOffsets() override { return c_.readCalOffsets(); }
  void writeCalOffset(int joint, double rad) override {
    if (writes_left_-- == 0) throw Error("link lost (test)");
    c_.writeCalOffset(joint, rad);
  }
  void restart() override { c_.restartController(); }
  std::array<double, 6> readMotorAngles() override { return c_.readMotorAngles(); }
  int writes_left_ = -1;  // -1: never fail

 private:
  Irc5Client& c_;
};

struct Cell {
  explicit Cell(std::uint64_t seed, std::array<double, 6> cal = {1, 2, 3, 0.2, 5, 6}) {
    SimControllerOptions o;
    o.world = randomWorld(seed);
    o.world.true_offsets_deg = {0.3, -0.5, 0.4, 0.6, -0.7, 0.2};
    o.motor.cal_offset_rad = cal;
    o.seed = seed;
    sim = std::make_unique<SimController>(o);
    sim->start();
    Irc5Options c;
    c.host = "127.0.0.1";
    c.port = sim->port();
    c.robot = builtinIrb1600();
    c.request_timeout = std::chrono::milliseconds(1000);
    c.backoff_initial = std::chrono::milliseconds(10);
    client = std::make_unique<Irc5Client>(c);
    client->connect();
    store = std::make_unique<ClientStore>(*client);
  }
  // What a perfect verification measures: the true remaining offsets.
  Offsets truth() const {
    Offsets o;
    for (int k = 0; k < 4; ++k)
      o[k] = {sim->world().true_offsets_deg[k + 1] + sim->zeroShiftDeg()[k + 1], 0.001};
    return o;
  }
  std::array<CalOffsetChange, 4> changes(const std::array<double, 6>& transmission) {
    const auto present = client->readCalOffsets();
    std::array<CalOffsetChange, 4> c;
    for (int j = 2; j <= 5; ++j)
      c[j - 2] = calOffsetChange(j, sim->world().true_offsets_deg[j - 1] * kDegToRad,
                                 transmission[j - 1], present[j - 1]);
    return c;
  }
  RobotInfo identity() { return client->robotInfo(); }
  OnlineApplyOptions options() {
    OnlineApplyOptions o;
    o.controller = identity();
    o.verify = [this] { return truth(); };
    o.update_revolution_counter = [this](int joint, double) {
      sim->updateRevolutionCounter(joint);  // the technician at the mark
      return true;
    };
    return o;
  }
  std::unique_ptr<SimController> sim;
  std::unique_ptr<Irc5Client> client;
  std::unique_ptr<ClientStore> store;
};

std::string journalPath(const std::string& name) {
  const std::string p =
      (std::filesystem::temp_directory_path() / ("zerocal-apply-" + name)).string();
  std::filesystem::remove(p);
  return p;
}

TEST(OnlineApply, RightTransmissionIsVerifiedAndKept) {
  Cell cell(1);
  ApplyJournal journal(journalPath("right.jsonl"));
  const auto changes = cell.changes(builtinIrb1600().transmission);
  EXPECT_TRUE(changes[2].crossesSeam());  // joint 4 at 0.2 rad: the counter step is exercised
  const OnlineApplyOutcome out =
      applyOnline(*cell.store, changes, cell.truth(), cell.options(), journal);
  EXPECT_EQ(out.state, ApplyState::kVerified) << out.message;
  for (const auto& m : cell.truth()) EXPECT_NEAR(m.value_deg, 0.0, 1e-5);
  const auto lines = journal.read();
  ASSERT_FALSE(lines.empty());
  EXPECT_EQ(lines.front()["step"], "begin");
  EXPECT_EQ(lines.back()["step"], "done");
  EXPECT_EQ(lines.back()["outcome"], "verified");
  EXPECT_FALSE(recoverApply(*cell.store, journal, cell.identity()).needed());
}

TEST(OnlineApply, AWrongSignIsRolledBackNamingTheJoint) {
  Cell cell(2);
  const auto before = cell.sim->calOffsets();
  ApplyJournal journal(journalPath("sign.jsonl"));
  std::array<double, 6> believed = builtinIrb1600().transmission;
  believed[2] = -believed[2];
  const OnlineApplyOutcome out =
      applyOnline(*cell.store, cell.changes(believed), cell.truth(), cell.options(), journal);
  EXPECT_EQ(out.state, ApplyState::kRolledBack);
  EXPECT_NE(out.message.find("delta3 doubled"), std::string::npos) << out.message;
  EXPECT_NE(out.message.find("the sign of joint 3's transmission is wrong"), std::string::npos);
  EXPECT_EQ(out.message.find("delta2"), std::string::npos) << out.message;
  for (int i = 0; i < 6; ++i) EXPECT_NEAR(cell.sim->calOffsets()[i], before[i], 1e-6);
  for (double s : cell.sim->zeroShiftDeg()) EXPECT_NEAR(s, 0.0, 1e-6);  // the world as it was
  EXPECT_EQ(journal.read().back()["outcome"], "rolled_back");
}

TEST(OnlineApply, AWrongRatioAndAForgottenCounterAreNamed) {
  Cell cell(3);
  std::array<double, 6> believed = builtinIrb1600().transmission;
  believed[1] = 100;  // joint 2: 100 believed, the arm has the model's 120
  OnlineApplyOptions options = cell.options();
  options.update_revolution_counter = [](int, double) { return true; };  // claimed, not done
  ApplyJournal journal(journalPath("ratio.jsonl"));
  const OnlineApplyOutcome out =
      applyOnline(*cell.store, cell.changes(believed), cell.truth(), options, journal);
  EXPECT_EQ(out.state, ApplyState::kRolledBack);
  EXPECT_NE(out.message.find("joint 2's transmission looks like +120.0, not +100"),
            std::string::npos)
      << out.message;
  EXPECT_NE(out.message.find("joint 4 is one motor turn"), std::string::npos) << out.message;
}

TEST(OnlineApply, AVerificationThatCannotCompleteRollsBack) {
  Cell cell(7);
  const auto before = cell.sim->calOffsets();
  OnlineApplyOptions options = cell.options();
  options.verify = []() -> Offsets { throw Error("spot not found (test)"); };
  ApplyJournal journal(journalPath("noverify.jsonl"));
  const OnlineApplyOutcome out = applyOnline(
      *cell.store, cell.changes(builtinIrb1600().transmission), cell.truth(), options, journal);
  EXPECT_EQ(out.state, ApplyState::kRolledBack);
  EXPECT_NE(out.message.find("the verification did not complete: spot not found (test)"),
            std::string::npos)
      << out.message;
  for (int i = 0; i < 6; ++i) EXPECT_NEAR(cell.sim->calOffsets()[i], before[i], 1e-6);
  // Joint 4 crossed the seam and its counter was updated: back on the old value it is updated
  // again, so the world is as it was.
  for (double s : cell.sim->zeroShiftDeg()) EXPECT_NEAR(s, 0.0, 1e-6);
}

TEST(OnlineApply, RefusesWhenTheControllerChangedSinceTheComputation) {
  Cell cell(4);
  const auto changes = cell.changes(builtinIrb1600().transmission);
  cell.sim->writeCalOffset(3, 0.5);
  ApplyJournal journal(journalPath("changed.jsonl"));
  EXPECT_THROW(applyOnline(*cell.store, changes, cell.truth(), cell.options(), journal), Error);
  EXPECT_TRUE(journal.read().empty());  // nothing begun
}

// A process killed after any step: the journal up to that step, the controller in the state the
// steps left it, then recovery on the next start.
TEST(OnlineApply, AnApplyInterruptedAtAnyStepIsRecoveredToTheBackup) {
  Cell reference(5);
  ApplyJournal full(journalPath("full.jsonl"));
  applyOnline(*reference.store, reference.changes(builtinIrb1600().transmission), reference.truth(),
              reference.options(), full);
  const auto lines = full.read();
  ASSERT_GE(lines.size(), 5u);
  for (std::size_t cut = 1; cut + 1 < lines.size(); ++cut) {
    Cell cell(5);
    const auto before = cell.sim->calOffsets();
    const std::string step = lines[cut - 1]["step"];
    // Replay the controller's side up to the cut.
    const auto written = lines.front()["new_rad"].get<std::array<double, 6>>();
    bool wrote = false, restarted = false;
    for (std::size_t i = 1; i < cut; ++i) {
      const std::string s = lines[i]["step"];
      wrote = wrote || s == "written";
      restarted = restarted || s == "restarted";
    }
    if (wrote)
      for (int j = 2; j <= 5; ++j) cell.client->writeCalOffset(j, written[j - 1]);
    if (restarted) cell.client->restartController();
    ApplyJournal journal(journalPath("cut.jsonl"));
    for (std::size_t i = 0; i < cut; ++i) journal.append(lines[i]);
    const Recovery r = recoverApply(*cell.store, journal, cell.identity());
    EXPECT_TRUE(r.needed()) << "cut after " << step;
    EXPECT_NE(r.message.find("interrupted after step '" + step + "'"), std::string::npos)
        << r.message;
    for (int i = 0; i < 6; ++i) EXPECT_NEAR(cell.sim->calOffsets()[i], before[i], 1e-6) << step;
    for (double s : cell.sim->zeroShiftDeg()) EXPECT_NEAR(s, 0.0, 1e-6) << step;
    // Cut after the backup alone, nothing was written: nothing is restored, nothing restarted.
    EXPECT_EQ(journal.read().back()["outcome"], wrote ? "recovered" : "not_written") << step;
    EXPECT_EQ(r.outcome, wrote ? RecoveryOutcome::kRestored : RecoveryOutcome::kNothingWritten);
    EXPECT_FALSE(recoverApply(*cell.store, journal, cell.identity()).needed());  // once is enough
  }
}

TEST(OnlineApply, ALinkLostWhileWritingIsJournalledAndRecovered) {
  Cell cell(6);
  const auto before = cell.sim->calOffsets();
  cell.store->writes_left_ = 2;
  ApplyJournal journal(journalPath("lost.jsonl"));
  EXPECT_THROW(applyOnline(*cell.store, cell.changes(builtinIrb1600().transmission), cell.truth(),
                           cell.options(), journal),
               Error);
  EXPECT_EQ(journal.read().back()["step"], "error");
  cell.store->writes_left_ = -1;
  const Recovery r = recoverApply(*cell.store, journal, cell.identity());
  EXPECT_EQ(r.outcome, RecoveryOutcome::kRestored) << r.message;  // two joints were written
  for (int i = 0; i < 6; ++i) EXPECT_NEAR(cell.sim->calOffsets()[i], before[i], 1e-6);
}

// The journal of an apply killed right after its backup: "begin" with the controller's values
// and those it was about to write (joint 3 changed).
struct BeganApply {
  explicit BeganApply(Cell& cell, const std::string& name, RobotInfo controller)
      : journal(journalPath(name)) {
    before = cell.sim->calOffsets();
    written = before;
    written[2] = before[2] + 0.01;
    journal.append({{"step", "begin"},
                    {"controller",
                     {{"robot_type", controller.robot_type},
                      {"serial", controller.serial},
                      {"software_version", controller.software_version}}},
                    {"before_rad", before},
                    {"new_rad", written},
                    {"changes", nlohmann::json::array()}});
  }
  ApplyJournal journal;
  std::array<double, 6> before{}, written{};
};

// Killed after the backup and before any write: the controller holds the backup, nothing is
// written and no restart is made (a restart of a robot cell costs a minute and is never needed).
TEST(OnlineApplyRecovery, AnApplyThatWroteNothingNeedsNoRestore) {
  Cell cell(8);
  BeganApply began(cell, "began.jsonl", cell.identity());
  const long restarts = cell.sim->restartCount();
  const Recovery r = recoverApply(*cell.store, began.journal, cell.identity());
  EXPECT_EQ(r.outcome, RecoveryOutcome::kNothingWritten) << r.message;
  EXPECT_EQ(cell.sim->restartCount(), restarts);
  EXPECT_FALSE(applyInterrupted(began.journal));
  EXPECT_EQ(began.journal.read().back()["outcome"], "not_written");
}

// Killed between two writes, before the "written" line: a joint holds the new value. Every joint
// holds the backup or the written value, so the backup is restored.
TEST(OnlineApplyRecovery, AnApplyKilledBetweenTwoWritesIsRestored) {
  Cell cell(8);
  BeganApply began(cell, "half.jsonl", cell.identity());
  cell.client->writeCalOffset(3, began.written[2]);
  const Recovery r = recoverApply(*cell.store, began.journal, cell.identity());
  EXPECT_EQ(r.outcome, RecoveryOutcome::kRestored) << r.message;
  for (int i = 0; i < 6; ++i) EXPECT_NEAR(cell.sim->calOffsets()[i], began.before[i], 1e-6);
}

// The controller holds values that are neither this apply's backup nor its written ones (a later
// apply was verified since): the recovery writes nothing, says what differs, and stays open.
TEST(OnlineApplyRecovery, ValuesThatAreNeitherBackupNorWrittenAreNeverWrittenOver) {
  Cell cell(8);
  BeganApply began(cell, "conflict.jsonl", cell.identity());
  const double verified = began.before[3] + 0.02;  // joint 4, calibrated and verified since
  cell.client->writeCalOffset(4, verified);
  cell.client->restartController();
  const long restarts = cell.sim->restartCount();
  const Recovery r = recoverApply(*cell.store, began.journal, cell.identity());
  EXPECT_EQ(r.outcome, RecoveryOutcome::kConflict);
  EXPECT_FALSE(r.resolved());
  EXPECT_EQ(r.differing_joints, std::vector<int>{4});
  EXPECT_NEAR(cell.sim->calOffsets()[3], verified, 1e-6);
  EXPECT_EQ(cell.sim->restartCount(), restarts);
  // Both sets of values and what the controller holds, for the FlexPendant.
  EXPECT_NE(r.message.find("backup " + valuesText(began.before)), std::string::npos) << r.message;
  EXPECT_NE(r.message.find("written " + valuesText(began.written)), std::string::npos) << r.message;
  EXPECT_NE(r.message.find("holds " + valuesText(cell.sim->calOffsets())), std::string::npos)
      << r.message;
  EXPECT_NE(r.message.find("joint 4"), std::string::npos) << r.message;
  EXPECT_TRUE(applyInterrupted(began.journal));
  // Tried again, it finds the same and journals it once.
  recoverApply(*cell.store, began.journal, cell.identity());
  int refused = 0;
  for (const auto& line : began.journal.read()) refused += line["step"] == "recovery_refused";
  EXPECT_EQ(refused, 1);
  // The technician checks the values on the FlexPendant and acknowledges them: closed.
  EXPECT_TRUE(acknowledgeApply(began.journal, cell.sim->calOffsets(), "checked (test)"));
  EXPECT_FALSE(applyInterrupted(began.journal));
  EXPECT_EQ(began.journal.read().back()["outcome"], "acknowledged");
  EXPECT_FALSE(acknowledgeApply(began.journal, std::nullopt, "again"));
  EXPECT_EQ(lastApplyRecord(began.journal)->outcome, "acknowledged");
}

// An apply journalled on another controller (a session folder copied from another cell), or one
// that recorded no controller: nothing is written into this one.
TEST(OnlineApplyRecovery, AnotherControllersApplyIsNeverWrittenIntoThisOne) {
  Cell cell(8);
  RobotInfo other = cell.identity();
  other.serial = "6400-500123";
  BeganApply began(cell, "foreign.jsonl", other);
  cell.client->writeCalOffset(3, began.written[2]);  // it even holds the "written" value
  const Recovery r = recoverApply(*cell.store, began.journal, cell.identity());
  EXPECT_EQ(r.outcome, RecoveryOutcome::kForeign);
  EXPECT_NE(r.message.find("6400-500123"), std::string::npos) << r.message;
  EXPECT_NEAR(cell.client->readCalOffsets()[2], began.written[2], 1e-6);  // left as it is
  EXPECT_TRUE(applyInterrupted(began.journal));
  EXPECT_EQ(lastApplyRecord(began.journal)->outcome, "unrecovered");

  BeganApply anonymous(cell, "anonymous.jsonl", RobotInfo{});
  EXPECT_EQ(recoverApply(*cell.store, anonymous.journal, cell.identity()).outcome,
            RecoveryOutcome::kForeign);
}

}  // namespace
}  // namespace zerocal::apply
