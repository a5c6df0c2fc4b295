#include "zerocal/service/session_board.h"

#include <algorithm>
#include <chrono>

namespace zerocal::service {

SessionBoard::SessionBoard(std::string backend_name) { status_.backend = std::move(backend_name); }

SessionStatus SessionBoard::status() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return status_;
}

void SessionBoard::setEventSink(SessionControl::EventSink sink) {
  std::lock_guard<std::mutex> lock(mutex_);
  sink_ = std::move(sink);
}

void SessionBoard::emit(const SessionEvent& event) const {
  SessionControl::EventSink sink;
  {
    std::lock_guard<std::mutex> lock(mutex_);
    sink = sink_;
  }
  if (sink) sink(event);
}

SessionBoard::Claim::Claim(SessionBoard& board, Purpose purpose) : board_(board) {
  std::lock_guard<std::mutex> lock(board_.mutex_);
  const SessionStatus& s = board_.status_;
  if (board_.closed_) throw Refused("busy", "the daemon is stopping");
  if (!board_.blocked_.empty() && purpose != Purpose::kRecovery)
    throw Refused("unrecovered", board_.blocked_);
  if (!board_.held_.empty()) throw Refused("busy", board_.held_ + ": one thing at a time");
  if (board_.claimed_ || isActive(s.state))
    throw Refused("busy", "session " + s.session_id + " is " + stateName(s.state) +
                              ": one session at a time (abort it first)");
  board_.claimed_ = true;
  board_.abort_ = false;
}

SessionBoard::Claim::~Claim() {
  {
    std::lock_guard<std::mutex> lock(board_.mutex_);
    board_.claimed_ = false;
  }
  board_.changed_.notify_all();
}

StateEvent SessionBoard::stateEvent() const {
  return {status_.state,      status_.session_id, status_.pose,
          status_.pose_count, status_.recorded,   status_.message};
}

template <class Change>
bool SessionBoard::changeState(Change&& change) {
  StateEvent event;
  {
    std::lock_guard<std::mutex> lock(mutex_);
    if (!change()) return false;
    event = stateEvent();
  }
  changed_.notify_all();
  emit(event);
  return true;
}

void SessionBoard::begin(SessionStatus status) {
  {
    std::lock_guard<std::mutex> lock(mutex_);
    status.backend = status_.backend;
    status_ = std::move(status);
  }
  changed_.notify_all();
}

void SessionBoard::announce() const {
  StateEvent event;
  {
    std::lock_guard<std::mutex> lock(mutex_);
    event = stateEvent();
  }
  emit(event);
}

void SessionBoard::setPhase(SessionState state, int pose) {
  changeState([&] {
    status_.state = state;
    status_.pose = std::min(pose, status_.pose_count);
    return true;
  });
}

void SessionBoard::finish(SessionState state, const std::string& message) {
  setState(state, message);
}

void SessionBoard::setState(SessionState state, const std::string& message) {
  changeState([&] {
    status_.state = state;
    status_.message = message;
    return true;
  });
}

bool SessionBoard::awaitPlacement(int placement, const Eigen::Vector3d& centre_mm,
                                  const std::string& message) {
  bool waiting = false;
  changeState([&] {
    // An abort asked for while the run was stopping ends the session: nobody would end it once
    // it waits with no worker.
    waiting = !abort_;
    status_.state = waiting ? SessionState::kAwaitingPlacement : SessionState::kAborted;
    status_.message = waiting ? message : "aborted before placement " + std::to_string(placement);
    status_.next_placement = waiting ? placement : 0;
    status_.next_centre_mm = centre_mm;
    return true;
  });
  return waiting;
}

SessionStatus SessionBoard::leaveWaiting() {
  SessionStatus status;
  changeState([&] {
    if (closed_) throw Refused("busy", "the daemon is stopping");
    if (status_.state != SessionState::kAwaitingPlacement)
      throw Refused("not_waiting",
                    status_.session_id.empty()
                        ? std::string("no session is waiting for the PSD to be moved")
                        : "no session is waiting for the PSD to be moved (session " +
                              status_.session_id + " is " + stateName(status_.state) + ")");
    status_.state = SessionState::kConnecting;
    status_.message.clear();
    status_.placement = status_.next_placement;
    status_.next_placement = 0;
    status = status_;
    return true;
  });
  return status;
}

bool SessionBoard::abortWaiting() {
  return changeState([&] {
    if (status_.state != SessionState::kAwaitingPlacement) return false;
    status_.state = SessionState::kAborted;
    status_.message =
        "aborted while waiting for the PSD at placement " + std::to_string(status_.next_placement);
    status_.next_placement = 0;
    return true;
  });
}

bool SessionBoard::awaitTechnician(const std::string& message, const std::function<void()>& tick) {
  {
    std::lock_guard<std::mutex> lock(mutex_);
    go_ahead_ = false;
  }
  setState(SessionState::kAwaitingCounter, message);
  bool went_on = false;
  for (;;) {
    {
      std::unique_lock<std::mutex> lock(mutex_);
      changed_.wait_for(lock, std::chrono::seconds(1), [this] { return go_ahead_ || abort_; });
      went_on = go_ahead_ && !abort_;
      if (go_ahead_ || abort_) break;
    }
    if (tick) tick();
  }
  // A continue has set applying already; an abort has not.
  if (!went_on) setState(SessionState::kApplying, "");
  return went_on;
}

bool SessionBoard::goAhead() {
  return changeState([&] {
    if (status_.state != SessionState::kAwaitingCounter || go_ahead_) return false;
    go_ahead_ = true;
    // Applying again from here on, so that a second continue finds nothing waiting.
    status_.state = SessionState::kApplying;
    status_.message.clear();
    return true;
  });
}

void SessionBoard::update(const std::function<void(SessionStatus&)>& change) {
  std::lock_guard<std::mutex> lock(mutex_);
  change(status_);
}

void SessionBoard::hold(const std::string& why) {
  std::lock_guard<std::mutex> lock(mutex_);
  held_ = why.empty() ? "held" : why;
}

void SessionBoard::block(const std::string& why) {
  std::lock_guard<std::mutex> lock(mutex_);
  blocked_ = why.empty() ? "an interrupted apply is not recovered" : why;
}

void SessionBoard::unblock() {
  std::lock_guard<std::mutex> lock(mutex_);
  blocked_.clear();
}

bool SessionBoard::blocked() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return !blocked_.empty();
}

void SessionBoard::release() {
  {
    std::lock_guard<std::mutex> lock(mutex_);
    held_.clear();
  }
  changed_.notify_all();
}

bool SessionBoard::requestAbort() {
  std::lock_guard<std::mutex> lock(mutex_);
  if (!claimed_ && held_.empty() && !isActive(status_.state)) return false;
  abort_ = true;
  changed_.notify_all();  // an apply waiting for the technician rolls back at once
  return true;
}

void SessionBoard::abortAll() {
  std::lock_guard<std::mutex> lock(mutex_);
  closed_ = true;
  abort_ = true;
  changed_.notify_all();
}

bool SessionBoard::activeOrClaimed() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return claimed_ || !held_.empty() || isActive(status_.state);
}

void SessionBoard::waitInactive() const {
  std::unique_lock<std::mutex> lock(mutex_);
  changed_.wait(lock, [this] { return !claimed_ && held_.empty() && !isActive(status_.state); });
}

}  // namespace zerocal::service
