#include "zerocal/daemon/logging.h"

#include <spdlog/sinks/rotating_file_sink.h>
#include <spdlog/sinks/stdout_sinks.h>

#include <filesystem>
#include <mutex>
#include <vector>

#include "zerocal/error.h"

namespace zerocal {
namespace {

// The sinks every named logger writes to. One set for the process: spdlog's registry already is
// process-wide, and loggers made before initLogging() are rewired to these by it.
struct Sinks {
  std::mutex mutex;
  std::vector<spdlog::sink_ptr> sinks{std::make_shared<spdlog::sinks::stderr_sink_mt>()};
  spdlog::level::level_enum level = spdlog::level::info;
};

Sinks& sinks() {
  static Sinks instance;
  return instance;
}

}  // namespace

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
  std::vector<spdlog::sink_ptr> next{std::make_shared<spdlog::sinks::stderr_sink_mt>()};
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
