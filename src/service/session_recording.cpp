#include "zerocal/service/session_recording.h"

#include "zerocal/daemon/logging.h"
#include "zerocal/record/from_folders.h"

namespace zerocal::service {

void recordSession(record::RobotRecord* record, const SessionStore& store, const std::string& id) {
  if (record == nullptr || id.empty()) return;
  try {
    record::recordFromFolder(*record, store, id);
  } catch (const std::exception& e) {
    makeLogger("record")->error(
        "session {} is not in the robot's record: {}; it is recorded from its folder at the "
        "next start",
        id, e.what());
  }
}

std::vector<record::HistoryEntry> robotHistory(const record::RobotRecord* record,
                                               const ResultFile& result) {
  if (record == nullptr || !result.cell) return {};
  try {
    return record->history({result.cell->controller.robot_type, result.cell->controller.serial});
  } catch (const std::exception& e) {
    makeLogger("record")->error("session {}: its report goes without the robot's trend: {}",
                                result.session, e.what());
    return {};
  }
}

}  // namespace zerocal::service
