#include "zerocal/results/check_judgement.h"

#include "zerocal/error.h"
#include "zerocal/io/json_reader.h"

namespace zerocal {

const char* checkOutcomeName(CheckJudgement::Outcome outcome) {
  switch (outcome) {
    case CheckJudgement::Outcome::kPass:
      return "pass";
    case CheckJudgement::Outcome::kChanged:
      return "changed";
    case CheckJudgement::Outcome::kMarginal:
      return "marginal";
  }
  return "marginal";
}

nlohmann::json toJson(const CheckJudgement& check) {
  return {{"outcome", checkOutcomeName(check.outcome)},
          {"joints", check.joints},
          {"bound_deg", check.bound_deg},
          {"summary", check.summary}};
}

CheckJudgement checkJudgementFromJson(const nlohmann::json& json, const std::string& where) {
  const JsonReader j(json, where);
  CheckJudgement c;
  const std::string outcome = j.string("outcome");
  bool known = false;
  for (const auto o : {CheckJudgement::Outcome::kPass, CheckJudgement::Outcome::kChanged,
                       CheckJudgement::Outcome::kMarginal})
    if (outcome == checkOutcomeName(o)) c.outcome = o, known = true;
  if (!known)
    throw InputError(where + ": 'outcome' is '" + outcome +
                     "', not one of pass, changed, marginal");
  for (const nlohmann::json& joint : j.array("joints")) {
    if (!joint.is_number_integer() || joint.get<int>() < 2 || joint.get<int>() > 5)
      throw InputError(where + ": 'joints' holds something other than a joint 2..5");
    c.joints.push_back(joint.get<int>());
  }
  c.bound_deg = j.number("bound_deg");
  c.summary = j.string("summary");
  return c;
}

}  // namespace zerocal
