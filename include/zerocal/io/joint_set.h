// The joint-set CSV: the poses of one calibration, as recorded or as planned.
//
//   # comment lines start with '#'; blank lines are skipped
//   q1,q2,q3,q4,q5,q6[,u,v][,placement][,other columns ignored]
//   10.00000,-5.25000,...
//
// q1..q6 are controller joint angles in degrees; u, v the PSD reading in mm when the pose was
// recorded (optional, both or neither); placement the 1-based PSD placement the pose aims at
// (optional: absent, every pose is placement 1). Column order is free; the header names them.
#pragma once

#include <optional>
#include <string>
#include <vector>

#include "zerocal/model/robot.h"
#include "zerocal/psd/spot.h"

namespace zerocal {

struct Pose {
  Joints q_deg{};
  std::optional<PsdSpot> spot;  // where the spot was on the PSD (the reading), if recorded
  int source_line = 0;          // 1-based line in the file, 0 when not from a file
  // Which PSD placement (1-based) the pose aims at: a session may move the PSD between groups of
  // poses, and each placement has its own unknown centre. 1 for a single placement.
  int placement = 1;
};

// The largest placement number a joint set may name.
inline constexpr int kMaxPlacements = 100;

// A joint set is a plan or a recording: far below these. Larger input is refused, not read.
inline constexpr std::size_t kMaxJointSetBytes = 1 << 20;
inline constexpr std::size_t kMaxJointSetPoses = 10000;

// Throws InputError naming the line for: a file that cannot be opened, is not a regular file or
// is larger than kMaxJointSetBytes, a missing header or columns, values that are not decimal
// numbers or not finite, rows with too few fields, u without v, more than kMaxJointSetPoses rows,
// a placement that is not a whole number from 1 to kMaxPlacements.
// A leading UTF-8 byte-order mark is skipped. Messages never quote the file's content.
std::vector<Pose> readJointSet(const std::string& path);
std::vector<Pose> parseJointSet(const std::string& text, const std::string& origin);

// Writes q1..q6 with 5 decimals (the controller's precision), u,v when every pose has them, and
// placement when any pose is not placement 1.
std::string formatJointSet(const std::vector<Pose>& poses, const std::string& comment = {});

}  // namespace zerocal
