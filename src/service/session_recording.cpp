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

}  // namespace zerocal::service
