// The record's entries from session folders: a finished session's entry from its files, and the
// controller events of apply journals that the apply engine itself wrote.
#include "zerocal/record/from_folders.h"

#include <gtest/gtest.h>

#include "record_fixture.h"
#include "temp_dir.h"
#include "zerocal/error.h"
#include "zerocal/store/session_files.h"

namespace zerocal::record {
namespace {

using test::FinishedSession;
using test::MemoryCalibration;

const std::array<double, 6> kPresent{1, 2, 3, 3.2, 5, 6};

std::vector<ControllerEvent> eventsOf(const SessionStore& store, const std::string& id) {
  return controllerEventsOfFolder(store, id);
}

TEST(SessionEntryOf, HoldsTheRobotVerdictOffsetsAndTimesTheSessionsFilesSay) {
  const testing::TempDir dir("zerocal-record");
  SessionStore store(dir.path);
  FinishedSession s;
  s.usable = false;
  s.reasons = {"delta5 is withheld"};
  s.offsets[3].reset();
  s.kind = SessionKind::kVerification;
  s.verifies = "20261122T070000Z";
  s.model_from = "20261120T000000Z";
  s.model_file = "model.yaml";
  s.reference = "20261119T000000Z";
  const std::string id = test::makeFinishedSession(store, s);
  const SessionFile session = store.readSession(id);
  const SessionEntry e = sessionEntryOf(session, store.readResult(id));
  EXPECT_EQ(e.session, id);
  EXPECT_EQ(e.robot, (RobotId{"IRB 1600-10/1.45", "SN-0001"}));
  EXPECT_EQ(e.software_version, "6.13.02");
  EXPECT_EQ(e.kind, "verification");
  EXPECT_EQ(e.verifies, "20261122T070000Z");
  ASSERT_TRUE(e.usable.has_value());
  EXPECT_FALSE(*e.usable);
  EXPECT_EQ(e.reasons, s.reasons);
  EXPECT_TRUE(e.converged);
  EXPECT_EQ(e.poses_used, 16);
  ASSERT_TRUE(e.offsets[0] && e.offsets[1] && e.offsets[2]);
  EXPECT_EQ(*e.offsets[1], (RecordedOffset{-0.52, 0.003}));
  EXPECT_FALSE(e.offsets[3]) << "a withheld offset is absent, not zero";
  EXPECT_EQ(e.cell_time_s, 61.5);
  EXPECT_EQ(e.started_unix_s, session.created_unix_s);
  EXPECT_EQ(e.finished_unix_s, 1'800'000'000);
  EXPECT_EQ(e.cal_offset_rad, kPresent);
  EXPECT_EQ(e.model_from, "20261120T000000Z");
  EXPECT_EQ(e.model_file, "model.yaml");
  EXPECT_EQ(e.reference, "20261119T000000Z");
}

TEST(SessionEntryOf, AResultWrittenBeforeVerdictsHasNoVerdictNotAFalseOne) {
  ResultFile r = test::resultOf({}, "20261122T070000Z");
  r.verdict_recorded = false;
  SessionFile session;
  session.id = "20261122T070000Z";
  EXPECT_FALSE(sessionEntryOf(session, r).usable.has_value());
}

TEST(SessionEntryOf, RefusesAResultThatNamesNoRobot) {
  FinishedSession s;
  s.identity = false;
  SessionFile session;
  session.id = "20261122T070000Z";
  try {
    sessionEntryOf(session, test::resultOf(s, session.id));
    FAIL() << "a session of no robot was given an entry";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("20261122T070000Z"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("names no robot"), std::string::npos) << e.what();
  }
}

TEST(ControllerEventsOf, AVerifiedApplyIsItsValuesBeforeAndAfterAndItsPassingVerification) {
  const testing::TempDir dir("zerocal-record");
  SessionStore store(dir.path);
  const std::string id = test::makeFinishedSession(store);
  MemoryCalibration controller(kPresent);
  const apply::OnlineApplyOutcome out = test::applyInto(
      store, id, controller, {0.31, -0.52, 0.12, 0.05}, {0.001, -0.001, 0.0005, 0.0});
  ASSERT_EQ(out.state, apply::ApplyState::kVerified) << out.message;

  const std::vector<ControllerEvent> events = eventsOf(store, id);
  ASSERT_EQ(events.size(), 2u);
  const ControllerEvent& a = events[0];
  EXPECT_EQ(a.kind, ControllerEventKind::kApply);
  EXPECT_EQ(a.outcome, "verified");
  EXPECT_EQ(a.before_rad, kPresent);
  EXPECT_EQ(a.after_rad, out.written_rad);
  EXPECT_NE(*a.after_rad, *a.before_rad);
  EXPECT_EQ(a.verification, id + "-verification");
  EXPECT_GT(a.time_unix_s, 1.7e9);
  EXPECT_EQ(a.message, out.message);
  const ControllerEvent& v = events[1];
  EXPECT_EQ(v.kind, ControllerEventKind::kVerification);
  EXPECT_EQ(v.outcome, "pass");
  EXPECT_EQ(v.before_rad, out.written_rad);
  EXPECT_EQ(v.after_rad, out.written_rad);
  EXPECT_EQ(v.verification, id + "-verification");
  ASSERT_TRUE(v.remaining[0] && v.remaining[3]);
  EXPECT_EQ(*v.remaining[1], (RecordedOffset{-0.001, 0.002}));
}

TEST(ControllerEventsOf, AFailedVerificationIsFollowedByTheRollbackToTheBackup) {
  const testing::TempDir dir("zerocal-record");
  SessionStore store(dir.path);
  const std::string id = test::makeFinishedSession(store);
  MemoryCalibration controller(kPresent);
  const apply::OnlineApplyOutcome out =
      test::applyInto(store, id, controller, {0.31, -0.52, 0.12, 0.05}, {0.001, 0.2, 0.0005, 0.0});
  ASSERT_EQ(out.state, apply::ApplyState::kRolledBack);
  ASSERT_EQ(controller.readCalOffsets(), kPresent);

  const std::vector<ControllerEvent> events = eventsOf(store, id);
  ASSERT_EQ(events.size(), 3u);
  EXPECT_EQ(events[0].kind, ControllerEventKind::kApply);
  EXPECT_EQ(events[0].outcome, "rolled_back");
  EXPECT_EQ(events[0].after_rad, out.written_rad) << "an apply's after: what it wrote";
  EXPECT_EQ(events[1].kind, ControllerEventKind::kVerification);
  EXPECT_EQ(events[1].outcome, "fail");
  const ControllerEvent& r = events[2];
  EXPECT_EQ(r.kind, ControllerEventKind::kRollback);
  EXPECT_EQ(r.outcome, "restored");
  EXPECT_EQ(r.before_rad, out.written_rad);
  EXPECT_EQ(r.after_rad, kPresent);
  EXPECT_NE(r.message.find("delta3"), std::string::npos) << r.message;
}

TEST(ControllerEventsOf, AnInterruptedApplyRecoveredIsARollbackFromWhatTheControllerHeld) {
  const testing::TempDir dir("zerocal-record");
  SessionStore store(dir.path);
  const std::string id = test::makeFinishedSession(store);
  MemoryCalibration controller(kPresent);
  controller.writes_left_ = 1;  // joint 2 written, the link lost at joint 3
  EXPECT_THROW(test::applyInto(store, id, controller, {0.31, -0.52, 0.12, 0.05}, {}), Error);
  const std::array<double, 6> found = controller.readCalOffsets();
  ASSERT_NE(found, kPresent);
  controller.writes_left_ = -1;
  apply::ApplyJournal journal(store.sessionDir(id) + "/" + kApplyJournalFileName);
  ASSERT_EQ(
      apply::recoverApply(controller, journal, {"SN-0001", "6.13.02", "IRB 1600-10/1.45"}).outcome,
      apply::RecoveryOutcome::kRestored);

  const std::vector<ControllerEvent> events = eventsOf(store, id);
  ASSERT_EQ(events.size(), 2u);
  EXPECT_EQ(events[0].kind, ControllerEventKind::kApply);
  EXPECT_EQ(events[0].outcome, "recovered");
  const ControllerEvent& r = events[1];
  EXPECT_EQ(r.kind, ControllerEventKind::kRollback);
  EXPECT_EQ(r.outcome, "restored");
  EXPECT_EQ(r.before_rad, found);
  EXPECT_EQ(r.after_rad, kPresent);
}

TEST(ControllerEventsOf, AnApplyStoppedBeforeAnyWriteChangedNothing) {
  const testing::TempDir dir("zerocal-record");
  SessionStore store(dir.path);
  const std::string id = test::makeFinishedSession(store);
  MemoryCalibration controller(kPresent);
  controller.writes_left_ = 0;
  EXPECT_THROW(test::applyInto(store, id, controller, {0.31, -0.52, 0.12, 0.05}, {}), Error);
  apply::ApplyJournal journal(store.sessionDir(id) + "/" + kApplyJournalFileName);
  ASSERT_EQ(
      apply::recoverApply(controller, journal, {"SN-0001", "6.13.02", "IRB 1600-10/1.45"}).outcome,
      apply::RecoveryOutcome::kNothingWritten);

  const std::vector<ControllerEvent> events = eventsOf(store, id);
  ASSERT_EQ(events.size(), 1u);
  EXPECT_EQ(events[0].outcome, "not_written");
  EXPECT_EQ(events[0].before_rad, kPresent);
  EXPECT_EQ(events[0].after_rad, kPresent);
}

TEST(ControllerEventsOf, AnAcknowledgedApplyKeepsWhatTheTechnicianFound) {
  const testing::TempDir dir("zerocal-record");
  SessionStore store(dir.path);
  const std::string id = test::makeFinishedSession(store);
  MemoryCalibration controller(kPresent);
  controller.writes_left_ = 2;
  EXPECT_THROW(test::applyInto(store, id, controller, {0.31, -0.52, 0.12, 0.05}, {}), Error);
  apply::ApplyJournal journal(store.sessionDir(id) + "/" + kApplyJournalFileName);
  const std::array<double, 6> found = controller.readCalOffsets();
  ASSERT_TRUE(apply::acknowledgeApply(journal, found, "checked on the FlexPendant"));

  const std::vector<ControllerEvent> events = eventsOf(store, id);
  ASSERT_EQ(events.size(), 2u);
  EXPECT_EQ(events[0].outcome, "acknowledged");
  EXPECT_EQ(events[1].kind, ControllerEventKind::kAcknowledgement);
  EXPECT_EQ(events[1].before_rad, found);
  EXPECT_EQ(events[1].message, "checked on the FlexPendant");
}

TEST(ControllerEventsOf, AVerificationAloneARefusedApplyAndNoFileApply) {
  const testing::TempDir dir("zerocal-record");
  SessionStore store(dir.path);
  const std::string id = test::makeFinishedSession(store);
  apply::ApplyJournal journal(store.sessionDir(id) + "/" + kApplyJournalFileName);
  // The file apply's record (zerocal-lab apply): a MOC.cfg written, nothing into the controller.
  store.writeFile(id, kApplyJournalFileName,
                  R"({"format":"zerocal-apply/1","moc":"MOC.cfg","out":"NEW.cfg","joints":[]})"
                  "\n");
  apply::TransmissionMeasurement m;
  m.joint = 3;
  m.configured = 100;
  m.measured = -100;
  m.message = "joint 3 turns the other way";
  apply::journalTransmissionCheck(journal, {m});
  // As the daemon's verification of an applied session journals it.
  journal.append({{"step", "verify"},
                  {"session", "20261122T090000Z"},
                  {"found_rad", kPresent},
                  {"pass", true},
                  {"offsets_after",
                   {{{"value_deg", 0.001}, {"sigma_deg", 0.002}},
                    {{"value_deg", 0.0}, {"sigma_deg", 0.002}},
                    {{"value_deg", -0.001}, {"sigma_deg", 0.003}},
                    {{"value_deg", 0.002}, {"sigma_deg", 0.004}}}},
                  {"message", "within bounds"}});

  const std::vector<ControllerEvent> events = eventsOf(store, id);
  ASSERT_EQ(events.size(), 2u);
  EXPECT_EQ(events[0].kind, ControllerEventKind::kApply);
  EXPECT_EQ(events[0].outcome, "refused");
  EXPECT_FALSE(events[0].before_rad) << "nothing was read or written";
  EXPECT_NE(events[0].message.find("joint 3"), std::string::npos) << events[0].message;
  EXPECT_EQ(events[1].kind, ControllerEventKind::kVerification);
  EXPECT_EQ(events[1].outcome, "pass");
  EXPECT_EQ(events[1].verification, "20261122T090000Z");
  EXPECT_EQ(events[1].before_rad, kPresent);
  EXPECT_EQ(*events[1].remaining[3], (RecordedOffset{0.002, 0.004}));
}

TEST(ControllerEventsOf, NamesTheLineOfAStepMissingWhatItNeeds) {
  const testing::TempDir dir("zerocal-record");
  SessionStore store(dir.path);
  const std::string id = test::makeFinishedSession(store);
  store.writeFile(id, kApplyJournalFileName,
                  "{\"step\":\"transmission_check\",\"agree\":true,\"measurements\":[]}\n"
                  "{\"step\":\"begin\",\"new_rad\":[1,2,3,4,5,6]}\n");
  try {
    eventsOf(store, id);
    FAIL() << "a begin without its backup was read";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("line 2"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find(id), std::string::npos) << e.what();
  }
}

TEST(ControllerEventsOf, NoJournalNoEvents) {
  const testing::TempDir dir("zerocal-record");
  SessionStore store(dir.path);
  EXPECT_TRUE(eventsOf(store, test::makeFinishedSession(store)).empty());
}

}  // namespace
}  // namespace zerocal::record
