#include "zerocal/store/journal.h"

#include <gtest/gtest.h>
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <limits>
#include <sstream>

#include "zerocal/store/session_store.h"

namespace zerocal {
namespace {

namespace fs = std::filesystem;

// A session of three poses, as the daemon creates one.
SessionFile threePoses(const nlohmann::json& config = nlohmann::json::object()) {
  SessionFile s;
  for (int i = 0; i < 3; ++i) {
    Pose p;
    p.q_deg = {1.0 * i, 2, 3, 4, 5, 6};
    s.plan.poses.push_back(p);
  }
  s.plan.description = "three poses";
  s.plan.prediction.sigma.assign(8, 0.001);
  s.plan.prediction.identifiable.assign(8, true);
  s.plan.prediction.reason.assign(8, "");
  s.target_mm = {900, -50, 400};
  s.noise_mm = 0.02;
  s.config = config;
  return s;
}

class JournalTest : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() /
           ("zerocal-journal-" + std::to_string(::getpid()) + "-" +
            ::testing::UnitTest::GetInstance()->current_test_info()->name());
    fs::remove_all(dir_);
    fs::create_directories(dir_);
  }
  void TearDown() override { fs::remove_all(dir_); }
  fs::path dir_;
};

// Values whose shortest decimal forms are long, so that any loss of precision shows.
PoseRecord sample(int index) {
  PoseRecord r;
  r.index = index;
  for (int j = 0; j < 6; ++j) r.joints_deg[j] = (0.1 + 0.2) * (j + 1) + index / 3.0 - 1e-13;
  r.reading.spot.u_mm = 1.0 / 3.0 + index;
  r.reading.spot.v_mm = -2.0 / 7.0;
  r.reading.se.u_mm = 1e-4 / 3.0;
  r.reading.se.v_mm = 5e-300;
  r.move_started_ns = 1795000000123456789 + index;
  r.recorded_ns = 1795000001987654321 + index;
  r.servo = {7, 5, 2.25, 0.5, 1.0 / 3.0, 0.2, 1.2345678901234567, 3};
  r.servo_path = {{0.0125, 1.0 / 3.0, -0.25}, {0.4, 1e-3 / 7.0, 2e-4}};
  return r;
}

void expectSame(const PoseRecord& a, const PoseRecord& b) {
  EXPECT_EQ(a.index, b.index);
  EXPECT_EQ(a.joints_deg, b.joints_deg);  // bit-exact, not near
  EXPECT_EQ(a.reading.spot.u_mm, b.reading.spot.u_mm);
  EXPECT_EQ(a.reading.spot.v_mm, b.reading.spot.v_mm);
  EXPECT_EQ(a.reading.se.u_mm, b.reading.se.u_mm);
  EXPECT_EQ(a.reading.se.v_mm, b.reading.se.v_mm);
  EXPECT_EQ(a.move_started_ns, b.move_started_ns);
  EXPECT_EQ(a.recorded_ns, b.recorded_ns);
  EXPECT_EQ(a.servo.moves, b.servo.moves);
  EXPECT_EQ(a.servo.iterations, b.servo.iterations);
  EXPECT_EQ(a.servo.move_s, b.servo.move_s);
  EXPECT_EQ(a.servo.acquisition_s, b.servo.acquisition_s);
  EXPECT_EQ(a.servo.servo_s, b.servo.servo_s);
  EXPECT_EQ(a.servo.settle_s, b.servo.settle_s);
  EXPECT_EQ(a.servo.final_error_um, b.servo.final_error_um);
  EXPECT_EQ(a.servo.search_moves, b.servo.search_moves);
  EXPECT_EQ(a.servo_path, b.servo_path);
}

void appendRaw(const fs::path& path, const std::string& bytes) {
  std::ofstream(path, std::ios::app | std::ios::binary) << bytes;
}

TEST_F(JournalTest, RoundTripIsBitExactAndCreatesTheFolders) {
  const fs::path path = dir_ / "a" / "b" / "journal.jsonl";
  {
    Journal journal(path.string());
    EXPECT_EQ(journal.nextIndex(), 0);
    for (int i = 0; i < 3; ++i) journal.append(sample(i));
    EXPECT_EQ(journal.nextIndex(), 3);
  }
  const JournalContents back = readJournal(path.string());
  ASSERT_EQ(back.records.size(), 3u);
  EXPECT_TRUE(back.dropped.empty());
  EXPECT_EQ(back.committed_bytes, fs::file_size(path));
  for (int i = 0; i < 3; ++i) expectSame(back.records[i], sample(i));
}

