#include "zerocal/daemon/journal.h"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <ctime>
#include <filesystem>
#include <fstream>
#include <map>
#include <mutex>
#include <sstream>

#include "zerocal/daemon/logging.h"

namespace zerocal {
namespace {

namespace fs = std::filesystem;
using Json = nlohmann::json;

constexpr const char* kSessionFile = "session.json";
constexpr const char* kJournalFile = "journal.jsonl";
constexpr const char* kResultFile = "result.json";
constexpr const char* kSessionFormat = "zerocal-session/1";

[[noreturn]] void fail(const std::string& what, int error) {
  throw JournalError(what + ": " + std::strerror(error));
}

void writeAll(int fd, const std::string& data, const std::string& path) {
  std::size_t done = 0;
  while (done < data.size()) {
    const ssize_t n = ::write(fd, data.data() + done, data.size() - done);
    if (n < 0) {
      if (errno == EINTR) continue;
      fail("cannot write " + path, errno);
    }
    done += static_cast<std::size_t>(n);
  }
}

void syncFd(int fd, const std::string& path) {
  while (::fsync(fd) != 0)
    if (errno != EINTR) fail("cannot fsync " + path, errno);
}

// A new directory entry (file or folder) is durable only once its parent folder is synced.
void syncDir(const fs::path& dir) {
  const int fd = ::open(dir.c_str(), O_RDONLY | O_DIRECTORY | O_CLOEXEC);
  if (fd < 0) fail("cannot open folder " + dir.string(), errno);
  const int result = ::fsync(fd);
  const int error = errno;
  ::close(fd);
  if (result != 0) fail("cannot fsync folder " + dir.string(), error);
}

// mkdir -p that syncs the parent of every folder it creates.
void makeDirs(const fs::path& dir) {
  if (dir.empty()) return;
  std::error_code ec;
  if (fs::is_directory(dir, ec)) return;
  const fs::path parent = dir.parent_path();
  if (!parent.empty() && parent != dir) makeDirs(parent);
  if (::mkdir(dir.c_str(), 0755) != 0 && errno != EEXIST)
    fail("cannot create folder " + dir.string(), errno);
  syncDir(parent.empty() ? fs::path(".") : parent);
}

void writeFileAtomically(const fs::path& path, const std::string& text) {
  const fs::path temporary = path.string() + ".tmp";
  const int fd = ::open(temporary.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0644);
  if (fd < 0) fail("cannot create " + temporary.string(), errno);
  try {
    writeAll(fd, text, temporary.string());
    syncFd(fd, temporary.string());
  } catch (...) {
    ::close(fd);
    throw;
  }
  ::close(fd);
  if (::rename(temporary.c_str(), path.c_str()) != 0)
    fail("cannot rename to " + path.string(), errno);
  syncDir(path.parent_path());
}

Json readJsonFile(const fs::path& path) {
  std::ifstream in(path);
  if (!in) throw JournalError("cannot read " + path.string());
  try {
    return Json::parse(in);
  } catch (const Json::exception& e) {
    throw JournalError(path.string() + ": " + e.what());
  }
}

bool allFinite(const PoseRecord& r) {
  for (double q : r.joints_deg)
    if (!std::isfinite(q)) return false;
  const auto& s = r.servo;
  for (double x : {r.u_mm, r.v_mm, r.u_se_mm, r.v_se_mm, s.move_s, s.acquisition_s, s.servo_s,
                   s.settle_s, s.final_error_um})
    if (!std::isfinite(x)) return false;
  for (const auto& point : r.servo_path)
    for (double x : point)
      if (!std::isfinite(x)) return false;
  return true;
}

std::string newSessionId(const fs::path& data_dir) {
  const std::time_t now = std::chrono::system_clock::to_time_t(std::chrono::system_clock::now());
  std::tm utc{};
  ::gmtime_r(&now, &utc);
  char stamp[32];
  std::strftime(stamp, sizeof stamp, "%Y%m%dT%H%M%SZ", &utc);
  std::string id = stamp;
  // Zero-padded so that ids made within one second still sort in creation order.
  for (int n = 2; fs::exists(data_dir / id); ++n) {
    char suffix[16];
    std::snprintf(suffix, sizeof suffix, "-%03d", n);
    id = std::string(stamp) + suffix;
  }
  return id;
}

}  // namespace

Json toJson(const PoseRecord& r) {
  if (!r.measured())
    return Json{{"index", r.index}, {"skipped", r.skipped}, {"recorded_ns", r.recorded_ns}};
  // nlohmann writes doubles in the shortest form that reads back to the same bits.
  Json line{{"index", r.index},
            {"joints_deg", r.joints_deg},
            {"u_mm", r.u_mm},
            {"v_mm", r.v_mm},
            {"u_se_mm", r.u_se_mm},
            {"v_se_mm", r.v_se_mm},
            {"move_started_ns", r.move_started_ns},
            {"recorded_ns", r.recorded_ns},
            {"servo",
             {{"moves", r.servo.moves},
              {"search_moves", r.servo.search_moves},
              {"iterations", r.servo.iterations},
              {"move_s", r.servo.move_s},
              {"acquisition_s", r.servo.acquisition_s},
              {"servo_s", r.servo.servo_s},
              {"settle_s", r.servo.settle_s},
              {"final_error_um", r.servo.final_error_um}}}};
  // No path recorded (a record made without the servo) is no key, as in older journals.
  if (!r.servo_path.empty()) line["servo_path"] = r.servo_path;
  if (r.remeasure_of >= 0) line["remeasure_of"] = r.remeasure_of;
  return line;
}

PoseRecord poseRecordFromJson(const Json& j) {
  try {
    PoseRecord r;
    j.at("index").get_to(r.index);
    if (j.contains("skipped")) {
      j.at("skipped").get_to(r.skipped);
      j.at("recorded_ns").get_to(r.recorded_ns);
      if (r.skipped.empty()) throw JournalError("pose record: skipped without a reason");
      return r;
    }
    j.at("joints_deg").get_to(r.joints_deg);
    j.at("u_mm").get_to(r.u_mm);
    j.at("v_mm").get_to(r.v_mm);
    j.at("u_se_mm").get_to(r.u_se_mm);
    j.at("v_se_mm").get_to(r.v_se_mm);
    j.at("move_started_ns").get_to(r.move_started_ns);
    j.at("recorded_ns").get_to(r.recorded_ns);
    const Json& s = j.at("servo");
    s.at("moves").get_to(r.servo.moves);
    s.at("iterations").get_to(r.servo.iterations);
    s.at("move_s").get_to(r.servo.move_s);
    s.at("acquisition_s").get_to(r.servo.acquisition_s);
    s.at("servo_s").get_to(r.servo.servo_s);
    s.at("settle_s").get_to(r.servo.settle_s);
    s.at("final_error_um").get_to(r.servo.final_error_um);
    // Added later: journals written before have neither.
    if (s.contains("search_moves")) s.at("search_moves").get_to(r.servo.search_moves);
    if (j.contains("servo_path")) j.at("servo_path").get_to(r.servo_path);
    if (j.contains("remeasure_of")) {
      j.at("remeasure_of").get_to(r.remeasure_of);
      if (r.remeasure_of < 0 || r.remeasure_of >= r.index)
        throw JournalError("pose record: remeasure_of " + std::to_string(r.remeasure_of) +
                           " is not an earlier line");
    }
    return r;
  } catch (const Json::exception& e) {
    throw JournalError(std::string("pose record: ") + e.what());
  }
}

JournalContents readJournal(const std::string& path) {
  JournalContents out;
  std::ifstream in(path, std::ios::binary);
  if (!in) {
    std::error_code ec;
    if (!fs::exists(path, ec)) return out;
    throw JournalError("cannot read " + path);
  }
  std::ostringstream buffer;
  buffer << in.rdbuf();
  const std::string text = buffer.str();

  std::size_t start = 0;
  int line_number = 0;
  while (start < text.size()) {
    ++line_number;
    const std::size_t newline = text.find('\n', start);
    const bool last = newline == std::string::npos || newline + 1 == text.size();
    const std::string line =
        text.substr(start, (newline == std::string::npos ? text.size() : newline) - start);
    std::string problem;
    PoseRecord record;
    if (newline == std::string::npos) {
      // append() acknowledges a pose only after its newline is on disk, so a line without one
      // was never acknowledged, however complete it looks.
      problem = "no newline";
    } else {
      try {
        record = poseRecordFromJson(Json::parse(line));
      } catch (const std::exception& e) {
        problem = e.what();
      }
    }
    if (!problem.empty()) {
      if (!last) throw JournalError(path + ":" + std::to_string(line_number) + ": " + problem);
      out.dropped = path + ":" + std::to_string(line_number) + ": dropped a torn last line (" +
                    std::to_string(line.size()) + " bytes, " + problem + ")";
      makeLogger("journal")->warn("{}", out.dropped);
      break;
    }
    if (record.index != out.nextIndex())
      throw JournalError(path + ":" + std::to_string(line_number) + ": pose index " +
                         std::to_string(record.index) + " where " +
                         std::to_string(out.nextIndex()) + " was due");
    out.records.push_back(record);
    out.committed_bytes = newline + 1;
    start = newline + 1;
  }
  return out;
}

Journal::Journal(const std::string& path) : path_(path) {
  JournalContents contents = readJournal(path);
  records_ = std::move(contents.records);
  dropped_ = std::move(contents.dropped);

  const fs::path file(path);
  makeDirs(file.parent_path());
  std::error_code ec;
  const bool existed = fs::exists(file, ec);
  fd_ = ::open(path.c_str(), O_WRONLY | O_CREAT | O_APPEND | O_CLOEXEC, 0644);
  if (fd_ < 0) fail("cannot open journal " + path, errno);
  try {
    if (!existed) syncDir(file.parent_path().empty() ? fs::path(".") : file.parent_path());
    if (!dropped_.empty()) {
      // Cut the torn tail so the next record does not continue the fragment's line.
      if (::ftruncate(fd_, static_cast<off_t>(contents.committed_bytes)) != 0)
        fail("cannot truncate journal " + path, errno);
      syncFd(fd_, path);
    }
  } catch (...) {
    ::close(fd_);
    throw;
  }
}

Journal::~Journal() {
  if (fd_ >= 0) ::close(fd_);
}

void Journal::append(const PoseRecord& record) {
  if (broken_) throw JournalError("journal " + path_ + " is unusable after a failed write");
  if (record.index != nextIndex())
    throw JournalError("journal " + path_ + ": pose index " + std::to_string(record.index) +
                       " where " + std::to_string(nextIndex()) + " is due");
  if (!allFinite(record))
    throw JournalError("journal " + path_ + ": pose " + std::to_string(record.index) +
                       " has a value that is not a finite number");
  const std::string line = toJson(record).dump() + "\n";
  try {
    // One write() per line: with O_APPEND a crash leaves at most this line torn.
    writeAll(fd_, line, path_);
    syncFd(fd_, path_);
  } catch (...) {
    // What reached the disk is unknown; only a re-open (which re-reads) may continue.
    broken_ = true;
    throw;
  }
  records_.push_back(record);
}

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
  return (fs::path(data_dir_) / id / kJournalFile).string();
}

