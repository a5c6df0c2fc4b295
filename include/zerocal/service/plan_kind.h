// Where a session's plan comes from: one of the planner's patterns, or a joint-set file. Shared
// by the session's requests and the configuration's session section.
#pragma once

namespace zerocal {

enum class PlanKind { kOptimal, kI, kII, kMixed, kFile };

}  // namespace zerocal