TEST_F(JournalTest, OneJsonObjectPerLine) {
  const fs::path path = dir_ / "journal.jsonl";
  Journal(path.string()).append(sample(0));
  std::ifstream in(path);
  std::string line;
  ASSERT_TRUE(std::getline(in, line));
  const auto j = nlohmann::json::parse(line);
  EXPECT_EQ(j["index"], 0);
  EXPECT_EQ(j["joints_deg"].size(), 6u);
  EXPECT_FALSE(std::getline(in, line));
}

// The report reads the spot path under exactly this key, as [t_s, u_mm, v_mm] triples.
TEST_F(JournalTest, ServoPathIsWrittenAsTriplesUnderItsKey) {
  const nlohmann::json j = toJson(sample(0));
  ASSERT_TRUE(j.contains("servo_path"));
  ASSERT_EQ(j["servo_path"].size(), 2u);
  EXPECT_EQ(j["servo_path"][1].size(), 3u);
  EXPECT_EQ(j["servo_path"][0][1].get<double>(), 1.0 / 3.0);
  EXPECT_EQ(j["servo"]["search_moves"].get<int>(), 3);
}

// Journals written before the path and the search moves were recorded still read back.
TEST_F(JournalTest, OlderRecordsWithoutPathOrSearchMovesReadBack) {
  nlohmann::json j = toJson(sample(0));
  j.erase("servo_path");
  j["servo"].erase("search_moves");
  const PoseRecord r = poseRecordFromJson(j);
  EXPECT_TRUE(r.servo_path.empty());
  EXPECT_EQ(r.servo.search_moves, 0);
  EXPECT_EQ(r.servo.moves, 7);
}

// A second measurement names the plan pose it measures again; it must be an earlier line's.
TEST_F(JournalTest, ASecondMeasurementNamesItsPlanPose) {
  PoseRecord again = sample(4);
  again.remeasure_of = 1;
  const nlohmann::json j = toJson(again);
  EXPECT_EQ(j["remeasure_of"], 1);
  EXPECT_FALSE(toJson(sample(1)).contains("remeasure_of"));  // plan lines as before
  const PoseRecord back = poseRecordFromJson(j);
  EXPECT_EQ(back.remeasure_of, 1);
  EXPECT_EQ(back.planIndex(), 1);
  EXPECT_EQ(sample(3).planIndex(), 3);
  nlohmann::json later = j;
  later["remeasure_of"] = 4;  // not an earlier line
  EXPECT_THROW(poseRecordFromJson(later), JournalError);
}

// A skipped pose keeps its place in the sequence: a line with its index and the reason only.
TEST_F(JournalTest, ASkippedPoseIsALineOfItsOwnThatKeepsTheIndicesConsecutive) {
  const fs::path path = dir_ / "journal.jsonl";
  {
    Journal journal(path.string());
    journal.append(sample(0));
    PoseRecord skipped;
    skipped.index = 1;
    skipped.skipped = "spot not found";
    skipped.recorded_ns = 42;
    journal.append(skipped);
    journal.append(sample(2));
    EXPECT_EQ(journal.records().size(), 3u);  // appended records are the journal's too
  }
  std::ifstream in(path);
  std::string line;
  std::getline(in, line);
  std::getline(in, line);
  EXPECT_EQ(nlohmann::json::parse(line),
            (nlohmann::json{{"index", 1}, {"skipped", "spot not found"}, {"recorded_ns", 42}}));
  const JournalContents back = readJournal(path.string());
  ASSERT_EQ(back.records.size(), 3u);
  EXPECT_TRUE(back.records[0].measured());
  EXPECT_FALSE(back.records[1].measured());
  EXPECT_EQ(back.records[1].skipped, "spot not found");
  expectSame(back.records[2], sample(2));
  // A skip without its reason is not a record.
  EXPECT_THROW(poseRecordFromJson({{"index", 1}, {"skipped", ""}, {"recorded_ns", 1}}),
               JournalError);
  EXPECT_THROW(poseRecordFromJson({{"index", 1}, {"skipped", 3}, {"recorded_ns", 1}}),
               JournalError);
}

