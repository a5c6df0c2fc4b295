// The latest PSD reading of the running session, written by the servo's thread and read by the
// control port's (status, readPsd): a sequence lock over atomics, so the writer (inside the servo
// cycle) never blocks, allocates or locks.
#pragma once

#include <atomic>
#include <optional>

#include "zerocal/cell/psd_reader.h"

namespace zerocal::service {

class LiveReadingSlot {
 public:
  void store(const PsdReading& r) noexcept {
    seq_.fetch_add(1, std::memory_order_acq_rel);  // odd: writing
    u_.store(r.spot.u_mm, std::memory_order_relaxed);
    v_.store(r.spot.v_mm, std::memory_order_relaxed);
    u_se_.store(r.se.u_mm, std::memory_order_relaxed);
    v_se_.store(r.se.v_mm, std::memory_order_relaxed);
    sum_.store(r.sum_v, std::memory_order_relaxed);
    time_.store(r.time_s, std::memory_order_relaxed);
    flags_.store((r.spot_present ? 1 : 0) | (r.in_valid_zone ? 2 : 0), std::memory_order_relaxed);
    seq_.fetch_add(1, std::memory_order_release);
  }
  // The latest reading; none since the last clear().
  std::optional<PsdReading> load() const noexcept {
    for (;;) {
      const unsigned before = seq_.load(std::memory_order_acquire);
      if (before == 0) return std::nullopt;
      if (before & 1u) continue;
      PsdReading r;
      r.spot.u_mm = u_.load(std::memory_order_relaxed);
      r.spot.v_mm = v_.load(std::memory_order_relaxed);
      r.se.u_mm = u_se_.load(std::memory_order_relaxed);
      r.se.v_mm = v_se_.load(std::memory_order_relaxed);
      r.sum_v = sum_.load(std::memory_order_relaxed);
      r.time_s = time_.load(std::memory_order_relaxed);
      const int flags = flags_.load(std::memory_order_relaxed);
      r.spot_present = flags & 1;
      r.in_valid_zone = flags & 2;
      std::atomic_thread_fence(std::memory_order_acquire);
      if (seq_.load(std::memory_order_relaxed) == before) return r;
    }
  }
  void clear() noexcept { seq_.store(0, std::memory_order_release); }

 private:
  std::atomic<unsigned> seq_{0};
  std::atomic<double> u_{0}, v_{0}, u_se_{0}, v_se_{0}, sum_{0}, time_{0};
  std::atomic<int> flags_{0};
};

}  // namespace zerocal::service
