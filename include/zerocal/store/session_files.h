// The files of a session folder (docs/daemon.md, docs/results.md):
//   session.json   SessionFile: what the session was asked to do, written once at its creation
//   journal.jsonl  PoseRecord per line (zerocal/store/journal.h)
//   faults.jsonl   FaultRecord per line, from the first servo fault on (zerocal/store/journal.h)
//   result.json    ResultFile: the solve and what the daemon knew of the run and the cell
// SessionFile and ResultFile, and the only code that turns them into JSON and back, are the
// results codec's (zerocal/results/), which the technician's client shares; this reads a folder.
#pragma once

#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "zerocal/results/result_file.h"
#include "zerocal/results/session_file.h"
#include "zerocal/store/journal.h"

namespace zerocal {

inline constexpr const char* kSessionFileName = "session.json";
inline constexpr const char* kJournalFileName = "journal.jsonl";
inline constexpr const char* kResultFileName = "result.json";
// Written into a session that will never be resumed or finished (the verification of an apply
// that was recovered since), with why.
inline constexpr const char* kClosedFileName = "closed.json";
// The online apply's and the verifications' journal of a session's offsets
// (zerocal/apply/online_apply.h), and the file apply's records (docs/apply.md).
inline constexpr const char* kApplyJournalFileName = "apply.jsonl";

// The three files of a session folder, read. Throws FileError naming the file that is missing,
// unreadable or not JSON, InputError for a member missing or of the wrong type, JournalError for
// a journal that cannot be read back (zerocal/store/journal.h). A session without a result
// is unfinished: FileError saying so.
struct SessionFolder {
  std::string dir;
  SessionFile session;
  std::vector<PoseRecord> journal;  // the committed lines
  ResultFile result;
};
SessionFolder readSessionFolder(const std::string& dir);

// One JSON file, parsed. Throws FileError naming the file and what is wrong.
nlohmann::json readJsonFile(const std::string& path, const std::string& what);

}  // namespace zerocal
