#include "zerocal/results/check_judgement.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <cstdio>

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

std::vector<Drift> driftBetween(const std::string& then_session,
                                const std::vector<double>& then_deg,
                                const std::vector<double>& then_sigma_deg,
                                const std::vector<double>& now_deg,
                                const std::vector<double>& now_sigma_deg) {
  std::vector<Drift> out;
  const std::size_t n = std::min({then_deg.size(), then_sigma_deg.size(), now_deg.size(),
                                  now_sigma_deg.size(), std::size_t{4}});
  for (std::size_t k = 0; k < n; ++k) {
    const double sigma = std::hypot(then_sigma_deg[k], now_sigma_deg[k]);
    const double moved = now_deg[k] - then_deg[k];
    if (!std::isfinite(moved) || !(sigma > 0) || !(std::abs(moved) > 3 * sigma)) continue;
    Drift d;
    d.joint = static_cast<int>(k) + 2;
    d.since = then_session;
    d.then_deg = then_deg[k];
    d.then_sigma_deg = then_sigma_deg[k];
    d.now_deg = now_deg[k];
    d.now_sigma_deg = now_sigma_deg[k];
    d.summary = fmt::format(FMT_STRING("joint {}'s zero moved {:+.4f} deg since session {} ({:.1f} "
                                       "sigma): a drift, or something happened to the robot in "
                                       "between"),
                            d.joint, moved, then_session, std::abs(moved) / sigma);
    out.push_back(d);
  }
  return out;
}

nlohmann::json toJson(const Drift& d) {
  return {{"joint", d.joint},       {"since", d.since},
          {"then_deg", d.then_deg}, {"then_sigma_deg", d.then_sigma_deg},
          {"now_deg", d.now_deg},   {"now_sigma_deg", d.now_sigma_deg},
          {"summary", d.summary}};
}

Drift driftFromJson(const nlohmann::json& json, const std::string& where) {
  const JsonReader j(json, where);
  Drift d;
  d.joint = j.integer("joint");
  if (d.joint < 2 || d.joint > 5) throw InputError(where + ": 'joint' is not one of 2..5");
  d.since = j.string("since");
  d.then_deg = j.number("then_deg");
  d.then_sigma_deg = j.number("then_sigma_deg");
  d.now_deg = j.number("now_deg");
  d.now_sigma_deg = j.number("now_sigma_deg");
  d.summary = j.string("summary");
  return d;
}

}  // namespace zerocal
