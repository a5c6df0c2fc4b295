// How many poses and PSD placements a plan may have: one definition for the engine, the
// configuration, the control port and the command line (which has no engine, hence a header of
// its own).
#pragma once

namespace zerocal {

// 2N residuals must exceed the 11 unknowns (delta2..delta5, the laser's four, the target's three).
constexpr int kMinimumPoses = 6;
// The most poses one plan may have, wherever a pose count is given: a larger count is a typing
// error, not a calibration plan.
constexpr int kMaxPlanPoses = 200;
// The most PSD placements of a default spread (defaultPlacements, zerocal/calib/planner.h): what
// a session may ask for by count alone.
constexpr int kMaxDefaultPlacements = 5;

}  // namespace zerocal
