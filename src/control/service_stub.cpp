// Temporary: the two free functions of service/session_manager.h the control port uses, until
// zerocal::service (src/service) is on this branch. Built only when that target does not exist.
#include "zerocal/service/session_manager.h"

namespace zerocal::service {

const char* stateName(SessionState state) {
  switch (state) {
    case SessionState::kIdle:
      return "idle";
    case SessionState::kConnecting:
      return "connecting";
    case SessionState::kMoving:
      return "moving";
    case SessionState::kServoing:
      return "servoing";
    case SessionState::kRecording:
      return "recording";
    case SessionState::kSolving:
      return "solving";
    case SessionState::kDone:
      return "done";
    case SessionState::kAborted:
      return "aborted";
    case SessionState::kFaulted:
      return "faulted";
  }
  return "?";
}

bool isActive(SessionState state) {
  return state != SessionState::kIdle && state != SessionState::kDone &&
         state != SessionState::kAborted && state != SessionState::kFaulted;
}

}  // namespace zerocal::service
