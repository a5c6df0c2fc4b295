// Text and JSON renderings of solver, planner and experiment results: the JSON is what
// result.json, session.json and `--json` hold (docs/results.md); the text is what the commands
// print.
#pragma once

#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "zerocal/calib/experiment.h"
#include "zerocal/calib/planner.h"
#include "zerocal/calib/sensitivity.h"
#include "zerocal/calib/solver.h"
#include "zerocal/calib/validation.h"

namespace zerocal {

// The verdict object of a result: {usable, reasons}; its text is the first lines of a solve's.
nlohmann::json toJson(const Verdict& verdict);
std::string toText(const Verdict& verdict);

nlohmann::json toJson(const SolveReport& report);
std::string toText(const SolveReport& report);

// The "validation" member of a result (docs/results.md); the fit itself is toJson(report.fit).
nlohmann::json toJson(const HoldoutReport& report);
std::string toText(const HoldoutReport& report);

nlohmann::json toJson(const Plan& plan);
std::string toText(const Plan& plan);

nlohmann::json toJson(const std::vector<ScenarioResult>& results, const ExperimentOptions& options);
std::string toText(const std::vector<ScenarioResult>& results, const ExperimentOptions& options);

nlohmann::json toJson(const std::array<JointSensitivity, kJointCount>& s);
std::string toText(const std::array<JointSensitivity, kJointCount>& s);

std::string costName(CostKind cost);

}  // namespace zerocal