// A pose carries its PSD placement ("placement", absent for 1 as in older journals); a move of
// the PSD is a line of its own, without an index, read back in its place.
TEST_F(JournalTest, PlacementsOfPosesAndMovesOfThePsdComeBackInTheirPlaces) {
  const fs::path path = dir_ / "journal.jsonl";
  {
    Journal journal(path.string());
    journal.append(sample(0));
    EXPECT_EQ(journal.placement(), 1);
    PoseRecord early = sample(1);
    early.placement = 2;
    EXPECT_THROW(journal.append(early), JournalError);  // the PSD is not there yet
    PlacementRecord moved;
    moved.placement = 3;
    EXPECT_THROW(journal.append(moved), JournalError);  // 2 comes first
    moved.placement = 2;
    moved.centre_mm = {700.5, 400.25, 200};
    moved.recorded_ns = 77;
    journal.append(moved);
    EXPECT_EQ(journal.placement(), 2);
    EXPECT_EQ(journal.nextIndex(), 1);  // a placement line takes no pose index
    journal.append(early);
    PoseRecord old = sample(2);  // at placement 1, where the PSD no longer is
    EXPECT_THROW(journal.append(old), JournalError);
  }
  std::ifstream in(path);
  std::string first, second, third;
  std::getline(in, first);
  std::getline(in, second);
  std::getline(in, third);
  EXPECT_FALSE(nlohmann::json::parse(first).contains("placement"));  // placement 1: as before
  EXPECT_EQ(
      nlohmann::json::parse(second),
      (nlohmann::json{{"placement", 2}, {"centre_mm", {700.5, 400.25, 200}}, {"recorded_ns", 77}}));
  EXPECT_EQ(nlohmann::json::parse(third)["placement"], 2);

  const JournalContents back = readJournal(path.string());
  ASSERT_EQ(back.records.size(), 2u);
  EXPECT_EQ(back.records[0].placement, 1);
  EXPECT_EQ(back.records[1].placement, 2);
  expectSame(back.records[1], sample(1));
  ASSERT_EQ(back.placements.size(), 1u);
  EXPECT_EQ(back.placements[0].placement, 2);
  EXPECT_EQ(back.placements[0].first_index, 1);
  EXPECT_EQ(back.placements[0].centre_mm, (std::array<double, 3>{700.5, 400.25, 200}));
  EXPECT_EQ(placementInForce(back.placements), 2);
  // Each pose knows its line in the file, the placement line counted.
  EXPECT_EQ(back.records[0].line, 1);
  EXPECT_EQ(back.records[1].line, 3);
  Journal reopened(path.string());
  EXPECT_EQ(reopened.placement(), 2);
  EXPECT_EQ(reopened.records()[1].line, 3);
  PoseRecord next = sample(2);
  next.placement = 2;
  EXPECT_EQ(reopened.append(next).line, 4);  // appended: the line it went to
  EXPECT_EQ(reopened.records().back().line, 4);
}

// The latest record of each plan pose, the one a solve takes: a second measurement replaces the
// first; a pose skipped is its skipped line; a pose not reached has none.
TEST_F(JournalTest, EachPlanPosesLatestRecordIsItsLastLine) {
  std::vector<PoseRecord> records(4);
  for (int i = 0; i < 4; ++i) records[i].index = i;
  records[1].skipped = "spot not found";
  records[3].remeasure_of = 0;  // plan pose 1 measured again
  const std::vector<const PoseRecord*> latest = latestRecords(records);
  ASSERT_EQ(latest.size(), 3u);
  EXPECT_EQ(latest[0], &records[3]);
  EXPECT_EQ(latest[1], &records[1]);
  EXPECT_EQ(latest[2], &records[2]);
  EXPECT_TRUE(latestRecords({}).empty());
}

