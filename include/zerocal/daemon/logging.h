// Diagnostic logging of the daemon: spdlog loggers by name ("session", "servo", "journal", ...)
// that share one set of sinks and the level of the configuration. Measured data never goes
// through these; it is recorded by the session journal (journal.h) in the data directory.
#pragma once

#include <spdlog/spdlog.h>

#include <memory>
#include <string>

#include "zerocal/daemon/config.h"
#include "zerocal/error.h"

namespace zerocal {

// Sets the sinks and level of every logger, existing and future: stderr (which systemd's journal
// records; when stderr is the journal's stream, each line carries its priority as "<4>" and no
// timestamp of its own), plus a rotating zerocald.log in `config.directory` when it is not empty
// (the folder is created). Call once at start-up, before other threads log. Throws Error when the
// log file cannot be opened.
void initLogging(const LoggingConfig& config);

// The logger of that name, created on first use with the current sinks and level. Thread-safe.
// Before initLogging() it logs to stderr at info level.
std::shared_ptr<spdlog::logger> makeLogger(const std::string& name);

spdlog::level::level_enum toSpdlogLevel(LogLevel level);

// True when stderr is the stream systemd connected to the journal (JOURNAL_STREAM names it).
bool stderrIsJournal();

}  // namespace zerocal
