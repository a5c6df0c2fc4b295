// Text renderings of solver, planner and experiment results (what the lab's commands print), and
// the JSON of the experiments and the sensitivity. The JSON of a solve, a hold-out validation
// and a plan (result.json, session.json, `--json`) is the results codec's, zerocal/results/,
// included here for the commands that print both.
#pragma once

#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "zerocal/calib/experiment.h"
#include "zerocal/calib/planner.h"
#include "zerocal/calib/sensitivity.h"
#include "zerocal/calib/solver.h"
#include "zerocal/calib/validation.h"
#include "zerocal/results/holdout_report.h"
#include "zerocal/results/plan.h"
#include "zerocal/results/solve_report.h"

namespace zerocal {

// The first lines of a solve's text: the verdict and its reasons.
std::string toText(const Verdict& verdict);
std::string toText(const SolveReport& report);
std::string toText(const HoldoutReport& report);
std::string toText(const Plan& plan);

nlohmann::json toJson(const std::vector<ScenarioResult>& results, const ExperimentOptions& options);
std::string toText(const std::vector<ScenarioResult>& results, const ExperimentOptions& options);

nlohmann::json toJson(const std::array<JointSensitivity, kJointCount>& s);
std::string toText(const std::array<JointSensitivity, kJointCount>& s);

}  // namespace zerocal