TEST_F(JournalTest, APoseAtAPlacementThePsdIsNotAtIsADamagedJournal) {
  const fs::path path = dir_ / "journal.jsonl";
  PoseRecord elsewhere = sample(0);
  elsewhere.placement = 2;  // no placement line before it
  appendRaw(path, toJson(elsewhere).dump() + "\n" + toJson(sample(1)).dump() + "\n");
  EXPECT_THROW(readJournal(path.string()), JournalError);
  fs::remove(path);
  PlacementRecord third;
  third.placement = 3;  // after placement 1
  appendRaw(path, toJson(sample(0)).dump() + "\n" + toJson(third).dump() + "\n" +
                      toJson(sample(1)).dump() + "\n");
  EXPECT_THROW(readJournal(path.string()), JournalError);
  // A move of the PSD torn by a crash is dropped like a torn pose: the session still waits.
  fs::remove(path);
  PlacementRecord second;
  second.placement = 2;
  const std::string line = toJson(second).dump();
  appendRaw(path, toJson(sample(0)).dump() + "\n" + line.substr(0, line.size() / 2));
  const JournalContents back = readJournal(path.string());
  EXPECT_TRUE(back.placements.empty());
  EXPECT_FALSE(back.dropped.empty());
}

TEST_F(JournalTest, RefusesOutOfOrderDuplicateAndNonFiniteRecords) {
  Journal journal((dir_ / "journal.jsonl").string());
  EXPECT_THROW(journal.append(sample(1)), JournalError);
  journal.append(sample(0));
  EXPECT_THROW(journal.append(sample(0)), JournalError);
  PoseRecord bad = sample(1);
  bad.reading.spot.u_mm = std::numeric_limits<double>::quiet_NaN();
  EXPECT_THROW(journal.append(bad), JournalError);
  journal.append(sample(1));
  EXPECT_EQ(readJournal((dir_ / "journal.jsonl").string()).records.size(), 2u);
}

TEST_F(JournalTest, TornLastLineIsDroppedWithAWarningAndCutOnResume) {
  const fs::path path = dir_ / "journal.jsonl";
  { Journal(path.string()).append(sample(0)); }
  const std::string full = toJson(sample(1)).dump();
  appendRaw(path, full.substr(0, full.size() / 2));  // a write cut short

  const JournalContents back = readJournal(path.string());
  EXPECT_EQ(back.records.size(), 1u);
  EXPECT_NE(back.dropped.find("torn"), std::string::npos) << back.dropped;

  Journal resumed(path.string());
  EXPECT_EQ(resumed.nextIndex(), 1);
  EXPECT_FALSE(resumed.dropped().empty());
  resumed.append(sample(1));
  const JournalContents after = readJournal(path.string());
  ASSERT_EQ(after.records.size(), 2u);
  EXPECT_TRUE(after.dropped.empty());
  expectSame(after.records[1], sample(1));
}

TEST_F(JournalTest, CompleteLookingLineWithoutNewlineWasNeverAcknowledged) {
  const fs::path path = dir_ / "journal.jsonl";
  appendRaw(path, toJson(sample(0)).dump());
  const JournalContents back = readJournal(path.string());
  EXPECT_TRUE(back.records.empty());
  EXPECT_FALSE(back.dropped.empty());
  EXPECT_EQ(back.committed_bytes, 0u);
}

TEST_F(JournalTest, GarbageAfterACrashIsDroppedOnlyAtTheEnd) {
  const fs::path path = dir_ / "journal.jsonl";
  { Journal(path.string()).append(sample(0)); }
  appendRaw(path, std::string(40, '\0') + "\n");  // what some file systems leave after a crash
  EXPECT_EQ(readJournal(path.string()).records.size(), 1u);
  appendRaw(path, toJson(sample(1)).dump() + "\n");  // ... but not in the middle
  EXPECT_THROW(readJournal(path.string()), JournalError);
}

