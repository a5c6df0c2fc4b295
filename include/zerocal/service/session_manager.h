// The daemon's one calibration session at a time: planning, the run on a worker thread, its state
// and progress, abort, resume after a restart, and the result files. The control port (and
// `zerocald --once`) drive it through SessionControl; the cell comes in through CellBackend.
//
// Threads: every SessionControl method may be called from any thread and returns promptly (none
// waits for the robot). The session itself runs on the manager's worker thread; events are
// delivered on that thread, without any lock held.
#pragma once

#include <Eigen/Core>
#include <array>
#include <atomic>
#include <chrono>
#include <condition_variable>
#include <cstdint>
#include <deque>
#include <functional>
#include <memory>
#include <mutex>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>
#include <thread>
#include <vector>

#include "zerocal/cell/cell.h"
#include "zerocal/service/session_control.h"
#include "zerocal/session/calibration_run.h"

namespace zerocal::service {

struct ManagerSettings {
  std::string data_dir;
  RunSettings run;
  double noise_mm = 0.010;  // default measurement sigma for plans and solves
  PlanKind plan = PlanKind::kOptimal;
  int poses = 8;
  std::string plan_file;
  std::optional<Eigen::Vector3d> target_mm;  // default nominal target; else the backend's
  nlohmann::json config_snapshot;            // written into each session.json
  // What every move costs the controller beyond its motion, when known (the simulated one's
  // model): the result's pose breakdown then shows it per pose, as moves x cost.
  std::optional<MoveOverhead> move_overhead;
  // Called with a finished session's folder after result.json is written (summary, report).
  std::function<void(const std::string& session_dir)> write_reports;
};

class SessionManager final : public SessionControl {
 public:
  SessionManager(CellBackend& backend, ManagerSettings settings);
  // Aborts a running session and waits for the worker (the robot stopped, the journal closed).
  ~SessionManager() override;

  SessionStatus status() const override;
  Plan preview(const StartRequest& request) const override;
  std::string start(const StartRequest& request) override;
  std::string resume(const ResumeRequest& request) override;
  bool abort() override;
  std::vector<SessionInfo> sessions() const override;
  nlohmann::json result(const std::string& id) const override;
  void readPsd(ReadingDone done) override;
  void setEventSink(EventSink sink) override;

  // Blocks until no session is active; returns the final status. For --once and shutdown.
  SessionStatus waitIdle();
  // The request the configuration describes (session.plan, poses, plan_file, target).
  StartRequest defaultRequest() const;
  // How long the worker thread (which also runs the servo) has been inside one step of its task
  // without a sign of progress: a phase change, a PSD reading, a recorded pose. Zero while it
  // waits for work. Lock-free, for the watchdog: a worker stuck while holding the mutex shows.
  std::chrono::steady_clock::duration workerStalledFor() const;

 private:
  class LiveSlot;
  class Claim;
  using Task = std::function<void(bool cancelled)>;  // cancelled: the daemon is stopping
  void workerLoop();
  void post(Task task);
  struct PoseSkip {
    int index = -1;  // 0-based pose to journal as skipped before running; -1: none
    std::string reason;
  };
  void runSession(const std::string& id, const std::vector<Pose>& plan,
                  const Eigen::Vector3d& target, double noise_mm, const PoseSkip& skip);
  void finish(SessionState state, const std::string& message);
  void setPhase(SessionState state, int pose);
  void emit(const SessionEvent& event);
  StateEvent stateEvent() const;  // mutex_ held
  void markProgress() noexcept;
  Plan makePlan(const StartRequest& request, Eigen::Vector3d& target, double& noise_mm) const;

  CellBackend& backend_;
  ManagerSettings settings_;
  SessionStore store_;
  CellKnowledge knowledge_;
  std::unique_ptr<LiveSlot> live_;

  mutable std::mutex mutex_;  // guards everything below it but abort_ and cell_
  std::condition_variable changed_;
  SessionStatus status_;
  bool starting_ = false;  // start()/resume() between the busy check and the posted run
  bool busy_ = false;      // the worker is running a task
  EventSink sink_;
  std::deque<Task> tasks_;
  bool stopping_ = false;
  std::atomic<bool> abort_{false};
  std::unique_ptr<ConnectedCell> cell_;  // worker thread only
  // Steady-clock nanoseconds of the worker's latest progress; 0 while it waits for work.
  std::atomic<std::int64_t> progress_ns_{0};
  std::thread worker_;  // last member: starts after the others exist
};

}  // namespace zerocal::service
