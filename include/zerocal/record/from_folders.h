// The record's entries from the session folders, the source of truth (zerocal/store/): what a
// finished session's session.json and result.json say of it, and what its apply journal
// (apply.jsonl) says of the controller. Pure functions of the files, so that recording a session
// as it finishes and rebuilding the whole record from the folders give the same entries.
#pragma once

#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "zerocal/record/robot_record.h"
#include "zerocal/results/result_file.h"
#include "zerocal/results/session_file.h"
#include "zerocal/store/session_store.h"

namespace zerocal::record {

// A finished session's entry. Throws InputError when the result names no robot (a result written
// before the daemon recorded the controller's identity, or not written by the daemon): the record
// keeps a robot's history, and a session of no known robot has no place in it.
SessionEntry sessionEntryOf(const SessionFile& session, const ResultFile& result);

// The controller events an apply journal's lines tell (ApplyJournal::read), in their order:
// each online apply (begin .. done) with the values it backed up and wrote, its verification,
// its rollback or the recovery that wrote the backup back, an acknowledgement, an apply refused
// by the transmission check, and each verification alone. The file apply's records (MOC.cfg
// written on the engineer's PC, nothing written into the controller) are passed over. Throws
// InputError naming the line for a step missing a member it needs.
std::vector<ControllerEvent> controllerEventsOf(const std::vector<nlohmann::json>& lines);

// Records finished session `id` of `store` and the events of its apply journal (none without
// one). Throws FileError or InputError when the folder cannot be read or names no robot, and
// what the record throws.
void recordFromFolder(RobotRecord& record, const SessionStore& store, const std::string& id);

// The events of session `id`'s apply journal; none when it has none.
std::vector<ControllerEvent> controllerEventsOfFolder(const SessionStore& store,
                                                      const std::string& id);

}  // namespace zerocal::record
