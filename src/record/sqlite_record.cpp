#include "zerocal/record/sqlite_record.h"

#include <chrono>
#include <ctime>
#include <filesystem>
#include <map>
#include <nlohmann/json.hpp>
#include <set>

#include "sqlite.h"
#include "zerocal/io/durable_file.h"
#include "zerocal/record/from_folders.h"

namespace zerocal::record {

namespace {

namespace fs = std::filesystem;
using nlohmann::json;
using sqlite::Connection;
using sqlite::Statement;
using sqlite::Transaction;

// The database header's application id ("zCAL"): a database of another program is no record.
constexpr std::int64_t kApplicationId = 0x7A43414C;

// Each version's step from the one before, in order; a database of version v runs the steps
// after v. A step is never edited once released: a change is a new step.
struct Migration {
  int version;
  const char* sql;
};
constexpr Migration kMigrations[] = {
    {1, R"sql(
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
PRAGMA application_id = 2051227980; -- kApplicationId
)sql"},
    // The controller events of each session's apply journal; the catch-up at open fills them in
    // from the folders, since a version 1 record never held them.
    {2, R"sql(
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
)sql"},
    // The robot model each session counted and wrote; the catch-up at open fills them in for the
    // sessions recorded before, from their folders (putFolderColumns).
    {3, R"sql(
ALTER TABLE sessions ADD COLUMN model_from TEXT NOT NULL DEFAULT '';
ALTER TABLE sessions ADD COLUMN model_file TEXT NOT NULL DEFAULT '';
)sql"},
    // The reference a session compares with; filled in as version 3's columns.
    {4, R"sql(
ALTER TABLE sessions ADD COLUMN reference TEXT NOT NULL DEFAULT '';
)sql"},
};
static_assert(sizeof kMigrations / sizeof kMigrations[0] == kRecordSchemaVersion,
              "one migration per schema version");
// A record older than this lacks session columns that the folders say (model_from, model_file,
// reference): the catch-up fills them in for the sessions it holds.
constexpr int kFolderColumnsSince = 4;

std::optional<std::array<double, 6>> valuesFromText(const Statement& s, int column) {
  if (s.isNull(column)) return std::nullopt;
  return json::parse(s.text(column)).get<std::array<double, 6>>();
}

std::optional<std::string> valuesText(const std::optional<std::array<double, 6>>& v) {
  if (!v) return std::nullopt;
  return json(*v).dump();
}

void bindOffsets(Statement& s, int first, const RecordedOffsets& offsets) {
  for (int k = 0; k < 4; ++k) {
    if (offsets[k]) {
      s.bind(first + 2 * k, offsets[k]->value_deg).bind(first + 2 * k + 1, offsets[k]->sigma_deg);
    } else {
      s.bindNull(first + 2 * k).bindNull(first + 2 * k + 1);
    }
  }
}

RecordedOffsets offsetsFrom(const Statement& s, int first) {
  RecordedOffsets offsets;
  for (int k = 0; k < 4; ++k)
    if (!s.isNull(first + 2 * k))
      offsets[k] = RecordedOffset{s.real(first + 2 * k), s.real(first + 2 * k + 1)};
  return offsets;
}

// The columns a SessionEntry is read from, in sessionFrom()'s order.
constexpr const char* kSessionColumns =
    "s.id, r.robot_type, r.serial, s.software_version, s.kind, s.verifies, s.usable, s.reasons, "
    "s.converged, s.poses_used, s.delta2_deg, s.delta2_sigma_deg, s.delta3_deg, "
    "s.delta3_sigma_deg, s.delta4_deg, s.delta4_sigma_deg, s.delta5_deg, s.delta5_sigma_deg, "
    "s.cell_time_s, s.started_unix_s, s.finished_unix_s, s.cal_offset_rad, s.model_from, "
    "s.model_file, s.reference";

SessionEntry sessionFrom(const Statement& s) {
  SessionEntry e;
  e.session = s.text(0);
  e.robot = {s.text(1), s.text(2)};
  e.software_version = s.text(3);
  e.kind = s.text(4);
  e.verifies = s.text(5);
  if (!s.isNull(6)) e.usable = s.integer(6) != 0;
  e.reasons = json::parse(s.text(7)).get<std::vector<std::string>>();
  e.converged = s.integer(8) != 0;
  e.poses_used = static_cast<int>(s.integer(9));
  e.offsets = offsetsFrom(s, 10);
  e.cell_time_s = s.optionalReal(18);
  e.started_unix_s = s.integer(19);
  if (!s.isNull(20)) e.finished_unix_s = s.integer(20);
  e.cal_offset_rad = valuesFromText(s, 21);
  e.model_from = s.text(22);
  e.model_file = s.text(23);
  e.reference = s.text(24);
  return e;
}

constexpr const char* kEventColumns =
    "e.session, e.kind, e.time_unix_s, e.outcome, e.before_rad, e.after_rad, e.verification, "
    "e.delta2_deg, e.delta2_sigma_deg, e.delta3_deg, e.delta3_sigma_deg, e.delta4_deg, "
    "e.delta4_sigma_deg, e.delta5_deg, e.delta5_sigma_deg, e.message";

ControllerEvent eventFrom(const Statement& s) {
  ControllerEvent e;
  e.kind = controllerEventKindFromName(s.text(1));
  e.time_unix_s = s.real(2);
  e.outcome = s.text(3);
  e.before_rad = valuesFromText(s, 4);
  e.after_rad = valuesFromText(s, 5);
  e.verification = s.text(6);
  e.remaining = offsetsFrom(s, 7);
  e.message = s.text(15);
  return e;
}

// Inside a transaction.
std::int64_t robotRow(Connection& db, const RobotId& robot) {
  Statement(db, "INSERT INTO robots (robot_type, serial) VALUES (?1, ?2) ON CONFLICT DO NOTHING",
            "record a robot")
      .bind(1, robot.robot_type)
      .bind(2, robot.serial)
      .run();
  Statement find(db, "SELECT id FROM robots WHERE robot_type = ?1 AND serial = ?2", "find a robot");
  find.bind(1, robot.robot_type).bind(2, robot.serial);
  if (!find.step()) throw FileError(db.path() + ": a robot just recorded cannot be found");
  return find.integer(0);
}

// Inside a transaction.
void putSession(Connection& db, const SessionEntry& e) {
  if (e.session.empty()) throw InputError("a session without an id cannot be recorded");
  const std::int64_t robot = robotRow(db, e.robot);
  Statement s(db, R"sql(
INSERT INTO sessions (id, robot, software_version, kind, verifies, usable, reasons, converged,
                      poses_used, delta2_deg, delta2_sigma_deg, delta3_deg, delta3_sigma_deg,
                      delta4_deg, delta4_sigma_deg, delta5_deg, delta5_sigma_deg, cell_time_s,
                      started_unix_s, finished_unix_s, cal_offset_rad, model_from, model_file,
                      reference)
VALUES (?1, ?2, ?3, ?4, ?5, ?6, ?7, ?8, ?9, ?10, ?11, ?12, ?13, ?14, ?15, ?16, ?17, ?18, ?19, ?20,
        ?21, ?22, ?23, ?24)
ON CONFLICT (id) DO UPDATE SET
  robot = excluded.robot, software_version = excluded.software_version, kind = excluded.kind,
  verifies = excluded.verifies, usable = excluded.usable, reasons = excluded.reasons,
  converged = excluded.converged, poses_used = excluded.poses_used,
  delta2_deg = excluded.delta2_deg, delta2_sigma_deg = excluded.delta2_sigma_deg,
  delta3_deg = excluded.delta3_deg, delta3_sigma_deg = excluded.delta3_sigma_deg,
  delta4_deg = excluded.delta4_deg, delta4_sigma_deg = excluded.delta4_sigma_deg,
  delta5_deg = excluded.delta5_deg, delta5_sigma_deg = excluded.delta5_sigma_deg,
  cell_time_s = excluded.cell_time_s, started_unix_s = excluded.started_unix_s,
  finished_unix_s = excluded.finished_unix_s, cal_offset_rad = excluded.cal_offset_rad,
  model_from = excluded.model_from, model_file = excluded.model_file,
  reference = excluded.reference
)sql",
              "record session " + e.session);
  s.bind(1, e.session).bind(2, robot).bind(3, e.software_version).bind(4, e.kind);
  s.bind(5, e.verifies).bind(6, e.usable).bind(7, json(e.reasons).dump());
  s.bind(8, e.converged).bind(9, e.poses_used);
  bindOffsets(s, 10, e.offsets);
  s.bind(18, e.cell_time_s).bind(19, e.started_unix_s).bind(20, e.finished_unix_s);
  s.bind(21, valuesText(e.cal_offset_rad)).bind(22, e.model_from).bind(23, e.model_file);
  s.bind(24, e.reference);
  s.run();
}

// Inside a transaction: the columns a record older than kFolderColumnsSince lacks.
void putFolderColumns(Connection& db, const SessionEntry& e) {
  Statement(db,
            "UPDATE sessions SET model_from = ?2, model_file = ?3, reference = ?4 WHERE id = ?1",
            "record session " + e.session + "'s robot model and reference")
      .bind(1, e.session)
      .bind(2, e.model_from)
      .bind(3, e.model_file)
      .bind(4, e.reference)
      .run();
}

bool hasSession(Connection& db, const std::string& session) {
  Statement s(db, "SELECT 1 FROM sessions WHERE id = ?1", "find session " + session);
  s.bind(1, session);
  return s.step();
}

// Inside a transaction.
void putEvents(Connection& db, const std::string& session,
               const std::vector<ControllerEvent>& events) {
  if (!hasSession(db, session))
    throw InputError("session " + session +
                     " is not in the record: its controller events cannot be recorded");
  Statement(db, "DELETE FROM controller_events WHERE session = ?1",
            "forget session " + session + "'s controller events")
      .bind(1, session)
      .run();
  Statement s(db, R"sql(
INSERT INTO controller_events (session, seq, kind, time_unix_s, outcome, before_rad, after_rad,
                               verification, delta2_deg, delta2_sigma_deg, delta3_deg,
                               delta3_sigma_deg, delta4_deg, delta4_sigma_deg, delta5_deg,
                               delta5_sigma_deg, message)
VALUES (?1, ?2, ?3, ?4, ?5, ?6, ?7, ?8, ?9, ?10, ?11, ?12, ?13, ?14, ?15, ?16, ?17)
)sql",
              "record session " + session + "'s controller events");
  for (std::size_t i = 0; i < events.size(); ++i) {
    const ControllerEvent& e = events[i];
    s.reset();
    s.bind(1, session).bind(2, static_cast<std::int64_t>(i));
    s.bind(3, std::string(controllerEventKindName(e.kind))).bind(4, e.time_unix_s);
    s.bind(5, e.outcome).bind(6, valuesText(e.before_rad)).bind(7, valuesText(e.after_rad));
    s.bind(8, e.verification);
    bindOffsets(s, 9, e.remaining);
    s.bind(17, e.message);
    s.run();
  }
}

