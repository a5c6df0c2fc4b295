// Sensitivity of the laser spot on the PSD to each joint (paper section III-E): how far the spot
// moves per small joint change, for a configuration and a stand-off.
#pragma once

#include <Eigen/Core>
#include <array>

#include "zerocal/calib/cell_model.h"

namespace zerocal {

struct JointSensitivity {
  Eigen::Vector2d spot_mm_per_deg = Eigen::Vector2d::Zero();  // in the PSD plane (b1, b2)
  double magnitude_mm_per_deg = 0;
  // The joint change that moves the spot by 0.02 mm (the paper's figure); infinite when the
  // joint does not move the spot.
  double deg_per_20um = 0;
};

// The PSD plane is normal to the nominal beam, `standoff_mm` along it from the laser's point;
// (b1, b2) is the laser basis (flange e1, e2 made orthogonal to the beam) carried to the base.
std::array<JointSensitivity, kJointCount> spotSensitivity(const CellModel& cell,
                                                          const Joints& q_deg, double standoff_mm);

}  // namespace zerocal