SessionInfo SessionStore::create(const Json& plan, const Json& config_snapshot) {
  makeDirs(data_dir_);
  const std::string id = newSessionId(data_dir_);
  const fs::path dir = sessionDir(id);
  makeDirs(dir);
  const std::time_t now = std::chrono::system_clock::to_time_t(std::chrono::system_clock::now());
  Json session{{"format", kSessionFormat},
               {"id", id},
               {"created_unix_s", static_cast<std::int64_t>(now)},
               {"plan", plan},
               {"config", config_snapshot}};
  writeFileAtomically(dir / kSessionFile, session.dump(2) + "\n");
  SessionInfo info;
  info.id = id;
  info.dir = dir.string();
  if (plan.is_object() && plan.contains("poses") && plan["poses"].is_array())
    info.planned_poses = static_cast<int>(plan["poses"].size());
  return info;
}

Json SessionStore::readSession(const std::string& id) const {
  return readJsonFile(fs::path(sessionDir(id)) / kSessionFile);
}

std::vector<SessionInfo> SessionStore::list() const {
  std::vector<SessionInfo> sessions;
  std::error_code ec;
  if (!fs::is_directory(data_dir_, ec)) return sessions;
  std::lock_guard<std::mutex> lock(cache_->mutex);
  for (const auto& entry : fs::directory_iterator(data_dir_, ec)) {
    std::error_code entry_ec;
    if (!entry.is_directory(entry_ec) ||
        !fs::is_regular_file(entry.path() / kSessionFile, entry_ec))
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
        const Json session = readSession(info.id);
        const Json plan = session.value("plan", Json());
        if (plan.is_object() && plan.contains("poses") && plan["poses"].is_array())
          info.planned_poses = static_cast<int>(plan["poses"].size());
      } catch (const JournalError& e) {
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
    info.finished = fs::exists(entry.path() / kResultFile, entry_ec);
    sessions.push_back(std::move(info));
  }
  if (ec) throw JournalError("cannot list " + data_dir_ + ": " + ec.message());
  std::sort(sessions.begin(), sessions.end(),
            [](const SessionInfo& a, const SessionInfo& b) { return a.id < b.id; });
  return sessions;
}

std::vector<SessionInfo> SessionStore::unfinished() const {
  auto sessions = list();
  sessions.erase(
      std::remove_if(sessions.begin(), sessions.end(),
                     [](const SessionInfo& s) { return s.finished || !s.damaged.empty(); }),
      sessions.end());
  return sessions;
}

void SessionStore::writeFile(const std::string& id, const std::string& name,
                             const std::string& text) {
  writeFileAtomically(fs::path(sessionDir(id)) / name, text);
}

void SessionStore::writeResult(const std::string& id, const Json& result) {
  writeFileAtomically(fs::path(sessionDir(id)) / kResultFile, result.dump(2) + "\n");
}

}  // namespace zerocal