std::vector<ControllerEvent> eventsOf(Connection& db, const std::string& session) {
  Statement s(db,
              (std::string("SELECT ") + kEventColumns +
               " FROM controller_events e WHERE e.session = ?1 ORDER BY e.seq")
                  .c_str(),
              "read session " + session + "'s controller events");
  s.bind(1, session);
  std::vector<ControllerEvent> events;
  while (s.step()) events.push_back(eventFrom(s));
  return events;
}

std::string utcStamp() {
  const std::time_t now = std::chrono::system_clock::to_time_t(std::chrono::system_clock::now());
  std::tm utc{};
  ::gmtime_r(&now, &utc);
  char stamp[32];
  std::strftime(stamp, sizeof stamp, "%Y%m%dT%H%M%SZ", &utc);
  return stamp;
}

// Renames the database and the write-ahead log and shared-memory files beside it to
// <path>.damaged-<stamp>[-wal|-shm] (kept together, so the copy still opens as it was). Returns
// the database's new name (empty when it had none). Throws FileError.
std::string moveAside(const std::string& path) {
  const std::string aside = path + ".damaged-" + utcStamp();
  std::string moved;
  for (const char* suffix : {"", "-wal", "-shm"}) {
    std::error_code ec;
    if (!fs::exists(path + suffix, ec)) continue;
    fs::rename(path + suffix, aside + suffix, ec);
    if (ec)
      throw FileError("cannot move the damaged record " + path + suffix +
                      " aside: " + ec.message());
    if (*suffix == '\0') moved = aside;
  }
  syncFolder(fs::path(path).parent_path().string());
  return moved;
}

}  // namespace

