// session.json (docs/results.md): what a session was asked to do, written once at its creation,
// and its JSON.
// Reading is strict about what a reader needs and tolerant of members it does not know, so that a
// newer file still reads; fromJson(toJson(x)) gives x back, and toJson(fromJson(j)) gives j for
// every file zerocal writes.
#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "zerocal/results/plan.h"

namespace zerocal {

// What a session is for. A verification measures the offsets left after an apply (or on its
// own, of an applied session): it is never resumed as a calibration.
enum class SessionKind { kCalibration, kVerification };
const char* sessionKindName(SessionKind kind);

// session.json.
struct SessionFile {
  std::string format = "zerocal-session/1";
  std::string id;
  std::int64_t created_unix_s = 0;
  SessionKind kind = SessionKind::kCalibration;  // absent in files before kinds: a calibration
  std::string verifies;  // a verification's: the id of the session whose apply it verifies
  Plan plan;             // the poses (joints only), how they were chosen, the predicted uncertainty
  Eigen::Vector3d target_mm = Eigen::Vector3d::Zero();  // nominal PSD centre, base frame
  double noise_mm = 0;                                  // measurement sigma of the plan and solve
  // With poses at several PSD placements: every placement's planned centre (base frame, mm),
  // placement 1's first (target_mm); where the technician is told to put the PSD. Empty with one.
  std::vector<Eigen::Vector3d> placement_centres_mm;
  nlohmann::json config;  // the daemon's configuration at creation (configToJson), as written
};

nlohmann::json toJson(const SessionFile& session);
// Throws InputError naming "session.json" and the member.
SessionFile sessionFileFromJson(const nlohmann::json& json);

}  // namespace zerocal
