// The cell seam's clocks (zerocal/cell/psd_reader.h).
#include <thread>

#include "zerocal/cell/psd_reader.h"

namespace zerocal {

void CellClock::waitS(double seconds) noexcept {
  if (seconds > 0) std::this_thread::sleep_for(std::chrono::duration<double>(seconds));
}

double SteadyCellClock::nowS() noexcept {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - start_).count();
}

}  // namespace zerocal
