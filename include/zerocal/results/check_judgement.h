// A check's conclusion (result.json's "check", docs/results.md): whether the robot's zeros are
// still the reference's. zerocal/calib/change.h judges it from the change since the reference.
#pragma once

#include <nlohmann/json.hpp>
#include <string>
#include <vector>

namespace zerocal {

struct CheckJudgement {
  enum class Outcome { kPass, kChanged, kMarginal };
  Outcome outcome = Outcome::kMarginal;
  std::vector<int> joints;  // the joints that moved (2..5), when changed
  double bound_deg = 0;     // how far a zero may be from the reference's and pass
  std::string summary;      // one sentence for the technician
};

const char* checkOutcomeName(CheckJudgement::Outcome outcome);  // "pass", "changed", "marginal"

nlohmann::json toJson(const CheckJudgement& check);
// Throws InputError naming `where` and the member.
CheckJudgement checkJudgementFromJson(const nlohmann::json& json, const std::string& where);

}  // namespace zerocal
