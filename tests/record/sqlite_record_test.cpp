// The cell's own record: what it keeps and gives back, its schema's versions (a migration from an
// older one, a newer one refused), the damage it recognises and rebuilds from the session
// folders, and commits that survive the process killed.
#include "zerocal/record/sqlite_record.h"

#include <gtest/gtest.h>
#include <signal.h>
#include <sqlite3.h>
#include <sys/wait.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>

#include "record_fixture.h"
#include "temp_dir.h"
#include "zerocal/record/from_folders.h"
#include "zerocal/store/session_files.h"

namespace zerocal::record {
namespace {

namespace fs = std::filesystem;
using test::FinishedSession;

const RobotId kRobotA{"IRB 1600-10/1.45", "SN-0001"};
const RobotId kRobotB{"IRB 1600-10/1.45", "SN-0002"};
const RobotId kRobotC{"IRB 2600-20/1.65", "SN-0001"};  // the same serial, another type

SessionEntry entry(const std::string& id, const RobotId& robot, std::int64_t started) {
  SessionEntry e;
  e.session = id;
  e.robot = robot;
  e.software_version = "6.13.02";
  e.kind = "calibration";
  e.usable = true;
  e.converged = true;
  e.poses_used = 16;
  e.offsets = {RecordedOffset{0.1, 0.002}, RecordedOffset{-0.2, 0.003}, RecordedOffset{0.3, 0.004},
               RecordedOffset{-0.4, 0.005}};
  e.cell_time_s = 70.25;
  e.started_unix_s = started;
  e.finished_unix_s = started + 80;
  e.cal_offset_rad = std::array<double, 6>{1, 2.5, 3.0000001, 0.2, 5, 6.2831};
  e.model_file = "model.yaml";
  return e;
}

// Raw SQL on a database file, as another program (or an older zerocal) would run it.
void rawSql(const std::string& path, const std::string& sql) {
  sqlite3* db = nullptr;
  ASSERT_EQ(sqlite3_open(path.c_str(), &db), SQLITE_OK);
  char* error = nullptr;
  const int code = sqlite3_exec(db, sql.c_str(), nullptr, nullptr, &error);
  const std::string why = error ? error : "";
  sqlite3_free(error);
  sqlite3_close(db);
  ASSERT_EQ(code, SQLITE_OK) << why;
}

std::string rawValue(const std::string& path, const std::string& sql) {
  sqlite3* db = nullptr;
  EXPECT_EQ(sqlite3_open(path.c_str(), &db), SQLITE_OK);
  sqlite3_stmt* s = nullptr;
  EXPECT_EQ(sqlite3_prepare_v2(db, sql.c_str(), -1, &s, nullptr), SQLITE_OK);
  std::string v;
  if (sqlite3_step(s) == SQLITE_ROW) v = reinterpret_cast<const char*>(sqlite3_column_text(s, 0));
  sqlite3_finalize(s);
  sqlite3_close(db);
  return v;
}

std::string recordPath(const std::string& dir) { return dir + "/" + kRecordFileName; }

TEST(SqliteRecord, GivesBackTheSessionsAndEventsItRecordedRobotByRobotOldestFirst) {
  const testing::TempDir dir("zerocal-record");
  SqliteRecord record(recordPath(dir.path));
  SessionEntry bare = entry("S3", kRobotA, 1'700'000'300);
  bare.usable.reset();
  bare.offsets[2].reset();
  bare.cell_time_s.reset();
  bare.finished_unix_s.reset();
  bare.cal_offset_rad.reset();
  bare.kind = "verification";
  bare.verifies = "S1";
  bare.model_file.clear();
  bare.model_from = "S1";
  bare.reference = "S0";
  bare.reasons = {"delta4 is withheld", "the PSD's \"map\" is old"};
  record.recordSessions({entry("S1", kRobotA, 1'700'000'100), entry("S2", kRobotB, 1'700'000'200),
                         bare, entry("S0", kRobotA, 1'700'000'000),
                         entry("S4", kRobotC, 1'700'000'400)});
  ControllerEvent apply;
  apply.kind = ControllerEventKind::kApply;
  apply.time_unix_s = 1'700'000'150.125;
  apply.outcome = "verified";
  apply.before_rad = std::array<double, 6>{1, 2, 3, 4, 5, 6};
  apply.after_rad = std::array<double, 6>{1, 2.0001, 3.0002, 4, 5, 6};
  apply.verification = "S3";
  apply.message = "every remaining offset is within bounds";
  ControllerEvent check = apply;
  check.kind = ControllerEventKind::kVerification;
  check.outcome = "pass";
  check.remaining = {RecordedOffset{0.001, 0.002}, std::nullopt, RecordedOffset{-0.001, 0.003},
                     RecordedOffset{0, 0.004}};
  ControllerEvent refused;
  refused.outcome = "refused";
  record.recordControllerEvents("S1", {refused, apply, check});

  const std::vector<HistoryEntry> a = record.history(kRobotA);
  ASSERT_EQ(a.size(), 3u);
  EXPECT_EQ(a[0].session, entry("S0", kRobotA, 1'700'000'000));
  EXPECT_EQ(a[1].session, entry("S1", kRobotA, 1'700'000'100));
  EXPECT_EQ(a[1].events, (std::vector<ControllerEvent>{refused, apply, check}));
  EXPECT_EQ(a[2].session, bare);
  EXPECT_TRUE(a[2].events.empty());
  EXPECT_EQ(record.history(kRobotC).size(), 1u) << "the type is part of the robot";
  EXPECT_TRUE(record.history({"IRB 1600-10/1.45", "SN-9999"}).empty());

  const std::vector<RobotSummary> robots = record.robots();
  ASSERT_EQ(robots.size(), 3u);
  EXPECT_EQ(robots[0].id, kRobotA);
  EXPECT_EQ(robots[0].sessions, 3);
  EXPECT_EQ(robots[0].first_unix_s, 1'700'000'000);
  EXPECT_EQ(robots[0].last_unix_s, 1'700'000'300);
  EXPECT_EQ(robots[1].id, kRobotB);
  EXPECT_EQ(robots[2].id, kRobotC);

  EXPECT_EQ(record.latest(kRobotA, "calibration", true)->session, "S1");
  EXPECT_EQ(record.latest(kRobotA, "verification", false)->session, "S3");
  EXPECT_FALSE(record.latest(kRobotA, "verification", true)) << "its verdict was not recorded";
  EXPECT_FALSE(record.latest(kRobotB, "reference", false));
}

TEST(SqliteRecord, ASessionRecordedAgainIsReplacedWithItsEventsAndRobotKept) {
  const testing::TempDir dir("zerocal-record");
  SqliteRecord record(recordPath(dir.path));
  record.recordSession(entry("S1", kRobotA, 100));
  ControllerEvent e;
  e.outcome = "verified";
  record.recordControllerEvents("S1", {e});
  SessionEntry changed = entry("S1", kRobotA, 100);
  changed.software_version = "6.14.00";
  changed.usable = false;
  record.recordSession(changed);
  const std::vector<HistoryEntry> h = record.history(kRobotA);
  ASSERT_EQ(h.size(), 1u);
  EXPECT_EQ(h[0].session, changed);
  EXPECT_EQ(h[0].events.size(), 1u);
  EXPECT_EQ(record.robots().at(0).software_version, "6.14.00");
  record.recordControllerEvents("S1", {});
  EXPECT_TRUE(record.history(kRobotA)[0].events.empty()) << "events are replaced as a whole";
}

TEST(SqliteRecord, RefusesEventsOfASessionItDoesNotHold) {
  const testing::TempDir dir("zerocal-record");
  SqliteRecord record(recordPath(dir.path));
  EXPECT_THROW(record.recordControllerEvents("S9", {ControllerEvent{}}), InputError);
  EXPECT_THROW(record.recordSession(entry("", kRobotA, 1)), InputError);
}

TEST(SqliteRecord, ANewRecordIsAZerocalRecordOfTheCurrentSchemaInWalMode) {
  const testing::TempDir dir("zerocal-record");
  const std::string path = recordPath(dir.path);
  {
    SqliteRecord record(path);
    EXPECT_EQ(record.openedAtVersion(), 0);
    record.recordSession(entry("S1", kRobotA, 100));
  }
  EXPECT_EQ(rawValue(path, "PRAGMA user_version"), std::to_string(kRecordSchemaVersion));
  EXPECT_EQ(rawValue(path, "PRAGMA journal_mode"), "wal");
  EXPECT_EQ(rawValue(path, "PRAGMA application_id"), std::to_string(0x7A43414C));
  EXPECT_EQ(SqliteRecord(path).openedAtVersion(), kRecordSchemaVersion);
}

// Schema version 1 as zerocal wrote it (robots and sessions, no controller events), frozen here:
// the migration must take such a file as it is.
constexpr const char* kVersion1Schema = R"sql(
CREATE TABLE robots (
  id INTEGER PRIMARY KEY,
  robot_type TEXT NOT NULL,
  serial TEXT NOT NULL,
  UNIQUE (robot_type, serial)
);
CREATE TABLE sessions (
  id TEXT PRIMARY KEY,
  robot INTEGER NOT NULL REFERENCES robots (id),
  software_version TEXT NOT NULL,
  kind TEXT NOT NULL,
  verifies TEXT NOT NULL,
  usable INTEGER,
  reasons TEXT NOT NULL,
  converged INTEGER NOT NULL,
  poses_used INTEGER NOT NULL,
  delta2_deg REAL, delta2_sigma_deg REAL,
  delta3_deg REAL, delta3_sigma_deg REAL,
  delta4_deg REAL, delta4_sigma_deg REAL,
  delta5_deg REAL, delta5_sigma_deg REAL,
  cell_time_s REAL,
  started_unix_s INTEGER NOT NULL,
  finished_unix_s INTEGER,
  cal_offset_rad TEXT
);
CREATE INDEX sessions_of_robot ON sessions (robot, started_unix_s, id);
PRAGMA application_id = 2051227980;
PRAGMA user_version = 1;
)sql";

TEST(SqliteRecord, MigratesAVersion1RecordKeepingItsSessionsAndFillsInTheEventsFromTheFolders) {
  const testing::TempDir dir("zerocal-record");
  SessionStore store(dir.path);
  const std::string applied = test::makeFinishedSession(store);
  test::MemoryCalibration controller({1, 2, 3, 3.2, 5, 6});
  ASSERT_EQ(
      test::applyInto(store, applied, controller, {0.31, -0.52, 0.12, 0.05}, {0, 0, 0, 0}).state,
      apply::ApplyState::kVerified);
  const std::string path = recordPath(dir.path);
  rawSql(path, kVersion1Schema);
  // The applied session as version 1 recorded it, and a session whose folder was removed since.
  rawSql(path,
         "INSERT INTO robots (id, robot_type, serial) VALUES (1, 'IRB 1600-10/1.45', 'SN-0001');"
         "INSERT INTO sessions VALUES ('" +
             applied +
             "', 1, '6.13.02', 'calibration', '', 1, '[]', 1, 16, 0.31, 0.002, -0.52, 0.003, "
             "0.12, 0.004, 0.05, 0.005, 61.5, 1700000000, 1800000000, '[1,2,3,3.2,5,6]');"
             "INSERT INTO sessions VALUES ('20200101T000000Z', 1, '6.10.00', 'calibration', '', "
             "NULL, '[\"old\"]', 1, 12, 0.5, 0.01, NULL, NULL, 0.1, 0.01, 0.2, 0.01, NULL, "
             "1500000000, NULL, NULL);");

  const OpenedRecord opened = openRecord(store, dir.path);
  EXPECT_EQ(opened.migrated_from, 1);
  EXPECT_FALSE(opened.built) << "migrated, not rebuilt";
  EXPECT_TRUE(opened.moved_aside.empty());
  EXPECT_EQ(opened.filled.sessions, 0) << "every finished session was recorded already";
  EXPECT_EQ(opened.filled.events, 2);
  EXPECT_EQ(rawValue(path, "PRAGMA user_version"), std::to_string(kRecordSchemaVersion));

  const std::vector<HistoryEntry> h = opened.record->history(kRobotA);
  ASSERT_EQ(h.size(), 2u);
  EXPECT_EQ(h[0].session.session, "20200101T000000Z") << "a version 1 session kept as it was";
  EXPECT_FALSE(h[0].session.usable);
  EXPECT_FALSE(h[0].session.offsets[1]);
  EXPECT_EQ(h[0].session.reasons, std::vector<std::string>{"old"});
  EXPECT_EQ(h[1].session.session, applied);
  EXPECT_EQ(h[1].session.started_unix_s, 1'700'000'000) << "as recorded, not as rebuilt";
  ASSERT_EQ(h[1].events.size(), 2u);
  EXPECT_EQ(h[1].events[0].outcome, "verified");
  EXPECT_EQ(h[1].events[1].kind, ControllerEventKind::kVerification);
}

// Version 2's step (the controller events), frozen here as zerocal released it.
constexpr const char* kVersion2Step = R"sql(
CREATE TABLE controller_events (
  session TEXT NOT NULL REFERENCES sessions (id) ON DELETE CASCADE,
  seq INTEGER NOT NULL,
  kind TEXT NOT NULL,
  time_unix_s REAL NOT NULL,
  outcome TEXT NOT NULL,
  before_rad TEXT,
  after_rad TEXT,
  verification TEXT NOT NULL,
  delta2_deg REAL, delta2_sigma_deg REAL,
  delta3_deg REAL, delta3_sigma_deg REAL,
  delta4_deg REAL, delta4_sigma_deg REAL,
  delta5_deg REAL, delta5_sigma_deg REAL,
  message TEXT NOT NULL,
  PRIMARY KEY (session, seq)
) WITHOUT ROWID;
PRAGMA user_version = 2;
)sql";

TEST(SqliteRecord, MigratesAVersion2RecordFillingInEachSessionsModelAndReferenceFromItsFolder) {
  const testing::TempDir dir("zerocal-record");
  SessionStore store(dir.path);
  FinishedSession model_session;
  model_session.model_file = "model.yaml";
  const std::string calibrated = test::makeFinishedSession(store, model_session);
  FinishedSession later;
  later.model_from = calibrated;
  later.kind = SessionKind::kCheck;
  later.reference = calibrated;
  const std::string counted = test::makeFinishedSession(store, later);
  const std::string path = recordPath(dir.path);
  rawSql(path, std::string(kVersion1Schema) + kVersion2Step);
  // Both sessions as version 2 recorded them (no model columns), with a start time the folders
  // do not say, and a session whose folder was removed since.
  std::string rows =
      "INSERT INTO robots (id, robot_type, serial) VALUES (1, 'IRB 1600-10/1.45', 'SN-0001');";
  for (const std::string& id : {calibrated, counted})
    rows += "INSERT INTO sessions VALUES ('" + id +
            "', 1, '6.13.02', 'calibration', '', 1, '[]', 1, 16, 0.31, 0.002, -0.52, 0.003, "
            "0.12, 0.004, 0.05, 0.005, 61.5, 1700000000, 1800000000, '[1,2,3,3.2,5,6]');";
  rows +=
      "INSERT INTO sessions VALUES ('20200101T000000Z', 1, '6.10.00', 'calibration', '', NULL, "
      "'[]', 1, 12, 0.5, 0.01, NULL, NULL, 0.1, 0.01, 0.2, 0.01, NULL, 1500000000, NULL, NULL);";
  rawSql(path, rows);

  const OpenedRecord opened = openRecord(store, dir.path);
  EXPECT_EQ(opened.migrated_from, 2);
  EXPECT_FALSE(opened.built);
  EXPECT_TRUE(opened.filled.problems.empty());
  EXPECT_EQ(opened.filled.sessions, 0) << "every finished session was recorded already";
  EXPECT_EQ(rawValue(path, "PRAGMA user_version"), std::to_string(kRecordSchemaVersion));
  const std::vector<HistoryEntry> h = opened.record->history(kRobotA);
  ASSERT_EQ(h.size(), 3u);
  EXPECT_EQ(h[0].session.session, "20200101T000000Z");
  EXPECT_EQ(h[0].session.model_from, "") << "no folder: nothing to fill in";
  EXPECT_EQ(h[1].session.session, calibrated);
  EXPECT_EQ(h[1].session.model_file, "model.yaml");
  EXPECT_EQ(h[1].session.model_from, "");
  EXPECT_EQ(h[1].session.started_unix_s, 1'700'000'000) << "the rest kept as recorded";
  EXPECT_EQ(h[2].session.model_from, calibrated);
  EXPECT_EQ(h[2].session.model_file, "");
  EXPECT_EQ(h[2].session.reference, calibrated);
  EXPECT_EQ(h[1].session.reference, "");

  // Opened again at the current version, a record's model columns are its own: a session
  // recorded with another model than its folder says keeps what was recorded.
  opened.record->recordSession([&] {
    SessionEntry e = h[2].session;
    e.model_from = "20261201T000000Z";
    return e;
  }());
  const OpenedRecord again = openRecord(store, dir.path);
  EXPECT_EQ(again.migrated_from, 0);
  EXPECT_EQ(again.record->history(kRobotA).at(2).session.model_from, "20261201T000000Z");
}

TEST(SqliteRecord, RefusesARecordOfANewerSchemaAndLeavesItAsItIs) {
  const testing::TempDir dir("zerocal-record");
  SessionStore store(dir.path);
  test::makeFinishedSession(store);
  const std::string path = recordPath(dir.path);
  rawSql(path,
         "CREATE TABLE robots (id INTEGER PRIMARY KEY, fleet TEXT);"
         "PRAGMA application_id = 2051227980; PRAGMA user_version = 7;");
  const std::string before = testing::readFile(path);
  for (int attempt = 0; attempt < 2; ++attempt) {
    try {
      if (attempt == 0)
        SqliteRecord record(path);
      else
        openRecord(store, dir.path);
      FAIL() << "a record of schema 7 was opened";
    } catch (const DamagedRecordError& e) {
      FAIL() << "a newer record is not damaged: " << e.what();
    } catch (const FileError& e) {
      const std::string what = e.what();
      EXPECT_NE(what.find("schema version 7"), std::string::npos) << what;
      EXPECT_NE(what.find("newer"), std::string::npos) << what;
      EXPECT_NE(what.find("rebuilt from the session folders"), std::string::npos) << what;
    }
  }
  EXPECT_EQ(testing::readFile(path), before);
  for (const auto& f : fs::directory_iterator(dir.path))
    EXPECT_EQ(f.path().string().find(".damaged-"), std::string::npos) << f.path();
}

// A record of `sessions` sessions, closed (its log checkpointed into the file).
void writeRecord(const std::string& path, int sessions) {
  SqliteRecord record(path);
  std::vector<SessionEntry> entries;
  for (int i = 0; i < sessions; ++i)
    entries.push_back(entry("S" + std::to_string(i), i % 2 ? kRobotA : kRobotB, 1000 + i));
  record.recordSessions(entries);
}

// At open: a damage found there is rebuilt before the daemon relies on the record, rather than
// found in the middle of recording a session.
void expectDamaged(const std::string& path, const std::string& what) {
  try {
    SqliteRecord record(path);
    ADD_FAILURE() << what << ": opened";
  } catch (const DamagedRecordError& e) {
    SUCCEED() << e.what();
  } catch (const std::exception& e) {
    ADD_FAILURE() << what << ": not recognised as damaged: " << e.what();
  }
}

TEST(SqliteRecord, RecognisesAFileThatIsNoRecordOrADamagedOne) {
  const testing::TempDir dir("zerocal-record");
  const std::string text = dir.path + "/text.sqlite";
  std::ofstream(text) << "zerocal sessions, noted by hand\nS1 usable\nS2 not usable\n";
  expectDamaged(text, "a text file");

  const std::string foreign = dir.path + "/foreign.sqlite";
  rawSql(foreign, "CREATE TABLE photos (id INTEGER PRIMARY KEY, name TEXT)");
  expectDamaged(foreign, "another program's database");
  const std::string versioned = dir.path + "/versioned.sqlite";
  rawSql(versioned, "CREATE TABLE photos (id INTEGER); PRAGMA user_version = 2");
  expectDamaged(versioned, "another program's database with a version of its own");

  const std::string cut = dir.path + "/cut.sqlite";
  writeRecord(cut, 400);
  ASSERT_GT(fs::file_size(cut), 16 * 4096u);
  fs::resize_file(cut, fs::file_size(cut) / 2);
  expectDamaged(cut, "a record cut short");

  const std::string overwritten = dir.path + "/overwritten.sqlite";
  writeRecord(overwritten, 400);
  {
    std::fstream f(overwritten, std::ios::in | std::ios::out | std::ios::binary);
    f.seekp(static_cast<std::streamoff>(fs::file_size(overwritten) / 2));
    const std::string junk(3 * 4096, '\x5a');
    f.write(junk.data(), static_cast<std::streamsize>(junk.size()));
  }
  expectDamaged(overwritten, "a record overwritten in part");

  const std::string header = dir.path + "/header.sqlite";
  writeRecord(header, 10);
  {
    std::fstream f(header, std::ios::in | std::ios::out | std::ios::binary);
    f.write("garbage garbage!", 16);
  }
  expectDamaged(header, "a record whose header is overwritten");
}

TEST(OpenRecord, BuildsAMissingRecordFromTheFoldersLeavingOutSessionsOfNoRobot) {
  const testing::TempDir dir("zerocal-record");
  SessionStore store(dir.path);
  const std::string a = test::makeFinishedSession(store);
  FinishedSession anonymous;
  anonymous.identity = false;
  const std::string b = test::makeFinishedSession(store, anonymous);
  store.create(test::plannedSession());  // unfinished: no result, not recorded
  const OpenedRecord opened = openRecord(store, dir.path);
  EXPECT_TRUE(opened.built);
  EXPECT_TRUE(opened.moved_aside.empty());
  EXPECT_EQ(opened.filled.sessions, 1);
  ASSERT_EQ(opened.filled.problems.size(), 1u);
  EXPECT_NE(opened.filled.problems[0].find(b), std::string::npos) << opened.filled.problems[0];
  const std::vector<HistoryEntry> h = opened.record->history(kRobotA);
  ASSERT_EQ(h.size(), 1u);
  EXPECT_EQ(h[0].session.session, a);
}

TEST(OpenRecord, MovesADamagedRecordAsideAndRebuildsIt) {
  const testing::TempDir dir("zerocal-record");
  SessionStore store(dir.path);
  for (int i = 0; i < 3; ++i) test::makeFinishedSession(store);
  const std::string path = recordPath(dir.path);
  std::ofstream(path) << "not a database at all, but long enough to have a header of sorts....."
                         "................................................................\n";
  const OpenedRecord opened = openRecord(store, dir.path);
  EXPECT_TRUE(opened.built);
  ASSERT_FALSE(opened.moved_aside.empty());
  EXPECT_NE(opened.moved_aside.find(std::string(kRecordFileName) + ".damaged-"), std::string::npos);
  EXPECT_NE(testing::readFile(opened.moved_aside).find("not a database at all"), std::string::npos)
      << "the damaged file is kept for a look";
  EXPECT_FALSE(opened.damage.empty());
  EXPECT_EQ(opened.filled.sessions, 3);
  EXPECT_EQ(opened.record->history(kRobotA).size(), 3u);
  EXPECT_EQ(SqliteRecord(path).openedAtVersion(), kRecordSchemaVersion);
}

// Every robot's history, for comparing two records.
std::vector<std::vector<HistoryEntry>> everything(const RobotRecord& record) {
  std::vector<std::vector<HistoryEntry>> all;
  for (const RobotSummary& r : record.robots()) all.push_back(record.history(r.id));
  return all;
}

// A small cell's life in folders: three robots, calibrations, a verification, applies verified
// and rolled back, one interrupted and recovered. Returns the ids.
std::vector<std::string> cellLife(SessionStore& store) {
  std::vector<std::string> ids;
  FinishedSession s;
  ids.push_back(test::makeFinishedSession(store, s));
  test::MemoryCalibration a({1, 2, 3, 3.2, 5, 6});
  test::applyInto(store, ids.back(), a, {0.31, -0.52, 0.12, 0.05}, {0, 0, 0, 0});
  s.robot.serial = "SN-0002";
  s.usable = false;
  s.reasons = {"delta5 is beyond 0.01 deg"};
  s.offsets[3].reset();
  ids.push_back(test::makeFinishedSession(store, s));
  s.usable = true;
  s.offsets[3] = RecordedOffset{0.2, 0.004};
  ids.push_back(test::makeFinishedSession(store, s));
  test::MemoryCalibration b({1, 2, 3, 3.2, 5, 6});
  test::applyInto(store, ids.back(), b, {0.3, -0.5, 0.1, 0.2}, {0.3, 0, 0, 0});  // rolled back
  s.kind = SessionKind::kVerification;
  s.verifies = ids.back();
  ids.push_back(test::makeFinishedSession(store, s));
  s = FinishedSession{};
  s.robot = {"SN-0001", "7.1.0", "IRB 2600-20/1.65"};
  ids.push_back(test::makeFinishedSession(store, s));
  test::MemoryCalibration c({1, 2, 3, 3.2, 5, 6});
  c.writes_left_ = 3;
  try {
    test::applyInto(store, ids.back(), c, {0.3, -0.5, 0.1, 0.2}, {});
  } catch (const Error&) {
  }
  c.writes_left_ = -1;
  apply::ApplyJournal journal(store.sessionDir(ids.back()) + "/" + kApplyJournalFileName);
  apply::recoverApply(c, journal, {"SN-0001", "6.13.02", "IRB 1600-10/1.45"});
  return ids;
}

TEST(OpenRecord, GivesTheSameHistoryAfterTheRecordIsDeletedAndRebuilt) {
  const testing::TempDir dir("zerocal-record");
  SessionStore store(dir.path);
  const std::vector<std::string> ids = cellLife(store);
  const std::string path = recordPath(dir.path);
  std::vector<std::vector<HistoryEntry>> recorded;
  {
    // Recorded as the daemon records: each session as it finishes.
    SqliteRecord record(path);
    for (const std::string& id : ids) recordFromFolder(record, store, id);
    recorded = everything(record);
  }
  ASSERT_EQ(recorded.size(), 3u);
  std::size_t sessions = 0, events = 0;
  for (const auto& h : recorded)
    for (const HistoryEntry& e : h) {
      ++sessions;
      events += e.events.size();
    }
  EXPECT_EQ(sessions, ids.size());
  EXPECT_GE(events, 6u);

  fs::remove(path);
  const OpenedRecord rebuilt = openRecord(store, dir.path);
  EXPECT_TRUE(rebuilt.built);
  EXPECT_TRUE(rebuilt.filled.problems.empty());
  EXPECT_EQ(rebuilt.filled.sessions, static_cast<int>(ids.size()));
  EXPECT_EQ(everything(*rebuilt.record), recorded);

  // And rebuilding a record in place gives it again.
  EXPECT_EQ(rebuilt.record->rebuild(store).sessions, static_cast<int>(ids.size()));
  EXPECT_EQ(everything(*rebuilt.record), recorded);
}

TEST(OpenRecord, CatchesUpWithSessionsAndApplyStepsNobodyRecorded) {
  const testing::TempDir dir("zerocal-record");
  SessionStore store(dir.path);
  const std::string first = test::makeFinishedSession(store);
  openRecord(store, dir.path);
  // The daemon killed after writing a result, before recording it; and an apply journalled
  // while the record was closed.
  const std::string second = test::makeFinishedSession(store);
  test::MemoryCalibration controller({1, 2, 3, 3.2, 5, 6});
  test::applyInto(store, first, controller, {0.31, -0.52, 0.12, 0.05}, {0, 0, 0, 0});
  const OpenedRecord opened = openRecord(store, dir.path);
  EXPECT_FALSE(opened.built);
  EXPECT_EQ(opened.filled.sessions, 1);
  EXPECT_EQ(opened.filled.events, 2);
  const std::vector<HistoryEntry> h = opened.record->history(kRobotA);
  ASSERT_EQ(h.size(), 2u);
  EXPECT_EQ(h[1].session.session, second);
  EXPECT_EQ(h[0].events.size(), 2u);
  const OpenedRecord again = openRecord(store, dir.path);
  EXPECT_EQ(again.filled.sessions, 0);
  EXPECT_EQ(again.filled.events, 0) << "events that did not change are not written again";
}

// Forks a process that records sessions `first`, `first` + 1, ... into `path` one commit each,
// telling the parent after each commit; kills it with SIGKILL after `commits` of them. Returns
// how many it had confirmed by then.
int recordInAChildAndKillIt(const std::string& path, int commits, int first = 0) {
  int pipe_fds[2];
  if (::pipe(pipe_fds) != 0) return -1;
  const pid_t child = ::fork();
  if (child == 0) {
    ::close(pipe_fds[0]);
    try {
      SqliteRecord record(path);
      for (int i = 0;; ++i) {
        record.recordSession(
            entry("S" + std::to_string(100000 + first + i), kRobotA, 1000 + first + i));
        const char done = 'c';
        if (::write(pipe_fds[1], &done, 1) != 1) ::_exit(2);
      }
    } catch (...) {
    }
    ::_exit(1);
  }
  ::close(pipe_fds[1]);
  int confirmed = 0;
  char buffer[64];
  while (confirmed < commits) {
    const ssize_t n = ::read(pipe_fds[0], buffer, sizeof buffer);
    if (n <= 0) break;
    confirmed += static_cast<int>(n);
  }
  ::kill(child, SIGKILL);
  int status = 0;
  ::waitpid(child, &status, 0);
  ::close(pipe_fds[0]);
  EXPECT_TRUE(WIFSIGNALED(status) && WTERMSIG(status) == SIGKILL) << "the child ended by itself";
  return confirmed;
}

TEST(SqliteRecord, LosesNoCommittedSessionWhenTheProcessIsKilled) {
  const testing::TempDir dir("zerocal-record");
  const std::string path = recordPath(dir.path);
  for (int round = 0; round < 3; ++round) {
    const std::size_t before = round == 0 ? 0 : SqliteRecord(path).history(kRobotA).size();
    const int confirmed = recordInAChildAndKillIt(path, 40, static_cast<int>(before));
    ASSERT_GE(confirmed, 40);
    SqliteRecord record(path);  // the integrity check passes: not damaged
    const std::vector<HistoryEntry> h = record.history(kRobotA);
    EXPECT_GE(h.size(), before + static_cast<std::size_t>(confirmed))
        << "a committed session was lost";
    // Every session there is whole: the killed commit is in or out, never in part.
    for (std::size_t i = 0; i < h.size(); ++i) {
      EXPECT_EQ(h[i].session, entry(h[i].session.session, kRobotA, h[i].session.started_unix_s));
      if (i > 0) {
        EXPECT_EQ(h[i].session.started_unix_s, h[i - 1].session.started_unix_s + 1)
            << "a session between two committed ones is missing";
      }
    }
  }
}

TEST(OpenRecord, AWriteAheadLogLeftWithoutItsDatabaseIsMovedAsideNotReplayed) {
  const testing::TempDir dir("zerocal-record");
  SessionStore store(dir.path);
  test::makeFinishedSession(store);
  const std::string path = recordPath(dir.path);
  ASSERT_GE(recordInAChildAndKillIt(path, 20), 20);
  ASSERT_TRUE(fs::exists(path + "-wal")) << "a killed process leaves its log";
  fs::remove(path);  // deleted by hand, its log left behind
  const OpenedRecord opened = openRecord(store, dir.path);
  EXPECT_TRUE(opened.built);
  EXPECT_NE(opened.damage.find("write-ahead log"), std::string::npos) << opened.damage;
  const std::vector<HistoryEntry> h = opened.record->history(kRobotA);
  ASSERT_EQ(h.size(), 1u) << "only the folders' session, nothing of the old log";
  bool kept = false;
  for (const auto& f : fs::directory_iterator(dir.path))
    kept = kept || f.path().string().find(".damaged-") != std::string::npos;
  EXPECT_TRUE(kept);
}

}  // namespace
}  // namespace zerocal::record
