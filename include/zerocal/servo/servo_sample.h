// One sample of the servo's recent history: a reading and the joints commanded when it was
// taken. The servo keeps the last few in its fault (servo.h, ServoFault), and faults.jsonl
// records them as they are (zerocal/store/journal.h, FaultRecord). A type of its own so that the
// journal can hold it without the servo's code.
#pragma once

#include "zerocal/cell/psd_reader.h"
#include "zerocal/model/robot.h"

namespace zerocal::servo {

struct ServoSample {
  double time_s = 0;  // cell clock, seconds
  Joints q_deg{};     // commanded joints when the reading was taken
  PsdReading reading;
};

}  // namespace zerocal::servo
