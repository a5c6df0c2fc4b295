#include "zerocal/results/placements.h"

#include <algorithm>

namespace zerocal {

std::vector<int> placementsOf(const std::vector<Pose>& poses) {
  std::vector<int> out;
  for (const Pose& p : poses) out.push_back(p.placement);
  std::sort(out.begin(), out.end());
  out.erase(std::unique(out.begin(), out.end()), out.end());
  return out;
}

}  // namespace zerocal
