#include "zerocal/calib/solver.h"

#include <boost/math/distributions/students_t.hpp>
#include <chrono>
#include <cmath>
#include <limits>

#include "costs.h"
#include "zerocal/calib/identifiability.h"
#include "zerocal/error.h"

namespace zerocal {
namespace {

class CancelCallback : public ceres::IterationCallback {
 public:
  explicit CancelCallback(const std::function<bool()>& cancelled) : cancelled_(cancelled) {}
  ceres::CallbackReturnType operator()(const ceres::IterationSummary&) override {
    return cancelled_ && cancelled_() ? ceres::SOLVER_ABORT : ceres::SOLVER_CONTINUE;
  }

 private:
  const std::function<bool()>& cancelled_;
};

}  // namespace

void checkPoses(const CellModel& cell, const std::vector<Pose>& poses) {
  if (poses.size() < static_cast<std::size_t>(kMinimumPoses))
    throw InputError(std::to_string(poses.size()) + " poses given; identifying " +
                     std::to_string(kIdentifiedCount) +
                     " parameters and the target point needs at least " +
                     std::to_string(kMinimumPoses) + " (use 8 or more)");
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
  if (loss != RobustLoss::kNone && !noise_mm)
    return "a robust loss needs the noise level (--noise), to know what counts as large";
  if (max_iterations < 1) return "max_iterations must be at least 1";
  if (!(outlier_threshold > 0)) return "the outlier threshold must be positive";
  return {};
}

SolveReport solve(const CellModel& cell, const std::vector<Pose>& poses,
                  const SolveOptions& options) {
  checkInput(cell, poses, options);
  const auto start = std::chrono::steady_clock::now();
  const int n = static_cast<int>(poses.size());
  bool readings = options.use_readings;
  for (const auto& p : poses) readings = readings && p.psd_uv_mm.has_value();

  SolveReport report;
  report.cost = options.cost;
  report.used_readings = readings;
  report.pose_count = n;

  // Start: zero offsets, nominal laser, the point the nominal lines pass closest to.
  CalibrationParameters est;
  est.target_mm = bestTarget(cell, poses, est, readings);

  const double sigma_in = options.noise_mm.value_or(1.0);
  ceres::Problem::Options problem_options;
  problem_options.cost_function_ownership = ceres::TAKE_OWNERSHIP;
  ceres::Problem problem(problem_options);
  if (options.cost == CostKind::kMaximumLikelihood) {
    for (const auto& pose : poses) {
      ceres::LossFunction* loss = nullptr;
      if (options.loss == RobustLoss::kHuber)
        loss = new ceres::HuberLoss(options.loss_scale_sigmas);
      if (options.loss == RobustLoss::kCauchy)
        loss = new ceres::CauchyLoss(options.loss_scale_sigmas);
      problem.AddResidualBlock(
          PointToLineCost::create(cell, pose.q_deg, hitPointOffset(cell, pose, readings), sigma_in),
          loss, est.delta_rad.data(), est.laser.data(), est.target_mm.data());
    }
  } else {
    problem.AddResidualBlock(PairwiseCost::create(cell, poses, sigma_in), nullptr,
                             est.delta_rad.data(), est.laser.data());
  }

  ceres::Solver::Options solver_options;
  solver_options.linear_solver_type = ceres::DENSE_QR;
  solver_options.max_num_iterations = options.max_iterations;
  solver_options.function_tolerance = 1e-15;
  solver_options.gradient_tolerance = 1e-15;
  solver_options.parameter_tolerance = 1e-14;
  solver_options.num_threads = 1;
  solver_options.logging_type = ceres::SILENT;
  CancelCallback cancel(options.cancelled);
  solver_options.callbacks.push_back(&cancel);
  ceres::Solver::Summary summary;
  ceres::Solve(solver_options, &problem, &summary);
  report.converged = summary.termination_type == ceres::CONVERGENCE;
  report.message = summary.termination_type == ceres::USER_FAILURE ? "cancelled" : summary.message;
  report.iterations = static_cast<int>(summary.iterations.size());
  if (options.cost == CostKind::kPairwise) est.target_mm = bestTarget(cell, poses, est, readings);
  report.estimate = est;

  // Residuals in mm, noise level, identifiability, covariance.
  const Eigen::MatrixXd jac_mm = pointToLineJacobian(cell, poses, est, 1.0, readings);
  double rss = 0;
  for (int i = 0; i < n; ++i) {
    PointToLineCost functor(cell, poses[i].q_deg, hitPointOffset(cell, poses[i], readings), 1.0);
    double r[2];
    functor(est.delta_rad.data(), est.laser.data(), est.target_mm.data(), r);
    PoseResidual pr;
    pr.source_line = poses[i].source_line;
    pr.miss_mm = {r[0], r[1]};
    pr.miss_norm_mm = pr.miss_mm.norm();
    rss += pr.miss_mm.squaredNorm();
    report.poses.push_back(pr);
  }
  const auto stand = standoffs(cell, poses, est);
  Identifiability ident = analyseIdentifiability(jac_mm, cell, poses, est, 1.0);
  report.rank = ident.rank;
  report.condition_number = ident.condition_number;
  report.dof = 2 * n - ident.rank;
  report.rms_miss_mm = std::sqrt(rss / n);
  if (options.noise_mm) {
    report.noise_mm = *options.noise_mm;
    if (report.dof > 0)
      report.chi2_per_dof = rss / (report.noise_mm * report.noise_mm) / report.dof;
  } else {
    report.noise_estimated = true;
    report.noise_mm =
        report.dof > 0 ? std::sqrt(rss / report.dof) : std::numeric_limits<double>::quiet_NaN();
  }
  const double sigma = report.noise_mm;
  // Re-judge identifiability against the noise actually in force.
  ident = analyseIdentifiability(jac_mm, cell, poses, est, sigma);
  Eigen::MatrixXd cov = sigma * sigma * ident.unit_covariance;
  if (options.cost == CostKind::kPairwise) {
    const Eigen::MatrixXd pc = pairwiseCovariance(cell, poses, est, sigma);
    cov.topLeftCorner(kIdentifiedCount, kIdentifiedCount) = pc;
    for (int k = 0; k < kIdentifiedCount; ++k)
      if (!ident.identifiable[k]) cov.row(k).setConstant(NAN), cov.col(k).setConstant(NAN);
  }

  double quantile = 1.959963984540054;
  if (report.noise_estimated && report.dof > 0)
    quantile = boost::math::quantile(boost::math::students_t(report.dof), 0.975);

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

  for (int i = 0; i < n; ++i) {
    auto& pr = report.poses[i];
    pr.standoff_mm = stand[i];
    pr.normalised = pr.miss_norm_mm / sigma;
    pr.outlier = pr.normalised > options.outlier_threshold;
  }
  report.solve_time_ms =
      std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
  return report;
}

}  // namespace zerocal
