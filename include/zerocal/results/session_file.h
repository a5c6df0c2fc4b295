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

// What a session is for (docs/record.md). A calibration finds the absolute zeros. A reference
// records the poses, the PSD placement and the controller's values at zeros known good, for later
// checks and restores to compare with; it claims nothing of the absolute zeros. A check
// re-measures a few of a reference's poses and says whether a zero moved; a restore re-measures
// them all and finds the change of each zero since the reference, which an apply writes back. A
// verification measures what is left after an apply (against the reference when the apply was a
// restore's): it is never resumed.
enum class SessionKind { kCalibration, kVerification, kReference, kCheck, kRestore };
const char* sessionKindName(SessionKind kind);
// Throws InputError naming `where` for a name no kind has.
SessionKind sessionKindFromName(const std::string& name, const std::string& where);

// session.json.
struct SessionFile {
  std::string format = "zerocal-session/1";
  std::string id;
  std::int64_t created_unix_s = 0;
  SessionKind kind = SessionKind::kCalibration;  // absent in files before kinds: a calibration
  std::string verifies;  // a verification's: the id of the session whose apply it verifies
  // Measured against a reference (a check, a restore, the verification of a restore's apply):
  // the reference session's id, and per plan pose the reference's 1-based plan pose it
  // re-measures. Empty otherwise.
  std::string reference;
  std::vector<int> reference_poses;
  // A calibration planned and solved with the calibrated model of an earlier calibration
  // (ResultFile::model_file): that calibration's id. Empty: the daemon's robot file.
  std::string model_from;
  Plan plan;  // the poses (joints only), how they were chosen, the predicted uncertainty
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
