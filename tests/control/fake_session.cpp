#include "fake_session.h"

#include <cmath>

namespace zerocal::control::testing {

using service::Refused;
using service::SessionState;

FakeSession::~FakeSession() {
  for (auto& t : readers_) t.join();
}

service::SessionStatus FakeSession::status() const {
  std::lock_guard<std::mutex> lock(mutex_);
  service::SessionStatus s = status_;
  if (s.state == SessionState::kServoing) s.live_servo_error_um = 12.5;  // as the real one shows
  return s;
}

namespace {

// Burns CPU for `time`, as planning does.
void spin(std::chrono::milliseconds time) {
  const auto until = std::chrono::steady_clock::now() + time;
  volatile double x = 0;
  while (std::chrono::steady_clock::now() < until)
    for (int i = 0; i < 1000; ++i) x = x + std::sqrt(static_cast<double>(i));
}

}  // namespace

service::PoseEvent measuredPose(int pose, double servo_error_um, int pose_count) {
  service::PoseEvent event;
  event.pose_count = pose_count;
  event.record.index = pose - 1;
  event.record.servo.final_error_um = servo_error_um;
  return event;
}

Plan FakeSession::preview(const service::StartRequest& request) const {
  if (request.poses < 6) throw Refused("bad_request", "at least 6 poses are needed");
  // Busy CPU like the planner, not a sleep: the io thread must not be the one doing it.
  spin(preview_time);
  Plan plan;
  plan.description = "fake plan of " + std::to_string(request.poses) + " poses";
  plan.poses.resize(request.poses);
  plan.prediction.sigma.assign(kIdentifiedCount, 0.001);
  plan.prediction.identifiable.assign(kIdentifiedCount, true);
  plan.prediction.reason.assign(kIdentifiedCount, "");
  plan.prediction.rank = 11;
  plan.prediction.required_accuracy_deg = 0.01;
  if (request.poses == 10) plan.prediction.sigma[0] = 0.02;  // a plan short of the accuracy
  if (request.poses == 9) {                                  // what 4 sessions cost a pose
    plan.prediction.cell_time_per_pose_s = 5.25;
    plan.prediction.cell_time_s = 9 * 5.25;
    plan.prediction.cell_time_sessions = 4;
  }
  return plan;
}

std::string FakeSession::start(const service::StartRequest& request) {
  ++start_calls_;
  spin(start_time);  // the real start plans before it answers
  std::lock_guard<std::mutex> lock(mutex_);
  if (service::isActive(status_.state))
    throw Refused("busy", "session " + status_.session_id + " is " +
                              service::stateName(status_.state) + ": one session at a time");
  if (request.poses == 7) throw Refused("not_identifiable", "delta5 is not identifiable");
  last_request_ = request;
  status_.state = SessionState::kConnecting;
  status_.session_id = "20261122-0001";
  status_.pose_count = request.poses;
  status_.predicted_sigma_deg = {0.001, 0.002, std::nan(""), 0.004};
  return status_.session_id;
}

std::string FakeSession::resume(const service::ResumeRequest& request) {
  std::lock_guard<std::mutex> lock(mutex_);
  last_resume_ = request;
  if (service::isActive(status_.state)) throw Refused("busy", "a session is running");
  if (!request.session.empty() && request.session != "20261122-0001")
    throw Refused("not_found", "no session " + request.session);
  status_.state = SessionState::kConnecting;
  status_.session_id = "20261122-0001";
  return status_.session_id;
}

// As the manager: only a session awaiting a placement goes on.
std::string FakeSession::continueSession(const service::ContinueRequest& request) {
  std::lock_guard<std::mutex> lock(mutex_);
  last_continue_ = request;
  if (status_.state != SessionState::kAwaitingPlacement)
    throw Refused("not_waiting", "no session is waiting for the PSD to be moved");
  status_.state = SessionState::kConnecting;
  status_.placement = status_.next_placement;
  status_.next_placement = 0;
  return status_.session_id;
}

// As the manager: confirmation first, then busy, then the session.
std::string FakeSession::apply(const service::ApplyRequest& request) {
  std::lock_guard<std::mutex> lock(mutex_);
  if (!request.confirm) throw Refused("not_confirmed", "confirm: true needed");
  if (service::isActive(status_.state)) throw Refused("busy", "a session is running");
  if (!request.session.empty() && request.session != result_session)
    throw Refused("not_found", "no session " + request.session);
  ++apply_calls_;
  status_.state = SessionState::kApplying;
  status_.session_id = result_session;
  return status_.session_id;
}

std::string FakeSession::verify(const service::VerifyRequest& request) {
  std::lock_guard<std::mutex> lock(mutex_);
  if (service::isActive(status_.state)) throw Refused("busy", "a session is running");
  if (!request.session.empty() && request.session != result_session)
    throw Refused("not_found", "no session " + request.session);
  status_.state = SessionState::kApplying;
  status_.session_id = result_session;
  return status_.session_id;
}

std::string FakeSession::acknowledge(const service::AcknowledgeRequest& request) {
  std::lock_guard<std::mutex> lock(mutex_);
  if (!request.confirm) throw Refused("not_confirmed", "confirm: true needed");
  if (status_.state != SessionState::kUnrecovered)
    throw Refused("not_found", "no interrupted apply to acknowledge");
  status_.state = SessionState::kDone;
  return status_.session_id;
}

bool FakeSession::abort() {
  ++abort_calls_;
  service::StateEvent event;
  {
    std::lock_guard<std::mutex> lock(mutex_);
    if (!service::isActive(status_.state)) return false;
    status_.state = SessionState::kAborted;
    status_.message = "aborted on request";
    event.state = status_.state;
    event.session = status_.session_id;
  }
  emit(event);
  return true;
}

std::vector<SessionInfo> FakeSession::sessions() const { return session_list; }

std::vector<record::RobotSummary> FakeSession::robots() const {
  if (!record_kept) return SessionControl::robots();
  return robot_list;
}

std::vector<record::HistoryEntry> FakeSession::history(const record::RobotId& robot) const {
  if (!record_kept) return SessionControl::history(robot);
  return history_list;
}

ResultFile FakeSession::result(const std::string& id) const {
  if (!id.empty() && id != result_session) throw Refused("not_found", "no result for " + id);
  return result_value;
}

void FakeSession::readPsd(ReadingDone done) {
  std::lock_guard<std::mutex> lock(mutex_);
  const bool fail = psd_fails;
  readers_.emplace_back([done = std::move(done), fail] {
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
    if (fail) return done(std::nullopt, "no USB-1408FS found");
    service::LiveReading r;
    r.reading.spot.u_mm = 0.012;
    r.reading.spot.v_mm = -0.034;
    r.reading.sum_v = 3.2;
    r.reading.spot_present = true;
    r.reading.in_valid_zone = true;
    done(r, "");
  });
}

void FakeSession::setEventSink(EventSink sink) {
  std::lock_guard<std::mutex> lock(mutex_);
  sink_ = std::move(sink);
}

void FakeSession::awaitPlacement(int placement, int placement_count,
                                 const Eigen::Vector3d& centre_mm) {
  {
    std::lock_guard<std::mutex> lock(mutex_);
    status_.placement_count = placement_count;
    status_.placement = placement - 1;
    status_.next_placement = placement;
    status_.next_centre_mm = centre_mm;
    status_.message = "move the PSD to placement " + std::to_string(placement);
  }
  setState(SessionState::kAwaitingPlacement, status_.pose, status_.pose_count);
}

void FakeSession::setState(SessionState state, int pose, int pose_count) {
  service::StateEvent event;
  {
    std::lock_guard<std::mutex> lock(mutex_);
    status_.state = state;
    status_.pose = pose;
    if (pose_count) status_.pose_count = pose_count;
    event.state = state;
    event.session = status_.session_id;
    event.pose = pose;
    event.pose_count = status_.pose_count;
  }
  emit(event);
}

void FakeSession::emit(const service::SessionEvent& event) {
  EventSink sink;
  {
    std::lock_guard<std::mutex> lock(mutex_);
    sink = sink_;
  }
  if (sink) sink(event);
}

service::StartRequest FakeSession::lastRequest() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return last_request_;
}

service::ContinueRequest FakeSession::lastContinue() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return last_continue_;
}

service::ResumeRequest FakeSession::lastResume() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return last_resume_;
}

}  // namespace zerocal::control::testing
