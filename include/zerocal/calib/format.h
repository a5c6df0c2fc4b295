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
// The inverse of toJson: toJson(solveReportFromJson(j)) == j. Of the estimate, only the target,
// the offsets and the laser parameters are in the JSON; the rest stays at its default. Throws
// InputError naming `where` and the member that is missing or of the wrong type.
SolveReport solveReportFromJson(const nlohmann::json& json, const std::string& where);

// The "validation" member of a result (docs/results.md); the fit itself is toJson(report.fit).
nlohmann::json toJson(const HoldoutReport& report);
std::string toText(const HoldoutReport& report);
// The inverse of toJson, without the fit (the result around it). Throws InputError.
HoldoutReport holdoutReportFromJson(const nlohmann::json& json, const std::string& where);

nlohmann::json toJson(const Plan& plan);
std::string toText(const Plan& plan);
// The inverse of toJson; a plan without "predicted" (hand-edited) predicts nothing: every sigma
// NaN, nothing identifiable. Throws InputError.
Plan planFromJson(const nlohmann::json& json, const std::string& where);

nlohmann::json toJson(const std::vector<ScenarioResult>& results, const ExperimentOptions& options);
std::string toText(const std::vector<ScenarioResult>& results, const ExperimentOptions& options);

nlohmann::json toJson(const std::array<JointSensitivity, kJointCount>& s);
std::string toText(const std::array<JointSensitivity, kJointCount>& s);

std::string costName(CostKind cost);
// How a solve modelled the readings ("hit-point", "point-to-line") and where its noise came from
// ("given", "estimated from the residuals"): result.json's "model" and "noise_source".
std::string modelName(const SolveReport& report);
std::string noiseSourceName(const SolveReport& report);

}  // namespace zerocal
