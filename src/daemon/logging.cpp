#include "zerocal/daemon/logging.h"

#include <spdlog/pattern_formatter.h>
#include <spdlog/sinks/rotating_file_sink.h>
#include <spdlog/sinks/stdout_sinks.h>
#include <spdlog/sinks/systemd_sink.h>
#include <sys/stat.h>
#include <sys/uio.h>

#include <algorithm>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <iterator>
#include <mutex>
#include <utility>
#include <vector>

#include "zerocal/error.h"

namespace zerocal {
namespace {

// The journal's native protocol (sd_journal_sendv): spdlog's systemd sink gives each line its
// priority and SYSLOG_IDENTIFIER=zerocald; this one adds the fields of the session the daemon is
// running, so that `journalctl SESSION_ID=<id>` shows one session's lines and `journalctl
// ROBOT=<serial>` one robot's. The line keeps its logger's name ("[servo] ...").
class JournalSink final : public spdlog::sinks::systemd_sink<std::mutex> {
 public:
  explicit JournalSink(JournalSend send) : systemd_sink("zerocald", true), send_(send) {
    set_formatter(std::make_unique<spdlog::pattern_formatter>(
        "[%n] %v", spdlog::pattern_time_type::local, std::string()));
  }

  void setSession(const LogSession& s) {
    std::lock_guard<std::mutex> lock(mutex_);
    session_ = s.session.empty() ? std::string() : "SESSION_ID=" + s.session;
    robot_ = s.robot.empty() ? std::string() : "ROBOT=" + s.robot;
  }

 protected:
  void sink_it_(const spdlog::details::log_msg& msg) override {
    spdlog::memory_buf_t text;
    formatter_->format(msg, text);
    const std::string message = "MESSAGE=" + std::string(text.data(), text.size());
    const std::string priority = "PRIORITY=" + std::to_string(syslog_level(msg.level));
    const std::string identifier = "SYSLOG_IDENTIFIER=" + ident_;
    const std::string* const lines[] = {&message, &priority, &identifier, &session_, &robot_};
    iovec fields[std::size(lines)];
    int count = 0;
    for (const std::string* field : lines)
      if (!field->empty()) fields[count++] = iovec{const_cast<char*>(field->data()), field->size()};
    // journald unreachable: the line still goes to stderr, which systemd records too.
    if (send_(fields, count) < 0)
      std::fprintf(stderr, "%.*s\n", static_cast<int>(text.size()), text.data());
  }

 private:
  JournalSend send_;
  std::string session_, robot_;
};

std::shared_ptr<spdlog::sinks::sink> makeStderrSink() {
  return std::make_shared<spdlog::sinks::stderr_sink_mt>();
}

// The sinks every named logger writes to. One set for the process: spdlog's registry already is
// process-wide, and loggers made before initLogging() are rewired to these by it.
struct Sinks {
  std::mutex mutex;
  std::vector<spdlog::sink_ptr> sinks{makeStderrSink()};
  spdlog::level::level_enum level = spdlog::level::info;
  std::shared_ptr<JournalSink> journal;  // in sinks, when the log goes to the journal
  LogSession session;
};

Sinks& sinks() {
  static Sinks instance;
  return instance;
}

}  // namespace

bool stderrIsJournal() {
  // systemd sets JOURNAL_STREAM=<device>:<inode> of the stream it connected; stderr may since
  // have been redirected (a shell under the unit), so compare it with stderr itself.
  const char* stream = std::getenv("JOURNAL_STREAM");
  unsigned long long device = 0, inode = 0;
  if (!stream || std::sscanf(stream, "%llu:%llu", &device, &inode) != 2) return false;
  struct stat st {};
  if (::fstat(2, &st) != 0) return false;
  return static_cast<unsigned long long>(st.st_dev) == device &&
         static_cast<unsigned long long>(st.st_ino) == inode;
}

spdlog::level::level_enum toSpdlogLevel(LogLevel level) {
  switch (level) {
    case LogLevel::kTrace:
      return spdlog::level::trace;
    case LogLevel::kDebug:
      return spdlog::level::debug;
    case LogLevel::kInfo:
      return spdlog::level::info;
    case LogLevel::kWarn:
      return spdlog::level::warn;
    case LogLevel::kError:
      return spdlog::level::err;
    case LogLevel::kCritical:
      return spdlog::level::critical;
    case LogLevel::kOff:
      return spdlog::level::off;
  }
  return spdlog::level::info;
}

void initLogging(const LoggingConfig& config, JournalSend journal) {
  if (!journal && stderrIsJournal()) journal = sd_journal_sendv;
  std::shared_ptr<JournalSink> journal_sink;
  if (journal) journal_sink = std::make_shared<JournalSink>(journal);
  std::vector<spdlog::sink_ptr> next{journal_sink ? spdlog::sink_ptr(journal_sink)
                                                  : makeStderrSink()};
  if (!config.directory.empty()) {
    try {
      std::filesystem::create_directories(config.directory);
      // 10 MB x 5 files bounds the disk a chatty debug level can take on the cell PC.
      next.push_back(std::make_shared<spdlog::sinks::rotating_file_sink_mt>(
          (std::filesystem::path(config.directory) / "zerocald.log").string(), 10 * 1024 * 1024,
          5));
    } catch (const std::exception& e) {
      throw Error("log directory " + config.directory + ": " + e.what());
    }
  }
  auto& state = sinks();
  std::lock_guard<std::mutex> lock(state.mutex);
  state.sinks = next;
  state.journal = journal_sink;
  if (journal_sink) journal_sink->setSession(state.session);
  state.level = toSpdlogLevel(config.level);
  spdlog::apply_all([&](const std::shared_ptr<spdlog::logger>& logger) {
    logger->sinks() = state.sinks;
    logger->set_level(state.level);
  });
}

LogSession setLogSession(const LogSession& next) {
  auto& state = sinks();
  std::lock_guard<std::mutex> lock(state.mutex);
  LogSession previous = std::exchange(state.session, next);
  if (state.journal) state.journal->setSession(next);
  return previous;
}

std::shared_ptr<spdlog::logger> makeLogger(const std::string& name) {
  auto& state = sinks();
  std::lock_guard<std::mutex> lock(state.mutex);
  if (auto existing = spdlog::get(name)) return existing;
  auto logger = std::make_shared<spdlog::logger>(name, state.sinks.begin(), state.sinks.end());
  logger->set_level(state.level);
  spdlog::register_logger(logger);
  return logger;
}

}  // namespace zerocal
