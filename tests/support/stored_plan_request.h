// A session request on a stored plan (stored_plan.h) instead of a plan made at start, for the
// tests of the session manager that need a session, not the planner.
#pragma once

#include <string>

#include "stored_plan.h"
#include "zerocal/service/session_control.h"

namespace zerocal::testing {

// `request` with its plan replaced by tests/data/plans/<name>.csv; usually the manager's
// defaultRequest(), so that everything else is as configured.
inline service::StartRequest onStoredPlan(service::StartRequest request, const std::string& name) {
  request.plan = PlanKind::kFile;
  request.plan_file = storedPlanPath(name);
  return request;
}

}  // namespace zerocal::testing
