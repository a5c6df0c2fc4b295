// A SessionControl without a cell, for the control port's tests and its load test: states change
// when told, start/resume refuse like the real one, preview and start burn CPU for a set time,
// readPsd answers from another thread, and events are emitted from the calling thread (as the real
// one does from its worker).
#pragma once

#include <atomic>
#include <chrono>
#include <mutex>
#include <thread>
#include <vector>

#include "zerocal/service/session_manager.h"

namespace zerocal::control::testing {

// The event the manager sends when a measured pose (1-based) is on disk.
service::PoseEvent measuredPose(int pose, double servo_error_um, int pose_count = 8);

class FakeSession : public service::SessionControl {
 public:
  ~FakeSession() override;

  service::SessionStatus status() const override;
  Plan preview(const service::StartRequest& request) const override;
  std::string start(const service::StartRequest& request) override;
  std::string resume(const service::ResumeRequest& request) override;
  std::string continueSession(const service::ContinueRequest& request) override;
  std::string apply(const service::ApplyRequest& request) override;
  std::string verify(const service::VerifyRequest& request) override;
  // Closes an unrecovered state (set through setState) when confirmed.
  std::string acknowledge(const service::AcknowledgeRequest& request) override;
  bool abort() override;
  std::vector<SessionInfo> sessions() const override;
  ResultFile result(const std::string& id) const override;
  std::optional<apply::ApplyRecord> lastApply(const std::string&) const override {
    return last_apply;
  }
  void readPsd(ReadingDone done) override;
  void setEventSink(EventSink sink) override;
  // robot_list and history_list when record_kept, else the daemon without a record.
  std::vector<record::RobotSummary> robots() const override;
  std::vector<record::HistoryEntry> history(const record::RobotId& robot) const override;

  // Test controls.
  void setState(service::SessionState state, int pose = 0, int pose_count = 0);
  // The session waits for the PSD at `placement` of `placement_count`, planned at `centre_mm`.
  void awaitPlacement(int placement, int placement_count, const Eigen::Vector3d& centre_mm);
  void emit(const service::SessionEvent& event);
  int startCalls() const { return start_calls_; }
  int abortCalls() const { return abort_calls_; }
  service::StartRequest lastRequest() const;
  service::ResumeRequest lastResume() const;
  service::ContinueRequest lastContinue() const;
  int applyCalls() const { return apply_calls_; }
  std::chrono::milliseconds preview_time{0};  // preview() spins this long
  std::chrono::milliseconds start_time{0};    // start() spins this long before it answers
  bool psd_fails = false;
  // What sessions() lists, oldest first (set before the server is asked).
  std::vector<SessionInfo> session_list{
      SessionInfo{"20261122-0000", "/tmp/s0", true, 8, 8, 0, ""},
      SessionInfo{"20261122-0001", "/tmp/s1", false, 8, 3, 1, ""}};
  // The robot's record: what robots() and history() (of any robot) answer.
  bool record_kept = true;
  std::vector<record::RobotSummary> robot_list;
  std::vector<record::HistoryEntry> history_list;
  // What lastApply() answers for any session.
  std::optional<apply::ApplyRecord> last_apply;
  // What result() answers for the session `result_session` (and for an empty id).
  std::string result_session = "20261122-0000";
  ResultFile result_value = [] {
    ResultFile r;  // as written before verdicts were recorded, with no parameters
    r.verdict_recorded = false;
    r.session = "20261122-0000";
    r.report.converged = true;
    return r;
  }();

 private:
  mutable std::mutex mutex_;
  service::SessionStatus status_;
  service::StartRequest last_request_;
  service::ResumeRequest last_resume_;
  service::ContinueRequest last_continue_;
  EventSink sink_;
  std::vector<std::thread> readers_;
  std::atomic<int> start_calls_{0};
  std::atomic<int> abort_calls_{0};
  std::atomic<int> apply_calls_{0};
};

}  // namespace zerocal::control::testing
