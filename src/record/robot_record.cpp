#include "zerocal/record/robot_record.h"

#include "zerocal/error.h"

namespace zerocal::record {

bool SessionEntry::operator==(const SessionEntry& o) const {
  return session == o.session && robot == o.robot && software_version == o.software_version &&
         kind == o.kind && verifies == o.verifies && usable == o.usable && reasons == o.reasons &&
         converged == o.converged && poses_used == o.poses_used && offsets == o.offsets &&
         cell_time_s == o.cell_time_s && started_unix_s == o.started_unix_s &&
         finished_unix_s == o.finished_unix_s && cal_offset_rad == o.cal_offset_rad &&
         model_from == o.model_from && model_file == o.model_file && reference == o.reference;
}

bool ControllerEvent::operator==(const ControllerEvent& o) const {
  return kind == o.kind && time_unix_s == o.time_unix_s && outcome == o.outcome &&
         before_rad == o.before_rad && after_rad == o.after_rad && verification == o.verification &&
         remaining == o.remaining && message == o.message;
}

const char* controllerEventKindName(ControllerEventKind kind) {
  switch (kind) {
    case ControllerEventKind::kApply:
      return "apply";
    case ControllerEventKind::kVerification:
      return "verification";
    case ControllerEventKind::kRollback:
      return "rollback";
    case ControllerEventKind::kAcknowledgement:
      return "acknowledgement";
  }
  return "?";
}

ControllerEventKind controllerEventKindFromName(const std::string& name) {
  for (ControllerEventKind kind :
       {ControllerEventKind::kApply, ControllerEventKind::kVerification,
        ControllerEventKind::kRollback, ControllerEventKind::kAcknowledgement})
    if (name == controllerEventKindName(kind)) return kind;
  throw InputError("no controller event is called \"" + name + "\"");
}

}  // namespace zerocal::record
