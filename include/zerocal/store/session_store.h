// The daemon's session folders, <data_dir>/<id>/ (zerocal/store/session_files.h for the files):
// created with their session.json, listed, read back and finished with their result.json. Ids
// are UTC creation times (20261122T050102Z, with a -002, -003... suffix on a clash), so they sort
// by age. The journal of a folder is appended by a Journal (zerocal/store/journal.h).
#pragma once

#include <memory>
#include <string>
#include <vector>

#include "zerocal/store/session_files.h"

namespace zerocal {

struct SessionInfo {
  std::string id;
  std::string dir;
  bool finished = false;   // result.json present
  int planned_poses = 0;   // the plan's poses in session.json
  int recorded_poses = 0;  // committed journal lines: poses measured or skipped
  int skipped_poses = 0;   // of those, skipped
  // Why the journal cannot be read back (a bad line before the last, indices out of order);
  // empty when it can. A damaged session is listed but never resumed.
  std::string damaged;
  SessionKind kind = SessionKind::kCalibration;
  std::string verifies;  // a verification's: whose apply it verifies
  // Why the session was closed unfinished (closed.json); empty when it was not. Never resumed.
  std::string closed;
};

class SessionStore {
 public:
  // Does not touch the disk.
  explicit SessionStore(std::string data_dir);
  ~SessionStore();

  // Creates <data_dir>/<id>/ (and data_dir if needed) and its session.json, durably, from
  // `session` with its id and creation time filled in; returns them. Throws FileError.
  SessionFile create(SessionFile session);
  // Every folder of data_dir with a readable session.json, oldest first; others are skipped. A
  // missing data_dir has none. A journal that cannot be read back marks its session `damaged`
  // (warned about once) and never fails the listing. Thread-safe. A session's journal is parsed
  // again only when its size or time changed, so listing a large archive costs a few stat()s a
  // session. Throws FileError only when data_dir itself cannot be listed.
  std::vector<SessionInfo> list() const;
  // Removes the temporary files (*.tmp) an atomic write left in the session folders when the
  // daemon stopped in the middle of it: none of them was ever a session's file. Returns their
  // paths. Call at start, before any session runs. Never throws; a file that cannot be removed is
  // left, and not returned.
  std::vector<std::string> removeStaleTemporaries() const;
  // The sessions that may be resumed: calibrations not finished, closed or damaged.
  std::vector<SessionInfo> unfinished() const;
  // Closes an unfinished session for good (closed.json with `why`, durably). Throws FileError.
  void close(const std::string& id, const std::string& why);
  // Throws FileError (missing, unreadable, not JSON) or InputError (a member missing or wrong).
  SessionFile readSession(const std::string& id) const;
  ResultFile readResult(const std::string& id) const;
  // Writes result.json atomically (temporary file, fsync, rename, fsync of the folder).
  void writeResult(const std::string& id, const ResultFile& result);
  // Writes another file of the session's folder atomically, as writeResult.
  void writeFile(const std::string& id, const std::string& name, const std::string& text);
  std::string journalPath(const std::string& id) const;
  std::string sessionDir(const std::string& id) const;
  const std::string& dataDir() const { return data_dir_; }

 private:
  struct Cache;
  std::string data_dir_;
  std::unique_ptr<Cache> cache_;
};

}  // namespace zerocal
