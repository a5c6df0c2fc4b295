#include "zerocal/calib/change.h"

#include <fmt/format.h>

#include <Eigen/Cholesky>
#include <Eigen/SVD>
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <functional>
#include <limits>

#include "solver_detail.h"
#include "zerocal/calib/identifiability.h"
#include "zerocal/calib/planner.h"
#include "zerocal/error.h"

namespace zerocal {
namespace {

constexpr double kInfinity = std::numeric_limits<double>::infinity();

// The unknowns of a change, in unknownName order: the 4 offsets, then the laser's and the
// centre's when re-mounted.
// The arm's uniform growth (all link lengths times 1 + g, its thermal state), after the
// unknowns of unknownName order.
constexpr int kGrowthColumn = kUnknownCount;

std::vector<int> freeColumns(const ChangeOptions& options) {
  std::vector<int> columns;
  for (int k = 0; k < kOffsetCount; ++k) columns.push_back(k);
  if (options.laser_remounted)
    for (int k = kOffsetCount; k < kIdentifiedCount; ++k) columns.push_back(k);
  if (options.psd_remounted)
    for (int k = kIdentifiedCount; k < kUnknownCount; ++k) columns.push_back(k);
  if (options.thermal_growth) columns.push_back(kGrowthColumn);
  return columns;
}

// The cell with its arm grown by `growth` (every link length a, d times 1 + growth).
CellModel grownCell(const CellModel& cell, double growth) {
  if (growth == 0) return cell;
  CellModel grown = cell;
  for (DhRow& row : grown.robot.dh) {
    row.a_mm *= 1 + growth;
    row.d_mm *= 1 + growth;
  }
  return grown;
}

Eigen::VectorXd grownMisses(const CellModel& cell, const std::vector<Pose>& poses,
                            const CalibrationParameters& p, double growth, bool readings) {
  return detail::poseMisses(grownCell(cell, growth), poses, p, readings);
}

// The misses' derivatives by the free unknowns at `p` and `growth`.
Eigen::MatrixXd changeJacobian(const CellModel& cell, const std::vector<Pose>& poses,
                               const CalibrationParameters& p, double growth, bool readings,
                               const std::vector<int>& columns) {
  const Eigen::MatrixXd base =
      pointToLineJacobian(grownCell(cell, growth), poses, p, 1.0, readings);
  Eigen::MatrixXd out(base.rows(), static_cast<Eigen::Index>(columns.size()));
  for (std::size_t c = 0; c < columns.size(); ++c) {
    if (columns[c] < kUnknownCount) {
      out.col(static_cast<Eigen::Index>(c)) = base.col(columns[c]);
      continue;
    }
    constexpr double h = 1e-7;
    out.col(static_cast<Eigen::Index>(c)) = (grownMisses(cell, poses, p, growth + h, readings) -
                                             grownMisses(cell, poses, p, growth - h, readings)) /
                                            (2 * h);
  }
  return out;
}

// The misses' derivatives by the PSD's centre (3 columns, mm) at `p` and `growth`.
Eigen::MatrixXd centreJacobian(const CellModel& cell, const std::vector<Pose>& poses,
                               const CalibrationParameters& p, double growth, bool readings) {
  return changeJacobian(cell, poses, p, growth, readings,
                        {kIdentifiedCount, kIdentifiedCount + 1, kIdentifiedCount + 2});
}

// The variance per axis (mm^2) of the PSD's centre now against the reference's when each seating
// on its base repeats to `repeatability_mm`: two seatings, each its own.
double reseatVariance(const ChangeOptions& options) {
  if (options.psd_remounted) return 0;
  return 2 * options.psd_base_repeatability_mm * options.psd_base_repeatability_mm;
}

// What the PSD's re-seating leaves in the free unknowns: their response to its centre moved
// (unit_cov J^T J_c, a turn of joint 2 moving every beam as a move of the centre does), times
// the spread of that move, `variance` per axis.
Eigen::MatrixXd reseatCovariance(const Eigen::MatrixXd& unit_cov, const Eigen::MatrixXd& j,
                                 const Eigen::MatrixXd& jc, double variance) {
  const Eigen::MatrixXd s = unit_cov * j.transpose() * jc;
  return variance * s * s.transpose();
}

void addStep(CalibrationParameters& p, double& growth, const std::vector<int>& columns,
             const Eigen::VectorXd& dx) {
  for (std::size_t c = 0; c < columns.size(); ++c) {
    const int k = columns[c];
    const double step = dx[static_cast<Eigen::Index>(c)];
    if (k == kGrowthColumn)
      growth += step;
    else if (k < kOffsetCount)
      p.delta_rad[k] += step;
    else if (k < kIdentifiedCount)
      p.laser[k - kOffsetCount] += step;
    else
      p.target_mm[k - kIdentifiedCount] += step;
  }
}

// The unit-variance covariance (J^T J)^-1 of the free unknowns, the rank and condition number of
// J column-scaled; the covariance is infinite on the diagonal where J is rank-deficient.
struct UnitCovariance {
  Eigen::MatrixXd cov;
  int rank = 0;
  double condition = kInfinity;
};
UnitCovariance unitCovariance(const Eigen::MatrixXd& j) {
  UnitCovariance out;
  Eigen::VectorXd scale = j.colwise().norm().transpose();
  for (Eigen::Index k = 0; k < scale.size(); ++k)
    if (!(scale[k] > 0)) scale[k] = 1;
  const Eigen::MatrixXd scaled = j * scale.cwiseInverse().asDiagonal();
  Eigen::JacobiSVD<Eigen::MatrixXd> svd(scaled, Eigen::ComputeThinU | Eigen::ComputeThinV);
  const Eigen::VectorXd s = svd.singularValues();
  for (Eigen::Index i = 0; i < s.size(); ++i) out.rank += s[i] > 1e-9 * s[0] ? 1 : 0;
  const Eigen::Index n = j.cols();
  out.cov = Eigen::MatrixXd::Constant(n, n, kInfinity);
  if (out.rank < n) return out;
  out.condition = s[0] / s[n - 1];
  const Eigen::MatrixXd v = svd.matrixV() * s.cwiseInverse().asDiagonal();
  out.cov =
      scale.cwiseInverse().asDiagonal() * (v * v.transpose()) * scale.cwiseInverse().asDiagonal();
  return out;
}

bool readingsOf(const std::vector<Pose>& a, const std::vector<Pose>& b, const SolveOptions& o) {
  bool readings = o.use_readings;
  for (const Pose& p : a) readings = readings && p.spot.has_value();
  for (const Pose& p : b) readings = readings && p.spot.has_value();
  return readings;
}

std::vector<Pose> pairedReference(const ReferenceFit& reference, const std::vector<int>& pairs) {
  std::vector<Pose> out;
  for (const int i : pairs) out.push_back(reference.poses[static_cast<std::size_t>(i)]);
  return out;
}

void checkPairs(const ReferenceFit& reference, const std::vector<int>& pairs, std::size_t now,
                int unknowns) {
  if (pairs.size() != now)
    throw InputError("the change needs one reference pose for each pose (" + std::to_string(now) +
                     " poses, " + std::to_string(pairs.size()) + " pairs)");
  std::vector<int> sorted = pairs;
  std::sort(sorted.begin(), sorted.end());
  for (std::size_t k = 0; k < sorted.size(); ++k) {
    if (sorted[k] < 0 || sorted[k] >= static_cast<int>(reference.poses.size()))
      throw InputError("pose pair " + std::to_string(k + 1) + " names reference pose " +
                       std::to_string(sorted[k] + 1) + ", and the reference has " +
                       std::to_string(reference.poses.size()));
    if (k > 0 && sorted[k] == sorted[k - 1])
      throw InputError("reference pose " + std::to_string(sorted[k] + 1) +
                       " is paired twice: each reference pose is re-measured once");
  }
  // At least one degree of freedom, so that the misfit is checked against the noise.
  if (2 * static_cast<int>(now) <= unknowns)
    throw InputError("a change with " + std::to_string(unknowns) + " unknowns needs at least " +
                     std::to_string(unknowns / 2 + 1) + " re-measured poses; " +
                     std::to_string(now) + " given");
}

// The change fitted to the pairs `active` over the unknowns `columns`, from the reference's
// parameters: Gauss-Newton, nearly linear (the change is a fraction of a degree).
struct ChangeFit {
  CalibrationParameters p;
  double growth = 0;         // the arm's growth since the reference (thermal_growth)
  Eigen::VectorXd misses;    // every pair's (2 per pose), at p
  Eigen::MatrixXd jacobian;  // the active pairs' rows, the free columns
  bool converged = false;
  int iterations = 0;
  std::string message;
};
ChangeFit fitChange(const CellModel& cell, const std::vector<Pose>& now,
                    const Eigen::VectorXd& reference_misses, const CalibrationParameters& start,
                    const std::vector<int>& columns, const std::vector<int>& active, bool readings,
                    const std::function<bool()>& cancelled) {
  ChangeFit fit;
  fit.p = start;
  std::vector<Pose> used;
  for (const int i : active) used.push_back(now[static_cast<std::size_t>(i)]);
  const auto activeRows = [&](const Eigen::VectorXd& all) {
    Eigen::VectorXd out(2 * active.size());
    for (std::size_t k = 0; k < active.size(); ++k)
      out.segment<2>(2 * static_cast<Eigen::Index>(k)) = all.segment<2>(2 * active[k]);
    return out;
  };
  fit.misses = grownMisses(cell, now, fit.p, fit.growth, readings) - reference_misses;
  fit.jacobian = changeJacobian(cell, used, fit.p, fit.growth, readings, columns);
  constexpr int kMostSteps = 30;
  for (int step = 0; step < kMostSteps && !fit.converged; ++step) {
    if (cancelled && cancelled()) {
      fit.message = "cancelled";
      return fit;
    }
    const Eigen::MatrixXd& j = fit.jacobian;
    const Eigen::VectorXd dx =
        -(j.transpose() * j).ldlt().solve(j.transpose() * activeRows(fit.misses));
    if (!dx.allFinite()) {
      fit.message = "the re-measured poses do not determine the change";
      return fit;
    }
    addStep(fit.p, fit.growth, columns, dx);
    fit.misses = grownMisses(cell, now, fit.p, fit.growth, readings) - reference_misses;
    fit.jacobian = changeJacobian(cell, used, fit.p, fit.growth, readings, columns);
    fit.iterations = step + 1;
    // Converged when no unknown moves by what could matter: offsets by 1e-11 rad, the growth by
    // 1e-10, the laser's slopes by 1e-9 and its point and the PSD's centre by 1e-5 mm (10 nm).
    // The centre's own floor is set by the rounding of the misses through the weakest direction
    // of the fit (with the centre free, the steps of a re-measurement of 6 poses rattle at about
    // 1e-6 mm), so a nanometre-level limit there would never be met.
    bool negligible = true;
    for (std::size_t c = 0; c < columns.size(); ++c) {
      const int k = columns[c];
      // The laser's four: its two slopes, then its two offsets (mm).
      const double limit = k == kGrowthColumn     ? 1e-10
                           : k < kOffsetCount     ? 1e-11
                           : k < kOffsetCount + 2 ? 1e-9
                                                  : 1e-5;
      negligible = negligible && std::abs(dx[static_cast<Eigen::Index>(c)]) < limit;
    }
    if (negligible) {
      fit.converged = true;
      fit.message = "converged in " + std::to_string(step + 1) + " Gauss-Newton steps";
    }
  }
  if (!fit.converged)
    fit.message = "no convergence in " + std::to_string(kMostSteps) + " Gauss-Newton steps";
  return fit;
}

// The options with the cell's per-pose noise in force (its reference sigma the pairs' unit).
ChangeOptions withCellNoise(const CellModel& cell, ChangeOptions options) {
  options.solve = zerocal::withCellNoise(cell, options.solve);
  return options;
}

}  // namespace

std::string ChangeOptions::validate() const {
  if (std::string why = solve.validate(); !why.empty()) return why;
  if (!solve.noise_mm)
    return "the change is measured against a given noise (noise_mm): a few re-measured poses "
           "cannot estimate it";
  if (!(max_psd_shift_mm > 0) || !std::isfinite(max_psd_shift_mm))
    return "max_psd_shift_mm must be a positive number of millimetres";
  if (!(psd_base_repeatability_mm >= 0 && psd_base_repeatability_mm <= kMostBaseRepeatabilityMm))
    return "psd_base_repeatability_mm must be within 0.." +
           detail::fixedText(kMostBaseRepeatabilityMm, 1) + " mm";
  return "";
}

int changeUnknownCount(const ChangeOptions& options) {
  return static_cast<int>(freeColumns(options).size());
}

SolveReport solveChange(const CellModel& cell, const ReferenceFit& reference,
                        const std::vector<Pose>& now, const std::vector<int>& pairs,
                        const ChangeOptions& given) {
  const ChangeOptions options = withCellNoise(cell, given);
  if (const std::string why = options.validate(); !why.empty()) throw InputError(why);
  const std::vector<int> columns = freeColumns(options);
  const int unknowns = static_cast<int>(columns.size());
  checkPairs(reference, pairs, now.size(), unknowns);
  checkJointLimits(cell, now);
  const std::vector<Pose> before = pairedReference(reference, pairs);
  const bool readings = readingsOf(now, before, options.solve);
  SolveReport report = detail::startReport(cell, now, options.solve);
  report.used_readings = readings;
  const int n = static_cast<int>(now.size());
  const double sigma = *options.solve.noise_mm;

  // The reference's own misses at its joints: what the link errors (and its noise) left there.
  // The change is what makes the misses now equal them: e(x) = m(q_now; p + x) - m(q_ref; p).
  const Eigen::VectorXd reference_misses =
      detail::poseMisses(cell, before, reference.estimate, readings);
  std::vector<int> active(static_cast<std::size_t>(n));
  for (int i = 0; i < n; ++i) active[static_cast<std::size_t>(i)] = i;
  ChangeFit fit = fitChange(cell, now, reference_misses, reference.estimate, columns, active,
                            readings, options.solve.cancelled);
  // A pose disturbed in either session (stray light, an unsettled reading) misses by far more
  // than the noise of a pair: the worst pair is left out while its miss alone is beyond what
  // chance allows among the pairs (Bonferroni at 1%) and enough pairs are left; it is named for
  // measuring again (the run does so once, then solves anew).
  std::vector<int> left_out;
  const double pair_sigma2 = 2 * sigma * sigma;
  constexpr std::size_t kMostLeftOut = 2;
  while (fit.converged && left_out.size() < kMostLeftOut &&
         2 * (static_cast<int>(active.size()) - 1) > unknowns) {
    int worst = -1;
    double worst_d = 0;
    for (const int i : active) {
      const double d = fit.misses.segment<2>(2 * i).squaredNorm() / pair_sigma2;
      if (d > worst_d) worst_d = d, worst = i;
    }
    // chi-square with 2 degrees of freedom beyond level a: d > -2 ln a.
    const double limit = -2 * std::log(0.01 / static_cast<double>(active.size()));
    if (worst < 0 || worst_d <= limit) break;
    std::vector<int> without;
    for (const int i : active)
      if (i != worst) without.push_back(i);
    ChangeFit refit = fitChange(cell, now, reference_misses, reference.estimate, columns, without,
                                readings, options.solve.cancelled);
    if (!refit.converged) break;
    left_out.push_back(worst);
    active = without;
    fit = std::move(refit);
  }
  report.converged = fit.converged;
  report.message = fit.message;
  if (options.thermal_growth) {
    report.message += fmt::format(FMT_STRING("; the arm grown by {:+.1f} ppm since the reference"),
                                  fit.growth * 1e6);
  }
  report.iterations = fit.iterations;
  const CalibrationParameters p = fit.p;
  const Eigen::MatrixXd& j = fit.jacobian;
  Eigen::VectorXd e(2 * active.size());
  std::vector<Pose> now_used, before_used;
  for (std::size_t k = 0; k < active.size(); ++k) {
    e.segment<2>(2 * static_cast<Eigen::Index>(k)) = fit.misses.segment<2>(2 * active[k]);
    now_used.push_back(now[static_cast<std::size_t>(active[k])]);
    before_used.push_back(before[static_cast<std::size_t>(active[k])]);
  }
  const int m = static_cast<int>(active.size());

  const UnitCovariance unit = unitCovariance(j);
  report.rank = unit.rank;
  report.condition_number = unit.condition;
  report.poses_used = m;
  report.dof = 2 * m - unknowns;
  detail::applyNoise(report, options.solve, e.squaredNorm() / 2);
  // The noise is given and known; a few poses' chi-square above 1 is chance, and scaling the
  // sigma by it would call an unchanged robot marginal. Only a misfit the noise cannot explain
  // (p < 1%) scales it, and the gate then judges it.
  if (report.chi2_p_value && *report.chi2_p_value >= 0.01) {
    report.noise_scale = 1;
    report.noise_mm = sigma;
  }
  const double pair_variance = 2 * report.noise_mm * report.noise_mm;
  Eigen::MatrixXd cov = pair_variance * unit.cov;

  // What the link tolerances leave: their effect on the misses at the joints now less their
  // effect at the reference's joints (docs/maths.md section 10).
  const ModelTolerances& t = options.solve.model;
  Eigen::MatrixXd model_cov = Eigen::MatrixXd::Zero(unknowns, unknowns);
  if (t.counted() && unit.rank == unknowns) {
    const Eigen::MatrixXd g =
        detail::linkSpread(cell, now_used, p, readings, t) -
        detail::linkSpread(cell, before_used, reference.estimate, readings, t);
    const Eigen::MatrixXd s = unit.cov * j.transpose() * g;
    model_cov = s * s.transpose();
    cov += model_cov;
  }
  const double reseat_variance = reseatVariance(options);
  if (reseat_variance > 0 && unit.rank == unknowns)
    cov += reseatCovariance(unit.cov, j, centreJacobian(cell, now_used, p, fit.growth, readings),
                            reseat_variance);
  report.model_length_mm = t.length_mm;
  report.model_angle_deg = t.angle_deg;
  report.model_calibrated = t.calibrated();
  if (cell.robot.hasGravityModel()) {
    report.model_sag_deg = t.sag_deg;
    report.model_sag_mean_deg = t.sag_mean_deg;
  }

  report.estimate = p;
  report.estimate.delta_rad = p.delta_rad - reference.estimate.delta_rad;
  const double quantile = detail::intervalQuantile(report);
  const auto slot = [&](int k) {
    const auto it = std::find(columns.begin(), columns.end(), k);
    return it == columns.end() ? -1 : static_cast<int>(it - columns.begin());
  };
  report.not_identifiable.push_back({"delta1_deg", delta1Reason()});
  report.not_identifiable.push_back({"delta6_deg", delta6Reason()});
  for (int k = 0; k < kIdentifiedCount; ++k) {
    ParameterEstimate pe;
    pe.name = unknownName(k);
    const int c = slot(k);
    const double unit_factor = k < kOffsetCount ? kRadToDeg : 1.0;
    pe.value =
        k < kOffsetCount ? report.estimate.delta_rad[k] * kRadToDeg : p.laser[k - kOffsetCount];
    if (c >= 0) {
      pe.sigma = std::sqrt(cov(c, c)) * unit_factor;
      pe.model_sigma = std::sqrt(model_cov(c, c)) * unit_factor;
      pe.identifiable = std::isfinite(pe.sigma);
      if (!pe.identifiable)
        pe.reason = "the re-measured poses do not determine it (rank " + std::to_string(unit.rank) +
                    " of " + std::to_string(unknowns) + ")";
    } else {
      pe.reason = "held at the reference's: the laser was not re-mounted";
    }
    if (k < kOffsetCount && pe.identifiable && !(pe.sigma <= options.solve.required_accuracy_deg)) {
      pe.identifiable = false;
      pe.reason = "its change is known only to " + detail::fixedText(pe.sigma, 4) +
                  " deg (one standard deviation); the required accuracy is " +
                  detail::fixedText(options.solve.required_accuracy_deg, 4) + " deg";
    }
    pe.ci95_low = pe.value - quantile * pe.sigma;
    pe.ci95_high = pe.value + quantile * pe.sigma;
    if (c >= 0 && !pe.identifiable) report.not_identifiable.push_back({pe.name, pe.reason});
    report.parameters.push_back(pe);
  }
  for (int k = kIdentifiedCount; k < kUnknownCount; ++k) {
    const int c = slot(k);
    report.target_sigma_mm[k - kIdentifiedCount] = c >= 0 ? std::sqrt(cov(c, c)) : 0.0;
  }
  report.correlation = Eigen::MatrixXd::Constant(kIdentifiedCount, kIdentifiedCount, NAN);
  for (int a = 0; a < kIdentifiedCount; ++a)
    for (int b = 0; b < kIdentifiedCount; ++b)
      if (slot(a) >= 0 && slot(b) >= 0)
        report.correlation(a, b) =
            cov(slot(a), slot(b)) / std::sqrt(cov(slot(a), slot(a)) * cov(slot(b), slot(b)));

  const std::vector<double> stand = standoffs(cell, now, p);
  double rss = 0;
  for (int i = 0; i < n; ++i) {
    PoseResidual r;
    r.source_line = now[static_cast<std::size_t>(i)].source_line;
    r.miss_mm = fit.misses.segment<2>(2 * i);
    r.miss_norm_mm = r.miss_mm.norm();
    r.normalised = r.miss_norm_mm / std::sqrt(pair_variance);
    r.standoff_mm = stand[static_cast<std::size_t>(i)];
    r.used = std::find(active.begin(), active.end(), i) != active.end();
    r.outlier = !r.used;
    if (r.used) rss += r.miss_mm.squaredNorm();
    report.poses.push_back(r);
  }
  report.rms_miss_mm = std::sqrt(rss / m);
  for (const int i : left_out) {
    report.remeasure.push_back(i + 1);
    report.suspect_poses.push_back(
        {i + 1, now[static_cast<std::size_t>(i)].source_line,
         "its miss differs from the reference's by " +
             detail::fixedText(report.poses[static_cast<std::size_t>(i)].normalised, 1) +
             " sigmas of a pair, beyond chance: disturbed in this session or in the reference's "
             "(stray light, an unsettled reading); left out",
         std::numeric_limits<double>::quiet_NaN()});
  }

  std::vector<std::string> problems;
  const double shift = (p.target_mm - reference.estimate.target_mm).norm();
  if (!options.psd_remounted && 2 * m > unknowns + kTargetCount) {
    // The PSD taken as where the reference had it: were it moved, the change would take the
    // move for a change of the zeros. The same poses with its centre free tell: a centre
    // significantly elsewhere (chi-square of 3 at 0.1%) is a PSD moved.
    std::vector<int> with_centre = columns;
    for (int k = kIdentifiedCount; k < kUnknownCount; ++k) with_centre.push_back(k);
    const ChangeFit free = fitChange(cell, now, reference_misses, reference.estimate, with_centre,
                                     active, readings, options.solve.cancelled);
    const UnitCovariance u = unitCovariance(free.jacobian);
    if (free.converged && u.rank == static_cast<int>(with_centre.size())) {
      const int c = static_cast<int>(columns.size());
      const Eigen::Vector3d moved = free.p.target_mm - reference.estimate.target_mm;
      // A centre within the base's repeatability is the PSD seated again, not moved.
      const Eigen::Matrix3d cov_moved =
          pair_variance * u.cov.block<3, 3>(c, c) + reseat_variance * Eigen::Matrix3d::Identity();
      const double chi2 = moved.dot(cov_moved.ldlt().solve(moved));
      constexpr double kChi2Of3At0_1Percent = 16.27;
      if (chi2 > kChi2Of3At0_1Percent)
        problems.push_back(
            "the PSD has moved since the reference: with its centre free the poses put it " +
            detail::fixedText(moved.norm(), 3) + " mm from where the reference found it (" +
            detail::fixedText(std::sqrt(chi2), 1) +
            " sigmas); put it back on its base as the reference had it, or take a new "
            "reference");
    }
  }
  if (!(shift <= options.max_psd_shift_mm))
    problems.push_back(
        "the PSD's centre is " + detail::fixedText(shift, 1) +
        " mm from where the reference found it, beyond the " +
        detail::fixedText(options.max_psd_shift_mm, 1) +
        " mm within which the robot's link errors cancel: put the PSD back on its base as the "
        "reference had it, or take a new reference");
  report.verdict =
      detail::judge(report, options.solve, problems, detail::MissesAgainst::kReference);
  return report;
}

Eigen::Vector4d predictChangeSigma(const CellModel& cell, const ReferenceFit& reference,
                                   const std::vector<int>& pairs, const ChangeOptions& given) {
  const ChangeOptions options = withCellNoise(cell, given);
  if (const std::string why = options.validate(); !why.empty()) throw InputError(why);
  const std::vector<Pose> poses = pairedReference(reference, pairs);
  const bool readings = readingsOf(poses, poses, options.solve);
  const Eigen::MatrixXd j =
      changeJacobian(cell, poses, reference.estimate, 0, readings, freeColumns(options));
  const UnitCovariance unit = unitCovariance(j);
  Eigen::Vector4d out = Eigen::Vector4d::Constant(kInfinity);
  if (unit.rank < j.cols()) return out;
  const double sigma = *options.solve.noise_mm;
  Eigen::MatrixXd cov = 2 * sigma * sigma * unit.cov;
  if (const double v = reseatVariance(options); v > 0)
    cov += reseatCovariance(unit.cov, j,
                            centreJacobian(cell, poses, reference.estimate, 0, readings), v);
  for (int k = 0; k < kOffsetCount; ++k) out[k] = std::sqrt(cov(k, k)) * kRadToDeg;
  return out;
}

std::vector<int> choosePosesForCheck(const CellModel& cell, const ReferenceFit& reference,
                                     const ChangeOptions& given, double sigma_deg, int at_least) {
  const ChangeOptions options = withCellNoise(cell, given);
  if (const std::string why = options.validate(); !why.empty()) throw InputError(why);
  const int count = static_cast<int>(reference.poses.size());
  const int unknowns = changeUnknownCount(options);
  const int fewest = std::max(unknowns / 2 + 1, at_least);
  std::vector<int> all(static_cast<std::size_t>(count));
  for (int i = 0; i < count; ++i) all[static_cast<std::size_t>(i)] = i;
  if (count <= fewest) return all;
  const std::vector<int> columns = freeColumns(options);
  const bool readings = readingsOf(reference.poses, reference.poses, options.solve);
  const Eigen::MatrixXd j =
      changeJacobian(cell, reference.poses, reference.estimate, 0, readings, columns);
  // Column scales over every pose, and a small ridge in those units: a set still too small to
  // determine every unknown is then ranked by how far it gets (the ridge is what it lacks).
  Eigen::VectorXd scale = j.colwise().norm().transpose() / std::sqrt(double(count));
  for (Eigen::Index k = 0; k < scale.size(); ++k)
    if (!(scale[k] > 0)) scale[k] = 1;
  const Eigen::MatrixXd js = j * scale.cwiseInverse().asDiagonal();
  // The centre's columns, for what the PSD's re-seating leaves (as solveChange counts it).
  const Eigen::MatrixXd jc = centreJacobian(cell, reference.poses, reference.estimate, 0, readings);
  const double noise_variance = 2 * *options.solve.noise_mm * *options.solve.noise_mm;
  const double reseat_variance = reseatVariance(options);
  const auto worst = [&](const Eigen::MatrixXd& info, const Eigen::MatrixXd& cross) {
    const Eigen::MatrixXd inv =
        info.ldlt().solve(Eigen::MatrixXd::Identity(info.rows(), info.cols()));
    const Eigen::MatrixXd s = inv * cross;
    double w = 0;
    for (int k = 0; k < kOffsetCount; ++k)
      w = std::max(w, (noise_variance * inv(k, k) + reseat_variance * s.row(k).squaredNorm()) /
                          (scale[k] * scale[k]));
    return std::sqrt(w) * kRadToDeg;
  };
  std::vector<int> chosen;
  std::vector<bool> taken(static_cast<std::size_t>(count), false);
  Eigen::MatrixXd info =
      1e-6 * Eigen::MatrixXd::Identity(static_cast<Eigen::Index>(columns.size()),
                                       static_cast<Eigen::Index>(columns.size()));
  Eigen::MatrixXd cross = Eigen::MatrixXd::Zero(info.rows(), kTargetCount);
  while (static_cast<int>(chosen.size()) < count) {
    int best = -1;
    double best_worst = kInfinity;
    for (int i = 0; i < count; ++i) {
      if (taken[static_cast<std::size_t>(i)]) continue;
      const Eigen::MatrixXd rows = js.middleRows(2 * i, 2);
      const double w =
          worst(info + rows.transpose() * rows, cross + rows.transpose() * jc.middleRows(2 * i, 2));
      if (w < best_worst) best_worst = w, best = i;
    }
    const Eigen::MatrixXd rows = js.middleRows(2 * best, 2);
    info += rows.transpose() * rows;
    cross += rows.transpose() * jc.middleRows(2 * best, 2);
    taken[static_cast<std::size_t>(best)] = true;
    chosen.push_back(best);
    if (static_cast<int>(chosen.size()) >= fewest && best_worst <= sigma_deg) {
      std::vector<int> sorted = chosen;
      std::sort(sorted.begin(), sorted.end());
      const Eigen::Vector4d predicted = predictChangeSigma(cell, reference, sorted, options);
      if (predicted.maxCoeff() <= sigma_deg) return sorted;
    }
  }
  return all;
}

void refuseWithoutChange(SolveReport& change) {
  for (int k = 0; k < kOffsetCount && k < static_cast<int>(change.parameters.size()); ++k) {
    const ParameterEstimate& pe = change.parameters[static_cast<std::size_t>(k)];
    if (!(std::abs(pe.value) <= 3 * pe.sigma)) return;
  }
  change.verdict.usable = false;
  change.verdict.reasons.push_back(
      "no change: every zero is within three sigmas of the reference's, nothing to write");
}

CheckJudgement judgeCheck(const SolveReport& change, double bound_deg) {
  CheckJudgement out;
  out.bound_deg = bound_deg;
  // A one-sided 95% bound on each change within the bound: the zero is where the reference had it.
  constexpr double kOneSided95 = 1.6448536269514722;
  bool all_within = change.verdict.usable;
  std::string moved;
  for (int k = 0; k < kOffsetCount && k < static_cast<int>(change.parameters.size()); ++k) {
    const ParameterEstimate& pe = change.parameters[static_cast<std::size_t>(k)];
    const double size = std::abs(pe.value);
    if (!(size + kOneSided95 * pe.sigma <= bound_deg)) all_within = false;
    if (change.converged && std::isfinite(pe.sigma) && size > bound_deg && size > 3 * pe.sigma) {
      out.joints.push_back(k + 2);
      moved += (moved.empty() ? "" : ", ") +
               fmt::format(FMT_STRING("joint {} by {:+.4f} deg (sigma {:.4f})"), k + 2, pe.value,
                           pe.sigma);
    }
  }
  const std::string bound = fmt::format(FMT_STRING("{:.4f}"), bound_deg);
  if (!out.joints.empty()) {
    out.outcome = CheckJudgement::Outcome::kChanged;
    out.summary = "changed since the reference: " + moved + "; a restore brings it back";
  } else if (all_within) {
    out.outcome = CheckJudgement::Outcome::kPass;
    out.summary = "pass: every zero within " + bound + " deg of the reference's (95% one-sided)";
  } else {
    out.outcome = CheckJudgement::Outcome::kMarginal;
    out.summary = "marginal: no zero is shown to have moved beyond " + bound +
                  " deg, nor every one to be within it" +
                  (change.verdict.reasons.empty() ? "" : " (" + change.verdict.reasons[0] + ")") +
                  "; check again, or restore";
  }
  return out;
}

}  // namespace zerocal
