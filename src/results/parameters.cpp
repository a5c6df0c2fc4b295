#include "zerocal/results/parameters.h"

namespace zerocal {

Joints CalibrationParameters::offsetsDeg() const {
  Joints out{};
  for (int i = 0; i < kOffsetCount; ++i) out[i + 1] = delta_rad[i] * kRadToDeg;
  return out;
}

std::string unknownName(int i) {
  static const char* names[kUnknownCount] = {
      "delta2_deg",    "delta3_deg",    "delta4_deg",        "delta5_deg",
      "laser_slope_1", "laser_slope_2", "laser_offset_1_mm", "laser_offset_2_mm",
      "target_x_mm",   "target_y_mm",   "target_z_mm"};
  return names[i];
}

std::string linkParamName(int k) {
  static const char* kinds[3] = {"da", "dd", "dalpha"};
  return kinds[k % 3] + std::to_string(k / 3 + 1) + (k % 3 == 2 ? "_deg" : "_mm");
}

std::string complianceParamName(int k) {
  return "compliance" + std::to_string(k + 2) + "_deg_per_knm";
}

}  // namespace zerocal
