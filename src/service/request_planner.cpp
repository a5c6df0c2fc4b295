#include "zerocal/service/request_planner.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <regex>

#include "zerocal/calib/identifiability.h"
#include "zerocal/io/joint_set.h"

namespace zerocal::service {
namespace {

// A verification's poses, those where a joint offset moves the spot least first: the shortest
// beam, most nearly square to the PSD (the spot moves by range / cos(incidence) per radian). Its
// spot prediction starts from the calibration, so the first pose's search is centred on where
// the spot would be if the apply was right; if it was not (a wrong transmission doubles an
// offset of up to a degree), this is the pose whose spot is still within the search, and each
// pose found teaches the prediction the next one.
void leastSensitiveFirst(std::vector<Pose>& poses, const CellModel& cell,
                         const CalibrationParameters& found) {
  const Eigen::Vector3d normal = cell.psd_rotation.col(2);
  const auto spread = [&](const Pose& pose) {
    const Line beam = laserLine(cell, pose.q_deg, found);
    const double range = (found.target_mm - beam.point).dot(beam.direction);
    return std::abs(range / normal.dot(beam.direction));
  };
  std::stable_sort(poses.begin(), poses.end(),
                   [&](const Pose& a, const Pose& b) { return spread(a) < spread(b); });
}

Pattern patternOf(PlanKind kind) {
  switch (kind) {
    case PlanKind::kI:
      return Pattern::kI;
    case PlanKind::kII:
      return Pattern::kII;
    case PlanKind::kMixed:
      return Pattern::kMixed;
    default:
      return Pattern::kOptimal;
  }
}

bool identifiesEveryOffset(const Prediction& prediction) {
  return std::all_of(prediction.identifiable.begin(),
                     prediction.identifiable.begin() + kOffsetCount, [](bool b) { return b; });
}

// The rule that holds for every plan, whatever its source: nothing moves unless the plan
// identifies delta2..delta5.
void refuseUnlessIdentifiable(const Prediction& prediction) {
  std::string refusal;
  for (int k = 0; k < kOffsetCount; ++k)
    if (!prediction.identifiable[k])
      refusal +=
          std::string(refusal.empty() ? "" : "; ") + unknownName(k) + ": " + prediction.reason[k];
  if (!refusal.empty())
    throw Refused("not_identifiable",
                  "the plan cannot identify every offset, nothing moved: " + refusal);
}

std::string fixedDeg(double deg) { return fmt::format(FMT_STRING("{:.4f}"), deg); }

// A calibration whose plan is predicted not to reach the required accuracy would move the robot
// for minutes to answer "not usable": it is refused before anything moves, with what would reach
// it, unless asked for explicitly.
void refuseUnlessAccurate(const Prediction& prediction, double required_deg, int placements) {
  std::string short_of;
  for (int k = 0; k < kOffsetCount; ++k)
    if (!(prediction.sigma[k] <= required_deg))
      short_of += std::string(short_of.empty() ? "" : ", ") + unknownName(k).substr(0, 6) +
                  " only to " + fixedDeg(prediction.sigma[k]);
  if (short_of.empty()) return;
  throw Refused("not_accurate",
                "the plan is predicted to determine " + short_of +
                    " deg (one sigma, the robot's link tolerances counted) against the required " +
                    fixedDeg(required_deg) +
                    " deg: its result would not be usable, nothing moved. " +
                    (placements > 1 ? std::string("More poses at each placement")
                                    : std::string("Several PSD placements (--placements 3)")) +
                    " would reach it, or, for a robot with a reference, a restore against it; to "
                    "calibrate anyway (the result then withholds those offsets), ask for it "
                    "(--even-if-not-usable)");
}

// The servo and the controller keep limit_margin_deg from every joint limit and fault a move into
// it, which a plan would find only once the robot got there: every pose is checked before
// anything moves.
void refuseOutsideLimits(const Robot& robot, const std::vector<Pose>& poses, double margin_deg,
                         const std::string& what) {
  for (std::size_t i = 0; i < poses.size(); ++i) {
    const std::string v = robot.limitViolation(poses[i].q_deg, margin_deg);
    if (v.empty()) continue;
    const int line = poses[i].source_line;
    throw Refused("out_of_limits",
                  fmt::format("{}pose {}{}: {} of {}; nothing moved", what, i + 1,
                              line ? fmt::format(" (line {})", line) : "", v, robot.name));
  }
}

// The plan's poses less those skipped: what the solve will have when the rest are measured.
std::vector<Pose> posesKept(const std::vector<Pose>& plan, const std::vector<bool>& skipped) {
  std::vector<Pose> kept;
  for (std::size_t i = 0; i < plan.size(); ++i)
    if (i >= skipped.size() || !skipped[i]) kept.push_back(plan[i]);
  return kept;
}

// Where the technician is to put the PSD for each placement of the poses: the target for the
// first, for the others the point their nominal lines cross (a planned placement's centre, which
// its poses aim at). Empty with one placement.
std::vector<Eigen::Vector3d> plannedCentres(const CellModel& cell, const std::vector<Pose>& poses,
                                            const Eigen::Vector3d& target) {
  const PlacementLayout layout(poses, cell.robot, false);
  if (layout.count() < 2) return {};
  CalibrationParameters nominal;
  nominal.target_mm = target;
  std::vector<Eigen::Vector3d> centres = placementTargets(cell, poses, layout, nominal, false);
  centres.front() = target;
  return centres;
}

// Several placements need a cell whose PSD can be moved between them.
void refuseUnlessPlaceable(const CellBackend& backend) {
  const std::string why = backend.placementsRefusal();
  if (!why.empty()) throw Refused("unsupported", why);
}

}  // namespace

void checkPlanInput(const Eigen::Vector3d& target, double noise_mm) {
  if (!(noise_mm > 0) || !std::isfinite(noise_mm))
    throw InputError("noise_mm must be a positive number of millimetres");
  // No robot cell is larger than this: a target beyond it is a typing error (or 1e308).
  constexpr double kFarthestTargetMm = 1e4;
  if (!target.allFinite() || target.norm() > kFarthestTargetMm)
    throw InputError("target_mm must be three finite numbers within 10 m of the robot's base");
}

void checkSessionId(const std::string& id) {
  static const std::regex kId("[0-9]{8}T[0-9]{6}Z(-[0-9]{3})?");
  if (!std::regex_match(id, kId))
    throw Refused("bad_request", "'" + id + "' is not a session id (like 20261122T050102Z)");
}

ResultFile finishedResult(const SessionStore& store, const std::string& requested) {
  std::string id = requested;
  if (id.empty()) {
    for (const SessionInfo& s : store.list())
      if (s.finished) id = s.id;  // oldest first: the last one is the latest
    if (id.empty()) throw Refused("not_found", "no finished session yet");
  }
  checkSessionId(id);
  if (!std::filesystem::exists(std::filesystem::path(store.sessionDir(id)) / kResultFileName))
    throw Refused("not_found", "session " + id + " has no result (unknown or unfinished)");
  try {
    return store.readResult(id);
  } catch (const Error& e) {
    throw Error("the result of session " + id + " cannot be read: " + e.what());
  }
}

std::string centreText(const Eigen::Vector3d& c) {
  return fmt::format(FMT_STRING("({:.1f}, {:.1f}, {:.1f}) mm"), c.x(), c.y(), c.z());
}

std::vector<bool> skippedPoses(const std::vector<PoseRecord>& records, std::size_t plan_size) {
  std::vector<bool> skipped(plan_size, false);
  for (const PoseRecord& r : records)
    if (!r.measured() && r.index >= 0 && static_cast<std::size_t>(r.index) < plan_size)
      skipped[r.index] = true;
  return skipped;
}

RequestPlanner::RequestPlanner(const CellKnowledge& knowledge, const CellBackend& backend,
                               PlannerSettings settings)
    : knowledge_(knowledge), backend_(backend), settings_(std::move(settings)) {}

Prediction RequestPlanner::predictWithout(const std::vector<Pose>& plan,
                                          const std::vector<bool>& skipped,
                                          const Eigen::Vector3d& target, double noise_mm) const {
  CalibrationParameters nominal;
  nominal.target_mm = target;
  return predictUncertainty(knowledge_.cell, posesKept(plan, skipped), nominal, noise_mm,
                            settings_.tolerances);
}

bool RequestPlanner::identifiesWithout(const RunPlan& plan,
                                       const std::vector<bool>& skipped) const {
  return identifiesEveryOffset(predictWithout(plan.poses, skipped, plan.target, plan.noise_mm));
}

Plan RequestPlanner::makePlan(const StartRequest& request, const Robot* model,
                              Eigen::Vector3d& target, double& noise_mm) const {
  // The cell as the session's solve will know it, and what its model admits.
  CellModel cell = knowledge_.cell;
  ModelTolerances tolerances = settings_.tolerances;
  if (model) {
    cell.robot = *model;
    tolerances = model->tolerance;
  }
  target = request.target_mm.value_or(settings_.target_mm.value_or(knowledge_.taught_centre_mm));
  noise_mm = request.noise_mm.value_or(settings_.noise_mm);
  try {
    checkPlanInput(target, noise_mm);
    if (request.plan == PlanKind::kFile) {
      if (request.plan_file.empty())
        throw Refused("bad_request", "plan 'file' needs a plan_file (a joint-set file)");
      Plan plan;
      plan.poses = readJointSet(request.plan_file);
      checkPoses(cell, plan.poses);  // the same minimum and limits as a solve
      refuseOutsideLimits(cell.robot, plan.poses, settings_.limit_margin_deg,
                          "plan file " + request.plan_file + ": ");
      plan.description = "plan file " + request.plan_file;
      CalibrationParameters nominal;
      nominal.target_mm = target;
      plan.prediction = predictUncertainty(cell, plan.poses, nominal, noise_mm, tolerances);
      return plan;
    }
    PlanOptions options;
    options.pattern = patternOf(request.plan);
    options.poses = request.poses;
    options.noise_mm = noise_mm;
    options.psd_normal = knowledge_.cell.psd_rotation.col(2);
    options.tolerances = tolerances;  // the prediction the technician sees is the solve's
    if (settings_.travel_s)
      options.travel_s = [this](const Joints& from, const Joints& to) {
        return settings_.travel_s(knowledge_.cell.robot, from, to);
      };
    if (request.placements < 1 || request.placements > kMaxDefaultPlacements)
      throw InputError("placements: " + std::to_string(request.placements) + " is outside 1.." +
                       std::to_string(kMaxDefaultPlacements));
    if (request.placements > 1) {
      refuseUnlessPlaceable(backend_);
      options.more_placements = defaultPlacements(target, request.placements);
    }
    Plan plan = planPoses(cell, target, options);
    if (request.found_before) leastSensitiveFirst(plan.poses, cell, *request.found_before);
    return plan;
  } catch (const InputError& e) {
    throw Refused("bad_request", e.what());
  }
}

Plan RequestPlanner::preview(const StartRequest& request, const Robot* model) const {
  Eigen::Vector3d target;
  double noise_mm = 0;
  Plan plan = makePlan(request, model, target, noise_mm);
  plan.prediction.required_accuracy_deg = settings_.required_accuracy_deg;
  return plan;
}

PlannedSession RequestPlanner::plan(const StartRequest& request, const Robot* model) const {
  PlannedSession p;
  p.plan = makePlan(request, model, p.run.target, p.run.noise_mm);
  p.plan.prediction.required_accuracy_deg = settings_.required_accuracy_deg;
  refuseUnlessIdentifiable(p.plan.prediction);
  // A verification is the daemon's own check of an apply, judged by what it changed; a reference
  // claims nothing of the absolute zeros.
  if (!request.even_if_not_usable && request.verifies.empty() &&
      request.kind != SessionKind::kReference)
    refuseUnlessAccurate(p.plan.prediction, settings_.required_accuracy_deg, request.placements);
  p.run.poses = p.plan.poses;
  p.run.centres = plannedCentres(knowledge_.cell, p.run.poses, p.run.target);
  checkPlaceable(p.run);  // a plan file's placements
  return p;
}

ChangeOptions RequestPlanner::changeOptions(SessionKind kind) const {
  ChangeOptions o;
  o.solve.noise_mm = settings_.noise_mm;
  o.solve.model = settings_.tolerances;
  o.solve.required_accuracy_deg = settings_.required_accuracy_deg;
  o.psd_base_repeatability_mm = settings_.psd_base_repeatability_mm;
  // A restore's values are written, and its verification decides whether they stay: the arm's
  // growth since the reference is an unknown of both, so that a reference taken warm and a
  // restore taken cold do not bias them (0.0033 deg RMS without, 0.0015 with, on 30 realistic
  // worlds). A check does without: its cost is poses, twice as many.
  o.thermal_growth = kind == SessionKind::kRestore || kind == SessionKind::kVerification;
  return o;
}

PlannedSession RequestPlanner::planChange(const StartRequest& request,
                                          const Reference& reference) const {
  const bool verification = !request.verifies.empty();
  const ChangeOptions options =
      changeOptions(verification ? SessionKind::kVerification : request.kind);
  // Each offset's predicted sigma a fifth of the required accuracy: an unchanged zero then lies
  // within the bound by more than its one-sided 95% margin with room to spare (judgeCheck), and a
  // change of twice the bound is named with certainty.
  constexpr double kCheckSigmaFraction = 0.2;
  // A restore's values are written: the fewest poses whose predicted sigma is 0.15 of the
  // required accuracy (0.0015 deg of 0.01), so that the measured error stays within 0.003 deg
  // RMS with the noise and the links' remainder on top (docs/simulated-cell.md measures it).
  constexpr double kRestoreSigmaFraction = 0.15;
  const bool restore = request.kind == SessionKind::kRestore && request.verifies.empty();
  // Poses to spare beyond the unknowns: a verification decides an apply, and a restore writes
  // one, on 6 (with 3 a noisy pose made a good restore's verification fail,
  // docs/simulated-cell.md); a check takes the fewest, to stay within half a minute.
  const int at_least = verification || restore ? 6 : 0;
  std::vector<int> pairs;
  try {
    pairs = choosePosesForCheck(
        knowledge_.cell, reference.fit, options,
        (restore ? kRestoreSigmaFraction : kCheckSigmaFraction) * settings_.required_accuracy_deg,
        at_least);
  } catch (const InputError& e) {
    throw Refused("bad_request", "reference " + reference.id + ": " + e.what());
  }
  PlannedSession p;
  Plan& plan = p.plan;
  for (const int i : pairs) {
    Pose pose = reference.fit.poses[static_cast<std::size_t>(i)];
    pose.spot.reset();  // a plan's poses are joint targets
    pose.source_line = 0;
    plan.poses.push_back(pose);
    p.reference_poses.push_back(reference.plan_poses[static_cast<std::size_t>(i)]);
  }
  refuseOutsideLimits(knowledge_.cell.robot, plan.poses, settings_.limit_margin_deg,
                      "reference " + reference.id + ": ");
  const Eigen::Vector4d sigma = predictChangeSigma(knowledge_.cell, reference.fit, pairs, options);
  Prediction& prediction = plan.prediction;
  double sum2 = 0;
  for (int k = 0; k < kIdentifiedCount; ++k) {
    const bool offset = k < kOffsetCount;
    prediction.sigma.push_back(offset ? sigma[k] : std::nan(""));
    prediction.identifiable.push_back(offset && std::isfinite(sigma[k]));
    prediction.reason.push_back(offset
                                    ? (std::isfinite(sigma[k]) ? "" : "not determined by the poses")
                                    : "held at the reference's: the laser was not re-mounted");
    if (offset) sum2 += sigma[k] * sigma[k];
  }
  prediction.rms_offset_sigma_deg = std::sqrt(sum2 / kOffsetCount);
  prediction.rank = changeUnknownCount(options);
  prediction.required_accuracy_deg = settings_.required_accuracy_deg;
  const std::string of = std::to_string(pairs.size()) + " of its " +
                         std::to_string(reference.fit.poses.size()) + " poses";
  plan.description = reference.placement > 0
                         ? "verification of the apply, against calibration " + reference.id +
                               "'s placement " + std::to_string(reference.placement) + ": " + of
                     : !request.verifies.empty()
                         ? "verification against reference " + reference.id + ": " + of
                     : restore ? "restore to reference " + reference.id + ": " + of
                               : "check against reference " + reference.id + ": " + of;
  if (restore && !request.even_if_not_usable)
    refuseUnlessAccurate(prediction, settings_.required_accuracy_deg, 1);
  p.run.poses = plan.poses;
  p.run.target = reference.fit.estimate.target_mm;  // where the reference found the PSD
  p.run.noise_mm = settings_.noise_mm;
  return p;
}

void RequestPlanner::checkPlaceable(const RunPlan& plan) const {
  if (!plan.centres.empty()) refuseUnlessPlaceable(backend_);
}

RunPlan RequestPlanner::runPlanOf(const std::string& id, const SessionFile& session) const {
  RunPlan plan{session.plan.poses, session.target_mm, session.noise_mm,
               session.placement_centres_mm};
  // session.json is a file anyone with access may have edited: what it asks of the robot is
  // checked exactly as a new plan is.
  try {
    checkPlanInput(plan.target, plan.noise_mm);
    if (session.reference.empty())
      checkPoses(knowledge_.cell, plan.poses);
    else
      checkJointLimits(knowledge_.cell, plan.poses);  // a check re-measures a few poses
    if (plan.centres.empty())
      plan.centres = plannedCentres(knowledge_.cell, plan.poses, plan.target);
    if (placementCount(plan.poses) > 1 &&
        static_cast<int>(plan.centres.size()) != placementCount(plan.poses))
      throw InputError("its plan has " + std::to_string(placementCount(plan.poses)) +
                       " placements but " + std::to_string(plan.centres.size()) + " centres");
    for (const Eigen::Vector3d& c : plan.centres) checkPlanInput(c, plan.noise_mm);
  } catch (const InputError& e) {
    throw Refused("bad_session", "session " + id + " cannot be resumed: " + e.what());
  }
  refuseOutsideLimits(knowledge_.cell.robot, plan.poses, settings_.limit_margin_deg,
                      "session " + id + " cannot be resumed: ");
  return plan;
}

int RequestPlanner::checkResume(const std::string& id, const RunPlan& plan,
                                const std::vector<PoseRecord>& records, int recorded,
                                int skip_pose) const {
  const std::vector<Pose>& poses = plan.poses;
  std::vector<bool> skipped = skippedPoses(records, poses.size());
  int skip_index = -1;
  if (skip_pose != 0) {
    if (recorded >= static_cast<int>(poses.size()))
      throw Refused("bad_request", "session " + id + " has all " + std::to_string(poses.size()) +
                                       " poses recorded: there is no pose left to skip");
    if (skip_pose != recorded + 1)
      throw Refused("bad_request", "pose " + std::to_string(skip_pose) +
                                       " cannot be skipped: only the next pose to measure can, " +
                                       "pose " + std::to_string(recorded + 1) + " of session " +
                                       id);
    skip_index = recorded;
    skipped[skip_index] = true;
  }
  try {
    refuseUnlessIdentifiable(predictWithout(poses, skipped, plan.target, plan.noise_mm));
  } catch (const Refused& e) {
    if (skip_index < 0) throw;
    throw Refused(e.code(), "without pose " + std::to_string(skip_index + 1) + ", " + e.what() +
                                "; the pose is not skipped");
  }
  return skip_index;
}

SkipAdvice RequestPlanner::adviseSkip(const std::string& id, const RunPlan& plan,
                                      const std::vector<PoseRecord>& records,
                                      int stopped_at) const {
  std::vector<bool> skipped = skippedPoses(records, plan.poses.size());
  skipped.at(stopped_at) = true;
  const std::string pose = std::to_string(stopped_at + 1);
  if (identifiesWithout(plan, skipped))
    return {stopped_at + 1, "the plan identifies every offset without pose " + pose +
                                ": `zerocal resume " + id + " --skip-pose " + pose + "` skips it"};
  return {0, "without pose " + pose +
                 " the plan would not identify every offset: plan a new "
                 "session"};
}

}  // namespace zerocal::service