// A joint no arm reaches, a spot on no detector: the line is damaged, as one that does not parse.
TEST_F(JournalTest, ValuesNoArmOrDetectorCanHaveAreDamage) {
  const auto with = [](const char* key, double value) {
    nlohmann::json j = toJson(sample(0));
    if (std::string(key) == "joints_deg")
      j["joints_deg"][2] = value;
    else
      j[key] = value;
    return j;
  };
  EXPECT_NO_THROW(poseRecordFromJson(with("joints_deg", -720)));
  EXPECT_NO_THROW(poseRecordFromJson(with("u_mm", 50)));
  for (const auto& [key, value] : {std::pair<const char*, double>{"joints_deg", 1e300},
                                   {"joints_deg", 720.5},
                                   {"u_mm", 1e308},
                                   {"v_mm", -1e308},
                                   {"v_mm", 50.5},
                                   {"u_se_mm", -1e-3},
                                   {"v_se_mm", 1e308}})
    EXPECT_THROW(poseRecordFromJson(with(key, value)), JournalError) << key << " " << value;
  // A count or an index that is no integer is no line append() wrote.
  EXPECT_THROW(poseRecordFromJson(with("index", 1e300)), JournalError);
  EXPECT_THROW(poseRecordFromJson(with("recorded_ns", 0.5)), JournalError);

  const fs::path path = dir_ / "journal.jsonl";
  appendRaw(path, toJson(sample(0)).dump() + "\n");
  nlohmann::json far = toJson(sample(1));
  far["joints_deg"][0] = 1e300;
  appendRaw(path, far.dump() + "\n");
  const JournalContents back = readJournal(path.string());  // the last line: dropped, warned
  EXPECT_EQ(back.records.size(), 1u);
  EXPECT_NE(back.dropped.find("joints_deg[0]"), std::string::npos) << back.dropped;
  appendRaw(path, toJson(sample(2)).dump() + "\n");  // before the last: the journal is damaged
  try {
    readJournal(path.string());
    FAIL() << "expected JournalError";
  } catch (const JournalError& e) {
    EXPECT_NE(std::string(e.what()).find("journal.jsonl:2: pose record: joints_deg[0]"),
              std::string::npos)
        << e.what();
  }
}

TEST_F(JournalTest, GapsAndDuplicatesInAJournalAreErrorsNotGuesses) {
  const fs::path path = dir_ / "journal.jsonl";
  appendRaw(path, toJson(sample(0)).dump() + "\n" + toJson(sample(0)).dump() + "\n");
  EXPECT_THROW(readJournal(path.string()), JournalError);
  fs::remove(path);
  appendRaw(path, toJson(sample(0)).dump() + "\n" + toJson(sample(2)).dump() + "\n");
  EXPECT_THROW(readJournal(path.string()), JournalError);
  EXPECT_THROW(Journal{path.string()}, JournalError);
}

TEST_F(JournalTest, MissingJournalIsEmpty) {
  EXPECT_TRUE(readJournal((dir_ / "none.jsonl").string()).records.empty());
}

TEST_F(JournalTest, UnwritableFolderIsAnError) {
  std::ofstream(dir_ / "file") << "x";
  // A path through a regular file fails even for root, unlike a chmod'ed folder.
  EXPECT_THROW(Journal((dir_ / "file" / "s" / "journal.jsonl").string()), JournalError);
  SessionStore store((dir_ / "file" / "sessions").string());
  EXPECT_THROW(store.create(SessionFile{}), FileError);
  if (::geteuid() != 0) {
    fs::create_directories(dir_ / "ro");
    fs::permissions(dir_ / "ro", fs::perms::owner_read | fs::perms::owner_exec);
    EXPECT_THROW(Journal((dir_ / "ro" / "journal.jsonl").string()), JournalError);
    EXPECT_THROW(SessionStore((dir_ / "ro").string()).create(SessionFile{}), FileError);
    fs::permissions(dir_ / "ro", fs::perms::owner_all);
  }
}

