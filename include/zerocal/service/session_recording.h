// The robot's record kept by the service: a session's folder recorded when it changed.
#pragma once

#include <string>

#include "zerocal/record/robot_record.h"
#include "zerocal/store/session_store.h"

namespace zerocal::service {

// Records finished session `id` of `store` (its result and its apply journal) in `record`, when
// the daemon keeps one (not null). Never throws: the session folders are the truth, and a
// record that could not take the session (logged) catches up with them at the next start.
void recordSession(record::RobotRecord* record, const SessionStore& store, const std::string& id);

}  // namespace zerocal::service
