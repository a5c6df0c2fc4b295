// The servo's figures for one recorded pose: a journal line holds them (zerocal/store/journal.h),
// and result.json's pose breakdown (zerocal/results/result_file.h).
#pragma once

namespace zerocal {

// What the servo did for one pose; durations in seconds of cell time.
// The four durations add up to the pose's cell time, from the start of the planned move to the
// recorded reading.
struct ServoStats {
  int moves = 0;              // servo and search moves, the planned move not counted
  int iterations = 0;         // fine-servo iterations
  double move_s = 0;          // the planned move
  double acquisition_s = 0;   // spot search, its settling excluded
  double servo_s = 0;         // fine servo, its settling excluded
  double settle_s = 0;        // waits after moves before readings that count (servo.settle_s each)
  double final_error_um = 0;  // distance of the spot from the centre at the recorded reading
  int search_moves = 0;       // of `moves`, searching for the spot (absent from older journals: 0)
};

}  // namespace zerocal
