// The thread that touches the cell: it runs a session's tasks one at a time (a run, a PSD reading
// taken on request) and keeps the progress mark that the daemon's watchdog reads.
#pragma once

#include <atomic>
#include <chrono>
#include <condition_variable>
#include <cstdint>
#include <deque>
#include <functional>
#include <mutex>
#include <thread>

namespace zerocal::service {

class SessionWorker {
 public:
  // `cancelled`: the worker is stopping; the task should only report that it did not run.
  using Task = std::function<void(bool cancelled)>;

  SessionWorker();
  // stop().
  ~SessionWorker();
  SessionWorker(const SessionWorker&) = delete;
  SessionWorker& operator=(const SessionWorker&) = delete;

  void post(Task task);
  // While no task is queued, `task` runs after every `period` of idleness (work that waits for a
  // device to come back). Replaces any earlier one.
  void setIdleTask(std::chrono::milliseconds period, std::function<void()> task);
  // Runs what is queued with cancelled = true and joins the thread. Idempotent.
  void stop();
  // Blocks until no task runs or waits.
  void waitIdle();
  bool idle() const;

  // A sign of progress (a phase change, a PSD reading, a recorded pose): lock-free, so the servo
  // cycle may call it.
  void markProgress() noexcept;
  // How long the running task has gone without a sign of progress; zero while none runs. A worker
  // stuck while holding a lock still shows.
  std::chrono::steady_clock::duration stalledFor() const;

 private:
  void loop();

  mutable std::mutex mutex_;
  std::condition_variable changed_;
  std::deque<Task> tasks_;
  bool busy_ = false;
  bool stopping_ = false;
  std::chrono::milliseconds idle_period_{0};
  std::function<void()> idle_task_;
  // Steady-clock nanoseconds of the latest progress; 0 while no task runs.
  std::atomic<std::int64_t> progress_ns_{0};
  std::thread thread_;  // last member: starts after the others exist
};

}  // namespace zerocal::service
