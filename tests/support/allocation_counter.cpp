#include "allocation_counter.h"

#include <cstdlib>
#include <new>

namespace {

// Trivial thread_locals: no initialiser runs, so operator new may touch them at any time.
thread_local bool t_counting = false;
thread_local bool t_paused = false;
thread_local long t_allocations = 0;

void* allocate(std::size_t size) {
  if (t_counting && !t_paused) ++t_allocations;
  if (void* p = std::malloc(size ? size : 1)) return p;
  throw std::bad_alloc();
}

void* allocateAligned(std::size_t size, std::align_val_t alignment) {
  if (t_counting && !t_paused) ++t_allocations;
  const auto a = static_cast<std::size_t>(alignment);
  if (void* p = std::aligned_alloc(a, (size + a - 1) / a * a)) return p;
  throw std::bad_alloc();
}

}  // namespace

void* operator new(std::size_t size) { return allocate(size); }
void* operator new[](std::size_t size) { return allocate(size); }
void* operator new(std::size_t size, std::align_val_t a) { return allocateAligned(size, a); }
void* operator new[](std::size_t size, std::align_val_t a) { return allocateAligned(size, a); }
void operator delete(void* p) noexcept { std::free(p); }
void operator delete[](void* p) noexcept { std::free(p); }
void operator delete(void* p, std::size_t) noexcept { std::free(p); }
void operator delete[](void* p, std::size_t) noexcept { std::free(p); }
void operator delete(void* p, std::align_val_t) noexcept { std::free(p); }
void operator delete[](void* p, std::align_val_t) noexcept { std::free(p); }
void operator delete(void* p, std::size_t, std::align_val_t) noexcept { std::free(p); }
void operator delete[](void* p, std::size_t, std::align_val_t) noexcept { std::free(p); }

namespace zerocal::test {

CountAllocations::CountAllocations() noexcept {
  t_allocations = 0;
  t_counting = true;
}
CountAllocations::~CountAllocations() { t_counting = false; }
long CountAllocations::count() const noexcept { return t_allocations; }

CountingPaused::CountingPaused() noexcept : was_(t_paused) { t_paused = true; }
CountingPaused::~CountingPaused() { t_paused = was_; }

CountingResumed::CountingResumed() noexcept : was_(t_paused) { t_paused = false; }
CountingResumed::~CountingResumed() { t_paused = was_; }

}  // namespace zerocal::test
