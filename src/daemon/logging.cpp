#include "zerocal/daemon/logging.h"

#include <spdlog/pattern_formatter.h>
#include <spdlog/sinks/rotating_file_sink.h>
#include <spdlog/sinks/stdout_sinks.h>
#include <sys/stat.h>

#include <algorithm>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <mutex>
#include <vector>

#include "zerocal/error.h"

namespace zerocal {
namespace {

// %* in a pattern: the line's syslog priority as journald reads it on a stream, "<3>" for an
// error (sd-daemon(3)), so that `journalctl -p warning` and the colours work.
class JournalPriorityFlag final : public spdlog::custom_flag_formatter {
 public:
  void format(const spdlog::details::log_msg& msg, const std::tm&,
              spdlog::memory_buf_t& dest) override {
    static constexpr const char* kPriority[] = {"<7>", "<7>", "<6>", "<4>", "<3>", "<2>", "<6>"};
    const char* p = kPriority[std::min<int>(msg.level, spdlog::level::off)];
    dest.append(p, p + 3);
  }
  std::unique_ptr<spdlog::custom_flag_formatter> clone() const override {
    return std::make_unique<JournalPriorityFlag>();
  }
};

std::shared_ptr<spdlog::sinks::sink> makeStderrSink() {
  auto sink = std::make_shared<spdlog::sinks::stderr_sink_mt>();
  if (stderrIsJournal()) {
    // journald stamps each line itself: no second timestamp, the level as a priority prefix.
    auto formatter = std::make_unique<spdlog::pattern_formatter>();
    formatter->add_flag<JournalPriorityFlag>('*').set_pattern("%*[%n] %v");
    sink->set_formatter(std::move(formatter));
  }
  return sink;
}

// The sinks every named logger writes to. One set for the process: spdlog's registry already is
// process-wide, and loggers made before initLogging() are rewired to these by it.
struct Sinks {
  std::mutex mutex;
  std::vector<spdlog::sink_ptr> sinks{makeStderrSink()};
  spdlog::level::level_enum level = spdlog::level::info;
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

void initLogging(const LoggingConfig& config) {
  std::vector<spdlog::sink_ptr> next{makeStderrSink()};
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
  state.level = toSpdlogLevel(config.level);
  spdlog::apply_all([&](const std::shared_ptr<spdlog::logger>& logger) {
    logger->sinks() = state.sinks;
    logger->set_level(state.level);
  });
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