struct SqliteRecord::Db {
  explicit Db(const std::string& path) : connection(path) {}
  Connection connection;
};

SqliteRecord::SqliteRecord(const std::string& path) : path_(path), db_(std::make_unique<Db>(path)) {
  Connection& db = db_->connection;
  // The first read of the file: SQLite says here when it is no database.
  const int version = std::stoi(db.value("PRAGMA user_version", "read the schema's version"));
  const std::int64_t application = std::stoll(db.value("PRAGMA application_id", "read the id"));
  if (version > kRecordSchemaVersion)
    throw FileError(path + " is a record of schema version " + std::to_string(version) +
                    ", newer than this zerocal knows (" + std::to_string(kRecordSchemaVersion) +
                    "): a newer zerocal wrote it. Run that zerocal again, or move the file away "
                    "and the record is rebuilt from the session folders at the next start");
  if (version > 0 && application != kApplicationId)
    throw DamagedRecordError(path + " is not a zerocal record (application id " +
                             std::to_string(application) + ")");
  if (version == 0 && db.value("SELECT count(*) FROM sqlite_master", "read the schema") != "0")
    throw DamagedRecordError(path + " holds tables but no zerocal schema: not a zerocal record");
  if (version > 0) {
    // Every page read once: a file cut short or overwritten in part shows here, not in the
    // middle of a session's recording.
    const std::string check = db.value("PRAGMA integrity_check(1)", "check the record");
    if (check != "ok") throw DamagedRecordError(path + " fails its integrity check: " + check);
  }
  if (db.value("PRAGMA journal_mode = WAL", "use a write-ahead log") != "wal")
    throw FileError(path + ": SQLite cannot keep a write-ahead log here");
  // FULL: each commit's log is on the disk when the commit returns, so that a session recorded
  // survives a power cut too (NORMAL would keep it through kill -9 only). A commit per session
  // costs an fsync or two.
  db.exec("PRAGMA synchronous = FULL", "set the record's synchronous mode");
  db.exec("PRAGMA foreign_keys = ON", "turn foreign keys on");
  opened_at_version_ = version;
  if (version == kRecordSchemaVersion) return;
  Transaction t(db);
  for (const Migration& m : kMigrations) {
    if (m.version <= version) continue;
    db.exec(m.sql, "migrate the record to schema version " + std::to_string(m.version));
    db.exec("PRAGMA user_version = " + std::to_string(m.version),
            "set the record's schema version");
  }
  t.commit();
}

