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

// A zero that moved since the robot's last comparison with the same reference (a check, a
// restore, or the verification of a restore's apply) by more than three sigmas of the difference:
// beyond what the history predicts (the zero as last measured), a drift or an event (a collision)
// between the two sessions. result.json's "drift".
struct Drift {
  int joint = 0;                            // 2..5
  std::string since;                        // the earlier session's id
  double then_deg = 0, then_sigma_deg = 0;  // its change since the reference
  double now_deg = 0, now_sigma_deg = 0;    // this session's
  std::string summary;                      // one sentence for the technician
};

// The drift of each offset between `then` and `now`, two reports against the same reference
// (their offsets are changes since it); offsets either did not determine are passed over.
std::vector<Drift> driftBetween(const std::string& then_session,
                                const std::vector<double>& then_deg,
                                const std::vector<double>& then_sigma_deg,
                                const std::vector<double>& now_deg,
                                const std::vector<double>& now_sigma_deg);

nlohmann::json toJson(const CheckJudgement& check);
// Throws InputError naming `where` and the member.
CheckJudgement checkJudgementFromJson(const nlohmann::json& json, const std::string& where);
nlohmann::json toJson(const Drift& drift);
Drift driftFromJson(const nlohmann::json& json, const std::string& where);

}  // namespace zerocal
