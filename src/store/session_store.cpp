#include "zerocal/store/session_store.h"

#include <fmt/format.h>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <ctime>
#include <filesystem>
#include <fstream>
#include <map>
#include <mutex>

#include "zerocal/daemon/logging.h"
#include "zerocal/error.h"
#include "zerocal/io/durable_file.h"

namespace zerocal {
namespace {

namespace fs = std::filesystem;

std::string newSessionId(const fs::path& data_dir) {
  const std::time_t now = std::chrono::system_clock::to_time_t(std::chrono::system_clock::now());
  std::tm utc{};
  ::gmtime_r(&now, &utc);
  char stamp[32];
  std::strftime(stamp, sizeof stamp, "%Y%m%dT%H%M%SZ", &utc);
  std::string id = stamp;
  // Zero-padded so that ids made within one second still sort in creation order.
  for (int n = 2; fs::exists(data_dir / id); ++n) {
    id = fmt::format(FMT_STRING("{}-{:03d}"), stamp, n);
  }
  return id;
}

// closed.json's reason; a closed.json that cannot be read still closes the session.
std::string closedReason(const fs::path& dir) {
  try {
    std::ifstream in(dir / kClosedFileName);
    const nlohmann::json j = nlohmann::json::parse(in);
    const std::string why = j.value("reason", "");
    if (!why.empty()) return why;
  } catch (const std::exception&) {
  }
  return "closed";
}

}  // namespace

// What list() learnt of each session, and the journal's size and time it learnt it from.
struct SessionStore::Cache {
  struct Entry {
    std::uintmax_t journal_size = 0;
    fs::file_time_type journal_time{};
    SessionInfo info;  // finished is not cached: result.json is checked at every listing
  };
  std::mutex mutex;
  std::map<std::string, Entry> entries;
};

SessionStore::SessionStore(std::string data_dir)
    : data_dir_(std::move(data_dir)), cache_(std::make_unique<Cache>()) {}

SessionStore::~SessionStore() = default;

std::string SessionStore::sessionDir(const std::string& id) const {
  return (fs::path(data_dir_) / id).string();
}

std::string SessionStore::journalPath(const std::string& id) const {
  return (fs::path(data_dir_) / id / kJournalFileName).string();
}

SessionFile SessionStore::create(SessionFile session) {
  makeDirsDurably(data_dir_);
  session.id = newSessionId(data_dir_);
  makeDirsDurably(sessionDir(session.id));
  session.created_unix_s = static_cast<std::int64_t>(
      std::chrono::system_clock::to_time_t(std::chrono::system_clock::now()));
  writeFileDurably((fs::path(sessionDir(session.id)) / kSessionFileName).string(),
                   toJson(session).dump(2) + "\n");
  return session;
}

SessionFile SessionStore::readSession(const std::string& id) const {
  return sessionFileFromJson(
      readJsonFile((fs::path(sessionDir(id)) / kSessionFileName).string(), "the session file"));
}

ResultFile SessionStore::readResult(const std::string& id) const {
  return resultFileFromJson(
      readJsonFile((fs::path(sessionDir(id)) / kResultFileName).string(), "the result"));
}

std::vector<SessionInfo> SessionStore::list() const {
  std::vector<SessionInfo> sessions;
  std::error_code ec;
  if (!fs::is_directory(data_dir_, ec)) return sessions;
  std::lock_guard<std::mutex> lock(cache_->mutex);
  for (const auto& entry : fs::directory_iterator(data_dir_, ec)) {
    std::error_code entry_ec;
    if (!entry.is_directory(entry_ec) ||
        !fs::is_regular_file(entry.path() / kSessionFileName, entry_ec))
      continue;
    const std::string id = entry.path().filename().string();
    const fs::path journal = journalPath(id);
    std::error_code stat_ec;
    const std::uintmax_t size = fs::exists(journal, stat_ec) ? fs::file_size(journal, stat_ec) : 0;
    const fs::file_time_type time =
        size > 0 ? fs::last_write_time(journal, stat_ec) : fs::file_time_type{};
    const auto cached = cache_->entries.find(id);
    if (stat_ec || cached == cache_->entries.end() || cached->second.journal_size != size ||
        cached->second.journal_time != time) {
      Cache::Entry fresh{size, time, {}};
      SessionInfo& info = fresh.info;
      info.id = id;
      info.dir = entry.path().string();
      try {
        const SessionFile session = readSession(info.id);
        info.planned_poses = static_cast<int>(session.plan.poses.size());
        info.kind = session.kind;
        info.verifies = session.verifies;
      } catch (const Error& e) {
        // A session.json cut short by a crash during create(): no pose was recorded there.
        makeLogger("journal")->warn("skipping session {}: {}", info.id, e.what());
        continue;
      }
      try {
        const JournalContents contents = readJournal(journal.string());
        info.recorded_poses = contents.nextIndex();
        for (const PoseRecord& r : contents.records) info.skipped_poses += !r.measured();
      } catch (const JournalError& e) {
        // One damaged session must not hide the others (nor stop the daemon): it is listed,
        // named and never resumed; its files are left exactly as they are.
        info.damaged = e.what();
        makeLogger("journal")->error("session {} is damaged and will not be resumed: {}", id,
                                     info.damaged);
      }
      cache_->entries[id] = std::move(fresh);
    }
    SessionInfo info = cache_->entries[id].info;
    info.finished = fs::exists(entry.path() / kResultFileName, entry_ec);
    if (fs::exists(entry.path() / kClosedFileName, entry_ec))
      info.closed = closedReason(entry.path());
    sessions.push_back(std::move(info));
  }
  if (ec) throw FileError("cannot list " + data_dir_ + ": " + ec.message());
  std::sort(sessions.begin(), sessions.end(),
            [](const SessionInfo& a, const SessionInfo& b) { return a.id < b.id; });
  return sessions;
}

std::vector<std::string> SessionStore::removeStaleTemporaries() const {
  std::vector<std::string> removed;
  std::error_code ec;
  for (const auto& session : fs::directory_iterator(data_dir_, ec)) {
    std::error_code entry_ec;
    if (!session.is_directory(entry_ec)) continue;
    for (const auto& file : fs::directory_iterator(session.path(), entry_ec)) {
      std::error_code file_ec;
      if (file.path().extension() == ".tmp" && !file.is_directory(file_ec) &&
          fs::remove(file.path(), file_ec))
        removed.push_back(file.path().string());
    }
  }
  std::sort(removed.begin(), removed.end());
  return removed;
}

std::vector<SessionInfo> SessionStore::unfinished() const {
  auto sessions = list();
  sessions.erase(std::remove_if(sessions.begin(), sessions.end(),
                                [](const SessionInfo& s) {
                                  return s.finished || !s.damaged.empty() || !s.closed.empty() ||
                                         s.kind == SessionKind::kVerification;
                                }),
                 sessions.end());
  return sessions;
}

void SessionStore::close(const std::string& id, const std::string& why) {
  writeFileDurably((fs::path(sessionDir(id)) / kClosedFileName).string(),
                   nlohmann::json{{"reason", why}}.dump(2) + "\n");
}

void SessionStore::writeFile(const std::string& id, const std::string& name,
                             const std::string& text) {
  writeFileDurably((fs::path(sessionDir(id)) / name).string(), text);
}

void SessionStore::writeResult(const std::string& id, const ResultFile& result) {
  writeFileDurably((fs::path(sessionDir(id)) / kResultFileName).string(),
                   toJson(result).dump(2) + "\n");
}

}  // namespace zerocal
