// Counts heap allocations per thread, for tests that a path allocates nothing. A test program
// that uses it links allocation_counter.cpp, which replaces the global operator new (every form);
// malloc from C libraries (libusb, glib) is not counted. Per thread, so that a simulator serving
// on its own thread is never counted.
#pragma once

namespace zerocal::test {

// Counts the calling thread's allocations while it lives.
class CountAllocations {
 public:
  CountAllocations() noexcept;
  ~CountAllocations();
  CountAllocations(const CountAllocations&) = delete;
  CountAllocations& operator=(const CountAllocations&) = delete;
  long count() const noexcept;
};

// Pauses counting on this thread while it lives: calls into what stands in for the hardware or
// the kernel on a real cell (a simulated board, a simulated clock). Nests with CountingResumed.
class CountingPaused {
 public:
  CountingPaused() noexcept;
  ~CountingPaused();
  CountingPaused(const CountingPaused&) = delete;
  CountingPaused& operator=(const CountingPaused&) = delete;

 private:
  bool was_;
};

// Counts again inside a CountingPaused: our code called back from the simulation.
class CountingResumed {
 public:
  CountingResumed() noexcept;
  ~CountingResumed();
  CountingResumed(const CountingResumed&) = delete;
  CountingResumed& operator=(const CountingResumed&) = delete;

 private:
  bool was_;
};

}  // namespace zerocal::test
