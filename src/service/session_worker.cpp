#include "zerocal/service/session_worker.h"

#include <algorithm>

namespace zerocal::service {

SessionWorker::SessionWorker() : thread_([this] { loop(); }) {}

SessionWorker::~SessionWorker() { stop(); }

namespace {

std::int64_t steadyNowNs() noexcept {
  return std::chrono::duration_cast<std::chrono::nanoseconds>(
             std::chrono::steady_clock::now().time_since_epoch())
      .count();
}

}  // namespace

void SessionWorker::loop() {
  for (;;) {
    Task task;
    bool cancelled = false;
    {
      std::unique_lock<std::mutex> lock(mutex_);
      const auto ready = [this] { return stopping_ || !tasks_.empty(); };
      if (idle_task_) {
        if (!changed_.wait_for(lock, idle_period_, ready)) {
          const std::function<void()> idle = idle_task_;
          task = [idle](bool) { idle(); };
        }
      } else {
        changed_.wait(lock, ready);
      }
      if (!task) {
        if (tasks_.empty()) return;  // stopping, nothing left
        task = std::move(tasks_.front());
        tasks_.pop_front();
        cancelled = stopping_;
      }
      busy_ = true;
    }
    markProgress();
    task(cancelled);
    progress_ns_.store(0, std::memory_order_relaxed);
    {
      std::lock_guard<std::mutex> lock(mutex_);
      busy_ = false;
    }
    changed_.notify_all();
  }
}

void SessionWorker::post(Task task) {
  {
    std::lock_guard<std::mutex> lock(mutex_);
    tasks_.push_back(std::move(task));
  }
  changed_.notify_all();
}

void SessionWorker::setIdleTask(std::chrono::milliseconds period, std::function<void()> task) {
  {
    std::lock_guard<std::mutex> lock(mutex_);
    idle_period_ = period;
    idle_task_ = std::move(task);
  }
  changed_.notify_all();
}

void SessionWorker::stop() {
  {
    std::lock_guard<std::mutex> lock(mutex_);
    stopping_ = true;
  }
  changed_.notify_all();
  if (thread_.joinable()) thread_.join();
}

void SessionWorker::waitIdle() {
  std::unique_lock<std::mutex> lock(mutex_);
  changed_.wait(lock, [this] { return !busy_ && tasks_.empty(); });
}

bool SessionWorker::idle() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return !busy_ && tasks_.empty();
}

void SessionWorker::markProgress() noexcept {
  progress_ns_.store(steadyNowNs(), std::memory_order_relaxed);
}

std::chrono::steady_clock::duration SessionWorker::stalledFor() const {
  const std::int64_t last = progress_ns_.load(std::memory_order_relaxed);
  if (last == 0) return std::chrono::steady_clock::duration::zero();
  return std::chrono::nanoseconds(std::max<std::int64_t>(0, steadyNowNs() - last));
}

}  // namespace zerocal::service