// A child appends and reports each acknowledged index through a pipe; it is killed with SIGKILL
// mid-way. Every acknowledged pose must be back, in order, none twice; at most the one being
// written when the kill came may be there beyond the acknowledged ones.
TEST_F(JournalTest, KillNineMidSessionLosesAndDuplicatesNothing) {
  const fs::path path = dir_ / "session" / "journal.jsonl";
  int acks[2];
  ASSERT_EQ(::pipe(acks), 0);
  const pid_t child = ::fork();
  ASSERT_GE(child, 0);
  if (child == 0) {
    ::close(acks[0]);
    try {
      Journal journal(path.string());
      for (int i = 0;; ++i) {
        journal.append(sample(i));
        if (::write(acks[1], &i, sizeof i) != sizeof i) ::_exit(2);
      }
    } catch (...) {
      ::_exit(3);
    }
  }
  ::close(acks[1]);
  int last_ack = -1, index = 0;
  while (last_ack < 19 && ::read(acks[0], &index, sizeof index) == sizeof index) last_ack = index;
  ::kill(child, SIGKILL);
  int status = 0;
  ::waitpid(child, &status, 0);
  ::close(acks[0]);
  ASSERT_TRUE(WIFSIGNALED(status)) << "the child ended before the kill";
  ASSERT_EQ(last_ack, 19);

  Journal resumed(path.string());
  const auto& records = resumed.records();
  ASSERT_GE(static_cast<int>(records.size()), last_ack + 1);
  for (std::size_t i = 0; i < records.size(); ++i) expectSame(records[i], sample(i));
  // Resuming continues right after the last committed pose.
  const int next = resumed.nextIndex();
  resumed.append(sample(next));
  const JournalContents after = readJournal(path.string());
  ASSERT_EQ(after.nextIndex(), next + 1);
  EXPECT_TRUE(after.dropped.empty());
}

TEST_F(JournalTest, SessionStoreLayoutListAndUnfinished) {
  SessionStore store((dir_ / "sessions").string());
  EXPECT_TRUE(store.list().empty());  // no folder yet
  const SessionFile draft = threePoses({{"servo", {{"tolerance_um", 2}}}});
  const SessionFile first = store.create(draft);
  const SessionFile second = store.create(threePoses());
  EXPECT_NE(first.id, second.id);
  EXPECT_LT(first.id, second.id);  // ids sort by creation
  EXPECT_GT(first.created_unix_s, 1700000000);
  EXPECT_TRUE(fs::is_regular_file(fs::path(store.sessionDir(first.id)) / "session.json"));

  const SessionFile session = store.readSession(first.id);
  EXPECT_EQ(toJson(session), toJson(first));
  EXPECT_EQ(session.plan.poses.size(), 3u);
  EXPECT_EQ(session.plan.poses[2].q_deg, draft.plan.poses[2].q_deg);
  EXPECT_EQ(session.config["servo"]["tolerance_um"], 2);
  EXPECT_EQ(session.id, first.id);

  {
    Journal journal(store.journalPath(first.id));
    journal.append(sample(0));
    journal.append(sample(1));
  }
  store.writeResult(second.id, ResultFile{});
  fs::create_directories(dir_ / "sessions" / "not-a-session");

  const auto all = store.list();
  ASSERT_EQ(all.size(), 2u);
  EXPECT_EQ(all[0].id, first.id);
  EXPECT_EQ(all[0].recorded_poses, 2);
  EXPECT_EQ(all[0].planned_poses, 3);
  EXPECT_FALSE(all[0].finished);
  EXPECT_TRUE(all[1].finished);
  const auto open = store.unfinished();
  ASSERT_EQ(open.size(), 1u);
  EXPECT_EQ(open[0].id, first.id);
  EXPECT_FALSE(fs::exists(fs::path(store.sessionDir(second.id)) / "result.json.tmp"));
}

TEST_F(JournalTest, SessionStoreListsADamagedJournalAndSeesEveryChangeToAJournal) {
  SessionStore store((dir_ / "sessions").string());
  const SessionFile good = store.create(threePoses());
  const SessionFile bad = store.create(threePoses());
  {
    Journal journal(store.journalPath(good.id));
    journal.append(sample(0));
  }
  {
    Journal journal(store.journalPath(bad.id));
    journal.append(sample(0));
    journal.append(sample(1));
  }
  EXPECT_EQ(store.list()[0].recorded_poses, 1);
  EXPECT_EQ(store.unfinished().size(), 2u);

  // A garbled line before the last one.
  std::string text;
  {
    std::ifstream in(store.journalPath(bad.id));
    text.assign(std::istreambuf_iterator<char>(in), {});
  }
  text[3] = '#';
  std::ofstream(store.journalPath(bad.id), std::ios::trunc) << text;
  const auto all = store.list();
  ASSERT_EQ(all.size(), 2u);
  EXPECT_TRUE(all[0].damaged.empty());
  EXPECT_NE(all[1].damaged.find("journal.jsonl:1"), std::string::npos) << all[1].damaged;
  const auto open = store.unfinished();
  ASSERT_EQ(open.size(), 1u);
  EXPECT_EQ(open[0].id, good.id);

  // A listing after the good journal grows sees the new pose (nothing stale is served).
  {
    Journal journal(store.journalPath(good.id));
    journal.append(sample(1));
  }
  EXPECT_EQ(store.list()[0].recorded_poses, 2);
  // And a repaired journal is no longer damaged.
  std::ofstream(store.journalPath(bad.id), std::ios::trunc);
  EXPECT_TRUE(store.list()[1].damaged.empty());
  EXPECT_EQ(store.list()[1].recorded_poses, 0);
}

