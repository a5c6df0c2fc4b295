// A finished session folder made the way zerocald makes one (the store's SessionFile, the
// journal's PoseRecords, a ResultFile around the solve), from a simulated recording, so that the
// report tests read real files without running the simulated cell.
#pragma once

#include <string>
#include <vector>

#include "zerocal/report/session_report.h"

namespace zerocal::test {

struct FixtureOptions {
  int poses = 10;
  std::vector<int> held_out;            // validation, 1-based; empty: none
  std::vector<int> poses_without_path;  // 1-based poses whose journal line has no servo_path
  std::vector<int> skipped;             // 1-based poses skipped at a resume (not with held_out)
  std::vector<int> remeasured;          // 1-based poses measured again after the plan's lines
  std::string id = "20261122T070000Z";
  std::string plan_description;  // empty: the planner's own
  bool identity = true;          // false: a result written before the robot's identity was
};

// Writes session.json, journal.jsonl and result.json into a fresh folder `name` (emptied first,
// kept afterwards for a look) in the build tree's tests/report/sessions and returns its path.
std::string makeSession(const std::string& name, const FixtureOptions& options = {});

// The same session's files in memory (what readSessionFiles would return).
SessionFolder sessionFiles(const FixtureOptions& options = {});

}  // namespace zerocal::test
