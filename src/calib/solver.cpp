#include "zerocal/calib/solver.h"

#include <fmt/format.h>

#include <Eigen/Eigenvalues>
#include <Eigen/SVD>
#include <algorithm>
#include <boost/math/distributions/chi_squared.hpp>
#include <boost/math/distributions/fisher_f.hpp>
#include <boost/math/distributions/students_t.hpp>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <limits>
#include <memory>

#include "costs.h"
#include "solver_detail.h"
#include "zerocal/calib/identifiability.h"
#include "zerocal/error.h"
#include "zerocal/model/gravity.h"

namespace zerocal {
using detail::subset;

void checkPoses(const CellModel& cell, const std::vector<Pose>& poses) {
  if (poses.size() < static_cast<std::size_t>(kMinimumPoses))
    throw InputError(std::to_string(poses.size()) + " poses given; identifying " +
                     std::to_string(kIdentifiedCount) +
                     " parameters and the target point needs at least " +
                     std::to_string(kMinimumPoses) + " (use 8 or more)");
  checkJointLimits(cell, poses);
}

void checkJointLimits(const CellModel& cell, const std::vector<Pose>& poses) {
  for (std::size_t i = 0; i < poses.size(); ++i) {
    const std::string v = cell.robot.limitViolation(poses[i].q_deg);
    if (!v.empty())
      throw InputError("pose " + std::to_string(i + 1) +
                       (poses[i].source_line
                            ? " (line " + std::to_string(poses[i].source_line) + ")"
                            : std::string()) +
                       ": " + v + " of " + cell.robot.name);
  }
}

namespace {

void checkInput(const CellModel& cell, const std::vector<Pose>& poses,
                const SolveOptions& options) {
  if (const std::string problem = options.validate(); !problem.empty())
    throw InputError("solve options: " + problem);
  checkPoses(cell, poses);
}

// Where the lines cross best: the start for the target, and the pairwise cost's target.
Eigen::Vector3d bestTarget(const CellModel& cell, const std::vector<Pose>& poses,
                           const CalibrationParameters& params, bool use_readings) {
  std::vector<Line> lines;
  for (const auto& pose : poses) {
    Line l = laserLine(cell, pose.q_deg, params);
    l.point -= hitPointOffset(cell, pose, use_readings);
    lines.push_back(l);
  }
  return closestPointToLines(lines);
}

// First-order covariance of the pairwise estimator (which has no likelihood of its own): the
// estimate moves with the measurements as d(theta) = -(Jt^T Jt)^+ Jt^T Jm dm, where dm are the
// lines' perpendicular misses (sigma each), so Cov = sigma^2 A A^T.
Eigen::MatrixXd pairwiseCovariance(const CellModel& cell, const std::vector<Pose>& poses,
                                   const CalibrationParameters& est, double sigma) {
  const int n = static_cast<int>(poses.size());
  std::vector<Eigen::Vector3d> p(n), d(n), b1(n), b2(n);
  for (int i = 0; i < n; ++i) {
    const Line l = laserLine(cell, poses[i].q_deg, est);
    p[i] = l.point;
    d[i] = l.direction;
    b1[i] = d[i].unitOrthogonal();
    b2[i] = d[i].cross(b1[i]);
  }
  std::unique_ptr<ceres::CostFunction> cost(PairwiseCost::create(cell, poses, 1.0));
  const int m = cost->num_residuals();
  Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor> jd(m, kOffsetCount),
      jl(m, kLaserParamCount);
  Eigen::VectorXd r(m);
  const double* blocks[2] = {est.delta_rad.data(), est.laser.data()};
  double* jacs[2] = {jd.data(), jl.data()};
  cost->Evaluate(blocks, r.data(), jacs);
  Eigen::MatrixXd jt(m, kIdentifiedCount);
  jt << jd, jl;
  Eigen::MatrixXd jm(m, 2 * n);
  const double h = 1e-4;  // mm: central differences are exact to O(h^2) for this smooth map
  for (int i = 0; i < n; ++i)
    for (int a = 0; a < 2; ++a) {
      const Eigen::Vector3d shift = (a == 0 ? b1[i] : b2[i]) * h;
      Eigen::VectorXd plus(m), minus(m);
      auto q = p;
      q[i] = p[i] + shift;
      PairwiseCost::midpointResiduals(q, d, 1.0, plus.data());
      q[i] = p[i] - shift;
      PairwiseCost::midpointResiduals(q, d, 1.0, minus.data());
      jm.col(2 * i + a) = (plus - minus) / (2 * h);
    }
  const Eigen::MatrixXd info = jt.transpose() * jt;
  const Eigen::MatrixXd a =
      -info.completeOrthogonalDecomposition().pseudoInverse() * jt.transpose() * jm;
  return sigma * sigma * a * a.transpose();
}

}  // namespace

std::string SolveOptions::validate() const {
  if (noise_mm && !(std::isfinite(*noise_mm) && *noise_mm > 0))
    return "the noise level must be a positive number of mm";
  if (!(loss_scale_sigmas > 0)) return "the robust loss scale must be positive";
  if (!(model.length_mm >= 0 && model.length_mm <= 10 && model.angle_deg >= 0 &&
        model.angle_deg <= 1))
    return "the link tolerances must be 0..10 mm and 0..1 deg";
  for (const double sag : model.sag_deg)
    if (!(sag >= 0 && sag <= 1)) return "the sag tolerances must be 0..1 deg";
  for (int c = 0; c < kComplianceCount; ++c)
    if (!(model.sag_mean_deg[c] >= 0 && model.sag_mean_deg[c] <= model.sag_deg[c]))
      return "each sag's mean must lie within 0..its tolerance (a mean cannot exceed its RMS)";
  if (model.calibrated() &&
      (model.link_covariance.rows() != kLinkParameterCount ||
       model.link_covariance.cols() != kLinkParameterCount || !model.link_covariance.allFinite()))
    return "the link covariance must be a finite 18 x 18 matrix";
  if (loss != RobustLoss::kNone && !noise_mm)
    return "a robust loss needs the noise level (--noise), to know what counts as large";
  if (max_iterations < 1) return "max_iterations must be at least 1";
  if (!(required_accuracy_deg > 0 && std::isfinite(required_accuracy_deg)))
    return "the required accuracy must be a positive number of degrees";
  if (!(max_offset_deg > 0)) return "the plausible offset bound must be positive";
  if (!(max_noise_scale >= 1)) return "the largest noise scale must be at least 1";
  if (!(gross_error_alpha > 0 && gross_error_alpha < 1))
    return "the gross-error test level must lie between 0 and 1";
  return {};
}

namespace {

struct Fit {
  CalibrationParameters est;
  bool converged = false;
  std::string message;
  int iterations = 0;
};

// The robust loss of the options, in noise sigmas; null for none.
std::unique_ptr<ceres::LossFunction> makeLoss(const SolveOptions& options) {
  switch (options.loss) {
    case RobustLoss::kHuber:
      return std::make_unique<ceres::HuberLoss>(options.loss_scale_sigmas);
    case RobustLoss::kCauchy:
      return std::make_unique<ceres::CauchyLoss>(options.loss_scale_sigmas);
    case RobustLoss::kNone:
      break;
  }
  return nullptr;
}

// One Ceres solve on the given poses from `start`.
Fit runFit(const CellModel& cell, const std::vector<Pose>& poses, const SolveOptions& options,
           bool readings, const CalibrationParameters& start) {
  Fit fit;
  fit.est = start;
  CalibrationParameters& est = fit.est;
  const double sigma_in = options.noise_mm.value_or(1.0);
  ceres::Problem::Options problem_options;
  problem_options.cost_function_ownership = ceres::TAKE_OWNERSHIP;
  ceres::Problem problem(problem_options);
  if (options.cost == CostKind::kMaximumLikelihood) {
    for (const auto& pose : poses)
      problem.AddResidualBlock(
          PointToLineCost::create(cell, pose.q_deg, hitPointOffset(cell, pose, readings), sigma_in,
                                  missWeight(cell, pose, start, readings)),
          makeLoss(options).release(), est.delta_rad.data(), est.laser.data(),
          est.target_mm.data());
  } else {
    problem.AddResidualBlock(PairwiseCost::create(cell, poses, sigma_in), nullptr,
                             est.delta_rad.data(), est.laser.data());
  }

  detail::CancelCallback cancel(options.cancelled);
  const ceres::Solver::Options solver_options = detail::solverOptions(options, &cancel);
  ceres::Solver::Summary summary;
  ceres::Solve(solver_options, &problem, &summary);
  fit.converged = summary.termination_type == ceres::CONVERGENCE;
  fit.message = summary.termination_type == ceres::USER_FAILURE ? "cancelled" : summary.message;
  fit.iterations = static_cast<int>(summary.iterations.size());
  if (options.cost == CostKind::kPairwise) est.target_mm = bestTarget(cell, poses, est, readings);
  return fit;
}

// The line's miss of each pose's hit point, mm: 2 per pose, weighed by each pose's missWeight.
Eigen::VectorXd misses(const CellModel& cell, const std::vector<Pose>& poses,
                       const CalibrationParameters& est, bool readings) {
  Eigen::VectorXd r(2 * poses.size());
  for (std::size_t i = 0; i < poses.size(); ++i) {
    PointToLineCost functor(cell, poses[i].q_deg, hitPointOffset(cell, poses[i], readings), 1.0,
                            missWeight(cell, poses[i], est, readings));
    functor(est.delta_rad.data(), est.laser.data(), est.target_mm.data(), r.data() + 2 * i);
  }
  return r;
}

// Deletion diagnostics, to first order: how much the sum of squared misses drops when pose i is
// given a free shift of its own (which is leaving it out), D_i = r_i^T (I - H_ii)^-1 r_i with H
// the hat matrix of the (column-scaled) Jacobian. NaN where the pose cannot be checked: the others
// do not determine what it measures (I - H_ii singular).
//
// When the model is known only to a tolerance (`spread_mm`: the misses' derivatives by the link
// parameters times their tolerances, 2 rows per pose), the link errors leave misses at every pose
// that are larger than the noise and correlated from pose to pose, and a pose would be blamed for
// what the arm's geometry does at all of them. The test is then the generalised one: misses and
// Jacobian weighed by W with W^T W = (I + spread spread^T / sigma0^2)^-1, and pose i's shift a
// column pair of W. What the tolerances can explain across the poses no longer counts against one
// pose; what sets one pose apart still does. The sums stay in mm^2 at the noise sigma0.
struct Deletion {
  std::vector<double> drop_mm2;
  double rss_mm2 = 0;  // weighted, at the weighted fit
  int rank = 0;
};
Deletion deletionDrops(const Eigen::MatrixXd& jac_mm, const Eigen::VectorXd& r,
                       const Eigen::MatrixXd& spread_mm, double sigma0_mm) {
  const int rows = static_cast<int>(jac_mm.rows());
  const int m = rows / 2;
  const bool weighed = spread_mm.cols() > 0 && sigma0_mm > 0;
  Eigen::MatrixXd w = Eigen::MatrixXd::Identity(rows, rows);
  if (weighed) {
    const Eigen::MatrixXd cov = Eigen::MatrixXd::Identity(rows, rows) +
                                spread_mm * spread_mm.transpose() / (sigma0_mm * sigma0_mm);
    w = cov.llt().matrixL().solve(Eigen::MatrixXd::Identity(rows, rows));
  }
  const Eigen::MatrixXd jw = weighed ? Eigen::MatrixXd(w * jac_mm) : jac_mm;
  Eigen::VectorXd scale = jw.colwise().norm().transpose();
  for (int k = 0; k < scale.size(); ++k)
    if (!(scale[k] > 0)) scale[k] = 1;
  const Eigen::MatrixXd scaled = jw * scale.cwiseInverse().asDiagonal();
  Eigen::BDCSVD<Eigen::MatrixXd> svd(scaled, Eigen::ComputeThinU);
  const Eigen::VectorXd s = svd.singularValues();
  Deletion out;
  for (int i = 0; i < s.size(); ++i) out.rank += s[i] > 1e-8 * std::max(s[0], 1e-300) ? 1 : 0;
  const Eigen::MatrixXd u = svd.matrixU().leftCols(out.rank);
  // The weighted fit's misses (r is the unweighted fit's; to first order the weighted fit moves
  // them by the projection), and each pose's shift columns with the fit projected out.
  const Eigen::VectorXd rw = weighed ? Eigen::VectorXd(w * r) : r;
  const Eigen::VectorXd e = weighed ? Eigen::VectorXd(rw - u * (u.transpose() * rw)) : r;
  out.rss_mm2 = e.squaredNorm();
  const Eigen::MatrixXd free_w = w - u * (u.transpose() * w);
  for (int i = 0; i < m; ++i) {
    const Eigen::Matrix2d c2 = w.middleCols(2 * i, 2).transpose() * w.middleCols(2 * i, 2);
    const Eigen::Matrix2d free =
        free_w.middleCols(2 * i, 2).transpose() * free_w.middleCols(2 * i, 2);
    const Eigen::SelfAdjointEigenSolver<Eigen::Matrix2d> eig(free);
    const Eigen::Vector2d b = weighed ? Eigen::Vector2d(free_w.middleCols(2 * i, 2).transpose() * e)
                                      : Eigen::Vector2d(r.segment<2>(2 * i));
    out.drop_mm2.push_back(eig.eigenvalues().minCoeff() < 1e-6 * c2.diagonal().maxCoeff()
                               ? std::numeric_limits<double>::quiet_NaN()
                               : b.dot(free.ldlt().solve(b)));
  }
  return out;
}

std::string poseName(const std::vector<Pose>& poses, int i) {
  return "pose " + std::to_string(i + 1) +
         (poses[i].source_line ? " (line " + std::to_string(poses[i].source_line) + ")"
                               : std::string());
}

std::string fixed(double v, int precision) {
  return fmt::format(FMT_STRING("{:.{}f}"), v, precision);
}

std::string general(double v) { return fmt::format(FMT_STRING("{:.2g}"), v); }

// One round of the deletion test on a fit: its misses (mm, 2 per pose) and their Jacobian.
struct DeletionTest {
  bool checkable = false;         // enough redundancy to test at all
  int best = -1, runner_up = -1;  // positions in the fitted poses, by decreasing statistic
  std::vector<double> ratio;      // statistic over its threshold, per fitted pose (NaN: unchecked)
  double rss_mm2 = 0;
  int dof = 0;
};
DeletionTest deletionTest(const detail::TrialFit& fit, const SolveOptions& options) {
  DeletionTest t;
  const Deletion d =
      deletionDrops(fit.jacobian_mm, fit.misses_mm, fit.spread_mm, options.noise_mm.value_or(0.0));
  const Eigen::VectorXd& r = fit.misses_mm;
  t.rss_mm2 = d.rss_mm2;
  t.dof = static_cast<int>(r.size()) - d.rank;
  const int rest_dof = t.dof - 2;  // of the fit without one pose
  if (rest_dof < 1) return t;
  int checked = 0;
  for (double x : d.drop_mm2) checked += std::isfinite(x) ? 1 : 0;
  if (checked == 0) return t;
  t.checkable = true;
  const double level = 1 - options.gross_error_alpha / checked;  // family-wise (Bonferroni)
  // With the noise given it is a floor: misses that the rest of the poses share (model error)
  // raise it, so that only what sets one pose apart from the others counts.
  const double threshold =
      options.noise_mm ? boost::math::quantile(boost::math::chi_squared(2), level)
                       : 2 * boost::math::quantile(boost::math::fisher_f(2, rest_dof), level);
  const double floor_mm2 = options.noise_mm ? *options.noise_mm * *options.noise_mm : 1e-12;
  double best = -1, second = -1;
  for (std::size_t i = 0; i < d.drop_mm2.size(); ++i) {
    const double drop = d.drop_mm2[i];
    if (!std::isfinite(drop)) {
      t.ratio.push_back(std::numeric_limits<double>::quiet_NaN());
      continue;
    }
    const double rest_var = std::max((t.rss_mm2 - drop) / rest_dof, floor_mm2);
    const double ratio = drop / rest_var / threshold;
    t.ratio.push_back(ratio);
    if (ratio > best) {
      second = best, t.runner_up = t.best;
      best = ratio, t.best = static_cast<int>(i);
    } else if (ratio > second) {
      second = ratio, t.runner_up = static_cast<int>(i);
    }
  }
  return t;
}

bool significant(const DeletionTest& t, int i) { return t.checkable && i >= 0 && t.ratio[i] > 1; }

}  // namespace

namespace detail {

Eigen::MatrixXd linkSpread(const CellModel& cell, const std::vector<Pose>& poses,
                           const CalibrationParameters& est, bool readings,
                           const ModelTolerances& tolerances) {
  const Eigen::VectorXd r0 = misses(cell, poses, est, readings);
  const bool with_sag = anyCounted(tolerances.sag_deg) && cell.robot.hasGravityModel();
  // The misses' derivatives by each link parameter (mm per mm, mm per rad).
  Eigen::MatrixXd unit(r0.size(), kLinkParameterCount);
  for (int j = 0; j < kJointCount; ++j)
    for (int kind = 0; kind < 3; ++kind) {
      CellModel perturbed = cell;
      DhRow& row = perturbed.robot.dh[j];
      const double h = kind == 2 ? 1e-6 : 1e-3;  // rad, mm
      (kind == 0 ? row.a_mm : kind == 1 ? row.d_mm : row.alpha_rad) += h;
      unit.col(3 * j + kind) = (misses(perturbed, poses, est, readings) - r0) / h;
    }
  Eigen::MatrixXd g(r0.size(), kLinkParameterCount + (with_sag ? kComplianceCount : 0));
  if (tolerances.calibrated()) {
    // A calibrated model's link errors are correlated (each identified combination is known far
    // better than its parts): one standard deviation of their joint spread is the covariance's
    // square root, whose columns are independent unit draws.
    const Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> eigen(tolerances.link_covariance);
    g.leftCols(kLinkParameterCount) =
        unit * eigen.eigenvectors() * eigen.eigenvalues().cwiseMax(0.0).cwiseSqrt().asDiagonal();
  } else {
    g.leftCols(kLinkParameterCount) = unit * tolerances.linkSigmas().asDiagonal();
  }
  if (with_sag) {
    // The sag of joints 2 and 3 turns the joint by c_j tau_j(q): at each pose what a change of
    // that joint's offset does, times the pose's torque over the largest (the misses per rad of
    // sag at the largest torque, as the several-placement solve counts it, docs/maths.md section
    // 8), drawn with the two sags' second moment.
    const auto bound = gravityTorqueBoundKnm(cell.robot, cell.robot.masses);
    Eigen::MatrixXd per_sag(r0.size(), kComplianceCount);
    for (int c = 0; c < kComplianceCount; ++c) {
      CalibrationParameters turned = est;
      constexpr double h = 1e-6;  // rad
      turned.delta_rad[c] += h;
      per_sag.col(c) = (misses(cell, poses, turned, readings) - r0) / h;
      for (std::size_t i = 0; i < poses.size(); ++i)
        per_sag.col(c).segment<2>(2 * static_cast<Eigen::Index>(i)) *=
            gravityTorqueKnm(cell.robot, cell.robot.masses, poses[i].q_deg)[c] / bound[c];
    }
    g.rightCols(kComplianceCount) = per_sag * (tolerances.sagRootDeg() * kDegToRad);
  }
  return g;
}

Eigen::VectorXd poseMisses(const CellModel& cell, const std::vector<Pose>& poses,
                           const CalibrationParameters& est, bool readings) {
  return misses(cell, poses, est, readings);
}

ceres::Solver::Options solverOptions(const SolveOptions& options, CancelCallback* cancel) {
  ceres::Solver::Options o;
  o.linear_solver_type = ceres::DENSE_QR;
  o.max_num_iterations = options.max_iterations;
  o.function_tolerance = 1e-15;
  o.gradient_tolerance = 1e-15;
  o.parameter_tolerance = 1e-14;
  o.num_threads = 1;
  o.logging_type = ceres::SILENT;
  o.callbacks.push_back(cancel);
  return o;
}

Verdict judge(const SolveReport& r, const SolveOptions& o,
              const std::vector<std::string>& gross_problems, MissesAgainst against) {
  Verdict v;
  auto& why = v.reasons;
  if (!r.converged) why.push_back("the solve did not converge (" + r.message + ")");
  std::string behind;
  int behind_count = 0;
  for (std::size_t i = 0; i < r.poses.size(); ++i)
    if (r.poses[i].used && !(r.poses[i].standoff_mm > 0)) {
      if (behind_count++ < 8) behind += (behind.empty() ? "" : ", ") + std::to_string(i + 1);
    }
  if (behind_count > 0)
    why.push_back("the fitted beam points away from the PSD (stand-off <= 0) at " +
                  std::to_string(behind_count) + " of " + std::to_string(r.poses_used) +
                  " poses (" + behind + (behind_count > 8 ? ", ..." : "") +
                  "), which no real beam does: the nominal laser direction or the robot model is "
                  "wrong");
  for (int k = 0; k < kOffsetCount; ++k) {
    const ParameterEstimate& p = r.parameters[k];
    if (!p.identifiable) {
      why.push_back(p.name.substr(0, 6) + " is not determined: " + p.reason);
    } else if (!(std::abs(p.value) <= o.max_offset_deg)) {
      why.push_back(p.name.substr(0, 6) + " = " + fixed(p.value, 3) +
                    " deg lies beyond the plausible +-" + fixed(o.max_offset_deg, 1) +
                    " deg of a zero offset: the model (robot file, laser direction) is wrong, "
                    "not the zero");
    }
  }
  if (r.noise_scale > o.max_noise_scale && against == MissesAgainst::kReference) {
    // Against a reference the links cancel: what the misses exceed is the noise of two
    // sessions, and what breaks it is the cell not being as the reference had it.
    why.push_back("the re-measured poses disagree with the reference's by " +
                  fixed(r.noise_scale, 1) +
                  " times the given noise (chi-square per degree of "
                  "freedom " +
                  fixed(r.chi2_per_dof.value_or(0), 1) + ", largest believable " +
                  fixed(o.max_noise_scale * o.max_noise_scale, 0) +
                  "): the PSD or the laser has been moved or re-mounted since the reference, or "
                  "the arm has changed beyond its zeros (a collision); put them back as the "
                  "reference had them and measure again, or, when that cannot be, calibrate the "
                  "absolute zeros (several PSD placements)");
  } else if (r.noise_scale > o.max_noise_scale) {
    // With the link tolerances counted, what the misses exceed is the noise and the tolerated
    // link errors together: the next step is to calibrate the links, not to mistrust the cell.
    const bool links = o.model.linksCounted();
    why.push_back("the poses miss by " + fixed(r.noise_scale, 1) + " times the given noise" +
                  (links ? " and the robot file's link tolerances allow" : "") +
                  " (chi-square per degree of freedom " + fixed(r.chi2_per_dof.value_or(0), 1) +
                  ", largest believable " + fixed(o.max_noise_scale * o.max_noise_scale, 0) +
                  (links ? "): the noise is worse than stated, or the links are worse than the "
                           "robot file admits (calibrate them with several PSD placements)"
                         : "): the stated noise or the model is not the cell's"));
  }
  for (const std::string& g : gross_problems) why.push_back(g);
  v.usable = why.empty();
  return v;
}

GrossErrorSearch findGrossErrors(
    const std::vector<Pose>& poses, std::vector<int> active, TrialFit fit,
    const SolveOptions& options, const SubsetFitter& refit,
    const std::function<std::string(const std::vector<int>&, int)>& cannot_leave_out) {
  // Leave out, one at a time, the pose whose removal explains the most misfit, while it explains
  // more than chance and the rest keeps the redundancy to check it.
  GrossErrorSearch g;
  constexpr int kMostLeftOut = 2;
  while (fit.converged) {
    // A beam fitted pointing away from the PSD is a wrong model at every pose, not one bad pose.
    if (fit.beam_points_away) break;
    const DeletionTest t = deletionTest(fit, options);
    if (!significant(t, t.best)) break;
    const int worst = active[t.best];
    if (static_cast<int>(g.left_out.size()) == kMostLeftOut) {
      g.problems.push_back(poseName(poses, worst) + " does not fit either, after " +
                           std::to_string(kMostLeftOut) +
                           " poses were left out: the poses do not describe one cell (a "
                           "wrong model or a disturbed session), measure them again");
      g.remeasure.push_back(worst + 1);
      break;
    }
    // Leaving it out must keep a check on the rest: 2 (N-1) - unknowns >= 3.
    if (t.dof - 2 < 3) {
      g.problems.push_back(poseName(poses, worst) +
                           " does not fit the others, but there are too few poses to leave "
                           "it out and still check the rest: measure it again or add poses");
      g.remeasure.push_back(worst + 1);
      break;
    }
    std::vector<int> without = active;
    without.erase(without.begin() + t.best);
    if (cannot_leave_out) {
      const std::string why = cannot_leave_out(without, worst);
      if (!why.empty()) {
        g.problems.push_back(poseName(poses, worst) + " does not fit the others, but " + why +
                             ": measure it again or add poses");
        g.remeasure.push_back(worst + 1);
        break;
      }
    }
    const TrialFit next = refit(without, fit.estimate);
    g.iterations += next.iterations;
    if (!next.converged) break;
    // The same misfit may be explained by another pose: then the data cannot say which is wrong.
    if (significant(t, t.runner_up)) {
      std::vector<int> other = active;
      other.erase(other.begin() + t.runner_up);
      const bool possible =
          !cannot_leave_out || cannot_leave_out(other, active[t.runner_up]).empty();
      if (possible) {
        const TrialFit alt = refit(other, fit.estimate);
        g.iterations += alt.iterations;
        if (alt.converged) {
          const DeletionTest ta = deletionTest(alt, options);
          const int pos = t.best < t.runner_up ? t.best : t.best - 1;
          if (ta.checkable && !significant(ta, pos)) {
            g.problems.push_back(
                poseName(poses, worst) + " or " + poseName(poses, active[t.runner_up]) +
                " does not fit, and the poses cannot tell which: leaving out either one leaves a "
                "consistent set; measure both again or add poses");
            g.remeasure.push_back(worst + 1);
            g.remeasure.push_back(active[t.runner_up] + 1);
            break;
          }
        }
      }
    }
    const double rss_without = next.misses_mm.squaredNorm();
    const int dof_without = t.dof - 2;
    SuspectPose sp;
    sp.pose = worst + 1;
    sp.source_line = poses[worst].source_line;
    const double before = t.rss_mm2 / t.dof, after = rss_without / dof_without;
    sp.chi2_without = after;  // in mm^2: the caller rescales it to the noise in force
    sp.reason =
        "does not fit the other poses: leaving it out lowers the misfit (RMS miss per "
        "degree of freedom) from " +
        fixed(1e3 * std::sqrt(before), 1) + " to " + fixed(1e3 * std::sqrt(after), 1) +
        " um (test statistic " + fixed(t.ratio[t.best], 1) + " times its " +
        general(options.gross_error_alpha) + " family-wise threshold); left out of the result";
    g.suspects.push_back(sp);
    g.remeasure.push_back(worst + 1);
    g.left_out.push_back(worst);
    active = std::move(without);
    fit = next;
  }
  g.active = std::move(active);
  g.fit = std::move(fit);
  return g;
}

std::vector<Pose> subset(const std::vector<Pose>& poses, const std::vector<int>& indices) {
  std::vector<Pose> out;
  for (int i : indices) out.push_back(poses[i]);
  return out;
}

std::vector<int> findDuplicates(const std::vector<Pose>& poses) {
  const int n = static_cast<int>(poses.size());
  std::vector<int> duplicate_of(n, -1);
  for (int i = 0; i < n; ++i)
    for (int j = 0; j < i && duplicate_of[i] < 0; ++j)
      if (duplicate_of[j] < 0 && poses[i].q_deg == poses[j].q_deg &&
          poses[i].spot == poses[j].spot && poses[i].placement == poses[j].placement)
        duplicate_of[i] = j;
  return duplicate_of;
}

void throwUnlessEnoughDistinct(const std::vector<Pose>& poses, const std::vector<int>& duplicate_of,
                               int distinct) {
  if (distinct >= kMinimumPoses) return;
  int first = 0;
  while (first < static_cast<int>(poses.size()) && duplicate_of[first] < 0) ++first;
  throw InputError(std::to_string(poses.size()) + " poses given, but only " +
                   std::to_string(distinct) + " are distinct (" + poseName(poses, first) +
                   " repeats an earlier one exactly); the solve needs at least " +
                   std::to_string(kMinimumPoses) + " distinct poses");
}

// The chi-square test's level at which a per-pose noise model is taken as not the cell's.
constexpr double kNoiseModelRejectedP = 0.01;

void applyNoise(SolveReport& report, const SolveOptions& options, double rss_mm2) {
  if (options.noise_mm) {
    report.noise_mm = *options.noise_mm;
    if (report.dof > 0) {
      const double chi2 = rss_mm2 / (report.noise_mm * report.noise_mm);
      report.chi2_per_dof = chi2 / report.dof;
      report.chi2_p_value =
          boost::math::cdf(boost::math::complement(boost::math::chi_squared(report.dof), chi2));
      // The poses miss by more than the stated noise: the honest sigma is the one they show
      // (the Birge ratio). Never scaled down: a small chi-square with few poses is chance. A
      // per-pose model is the arm's own repeatability, not a guess of one sigma: a chi-square
      // above 1 is chance too (scaling by it would inflate every sigma by about 10% on 24
      // degrees of freedom), and only a misfit it cannot explain (p < 1%) scales it.
      const bool model_rejected =
          report.joint_repeatability_deg == 0 || *report.chi2_p_value < kNoiseModelRejectedP;
      report.noise_scale = model_rejected ? std::max(1.0, std::sqrt(*report.chi2_per_dof)) : 1.0;
      report.noise_mm *= report.noise_scale;
    }
  } else {
    report.noise_estimated = true;
    report.noise_mm =
        report.dof > 0 ? std::sqrt(rss_mm2 / report.dof) : std::numeric_limits<double>::quiet_NaN();
  }
}

double intervalQuantile(const SolveReport& report) {
  // Student's t whenever the sigma in force comes from the residuals (estimated, or scaled up).
  if ((report.noise_estimated || report.noise_scale > 1) && report.dof > 0)
    return boost::math::quantile(boost::math::students_t(report.dof), 0.975);
  return 1.959963984540054;
}

SolveReport startReport(const CellModel& cell, const std::vector<Pose>& poses,
                        const SolveOptions& options) {
  SolveReport report;
  report.cost = options.cost;
  report.used_readings = options.use_readings;
  for (const auto& p : poses) report.used_readings = report.used_readings && p.spot.has_value();
  report.pose_count = static_cast<int>(poses.size());
  report.required_accuracy_deg = options.required_accuracy_deg;
  report.joint_repeatability_deg = cell.noise.joint_repeatability_deg;
  return report;
}

std::string fixedText(double v, int precision) { return fixed(v, precision); }

std::string poseLabel(const std::vector<Pose>& poses, int i) { return poseName(poses, i); }

}  // namespace detail

SolveOptions withCellNoise(const CellModel& cell, SolveOptions options) {
  if (cell.noise.perPose()) options.noise_mm = cell.noise.referenceMm();
  return options;
}

SolveReport solve(const CellModel& cell, const std::vector<Pose>& poses,
                  const SolveOptions& given) {
  const SolveOptions options = withCellNoise(cell, given);
  checkInput(cell, poses, options);
  // Several placements keep one sigma for every pose: weighed per pose, their offsets came out
  // worse (30 realistic worlds: RMS 0.0026 -> 0.0031 deg, one delta2 withheld), the cause not
  // found yet (docs/maths.md section 8).
  if (placementCount(poses) > 1) return detail::solveMultiPlacement(atDetector(cell), poses, given);
  const auto start = std::chrono::steady_clock::now();
  const int n = static_cast<int>(poses.size());
  SolveReport report = detail::startReport(cell, poses, options);
  const bool readings = report.used_readings;

  // Exact duplicates (the same joints and reading) are one measurement recorded twice: counted
  // once, or they would claim information (and degrees of freedom) that was never measured.
  const std::vector<int> duplicate_of = detail::findDuplicates(poses);
  std::vector<int> active;
  for (int i = 0; i < n; ++i)
    if (duplicate_of[i] < 0) active.push_back(i);
  detail::throwUnlessEnoughDistinct(poses, duplicate_of, static_cast<int>(active.size()));

  // Start: zero offsets, nominal laser, the point the nominal lines pass closest to.
  CalibrationParameters nominal;
  nominal.target_mm = bestTarget(cell, subset(poses, active), nominal, readings);
  Fit fit = runFit(cell, subset(poses, active), options, readings, nominal);
  // Each pose's weight depends (a little) on where its line meets the detector: weighed at the
  // nominal start, the fit is repeated with the weights at its estimate.
  if (cell.noise.perPose() && fit.converged) {
    const int first_iterations = fit.iterations;
    fit = runFit(cell, subset(poses, active), options, readings, fit.est);
    fit.iterations += first_iterations;
  }

  // Gross errors: the deletion diagnostics on the maximum-likelihood fit.
  std::vector<CalibrationParameters> estimates;
  const auto describe = [&](const std::vector<int>& subset_of, const Fit& f) {
    const std::vector<Pose> chosen = subset(poses, subset_of);
    detail::TrialFit t;
    t.converged = f.converged;
    t.iterations = f.iterations;
    t.message = f.message;
    t.estimate = static_cast<int>(estimates.size());
    estimates.push_back(f.est);
    t.misses_mm = misses(cell, chosen, f.est, readings);
    t.jacobian_mm = pointToLineJacobian(cell, chosen, f.est, 1.0, readings);
    if (options.model.counted())
      t.spread_mm = detail::linkSpread(cell, chosen, f.est, readings, options.model);
    const auto s = standoffs(cell, chosen, f.est);
    t.beam_points_away = *std::min_element(s.begin(), s.end()) <= 0;
    return t;
  };
  const auto trial = [&](const std::vector<int>& subset_of, int start) {
    return describe(subset_of,
                    runFit(cell, subset(poses, subset_of), options, readings, estimates[start]));
  };
  std::vector<int> left_out;
  std::vector<std::string> gross_problems;
  int iterations = fit.iterations;
  const bool diagnose = options.find_gross_errors && options.cost == CostKind::kMaximumLikelihood &&
                        options.loss == RobustLoss::kNone;
  if (diagnose && fit.converged) {
    detail::TrialFit first = describe(active, fit);
    detail::GrossErrorSearch g = detail::findGrossErrors(poses, active, first, options, trial, {});
    iterations += g.iterations;
    active = g.active;
    left_out = g.left_out;
    gross_problems = g.problems;
    report.suspect_poses = g.suspects;
    report.remeasure = g.remeasure;
    fit.est = estimates[g.fit.estimate];
    fit.converged = g.fit.converged;
    fit.message = g.fit.message;
  }
  report.iterations = iterations;
  report.converged = fit.converged;
  report.message = fit.message;
  const CalibrationParameters est = fit.est;
  report.estimate = est;
  const std::vector<Pose> used = subset(poses, active);
  const int m = static_cast<int>(used.size());
  report.poses_used = m;

  // Residuals in mm (every given pose, at the result), noise level, identifiability, covariance.
  Eigen::MatrixXd jac_mm = pointToLineJacobian(cell, used, est, 1.0, readings);
  const Eigen::VectorXd r_all = misses(cell, poses, est, readings);
  const Eigen::VectorXd r_at_detector = misses(atDetector(cell), poses, est, readings);
  // A robust loss weighs each pose by rho'(s) at the solution (s: its squared miss in noise
  // sigmas, as Ceres sees it), which is how much it still pulls on the result. The covariance,
  // the chi-square and the degrees of freedom are those of that weighted fit, so that a pose the
  // loss has set aside no longer counts as information.
  std::vector<double> weight(n, 1.0);
  if (std::unique_ptr<ceres::LossFunction> loss = makeLoss(options)) {
    const double s2 = *options.noise_mm * *options.noise_mm;
    for (int k = 0; k < m; ++k) {
      double rho[3];
      loss->Evaluate(r_all.segment<2>(2 * active[k]).squaredNorm() / s2, rho);
      weight[active[k]] = rho[1];
      jac_mm.middleRows(2 * k, 2) *= std::sqrt(rho[1]);
    }
  }
  double rss = 0, weights = 0, unweighted_rss = 0;
  for (int i : active) {
    rss += weight[i] * r_all.segment<2>(2 * i).squaredNorm();
    unweighted_rss += r_at_detector.segment<2>(2 * i).squaredNorm();
    weights += weight[i];
  }
  for (int i = 0; i < n; ++i) {
    PoseResidual pr;
    pr.source_line = poses[i].source_line;
    pr.miss_mm = r_at_detector.segment<2>(2 * i);
    pr.miss_norm_mm = pr.miss_mm.norm();
    pr.used = std::binary_search(active.begin(), active.end(), i);
    pr.duplicate_of = duplicate_of[i] + 1;
    pr.outlier = std::find(left_out.begin(), left_out.end(), i) != left_out.end();
    report.poses.push_back(pr);
  }
  const auto stand = standoffs(cell, poses, est);
  Identifiability ident =
      analyseIdentifiability(jac_mm, cell, used, est, 1.0, options.required_accuracy_deg);
  report.rank = ident.rank;
  report.condition_number = ident.condition_number;
  report.dof = static_cast<int>(std::lround(2 * weights)) - ident.rank;
  report.rms_miss_mm = std::sqrt(unweighted_rss / m);
  // With the link tolerances counted, the misses the tolerated link errors explain are not noise:
  // the chi-square, and with it the Birge ratio and the noise gate, is that of the link-weighted
  // misses (W^T W = (I + G G^T / sigma^2)^-1, the deletion test's), so that the link misfit is
  // counted once, in the model part below, and not a second time in a scaled-up noise.
  const Eigen::MatrixXd spread = options.model.counted()
                                     ? detail::linkSpread(cell, used, est, readings, options.model)
                                     : Eigen::MatrixXd();
  const bool link_weighted = spread.cols() > 0 && options.noise_mm &&
                             options.loss == RobustLoss::kNone && jac_mm.rows() > 0;
  if (link_weighted) {
    Eigen::VectorXd r_used(2 * m);
    for (int k = 0; k < m; ++k) r_used.segment<2>(2 * k) = r_all.segment<2>(2 * active[k]);
    rss = deletionDrops(jac_mm, r_used, spread, *options.noise_mm).rss_mm2;
  }
  detail::applyNoise(report, options, rss);
  const double sigma = report.noise_mm;
  for (SuspectPose& sp : report.suspect_poses) {
    const double unit = options.noise_mm ? *options.noise_mm : sigma;
    sp.chi2_without /= unit * unit;
  }
  // Re-judge identifiability against the noise actually in force.
  ident = analyseIdentifiability(jac_mm, cell, used, est, sigma, options.required_accuracy_deg);
  Eigen::MatrixXd cov = sigma * sigma * ident.unit_covariance;
  if (options.cost == CostKind::kPairwise) {
    const Eigen::MatrixXd pc = pairwiseCovariance(cell, used, est, sigma);
    cov.topLeftCorner(kIdentifiedCount, kIdentifiedCount) = pc;
    for (int k = 0; k < kIdentifiedCount; ++k)
      if (!ident.identifiable[k]) cov.row(k).setConstant(NAN), cov.col(k).setConstant(NAN);
  }

  // The link lengths and twists are not identified but known only to a tolerance: each moves the
  // estimate by S = J^+ G (G: the misses' derivatives by that link parameter) whatever the number
  // of poses. Their consider covariance S diag(tolerance^2) S^T is added to the statistical one.
  Eigen::MatrixXd model_cov = Eigen::MatrixXd::Zero(kUnknownCount, kUnknownCount);
  report.model_length_mm = options.model.length_mm;
  report.model_angle_deg = options.model.angle_deg;
  report.model_calibrated = options.model.calibrated();
  if (spread.cols() > kLinkParameterCount) {  // counted: a gravity model
    report.model_sag_deg = options.model.sag_deg;
    report.model_sag_mean_deg = options.model.sag_mean_deg;
  }
  if (spread.cols() > 0) {
    // A parameter the poses do not determine has no covariance (NaN) and no model part either.
    const Eigen::MatrixXd u =
        ident.unit_covariance.unaryExpr([](double x) { return std::isfinite(x) ? x : 0.0; });
    const Eigen::MatrixXd s_matrix = u * jac_mm.transpose() * spread;
    if (s_matrix.allFinite()) {
      // The link-weighted chi-square tests noise and tolerated link errors together: when the
      // poses miss by more than both allow, both parts grow by the Birge ratio (the links may be
      // worse than their tolerance as well as the noise worse than given).
      const double scale2 = link_weighted ? report.noise_scale * report.noise_scale : 1.0;
      model_cov = scale2 * s_matrix * s_matrix.transpose();
      cov += model_cov;
    }
  }

  const double quantile = detail::intervalQuantile(report);

  report.not_identifiable.push_back({"delta1_deg", delta1Reason()});
  const Eigen::VectorXd values = [&] {
    Eigen::VectorXd v(kUnknownCount);
    v << est.delta_rad * kRadToDeg, est.laser, est.target_mm;
    return v;
  }();
  for (int k = 0; k < kIdentifiedCount; ++k) {
    ParameterEstimate pe;
    pe.name = unknownName(k);
    pe.identifiable = ident.identifiable[k];
    pe.reason = ident.reason[k];
    const double unit = k < kOffsetCount ? kRadToDeg : 1.0;
    pe.value = values[k];
    pe.sigma = std::sqrt(cov(k, k)) * unit;
    pe.model_sigma = std::sqrt(model_cov(k, k)) * unit;
    if (k < kOffsetCount && pe.identifiable && pe.model_sigma > 0 &&
        !(pe.sigma <= options.required_accuracy_deg)) {
      // Determined by the poses, but not to the accuracy the calibration is for once the
      // model's tolerance is counted.
      pe.identifiable = false;
      pe.reason = "known only to " + fixed(pe.sigma, 3) + " deg (one standard deviation), " +
                  fixed(pe.model_sigma, 3) +
                  " deg of it from the robot's link tolerances, which these poses cannot "
                  "separate from it; the required accuracy is " +
                  fixed(options.required_accuracy_deg, 3) + " deg";
    }
    pe.ci95_low = pe.value - quantile * pe.sigma;
    pe.ci95_high = pe.value + quantile * pe.sigma;
    if (!pe.identifiable) report.not_identifiable.push_back({pe.name, pe.reason});
    report.parameters.push_back(pe);
  }
  for (int k = kIdentifiedCount; k < kUnknownCount; ++k) {
    report.target_sigma_mm[k - kIdentifiedCount] = std::sqrt(cov(k, k));
    if (!ident.identifiable[k])
      report.not_identifiable.push_back({unknownName(k), ident.reason[k]});
  }
  report.not_identifiable.insert(report.not_identifiable.begin() + 1,
                                 {"delta6_deg", delta6Reason()});
  report.correlation.resize(kIdentifiedCount, kIdentifiedCount);
  for (int a = 0; a < kIdentifiedCount; ++a)
    for (int b = 0; b < kIdentifiedCount; ++b)
      report.correlation(a, b) = cov(a, b) / std::sqrt(cov(a, a) * cov(b, b));

  // Each pose's miss in what the model allows at it (a 2-D Mahalanobis distance): the given
  // noise, not scaled by the fit's misfit, so that misses beyond it show; with the link
  // tolerances counted, plus what they spread there (sigma^2 I + S_i S_i^T, the weighting the
  // noise gate and the deletion test use); the estimated noise when none is given.
  const double unit = options.noise_mm ? *options.noise_mm : sigma;
  std::vector<int> fitted_as(n, -1);
  for (int k = 0; k < m; ++k) fitted_as[active[k]] = k;
  for (int i = 0; i < n; ++i) {
    auto& pr = report.poses[i];
    pr.standoff_mm = stand[i];
    const Eigen::Vector2d miss = r_all.segment<2>(2 * i);
    Eigen::Matrix2d allowed = unit * unit * Eigen::Matrix2d::Identity();
    if (link_weighted && fitted_as[i] >= 0) {
      const Eigen::MatrixXd s_i = spread.middleRows(2 * fitted_as[i], 2);
      allowed += s_i * s_i.transpose();
    }
    pr.normalised = std::sqrt(miss.dot(allowed.ldlt().solve(miss)));
  }
  for (int i : active)
    if (options.loss != RobustLoss::kNone &&
        r_all.segment<2>(2 * i).norm() > options.loss_scale_sigmas * *options.noise_mm) {
      report.poses[i].outlier = true;
      report.suspect_poses.push_back(
          {i + 1, poses[i].source_line,
           "the robust loss weighs it " + fixed(weight[i], 2) + " (it misses by " +
               fixed(r_all.segment<2>(2 * i).norm() / *options.noise_mm, 1) +
               " given noise sigmas, beyond where the loss bends): it counts for that fraction of "
               "a "
               "pose",
           std::numeric_limits<double>::quiet_NaN()});
    }
  for (int i = 0; i < n; ++i)
    if (duplicate_of[i] >= 0)
      report.suspect_poses.push_back(
          {i + 1, poses[i].source_line,
           "repeats " + poseName(poses, duplicate_of[i]) +
               " exactly (the same joints and reading): one measurement, counted once",
           report.chi2_per_dof.value_or(1.0)});
  report.verdict = detail::judge(report, options, gross_problems);
  report.solve_time_ms =
      std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
  return report;
}

Robot calibratedRobot(const Robot& robot, const SolveReport& report) {
  Robot out = calibratedRobot(robot, report.estimate);
  if (report.link_covariance.size() > 0) out.tolerance.link_covariance = report.link_covariance;
  return out;
}

}  // namespace zerocal