// faults.jsonl: one line per latched fault, samples as [t_s, q1..q6, u, v, sum_v, present,
// valid], read back to the bit; a non-finite number is null on disk; a line torn by a crash is
// dropped by the reader and cut by the next append.
TEST_F(JournalTest, FaultLogRoundTripsAndSurvivesATornLastLine) {
  FaultRecord f;
  f.plan_index = 3;
  f.remeasure = true;
  f.status = "spot lost";
  f.message = "the spot left the detector";
  f.recorded_ns = 1763795000123456789;
  for (int k = 0; k < 2; ++k) {
    servo::ServoSample s;
    s.time_s = 12.5 + k / 3.0;
    s.q_deg = Joints{1.0 / 3.0, -2, 3, 4, 5, 6.0 + k};
    s.reading.spot = {0.1 / 3.0, -2e-4 / 7.0};
    s.reading.sum_v = k == 0 ? 3.9 : std::numeric_limits<double>::quiet_NaN();
    s.reading.spot_present = k == 0;
    s.reading.in_valid_zone = false;
    f.samples.push_back(s);
  }
  const nlohmann::json j = toJson(f);
  ASSERT_EQ(j["samples"].size(), 2u);
  ASSERT_EQ(j["samples"][0].size(), 12u);
  EXPECT_EQ(j["samples"][0][0].get<double>(), 12.5);
  EXPECT_EQ(j["samples"][0][1].get<double>(), 1.0 / 3.0);
  EXPECT_EQ(j["samples"][0][7].get<double>(), 0.1 / 3.0);
  EXPECT_EQ(j["samples"][0][10], true);
  EXPECT_TRUE(nlohmann::json::parse(j.dump())["samples"][1][9].is_null());

  const std::string path = faultLogPath((dir_ / "journal.jsonl").string());
  EXPECT_EQ(path, (dir_ / "faults.jsonl").string());
  EXPECT_TRUE(readFaults(path).empty());  // no fault yet: no file
  appendFault(path, f);
  std::ofstream(path, std::ios::app) << R"({"plan_index": 4, "sta)";  // a crash mid-write
  ASSERT_EQ(readFaults(path).size(), 1u);
  f.plan_index = 5;
  appendFault(path, f);
  const std::vector<FaultRecord> back = readFaults(path);
  ASSERT_EQ(back.size(), 2u);
  EXPECT_EQ(back[1].plan_index, 5);
  const FaultRecord& b = back[0];
  EXPECT_EQ(b.plan_index, 3);
  EXPECT_TRUE(b.remeasure);
  EXPECT_EQ(b.status, f.status);
  EXPECT_EQ(b.message, f.message);
  EXPECT_EQ(b.recorded_ns, f.recorded_ns);
  ASSERT_EQ(b.samples.size(), 2u);
  for (std::size_t k = 0; k < 2; ++k) {
    EXPECT_EQ(b.samples[k].time_s, f.samples[k].time_s);
    EXPECT_EQ(b.samples[k].q_deg, f.samples[k].q_deg);
    EXPECT_EQ(b.samples[k].reading.spot, f.samples[k].reading.spot);
    EXPECT_EQ(b.samples[k].reading.spot_present, f.samples[k].reading.spot_present);
    EXPECT_EQ(b.samples[k].reading.in_valid_zone, f.samples[k].reading.in_valid_zone);
  }
  EXPECT_EQ(b.samples[0].reading.sum_v, 3.9);
  EXPECT_TRUE(std::isnan(b.samples[1].reading.sum_v));
}

}  // namespace
}  // namespace zerocal