SqliteRecord::~SqliteRecord() = default;

void SqliteRecord::recordSession(const SessionEntry& entry) { recordSessions({entry}); }

void SqliteRecord::recordSessions(const std::vector<SessionEntry>& entries) {
  std::lock_guard<std::mutex> lock(mutex_);
  Transaction t(db_->connection);
  for (const SessionEntry& e : entries) putSession(db_->connection, e);
  t.commit();
}

void SqliteRecord::recordControllerEvents(const std::string& session,
                                          const std::vector<ControllerEvent>& events) {
  std::lock_guard<std::mutex> lock(mutex_);
  Transaction t(db_->connection);
  putEvents(db_->connection, session, events);
  t.commit();
}

std::vector<RobotSummary> SqliteRecord::robots() const {
  std::lock_guard<std::mutex> lock(mutex_);
  Statement s(db_->connection, R"sql(
SELECT r.robot_type, r.serial, count(*), min(s.started_unix_s), max(s.started_unix_s),
       (SELECT l.software_version FROM sessions l WHERE l.robot = r.id
        ORDER BY l.started_unix_s DESC, l.id DESC LIMIT 1)
FROM robots r JOIN sessions s ON s.robot = r.id
GROUP BY r.id ORDER BY r.robot_type, r.serial
)sql",
              "list the robots");
  std::vector<RobotSummary> robots;
  while (s.step()) {
    RobotSummary r;
    r.id = {s.text(0), s.text(1)};
    r.sessions = static_cast<int>(s.integer(2));
    r.first_unix_s = s.integer(3);
    r.last_unix_s = s.integer(4);
    r.software_version = s.text(5);
    robots.push_back(std::move(r));
  }
  return robots;
}

std::vector<HistoryEntry> SqliteRecord::history(const RobotId& robot) const {
  std::lock_guard<std::mutex> lock(mutex_);
  Connection& db = db_->connection;
  const std::string doing = "read the history of " + robot.robot_type + " " + robot.serial;
  std::vector<HistoryEntry> history;
  std::map<std::string, std::size_t> index;
  {
    Statement s(db,
                (std::string("SELECT ") + kSessionColumns +
                 " FROM sessions s JOIN robots r ON s.robot = r.id"
                 " WHERE r.robot_type = ?1 AND r.serial = ?2"
                 " ORDER BY s.started_unix_s, s.id")
                    .c_str(),
                doing);
    s.bind(1, robot.robot_type).bind(2, robot.serial);
    while (s.step()) {
      history.push_back({sessionFrom(s), {}});
      index[history.back().session.session] = history.size() - 1;
    }
  }
  Statement e(db,
              (std::string("SELECT ") + kEventColumns +
               " FROM controller_events e JOIN sessions s ON e.session = s.id"
               " JOIN robots r ON s.robot = r.id"
               " WHERE r.robot_type = ?1 AND r.serial = ?2 ORDER BY e.session, e.seq")
                  .c_str(),
              doing);
  e.bind(1, robot.robot_type).bind(2, robot.serial);
  while (e.step()) history[index.at(e.text(0))].events.push_back(eventFrom(e));
  return history;
}

