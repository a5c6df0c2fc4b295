// The files of a session folder as types, and the only code that turns them into JSON and back
// (docs/daemon.md, docs/results.md):
//   session.json   SessionFile: what the session was asked to do, written once at its creation
//   journal.jsonl  PoseRecord per line (zerocal/store/journal.h)
//   faults.jsonl   FaultRecord per line, from the first servo fault on (zerocal/store/journal.h)
//   result.json    ResultFile: the solve and what the daemon knew of the run and the cell
// Reading is strict about what a reader needs and tolerant of members it does not know, so that a
// newer file still reads; fromJson(toJson(x)) gives x back, and toJson(fromJson(j)) gives j for
// every file zerocal writes.
#pragma once

#include <Eigen/Core>
#include <array>
#include <cstdint>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>
#include <vector>

#include "zerocal/calib/planner.h"
#include "zerocal/calib/solver.h"
#include "zerocal/calib/validation.h"
#include "zerocal/cell/controller_link.h"
#include "zerocal/store/journal.h"

namespace zerocal {

inline constexpr const char* kSessionFileName = "session.json";
inline constexpr const char* kJournalFileName = "journal.jsonl";
inline constexpr const char* kResultFileName = "result.json";
// Written into a session that will never be resumed or finished (the verification of an apply
// that was recovered since), with why.
inline constexpr const char* kClosedFileName = "closed.json";

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

// One pose of result.json's "pose_breakdown": where its cell time went.
struct PoseTimes {
  int pose = 0;         // 1-based plan pose
  std::string skipped;  // why, when the pose was skipped (nothing else is then known)
  bool again = false;   // its second measurement
  ServoStats servo;
  // What every move costs the controller beyond its motion, when the cell knows it (the
  // simulated controller), for all moves of the pose; included in the times of `servo`.
  std::optional<double> move_overhead_s, fine_point_settle_s;
};

// result.json: the solve (the top-level members) and the daemon's members around it. Members
// written by some writers only are optional: a result of `zerocal solve` has no cell time.
struct ResultFile {
  SolveReport report;
  // False for a result written before verdicts were recorded: its "verdict" is absent, and a
  // reader judges by convergence and identifiability alone.
  bool verdict_recorded = true;
  std::optional<HoldoutReport> validation;  // when poses were held out of the solve
  std::string session;                      // the session's id; empty when not a session's
  std::optional<double> cell_time_s;
  std::optional<int> resumed_from;
  std::optional<std::vector<int>> remeasured;  // 1-based plan poses measured again
  struct Cell {
    RobotInfo controller;  // as the controller named the robot
    std::string psd_map;   // the map's file and fingerprint
  };
  std::optional<Cell> cell;
  // The controller's motor calibration (MOC cal_offset of joints 1..6, rad in [0, 2 pi)) while
  // the session measured: the values its offsets are relative to. An online apply refuses when
  // the controller holds others. Absent when the link offers no calibration (or an older file).
  std::optional<std::array<double, 6>> cal_offset_rad;
  std::string zerocal_version;  // empty: not recorded
  std::optional<std::int64_t> finished_unix_s;
  struct Recoveries {
    int reconnects = 0, reopens = 0;
  };
  std::optional<Recoveries> recoveries;
  // A simulated session's true offsets (deg, delta2..delta5) and the file of its whole world.
  struct Truth {
    std::array<double, 4> offsets_deg{};
    std::string world_file;  // empty: not written
  };
  std::optional<Truth> truth;
  std::optional<std::vector<PoseTimes>> pose_breakdown;
};

nlohmann::json toJson(const SessionFile& session);
nlohmann::json toJson(const ResultFile& result);
// Throw InputError naming the file ("session.json", "result.json") and the member.
SessionFile sessionFileFromJson(const nlohmann::json& json);
ResultFile resultFileFromJson(const nlohmann::json& json);

// The three files of a session folder, read. Throws FileError naming the file that is missing,
// unreadable or not JSON, InputError for a member missing or of the wrong type, JournalError for
// a journal that cannot be read back (zerocal/store/journal.h). A session without a result
// is unfinished: FileError saying so.
struct SessionFolder {
  std::string dir;
  SessionFile session;
  std::vector<PoseRecord> journal;  // the committed lines
  ResultFile result;
};
SessionFolder readSessionFolder(const std::string& dir);

// One JSON file, parsed. Throws FileError naming the file and what is wrong.
nlohmann::json readJsonFile(const std::string& path, const std::string& what);

}  // namespace zerocal
