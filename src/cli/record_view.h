// The robot's record as the terminal shows it: `zerocal robots` and `zerocal history`, from the
// control port's answers (docs/protocol.md), as text or as CSV.
#pragma once

#include <nlohmann/json.hpp>
#include <ostream>

namespace zerocal::cli {

// The `robots` answer's list: a line per robot.
void printRobots(const nlohmann::json& robots, std::ostream& out);
// The `history` answer: the robot, then a line per session (date, kind, verdict, each offset
// with its sigma) and under it what was written into the controller.
void printHistory(const nlohmann::json& answer, std::ostream& out);
// The `history` answer as CSV: a header, then a row per session (RFC 4180 quoting).
void printHistoryCsv(const nlohmann::json& answer, std::ostream& out);

}  // namespace zerocal::cli
