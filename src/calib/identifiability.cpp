#include "zerocal/calib/identifiability.h"

#include <Eigen/QR>
#include <Eigen/SVD>
#include <algorithm>
#include <cmath>
#include <limits>
#include <sstream>
#include <stdexcept>

#include "costs.h"

namespace zerocal {
namespace {

// Relative singular value below which a direction counts as numerically null.
constexpr double kNullTolerance = 1e-8;

// An uncertainty above these (for sigma = the measurement noise) means the poses do not
// determine the unknown in any useful sense: for an offset, worse than the accuracy the
// calibration is for; for the laser and the target, larger than any plausible mounting error.
double determinedLimit(int k, double required_accuracy_deg) {
  if (k < kOffsetCount) return required_accuracy_deg * kDegToRad;  // rad
  if (k < kOffsetCount + 2) return 0.05;                           // slope
  if (k < kIdentifiedCount) return 10.0;                           // mm
  return 50.0;                                                     // target, mm
}

std::string readable(int k) {
  if (k < kOffsetCount) return "delta" + std::to_string(k + 2);
  if (k < kOffsetCount + 2) return "the laser direction";
  if (k < kIdentifiedCount) return "the laser offset";
  return "the target position";
}

std::string fmt(double v, int precision = 1) {
  std::ostringstream s;
  s.setf(std::ios::fixed);
  s.precision(precision);
  s << v;
  return s.str();
}

}  // namespace

std::string delta1Reason() {
  return "not identifiable by construction: a change of delta1 turns every laser line rigidly "
         "about the fixed joint-1 axis, which the unknown target position absorbs";
}

std::string delta6Reason() {
  return "not identifiable by construction: a change of delta6 turns the laser about the flange "
         "axis, which the laser-line parameters absorb";
}

Eigen::MatrixXd pointToLineJacobian(const CellModel& cell, const std::vector<Pose>& poses,
                                    const CalibrationParameters& params, double sigma_mm,
                                    bool use_readings) {
  const int n = static_cast<int>(poses.size());
  Eigen::MatrixXd jac(2 * n, kUnknownCount);
  const double* blocks[3] = {params.delta_rad.data(), params.laser.data(), params.target_mm.data()};
  Eigen::Matrix<double, 2, kOffsetCount, Eigen::RowMajor> jd;
  Eigen::Matrix<double, 2, kLaserParamCount, Eigen::RowMajor> jl;
  Eigen::Matrix<double, 2, kTargetCount, Eigen::RowMajor> jt;
  double* jacobians[3] = {jd.data(), jl.data(), jt.data()};
  double residual[2];
  for (int i = 0; i < n; ++i) {
    PointToLineCost functor(cell, poses[i].q_deg, hitPointOffset(cell, poses[i], use_readings),
                            sigma_mm, missWeight(cell, poses[i], params, use_readings));
    ceres::AutoDiffCostFunction<PointToLineCost, 2, kOffsetCount, kLaserParamCount, kTargetCount>
        cost(&functor, ceres::DO_NOT_TAKE_OWNERSHIP);
    cost.Evaluate(blocks, residual, jacobians);
    jac.block(2 * i, 0, 2, kOffsetCount) = jd;
    jac.block(2 * i, kOffsetCount, 2, kLaserParamCount) = jl;
    jac.block(2 * i, kIdentifiedCount, 2, kTargetCount) = jt;
  }
  return jac;
}

std::vector<double> standoffs(const CellModel& cell, const std::vector<Pose>& poses,
                              const CalibrationParameters& params) {
  std::vector<double> out;
  for (const auto& pose : poses) {
    const Line l = laserLine(cell, pose.q_deg, params);
    out.push_back(l.direction.dot(params.target_mm - l.point));
  }
  return out;
}

Identifiability analyseIdentifiability(const Eigen::MatrixXd& jacobian, const CellModel& cell,
                                       const std::vector<Pose>& poses,
                                       const CalibrationParameters& params, double sigma_mm,
                                       double required_accuracy_deg,
                                       const std::string& bound_name) {
  const int n = static_cast<int>(jacobian.cols());
  Identifiability out;
  out.identifiable.assign(n, true);
  out.reason.assign(n, "");
  if (static_cast<int>(poses.size()) < kMinimumPoses) {
    // 2N readings cannot determine 11 unknowns: say so plainly instead of naming a trade that
    // depends on which of the many null directions the SVD happens to return.
    const int count = static_cast<int>(poses.size());
    out.identifiable.assign(n, false);
    out.reason.assign(n, std::to_string(count) + " pose" + (count == 1 ? "" : "s") + " give " +
                             std::to_string(2 * count) + " readings for " +
                             std::to_string(kUnknownCount) + " unknowns: at least " +
                             std::to_string(kMinimumPoses) + " poses are needed");
    out.singular_values = Eigen::VectorXd::Zero(n);
    out.condition_number = std::numeric_limits<double>::infinity();
    out.unit_covariance = Eigen::MatrixXd::Constant(n, n, std::numeric_limits<double>::quiet_NaN());
    return out;
  }

  // Column scaling makes the SVD speak of parameter directions, not units.
  Eigen::VectorXd scale(n);
  for (int k = 0; k < n; ++k) {
    scale[k] = jacobian.col(k).norm();
    if (!(scale[k] > 0)) scale[k] = 1;  // an all-zero column: null by itself
  }
  const Eigen::MatrixXd scaled = jacobian * scale.cwiseInverse().asDiagonal();
  // The full V and zero-padded singular values keep the loops below within bounds whatever the
  // Jacobian's shape (a thin V of a short Jacobian lacks the null directions).
  Eigen::JacobiSVD<Eigen::MatrixXd> svd(scaled, Eigen::ComputeFullV);
  Eigen::VectorXd s = Eigen::VectorXd::Zero(n);
  s.head(svd.singularValues().size()) = svd.singularValues();
  const Eigen::MatrixXd v = svd.matrixV();
  out.singular_values = s;
  const double tol = kNullTolerance * std::max(s.size() ? s[0] : 0.0, 1e-300);
  out.rank = 0;
  for (int i = 0; i < s.size(); ++i) out.rank += s[i] > tol ? 1 : 0;
  out.condition_number = out.rank == n ? s[0] / s[n - 1] : std::numeric_limits<double>::infinity();

  // Unit-sigma covariance on the identifiable subspace (pseudo-inverse).
  Eigen::MatrixXd cov_scaled = Eigen::MatrixXd::Zero(n, n);
  for (int i = 0; i < out.rank; ++i) cov_scaled += v.col(i) * v.col(i).transpose() / (s[i] * s[i]);
  out.unit_covariance =
      scale.cwiseInverse().asDiagonal() * cov_scaled * scale.cwiseInverse().asDiagonal();

  // Context for the words.
  double q1_min = 1e300, q1_max = -1e300, q5_abs_max = 0;
  for (const auto& p : poses) {
    q1_min = std::min(q1_min, p.q_deg[0]);
    q1_max = std::max(q1_max, p.q_deg[0]);
    q5_abs_max = std::max(q5_abs_max, std::abs(p.q_deg[4]));
  }
  const auto stand = standoffs(cell, poses, params);
  const double s_min = stand.empty() ? 0.0 : *std::min_element(stand.begin(), stand.end());
  const double s_max = stand.empty() ? 0.0 : *std::max_element(stand.begin(), stand.end());

  for (int k = 0; k < n; ++k) {
    // The null (or, failing that, the weakest) direction in which k takes part the most.
    double null_weight = 0;
    for (int i = out.rank; i < n; ++i) null_weight += v(k, i) * v(k, i);
    null_weight = std::sqrt(null_weight);
    const double sigma_k = sigma_mm * std::sqrt(std::max(0.0, out.unit_covariance(k, k)));
    const bool in_null = null_weight > 1e-4;
    const bool too_weak = !in_null && sigma_k > determinedLimit(k, required_accuracy_deg);
    if (!in_null && !too_weak) continue;
    out.identifiable[k] = false;

    int dir = n - 1;
    double best = -1;
    const int first = in_null ? out.rank : 0;
    for (int i = first; i < n; ++i) {
      // weigh by 1/s so that the weakest directions carrying k are preferred
      const double w = std::abs(v(k, i)) / (in_null ? 1.0 : s[i]);
      if (w > best) best = w, dir = i;
    }
    std::vector<int> partners;
    const double vmax = v.col(dir).cwiseAbs().maxCoeff();
    for (int j = 0; j < n; ++j)
      if (j != k && std::abs(v(j, dir)) > 0.2 * vmax) partners.push_back(j);
    auto has = [&](int lo, int hi) {
      for (int j : partners)
        if (j >= lo && j < hi) return true;
      return false;
    };

    std::string why;
    const bool laser_k = k >= kOffsetCount && k < kIdentifiedCount;
    if ((k == 0 || (k >= kIdentifiedCount && has(0, 1))) && q1_max - q1_min < 2.0) {
      why = "joint 1 spans " + fmt(q1_max - q1_min) +
            " deg over the poses: delta2 trades against the target position";
    } else if ((laser_k || (k < kIdentifiedCount && has(kOffsetCount, kIdentifiedCount))) &&
               s_max - s_min < std::max(5.0, 0.02 * s_max)) {
      why = "stand-off distance is the same at every pose (" + fmt(s_min) + " to " + fmt(s_max) +
            " mm): laser direction and offset trade";
    } else if ((k == 2 || (laser_k && has(2, 3))) && q5_abs_max < 2.0) {
      why = "joint 5 stays within " + fmt(q5_abs_max) +
            " deg of zero at every pose: the joint-4 and joint-6 axes coincide, so delta4 "
            "trades against the laser parameters";
    } else {
      why = readable(k) + " trades against ";
      std::vector<std::string> names;
      for (int j : partners) {
        const std::string r = readable(j);
        if (r != readable(k) && std::find(names.begin(), names.end(), r) == names.end())
          names.push_back(r);
      }
      if (names.empty()) names.push_back("nothing else: no pose is sensitive to it");
      for (std::size_t i = 0; i < names.size(); ++i)
        why += (i ? (i + 1 == names.size() ? " and " : ", ") : "") + names[i];
      why += " at these poses";
    }
    if (too_weak) {
      const bool angle = k < kOffsetCount;
      why += " (it is determined only to " + fmt(angle ? sigma_k * kRadToDeg : sigma_k, 3) +
             (angle ? " deg" : "") + ", one standard deviation" +
             (angle ? "; " + bound_name + " is " + fmt(required_accuracy_deg, 3) + " deg" : "") +
             ")";
    }
    out.reason[k] = why;
  }
  for (int k = 0; k < n; ++k)
    if (!out.identifiable[k])
      for (int j = 0; j < n; ++j)
        out.unit_covariance(k, j) = out.unit_covariance(j, k) =
            std::numeric_limits<double>::quiet_NaN();
  return out;
}

}  // namespace zerocal

