// The solve for poses at two or more PSD placements: each placement its own centre, and the
// link errors the poses can identify beside the offsets and the laser (docs/maths.md section 8).
#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>

#include "costs.h"
#include "solver_detail.h"
#include "zerocal/calib/identifiability.h"
#include "zerocal/calib/planner.h"
#include "zerocal/error.h"

namespace zerocal::detail {
namespace {

struct MultiFit {
  CalibrationParameters est;
  std::vector<Eigen::Vector3d> targets;  // per placement slot
  bool converged = false;
  std::string message;
  int iterations = 0;
};

// The columns of the unknowns the base-parameter analysis kept.
Eigen::MatrixXd identifiedColumns(const Eigen::MatrixXd& jacobian, const BaseParameters& base) {
  Eigen::MatrixXd out(jacobian.rows(), base.count);
  int j = 0;
  for (int k = 0; k < static_cast<int>(jacobian.cols()); ++k)
    if (base.identified[k]) out.col(j++) = jacobian.col(k);
  return out;
}

// Holds the entries of a parameter block that the base-parameter analysis did not keep.
void holdUnidentified(ceres::Problem& problem, double* block, int first, int size,
                      const BaseParameters& base) {
  std::vector<int> held;
  for (int i = 0; i < size; ++i)
    if (!base.identified[first + i]) held.push_back(i);
  if (static_cast<int>(held.size()) == size)
    problem.SetParameterBlockConstant(block);
  else if (!held.empty())
    problem.SetManifold(block, new ceres::SubsetManifold(size, held));
}

MultiFit fit(const CellModel& cell, const std::vector<Pose>& poses, const PlacementLayout& layout,
             const BaseParameters& base, const SolveOptions& options, bool readings,
             const CalibrationParameters& start, const std::vector<Eigen::Vector3d>& targets) {
  MultiFit f;
  f.est = start;
  f.targets = targets;
  ceres::Problem::Options problem_options;
  problem_options.cost_function_ownership = ceres::TAKE_OWNERSHIP;
  problem_options.manifold_ownership = ceres::TAKE_OWNERSHIP;
  ceres::Problem problem(problem_options);
  const double sigma_in = options.noise_mm.value_or(1.0);
  for (const Pose& pose : poses) {
    CalibrationParameters at = start;
    at.target_mm = targets[layout.slot(pose.placement)];
    problem.AddResidualBlock(
        LinkPointToLineCost::create(cell, pose.q_deg, hitPointOffset(cell, pose, readings),
                                    sigma_in, missWeight(cell, pose, at, readings)),
        nullptr, f.est.delta_rad.data(), f.est.laser.data(), f.est.link.data(),
        f.est.compliance.data(), f.targets[layout.slot(pose.placement)].data());
  }
  holdUnidentified(problem, f.est.delta_rad.data(), 0, kOffsetCount, base);
  holdUnidentified(problem, f.est.laser.data(), kOffsetCount, kLaserParamCount, base);
  holdUnidentified(problem, f.est.link.data(), PlacementLayout::firstLink(), kLinkParameterCount,
                   base);
  if (layout.compliance == 0)
    problem.SetParameterBlockConstant(f.est.compliance.data());
  else
    holdUnidentified(problem, f.est.compliance.data(), PlacementLayout::firstCompliance(),
                     kComplianceCount, base);
  for (int p = 0; p < layout.count(); ++p)
    holdUnidentified(problem, f.targets[p].data(), layout.firstTarget() + kTargetCount * p,
                     kTargetCount, base);

  CancelCallback cancel(options.cancelled);
  const ceres::Solver::Options solver_options = solverOptions(options, &cancel);
  ceres::Solver::Summary summary;
  ceres::Solve(solver_options, &problem, &summary);
  f.converged = summary.termination_type == ceres::CONVERGENCE;
  f.message = summary.termination_type == ceres::USER_FAILURE ? "cancelled" : summary.message;
  f.iterations = static_cast<int>(summary.iterations.size());
  return f;
}

// The poses moved (by a minimum-norm change of the joints, a fraction of a degree) so that the
// nominal lines pass exactly through their placement's centre: where the base parameters are
// found. A pose that cannot be moved so keeps its joints.
std::vector<Pose> onTheirCentres(const CellModel& cell, const std::vector<Pose>& poses,
                                 const PlacementLayout& layout,
                                 const std::vector<Eigen::Vector3d>& targets) {
  std::vector<Pose> out;
  for (const Pose& p : poses) {
    Pose moved = p;
    moved.spot.reset();
    if (const auto q = servoOnto(cell, {}, targets[layout.slot(p.placement)], p.q_deg))
      moved.q_deg = *q;
    out.push_back(moved);
  }
  return out;
}

void checkPlacements(const std::vector<Pose>& poses, const PlacementLayout& layout,
                     const SolveOptions& options) {
  if (options.cost != CostKind::kMaximumLikelihood)
    throw InputError(
        "the poses are at " + std::to_string(layout.count()) +
        " PSD placements: only the maximum-likelihood cost identifies several placements");
  if (options.loss != RobustLoss::kNone)
    throw InputError("the poses are at " + std::to_string(layout.count()) +
                     " PSD placements: a robust loss is not offered with several placements");
  for (int placement : layout.placements) {
    const auto n = std::count_if(poses.begin(), poses.end(),
                                 [&](const Pose& p) { return p.placement == placement; });
    if (n < kMinimumPosesPerPlacement)
      throw InputError("placement " + std::to_string(placement) + " has " + std::to_string(n) +
                       " pose" + (n == 1 ? "" : "s") + "; each placement's centre needs at least " +
                       std::to_string(kMinimumPosesPerPlacement));
  }
}

}  // namespace

Eigen::MatrixXd placementModelCovariance(const CellModel& cell, const std::vector<Pose>& used,
                                         const PlacementLayout& layout, const BaseParameters& base,
                                         const Eigen::MatrixXd& jac,
                                         const Eigen::MatrixXd& unit_cov,
                                         const ModelTolerances& model) {
  const int unknowns = layout.unknownCount();
  const bool count_sag =
      layout.compliance == 0 && anyCounted(model.sag_deg) && cell.robot.hasGravityModel();
  std::vector<Eigen::VectorXd> columns;
  std::vector<double> tolerances;
  // Each link error the poses do not identify, to its one sigma (a calibrated model's: its
  // covariance's diagonal; its correlations are left out here, the poses re-identify the rest).
  const Eigen::VectorXd link_sigma = model.linkSigmas();
  if (model.linksCounted())
    for (int k = PlacementLayout::firstLink(); k < PlacementLayout::firstCompliance(); ++k)
      if (!base.identified[k]) {
        columns.push_back(jac.col(k));
        tolerances.push_back(link_sigma[k - PlacementLayout::firstLink()]);
      }
  if (count_sag) {
    // Per rad of sag at the largest torque: delta2's and delta3's columns times each pose's
    // torque over the largest, drawn together with the sags' second moment.
    const auto bound = gravityTorqueBoundKnm(cell.robot, cell.robot.masses);
    Eigen::MatrixXd per_sag = jac.leftCols(kComplianceCount);  // delta2, delta3
    for (int c = 0; c < kComplianceCount; ++c)
      for (std::size_t i = 0; i < used.size(); ++i)
        per_sag.col(c).segment<2>(2 * static_cast<Eigen::Index>(i)) *=
            gravityTorqueKnm(cell.robot, cell.robot.masses, used[i].q_deg)[c] / bound[c];
    const Eigen::MatrixXd drawn = per_sag * (model.sagRootDeg() * kDegToRad);
    for (int c = 0; c < kComplianceCount; ++c) {
      columns.push_back(drawn.col(c));
      tolerances.push_back(1.0);
    }
  }
  if (columns.empty()) return Eigen::MatrixXd::Zero(unknowns, unknowns);
  Eigen::MatrixXd g(jac.rows(), static_cast<Eigen::Index>(columns.size()));
  for (std::size_t j = 0; j < columns.size(); ++j)
    g.col(static_cast<Eigen::Index>(j)) = columns[j] * tolerances[j];
  const Eigen::MatrixXd s_matrix = unit_cov * jac.transpose() * g;
  return s_matrix * s_matrix.transpose();
}

// The covariance of a calibrated model's link errors (what it holds less the truth): an
// identified error's estimate carries its covariance `cov` (noise and what is held at nominal);
// one the poses do not identify stays at nominal, known to the model's sigma s_u, and the
// estimates that absorbed it moved by S_u = unit_cov J^T J_u per unit of it, so that each is
// correlated with it by -S_u s_u^2. (A given model's own correlations and the sag's are left
// out: the diagonal of what the model admitted.)
Eigen::MatrixXd calibratedLinkCovariance(const PlacementLayout& layout, const BaseParameters& base,
                                         const Eigen::MatrixXd& jac,
                                         const Eigen::MatrixXd& unit_cov,
                                         const Eigen::MatrixXd& cov, const ModelTolerances& model) {
  const int first = PlacementLayout::firstLink();
  const Eigen::VectorXd sigma = model.linkSigmas();
  Eigen::MatrixXd p = Eigen::MatrixXd::Zero(kLinkParameterCount, kLinkParameterCount);
  for (int a = 0; a < kLinkParameterCount; ++a)
    for (int b = 0; b < kLinkParameterCount; ++b)
      if (base.identified[first + a] && base.identified[first + b])
        p(a, b) = cov(first + a, first + b);
  for (int u = 0; u < kLinkParameterCount; ++u) {
    if (base.identified[first + u]) continue;
    const double variance = sigma[u] * sigma[u];
    p(u, u) = variance;
    const Eigen::VectorXd moved = unit_cov * jac.transpose() * jac.col(first + u);
    for (int i = 0; i < kLinkParameterCount; ++i)
      if (base.identified[first + i]) p(i, u) = p(u, i) = -moved[first + i] * variance;
  }
  return p;
}

SolveReport solveMultiPlacement(const CellModel& cell, const std::vector<Pose>& poses,
                                const SolveOptions& options) {
  const auto started = std::chrono::steady_clock::now();
  const PlacementLayout layout(poses, cell.robot, options.identify_compliance);
  checkPlacements(poses, layout, options);
  const int n = static_cast<int>(poses.size());
  SolveReport report = startReport(cell, poses, options);
  const bool readings = report.used_readings;
  report.model_length_mm = options.model.length_mm;
  report.model_angle_deg = options.model.angle_deg;
  report.model_calibrated = options.model.calibrated();

  const std::vector<int> duplicate_of = findDuplicates(poses);
  std::vector<int> active;
  for (int i = 0; i < n; ++i)
    if (duplicate_of[i] < 0) active.push_back(i);
  throwUnlessEnoughDistinct(poses, duplicate_of, static_cast<int>(active.size()));
  const std::vector<Pose> distinct = subset(poses, active);

  // Start: zero offsets and link errors, nominal laser, each centre where its nominal lines
  // pass closest. The base parameters are found there: which unknowns the poses can separate
  // is a property of the poses, not of small changes of the parameters.
  CalibrationParameters start;
  const std::vector<Eigen::Vector3d> start_targets =
      placementTargets(cell, distinct, layout, start, readings);
  const BaseParameters base = analyseBaseParameters(
      placementJacobian(cell, onTheirCentres(cell, distinct, layout, start_targets), layout, start,
                        start_targets, 1.0, false),
      layout);
  std::vector<MultiFit> fits{
      fit(cell, distinct, layout, base, options, readings, start, start_targets)};
  int iterations = fits[0].iterations;

  // Gross errors: the single-placement solve's deletion diagnostics, on the identified unknowns.
  const auto describe = [&](const std::vector<int>& subset_of, int handle) {
    const MultiFit& mf = fits[handle];
    const std::vector<Pose> chosen = subset(poses, subset_of);
    TrialFit t;
    t.converged = mf.converged;
    t.iterations = mf.iterations;
    t.estimate = handle;
    const Eigen::MatrixXd full =
        placementJacobian(cell, chosen, layout, mf.est, mf.targets, 1.0, readings, &t.misses_mm);
    t.jacobian_mm = identifiedColumns(full, base);
    for (const Pose& p : chosen) {
      const Line l = laserLine(cell, p.q_deg, mf.est);
      t.beam_points_away = t.beam_points_away ||
                           !(l.direction.dot(mf.targets[layout.slot(p.placement)] - l.point) > 0);
    }
    return t;
  };
  const auto refit = [&](const std::vector<int>& subset_of, int from) {
    const MultiFit start_fit = fits[from];
    fits.push_back(fit(cell, subset(poses, subset_of), layout, base, options, readings,
                       start_fit.est, start_fit.targets));
    return describe(subset_of, static_cast<int>(fits.size()) - 1);
  };
  // Each placement's centre needs its poses.
  const auto cannotLeaveOut = [&](const std::vector<int>& remaining, int i) {
    const int placement = poses[i].placement;
    const auto left = std::count_if(remaining.begin(), remaining.end(),
                                    [&](int k) { return poses[k].placement == placement; });
    return left < kMinimumPosesPerPlacement
               ? "placement " + std::to_string(placement) + " would keep only " +
                     std::to_string(left) + " poses, too few for its centre"
               : std::string();
  };
  std::vector<int> left_out;
  std::vector<std::string> gross_problems;
  int chosen_fit = 0;
  if (options.find_gross_errors && fits[0].converged) {
    const GrossErrorSearch g =
        findGrossErrors(poses, active, describe(active, 0), options, refit, cannotLeaveOut);
    iterations += g.iterations;
    active = g.active;
    left_out = g.left_out;
    gross_problems = g.problems;
    report.suspect_poses = g.suspects;
    report.remeasure = g.remeasure;
    chosen_fit = g.fit.estimate;
  }
  const MultiFit& f = fits[chosen_fit];
  const std::vector<Pose> used = subset(poses, active);
  const int m = static_cast<int>(used.size());
  report.poses_used = m;
  report.converged = f.converged;
  report.message = f.message;
  report.iterations = iterations;
  report.estimate = f.est;
  report.estimate.target_mm = f.targets[0];

  Eigen::VectorXd r_used;
  const Eigen::MatrixXd jac =
      placementJacobian(cell, used, layout, f.est, f.targets, 1.0, readings, &r_used);
  report.rank = base.count;
  report.dof = 2 * m - base.count;
  applyNoise(report, options, r_used.squaredNorm());
  const double sigma = report.noise_mm;
  Eigen::MatrixXd cov = baseCovariance(jac, base, &report.condition_number) * sigma * sigma;

  // The link errors the poses cannot identify are held at nominal; known to the tolerances,
  // their effect on the identified unknowns is a consider covariance (as with one placement).
  // An error combined only with the laser or a centre moves nothing else: its part is zero.
  // The gravity sag, when its compliance is not identified, counts the same way: theta_j moves
  // by c_j tau_j(q), so its column is delta_j's times the pose's torque, and c_j is known to the
  // sag tolerance at the largest torque.
  const bool count_sag =
      layout.compliance == 0 && anyCounted(options.model.sag_deg) && cell.robot.hasGravityModel();
  if (count_sag) {
    report.model_sag_deg = options.model.sag_deg;
    report.model_sag_mean_deg = options.model.sag_mean_deg;
  }
  const Eigen::MatrixXd unit_cov =
      (cov / (sigma * sigma)).unaryExpr([](double x) { return std::isfinite(x) ? x : 0.0; });
  const Eigen::MatrixXd model_cov =
      placementModelCovariance(cell, used, layout, base, jac, unit_cov, options.model);
  cov += model_cov;
  report.link_covariance =
      calibratedLinkCovariance(layout, base, jac, unit_cov, cov, options.model);

  const double quantile = intervalQuantile(report);
  report.not_identifiable.push_back({"delta1_deg", delta1Reason()});
  report.not_identifiable.push_back({"delta6_deg", delta6Reason()});
  // Reported in degrees: the offsets, the link twists, the compliance (deg per kN m).
  const auto unitOf = [&](int k) {
    const bool angle = k < kOffsetCount || layout.isCompliance(k) ||
                       (layout.isLink(k) && (k - PlacementLayout::firstLink()) % 3 == 2);
    return angle ? kRadToDeg : 1.0;
  };
  const auto value = [&](int k) {
    if (k < kOffsetCount) return f.est.delta_rad[k];
    if (k < kIdentifiedCount) return f.est.laser[k - kOffsetCount];
    if (layout.isLink(k)) return f.est.link[k - PlacementLayout::firstLink()];
    return f.est.compliance[k - PlacementLayout::firstCompliance()];
  };
  for (int k = 0; k < layout.firstTarget(); ++k) {
    ParameterEstimate pe;
    pe.name = layout.name(k);
    pe.identifiable = base.identified[k];
    pe.reason = base.reason[k];
    const double unit = unitOf(k);
    pe.value = value(k) * unit;
    pe.sigma = std::sqrt(cov(k, k)) * unit;
    pe.model_sigma = std::sqrt(model_cov(k, k)) * unit;
    if (k < kOffsetCount && pe.identifiable && !(pe.sigma <= options.required_accuracy_deg)) {
      pe.identifiable = false;
      pe.reason = "known only to " + fixedText(pe.sigma, 4) + " deg (one standard deviation" +
                  (pe.model_sigma > 0 ? ", " + fixedText(pe.model_sigma, 4) +
                                            " deg of it from the tolerances of what the "
                                            "poses do not identify"
                                      : std::string()) +
                  "); the required accuracy is " + fixedText(options.required_accuracy_deg, 4) +
                  " deg";
    }
    pe.ci95_low = pe.value - quantile * pe.sigma;
    pe.ci95_high = pe.value + quantile * pe.sigma;
    if (!pe.identifiable) report.not_identifiable.push_back({pe.name, pe.reason});
    report.parameters.push_back(pe);
  }
  for (int p = 0; p < layout.count(); ++p) {
    SolveReport::PlacementCentre c;
    c.placement = layout.placements[p];
    c.poses = static_cast<int>(std::count_if(
        poses.begin(), poses.end(), [&](const Pose& q) { return q.placement == c.placement; }));
    c.target_mm = f.targets[p];
    for (int a = 0; a < kTargetCount; ++a) {
      const int k = layout.firstTarget() + kTargetCount * p + a;
      c.target_sigma_mm[a] = std::sqrt(cov(k, k));
      if (!base.identified[k]) report.not_identifiable.push_back({layout.name(k), base.reason[k]});
    }
    report.placements.push_back(c);
  }
  report.target_sigma_mm = report.placements.front().target_sigma_mm;
  report.correlation.resize(kIdentifiedCount, kIdentifiedCount);
  for (int a = 0; a < kIdentifiedCount; ++a)
    for (int b = 0; b < kIdentifiedCount; ++b)
      report.correlation(a, b) = cov(a, b) / std::sqrt(cov(a, a) * cov(b, b));

  // Every given pose's miss and stand-off at the result (duplicates included).
  Eigen::VectorXd r_all, r_at_detector;
  placementJacobian(cell, poses, layout, f.est, f.targets, 1.0, readings, &r_all);
  placementJacobian(atDetector(cell), poses, layout, f.est, f.targets, 1.0, readings,
                    &r_at_detector);
  double rss = 0;
  for (int i = 0; i < n; ++i) {
    PoseResidual pr;
    pr.source_line = poses[i].source_line;
    pr.miss_mm = r_at_detector.segment<2>(2 * i);
    pr.miss_norm_mm = pr.miss_mm.norm();
    // In the given noise, not scaled by the fit's misfit (the estimated one when none is given).
    pr.normalised = r_all.segment<2>(2 * i).norm() / (options.noise_mm ? *options.noise_mm : sigma);
    pr.used = std::binary_search(active.begin(), active.end(), i);
    pr.outlier = std::find(left_out.begin(), left_out.end(), i) != left_out.end();
    pr.duplicate_of = duplicate_of[i] + 1;
    const Line l = laserLine(cell, poses[i].q_deg, f.est);
    pr.standoff_mm = l.direction.dot(f.targets[layout.slot(poses[i].placement)] - l.point);
    if (pr.used) rss += pr.miss_mm.squaredNorm();
    report.poses.push_back(pr);
  }
  report.rms_miss_mm = std::sqrt(rss / m);
  const double unit = options.noise_mm ? *options.noise_mm : sigma;
  for (SuspectPose& sp : report.suspect_poses) sp.chi2_without /= unit * unit;
  for (int i = 0; i < n; ++i)
    if (duplicate_of[i] >= 0)
      report.suspect_poses.push_back(
          {i + 1, poses[i].source_line,
           "repeats " + poseLabel(poses, duplicate_of[i]) +
               " exactly (the same joints, reading and placement): one measurement, counted once",
           report.chi2_per_dof.value_or(1.0)});
  report.verdict = judge(report, options, gross_problems);
  report.solve_time_ms =
      std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - started).count();
  return report;
}

}  // namespace zerocal::detail
