// The robot's record kept by the service: a session's folder recorded when it changed.
#pragma once

#include <string>
#include <vector>

#include "zerocal/record/robot_record.h"
#include "zerocal/store/session_store.h"

namespace zerocal::service {

// Records finished session `id` of `store` (its result and its apply journal) in `record`, when
// the daemon keeps one (not null). Never throws: the session folders are the truth, and a
// record that could not take the session (logged) catches up with them at the next start.
void recordSession(record::RobotRecord* record, const SessionStore& store, const std::string& id);

// The history of the robot that finished session `result` measured, from `record`, for its
// report's trend; empty without a record, for a result that names no robot, or when the record
// cannot be read (logged: the report then goes without its trend).
std::vector<record::HistoryEntry> robotHistory(const record::RobotRecord* record,
                                               const ResultFile& result);

}  // namespace zerocal::service