namespace zerocal {

int PlacementLayout::slot(int placement) const {
  const auto it = std::lower_bound(placements.begin(), placements.end(), placement);
  if (it == placements.end() || *it != placement)
    throw std::out_of_range("placement " + std::to_string(placement) + " is not in the layout");
  return static_cast<int>(it - placements.begin());
}

std::string PlacementLayout::name(int k) const {
  if (k < kIdentifiedCount) return unknownName(k);
  if (isLink(k)) return linkParamName(k - firstLink());
  if (isCompliance(k)) return complianceParamName(k - firstCompliance());
  const int t = k - firstTarget();
  return "target" + std::to_string(placements[t / kTargetCount]) + "_" + "xyz"[t % kTargetCount] +
         "_mm";
}

std::string PlacementLayout::readable(int k) const {
  if (k < kOffsetCount) return "delta" + std::to_string(k + 2);
  if (k < kIdentifiedCount) return "the laser line";
  if (isLink(k)) {
    const std::string n = linkParamName(k - firstLink());
    return n.substr(0, n.rfind('_'));
  }
  if (isCompliance(k))
    return "the compliance of joint " + std::to_string(k - firstCompliance() + 2);
  return "the placement-" + std::to_string(placements[(k - firstTarget()) / kTargetCount]) +
         " centre";
}

Eigen::MatrixXd placementJacobian(const CellModel& cell, const std::vector<Pose>& poses,
                                  const PlacementLayout& layout,
                                  const CalibrationParameters& params,
                                  const std::vector<Eigen::Vector3d>& targets, double sigma_mm,
                                  bool use_readings, Eigen::VectorXd* residuals) {
  const int n = static_cast<int>(poses.size());
  Eigen::MatrixXd jac = Eigen::MatrixXd::Zero(2 * n, layout.unknownCount());
  if (residuals) residuals->resize(2 * n);
  Eigen::Matrix<double, 2, kOffsetCount, Eigen::RowMajor> jd;
  Eigen::Matrix<double, 2, kLaserParamCount, Eigen::RowMajor> jl;
  Eigen::Matrix<double, 2, kLinkParameterCount, Eigen::RowMajor> jk;
  Eigen::Matrix<double, 2, kComplianceCount, Eigen::RowMajor> jc;
  Eigen::Matrix<double, 2, kTargetCount, Eigen::RowMajor> jt;
  double* jacobians[5] = {jd.data(), jl.data(), jk.data(), jc.data(), jt.data()};
  double r[2];
  for (int i = 0; i < n; ++i) {
    const int slot = layout.slot(poses[i].placement);
    const double* blocks[5] = {params.delta_rad.data(), params.laser.data(), params.link.data(),
                               params.compliance.data(), targets[slot].data()};
    CalibrationParameters at = params;
    at.target_mm = targets[slot];
    LinkPointToLineCost functor(cell, poses[i].q_deg, hitPointOffset(cell, poses[i], use_readings),
                                sigma_mm, missWeight(cell, poses[i], at, use_readings));
    ceres::AutoDiffCostFunction<LinkPointToLineCost, 2, kOffsetCount, kLaserParamCount,
                                kLinkParameterCount, kComplianceCount, kTargetCount>
        cost(&functor, ceres::DO_NOT_TAKE_OWNERSHIP);
    cost.Evaluate(blocks, r, jacobians);
    jac.block(2 * i, 0, 2, kOffsetCount) = jd;
    jac.block(2 * i, kOffsetCount, 2, kLaserParamCount) = jl;
    jac.block(2 * i, PlacementLayout::firstLink(), 2, kLinkParameterCount) = jk;
    jac.block(2 * i, PlacementLayout::firstCompliance(), 2, layout.compliance) =
        jc.leftCols(layout.compliance);
    jac.block(2 * i, layout.firstTarget() + kTargetCount * slot, 2, kTargetCount) = jt;
    if (residuals) residuals->segment<2>(2 * i) = Eigen::Vector2d(r[0], r[1]);
  }
  return jac;
}

BaseParameters analyseBaseParameters(const Eigen::MatrixXd& jacobian,
                                     const PlacementLayout& layout) {
  // A column below this fraction of the largest (same units: the misses per unit of the
  // parameter, rad or mm) moves no miss; a column whose part outside the span of the kept ones
  // is below kDependent of its length is a combination of them (structural dependencies come
  // out near 1e-12, the weakest real parameters of a spread plan near 1e-3).
  constexpr double kNoEffect = 1e-10;
  constexpr double kDependent = 1e-6;
  const int n = static_cast<int>(jacobian.cols());
  std::vector<int> order;
  for (int k = 0; k < kIdentifiedCount; ++k) order.push_back(k);
  for (int k = layout.firstTarget(); k < n; ++k) order.push_back(k);
  for (int k = PlacementLayout::firstCompliance(); k < layout.firstTarget(); ++k)
    order.push_back(k);
  for (int k = PlacementLayout::firstLink(); k < PlacementLayout::firstCompliance(); ++k)
    order.push_back(k);
  BaseParameters out;
  out.identified.assign(n, false);
  out.reason.assign(n, "");
  double largest = 0;
  for (int k = 0; k < n; ++k) largest = std::max(largest, jacobian.col(k).norm());
  std::vector<int> kept;
  Eigen::MatrixXd basis(jacobian.rows(), 0);  // orthonormal, spans the kept scaled columns
  for (int k : order) {
    const double norm = jacobian.col(k).norm();
    if (!(norm > kNoEffect * largest)) {
      out.reason[k] = "no effect on the measurements at these poses";
      continue;
    }
    const Eigen::VectorXd u = jacobian.col(k) / norm;
    Eigen::VectorXd rest = u - basis * (basis.transpose() * u);
    rest -= basis * (basis.transpose() * rest);  // once more, for orthogonality in rounding
    if (rest.norm() > kDependent) {
      basis.conservativeResize(Eigen::NoChange, basis.cols() + 1);
      basis.col(basis.cols() - 1) = rest.normalized();
      kept.push_back(k);
      out.identified[k] = true;
      continue;
    }
    // The combination: u = A beta with A the kept scaled columns.
    Eigen::MatrixXd a(jacobian.rows(), static_cast<Eigen::Index>(kept.size()));
    for (std::size_t j = 0; j < kept.size(); ++j)
      a.col(static_cast<Eigen::Index>(j)) = jacobian.col(kept[j]).normalized();
    const Eigen::VectorXd beta = a.colPivHouseholderQr().solve(u);
    const double biggest = beta.cwiseAbs().maxCoeff();
    std::vector<std::string> names;
    for (std::size_t j = 0; j < kept.size(); ++j)
      if (std::abs(beta[static_cast<Eigen::Index>(j)]) > 0.1 * biggest) {
        const std::string r = layout.readable(kept[j]);
        if (std::find(names.begin(), names.end(), r) == names.end()) names.push_back(r);
      }
    std::string why = "not identifiable: combined with ";
    for (std::size_t i = 0; i < names.size(); ++i)
      why += (i ? (i + 1 == names.size() ? " and " : ", ") : "") + names[i];
    out.reason[k] = why + " (a change of it is a change of those, to the measurements)";
  }
  out.count = static_cast<int>(kept.size());
  return out;
}

Eigen::MatrixXd baseCovariance(const Eigen::MatrixXd& jacobian, const BaseParameters& base,
                               double* condition_number) {
  const int n = static_cast<int>(jacobian.cols());
  std::vector<int> cols;
  for (int k = 0; k < n; ++k)
    if (base.identified[k]) cols.push_back(k);
  const int m = static_cast<int>(cols.size());
  Eigen::MatrixXd jb(jacobian.rows(), m);
  Eigen::VectorXd scale(m);
  for (int j = 0; j < m; ++j) {
    scale[j] = jacobian.col(cols[j]).norm();
    jb.col(j) = jacobian.col(cols[j]) / scale[j];
  }
  Eigen::JacobiSVD<Eigen::MatrixXd> svd(jb, Eigen::ComputeThinV);
  const Eigen::VectorXd s = svd.singularValues();
  Eigen::MatrixXd inv = Eigen::MatrixXd::Zero(m, m);
  int rank = 0;
  for (int i = 0; i < s.size(); ++i)
    if (s[i] > kNullTolerance * s[0]) {
      inv += svd.matrixV().col(i) * svd.matrixV().col(i).transpose() / (s[i] * s[i]);
      ++rank;
    }
  if (condition_number)
    *condition_number =
        rank == m && m > 0 ? s[0] / s[m - 1] : std::numeric_limits<double>::infinity();
  inv = scale.cwiseInverse().asDiagonal() * inv * scale.cwiseInverse().asDiagonal();
  Eigen::MatrixXd cov = Eigen::MatrixXd::Constant(n, n, std::numeric_limits<double>::quiet_NaN());
  for (int a = 0; a < m; ++a)
    for (int b = 0; b < m; ++b) cov(cols[a], cols[b]) = inv(a, b);
  return cov;
}

std::vector<Eigen::Vector3d> placementTargets(const CellModel& cell, const std::vector<Pose>& poses,
                                              const PlacementLayout& layout,
                                              const CalibrationParameters& params,
                                              bool use_readings) {
  std::vector<std::vector<Line>> lines(layout.count());
  for (const auto& pose : poses) {
    Line l = laserLine(cell, pose.q_deg, params);
    l.point -= hitPointOffset(cell, pose, use_readings);
    lines[layout.slot(pose.placement)].push_back(l);
  }
  std::vector<Eigen::Vector3d> out;
  for (const auto& group : lines) out.push_back(closestPointToLines(group));
  return out;
}

}  // namespace zerocal