std::optional<SessionEntry> SqliteRecord::latest(const RobotId& robot, const std::string& kind,
                                                 bool usable_only) const {
  std::lock_guard<std::mutex> lock(mutex_);
  Statement s(db_->connection,
              (std::string("SELECT ") + kSessionColumns +
               " FROM sessions s JOIN robots r ON s.robot = r.id"
               " WHERE r.robot_type = ?1 AND r.serial = ?2 AND s.kind = ?3"
               " AND (?4 = 0 OR s.usable = 1)"
               " ORDER BY s.started_unix_s DESC, s.id DESC LIMIT 1")
                  .c_str(),
              "find the latest " + kind + " of " + robot.robot_type + " " + robot.serial);
  s.bind(1, robot.robot_type).bind(2, robot.serial).bind(3, kind).bind(4, usable_only);
  if (!s.step()) return std::nullopt;
  return sessionFrom(s);
}

FillReport SqliteRecord::rebuild(const SessionStore& store) { return fill(store, true); }

FillReport SqliteRecord::catchUp(const SessionStore& store) { return fill(store, false); }

FillReport SqliteRecord::fill(const SessionStore& store, bool everything) {
  const std::vector<SessionInfo> sessions = store.list();
  std::lock_guard<std::mutex> lock(mutex_);
  Connection& db = db_->connection;
  FillReport report;
  Transaction t(db);
  std::set<std::string> known;
  if (everything) {
    db.exec("DELETE FROM controller_events; DELETE FROM sessions; DELETE FROM robots",
            "empty the record");
  } else {
    Statement s(db, "SELECT id FROM sessions", "list the recorded sessions");
    while (s.step()) known.insert(s.text(0));
  }
  // A record older than the folder columns holds its sessions with them empty: what the folders
  // say of them is filled in, the rest kept as recorded.
  const bool fill_columns =
      !everything && opened_at_version_ > 0 && opened_at_version_ < kFolderColumnsSince;
  for (const SessionInfo& info : sessions) {
    if (!info.finished) continue;
    const bool recorded = known.count(info.id) > 0;
    if (!recorded || fill_columns) {
      SessionEntry entry;
      try {
        entry = sessionEntryOf(store.readSession(info.id), store.readResult(info.id));
      } catch (const Error& e) {
        // One session that cannot be read (or names no robot) must not keep the others out.
        report.problems.push_back(recorded
                                      ? std::string(e.what()) +
                                            "; its robot model and reference are not in the record"
                                      : std::string(e.what()));
        if (!recorded) continue;
      }
      // The record's own failure stops the fill: rolled back.
      if (!recorded) {
        putSession(db, entry);
        ++report.sessions;
      } else if (!entry.session.empty()) {
        putFolderColumns(db, entry);
      }
    }
    std::vector<ControllerEvent> events;
    try {
      events = controllerEventsOfFolder(store, info.id);
    } catch (const InputError& e) {
      report.problems.push_back(std::string(e.what()) +
                                "; the session is recorded without its controller events");
      continue;
    }
    if (events.empty() && everything) continue;
    if (!everything && eventsOf(db, info.id) == events) continue;
    putEvents(db, info.id, events);
    report.events += static_cast<int>(events.size());
  }
  t.commit();
  return report;
}

OpenedRecord openRecord(const SessionStore& store, const std::string& data_dir) {
  makeDirsDurably(data_dir);
  const std::string path = (fs::path(data_dir) / kRecordFileName).string();
  OpenedRecord opened;
  std::error_code ec;
  if (!fs::exists(path, ec) && (fs::exists(path + "-wal", ec) || fs::exists(path + "-shm", ec))) {
    // A log left by a database that was removed: SQLite would replay it into the new one.
    moveAside(path);
    opened.damage = "a write-ahead log was left without its database";
  }
  try {
    opened.record = std::make_unique<SqliteRecord>(path);
  } catch (const DamagedRecordError& e) {
    opened.damage = e.what();
    opened.moved_aside = moveAside(path);
    opened.record = std::make_unique<SqliteRecord>(path);
  }
  const int version = opened.record->openedAtVersion();
  if (version == 0) {
    opened.built = true;
    opened.filled = opened.record->rebuild(store);
  } else {
    if (version < kRecordSchemaVersion) opened.migrated_from = version;
    opened.filled = opened.record->catchUp(store);
  }
  return opened;
}

}  // namespace zerocal::record
