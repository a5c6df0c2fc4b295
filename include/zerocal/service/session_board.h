// The state machine of the daemon's one session at a time, and its status: every change is made
// here under one lock and announced as an event after the lock is released. The control side
// reads and claims it; the worker moves it on.
//
//   idle/done/aborted/faulted --claim, begin--> connecting --> moving <-> servoing <-> recording
//     ^                                                          |                       |
//     +------------------------- finish (done, aborted, faulted) +--> solving -----------+
//     ^                                                                                  |
//     +-- abortWaiting -- awaiting_placement <--awaitPlacement--------------------------+
//                                 |
//                                 +--leaveWaiting--> connecting (the next placement's poses)
#pragma once

#include <Eigen/Core>
#include <atomic>
#include <condition_variable>
#include <functional>
#include <mutex>
#include <string>

#include "zerocal/service/session_control.h"

namespace zerocal::service {

class SessionBoard {
 public:
  explicit SessionBoard(std::string backend_name);

  SessionStatus status() const;
  void setEventSink(SessionControl::EventSink sink);
  // Calls the sink, if any, on the calling thread, without the lock.
  void emit(const SessionEvent& event) const;

  // Between the busy check of a start or resume and its run being posted (or its refusal): a
  // second request is refused busy meanwhile, and an abort is for the session being claimed.
  // Throws Refused("busy"); while the board is blocked, Refused("unrecovered") unless the claim
  // is for the recovery itself.
  class Claim {
   public:
    enum class Purpose { kSession, kRecovery };
    explicit Claim(SessionBoard& board, Purpose purpose = Purpose::kSession);
    ~Claim();
    Claim(const Claim&) = delete;
    Claim& operator=(const Claim&) = delete;

   private:
    SessionBoard& board_;
  };

  // A new run: the status becomes `status` (its state connecting); announce() tells it.
  void begin(SessionStatus status);
  // Emits the current state.
  void announce() const;
  // The run is at `state` for 1-based `pose` (clamped to the pose count: the solve comes after the
  // last pose).
  void setPhase(SessionState state, int pose);
  // The run ended in `state`; `message` says why when it did not finish.
  void finish(SessionState state, const std::string& message);
  // The run stopped for the PSD to be moved to `placement`, planned at `centre_mm`; `message`
  // tells the technician. The status says so until leaveWaiting() or abortWaiting(). False (the
  // session aborted instead) when an abort was requested meanwhile.
  bool awaitPlacement(int placement, const Eigen::Vector3d& centre_mm, const std::string& message);
  // For a continue: the waiting session goes on (connecting) and its status is returned. Throws
  // Refused("not_waiting") when no session awaits a placement, Refused("busy") when the daemon is
  // stopping.
  SessionStatus leaveWaiting();
  // A waiting session ends as aborted; false when none waits (no worker runs a waiting session,
  // so nothing else would end it).
  bool abortWaiting();
  // An online apply's worker waits for the technician: the status says awaiting_counter with
  // `message` until goAhead() (a continue) or an abort; `tick` is called about every second
  // meanwhile (the watchdog's progress mark). True when the technician went on, false on an
  // abort; the state is applying again either way.
  bool awaitTechnician(const std::string& message, const std::function<void()>& tick);
  // For a continue: the apply waiting for the technician goes on. False when none waits.
  bool goAhead();
  // Changes the status without an event (progress figures).
  void update(const std::function<void(SessionStatus&)>& change);

  // While held (an online apply around its verification session), the board counts as active
  // whatever its state: a claim is refused busy with `why`, waitInactive() waits, an abort is
  // for the verification. Released by release().
  void hold(const std::string& why);
  void release();

  // While blocked (an interrupted apply that is not recovered: the controller's values are not
  // known to be verified ones), every claim but a recovery's is refused with `why`, which says
  // what to check on the controller. Unblocked by unblock().
  void block(const std::string& why);
  void unblock();
  bool blocked() const;

  // Asks the running or claimed session to stop; false when there is none.
  bool requestAbort();
  // Set by requestAbort() (or abortAll()) until the next claim; the run polls it.
  const std::atomic<bool>& abortRequested() const { return abort_; }
  // Asks whatever runs to stop, and refuses claims from now on: the daemon is stopping.
  void abortAll();

  bool activeOrClaimed() const;
  // Blocks until no session is active or claimed.
  void waitInactive() const;

 private:
  StateEvent stateEvent() const;  // mutex_ held
  // The state and message become these, and the change is announced.
  void setState(SessionState state, const std::string& message);
  // Runs `change` on the status under the lock; when it returns true, wakes the waiters and
  // announces the new state once the lock is released. Returns what `change` returned (it may
  // throw, and then nothing is announced). Defined and used in session_board.cpp only.
  template <class Change>
  bool changeState(Change&& change);

  mutable std::mutex mutex_;
  mutable std::condition_variable changed_;
  SessionStatus status_;
  bool claimed_ = false;
  std::string held_;     // why the board is held; empty: not held
  std::string blocked_;  // why the board is blocked; empty: not blocked
  bool closed_ = false;
  bool go_ahead_ = false;  // awaitTechnician: the technician continued
  std::atomic<bool> abort_{false};
  SessionControl::EventSink sink_;
};

}  // namespace zerocal::service
