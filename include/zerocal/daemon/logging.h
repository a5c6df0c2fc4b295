// Diagnostic logging of the daemon: spdlog loggers by name ("session", "servo", "journal", ...)
// that share one set of sinks and the level of the configuration. Measured data never goes
// through these; it is recorded by the session journal (journal.h) in the data directory.
#pragma once

#include <spdlog/spdlog.h>
#include <sys/uio.h>

#include <memory>
#include <string>

#include "zerocal/daemon/config.h"
#include "zerocal/error.h"

namespace zerocal {

// sd_journal_sendv(3)'s signature: a line to the journal as its fields.
using JournalSend = int (*)(const iovec* fields, int count);

// Sets the sinks and level of every logger, existing and future: the journal when stderr is the
// journal's stream (under systemd: each line with its priority, SYSLOG_IDENTIFIER=zerocald and
// the running session's SESSION_ID and ROBOT: LogSession), else stderr; plus a rotating
// zerocald.log in `config.directory` when it is not empty (the folder is created). `journal`
// sends to the journal whatever stderr is (a test's capture). Call once at start-up, before
// other threads log. Throws Error when the log file cannot be opened.
void initLogging(const LoggingConfig& config, JournalSend journal = nullptr);

// The session the daemon is running and its robot (the controller's serial), which each line to
// the journal carries as SESSION_ID and ROBOT; empty: none.
struct LogSession {
  std::string session, robot;
};
// Sets it until set again, and returns the one it replaces. Thread-safe.
LogSession setLogSession(const LogSession& next);

// The journal's fields of a session while it lives (the robot's set when known); the one before
// it again after (an apply's verification inside the apply).
class LoggedSession {
 public:
  explicit LoggedSession(std::string session)
      : session_(std::move(session)), previous_(setLogSession({session_, ""})) {}
  ~LoggedSession() { setLogSession(previous_); }
  LoggedSession(const LoggedSession&) = delete;
  LoggedSession& operator=(const LoggedSession&) = delete;
  void setRobot(const std::string& serial) const { setLogSession({session_, serial}); }

 private:
  std::string session_;
  LogSession previous_;
};

// The logger of that name, created on first use with the current sinks and level. Thread-safe.
// Before initLogging() it logs to stderr at info level.
std::shared_ptr<spdlog::logger> makeLogger(const std::string& name);

spdlog::level::level_enum toSpdlogLevel(LogLevel level);

// True when stderr is the stream systemd connected to the journal (JOURNAL_STREAM names it).
bool stderrIsJournal();

}  // namespace zerocal
