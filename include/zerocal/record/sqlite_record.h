// The cell's own record: an SQLite database per daemon, <data_dir>/record.sqlite (docs/record.md).
//
// Durable: WAL journal with synchronous=FULL, so a session recorded (its transaction committed)
// survives the daemon killed at any moment, and a power cut. Versioned: the schema's version is
// the database's user_version, and an older database is migrated at open, in one transaction.
// Rebuilt: the session folders are the source of truth, and openRecord() recreates a database
// that is missing or damaged from them.
#pragma once

#include <memory>
#include <mutex>
#include <string>
#include <vector>

#include "zerocal/error.h"
#include "zerocal/record/robot_record.h"
#include "zerocal/store/session_store.h"

namespace zerocal::record {

inline constexpr const char* kRecordFileName = "record.sqlite";
// The schema this code writes: 1 robots and sessions, 2 the controller events, 3 the robot model
// each session counted and wrote, 4 the reference a session compares with.
inline constexpr int kRecordSchemaVersion = 4;

// The file is no zerocal record, or a damaged one: not an SQLite database, another program's
// database, or its integrity check fails. openRecord() moves such a file aside and rebuilds.
class DamagedRecordError : public FileError {
 public:
  using FileError::FileError;
};

// What a rebuild or a catch-up recorded from the session folders, and what it could not.
struct FillReport {
  int sessions = 0;  // sessions recorded
  int events = 0;    // controller events recorded
  // Each finished session not recorded, or recorded without its controller events, and why
  // (its result names no robot, a file cannot be read).
  std::vector<std::string> problems;
};

class SqliteRecord final : public RobotRecord {
 public:
  // Opens the database at `path`, creating it when there is none, and migrates an older schema
  // to kRecordSchemaVersion. Throws DamagedRecordError (see above), or FileError when the file
  // cannot be opened, read or written, or holds a newer schema than this zerocal knows (then it
  // is left as it is: a newer zerocal's record is not damaged).
  explicit SqliteRecord(const std::string& path);
  ~SqliteRecord() override;
  SqliteRecord(const SqliteRecord&) = delete;
  SqliteRecord& operator=(const SqliteRecord&) = delete;

  // RobotRecord; thread-safe (one connection behind a lock).
  void recordSession(const SessionEntry& entry) override;
  void recordSessions(const std::vector<SessionEntry>& entries) override;
  void recordControllerEvents(const std::string& session,
                              const std::vector<ControllerEvent>& events) override;
  std::vector<RobotSummary> robots() const override;
  std::vector<HistoryEntry> history(const RobotId& robot) const override;
  std::optional<SessionEntry> latest(const RobotId& robot, const std::string& kind,
                                     bool usable_only) const override;

  // Replaces the whole record by what the finished sessions of `store` say, in one transaction:
  // the record is either as before or rebuilt. Throws FileError when it cannot be written (or
  // the folders cannot be listed).
  FillReport rebuild(const SessionStore& store);
  // Records the finished sessions of `store` the record lacks, and every apply journal's events
  // anew: what happened while nobody recorded it (the daemon killed between writing a result and
  // recording it, a migration that added what older versions did not record). Sessions whose
  // folder is gone stay in the record. Throws as rebuild.
  FillReport catchUp(const SessionStore& store);

  // The version the database had when opened (0: created now); kRecordSchemaVersion after.
  int openedAtVersion() const { return opened_at_version_; }
  const std::string& path() const { return path_; }

 private:
  struct Db;
  FillReport fill(const SessionStore& store, bool everything);
  std::string path_;
  std::unique_ptr<Db> db_;
  int opened_at_version_ = 0;
  mutable std::mutex mutex_;
};

// The daemon's record, <data_dir>/record.sqlite, as it opened.
struct OpenedRecord {
  std::unique_ptr<SqliteRecord> record;
  bool built = false;       // there was none, or it was damaged: built from the folders
  std::string moved_aside;  // where the damaged file went (its -wal and -shm beside it)
  std::string damage;       // why it was moved aside
  int migrated_from = 0;    // the older schema version it was migrated from; 0 when none
  FillReport filled;        // what the rebuild or the catch-up recorded
};
// Opens the record of `store`'s sessions in data_dir (created when missing): a database that is
// missing is built from the session folders; a damaged one (DamagedRecordError) is renamed
// <name>.damaged-<UTC time>, kept for a look, and rebuilt; one that opens is caught up with the
// folders. Throws FileError when the record cannot be created, is of a newer schema than this
// zerocal knows (the message says how to go on), or cannot be moved aside.
OpenedRecord openRecord(const SessionStore& store, const std::string& data_dir);

}  // namespace zerocal::record
