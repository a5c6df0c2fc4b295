#include "zerocal/calib/planner.h"

#include <ceres/jet.h>

#include <Eigen/Dense>
#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <limits>
#include <numeric>
#include <random>
#include <sstream>

#include "solver_detail.h"
#include "zerocal/calib/identifiability.h"
#include "zerocal/error.h"
#include "zerocal/model/kinematics.h"

namespace zerocal {
namespace {

using Jet6 = ceres::Jet<double, kJointCount>;
using Vector6d = Eigen::Matrix<double, 6, 1>;

// Damped, minimum-norm Gauss-Newton on the joints: residual(q) -> (r, J) with J = dr/dq.
// Steps are clamped so that a far seed walks rather than jumps between branches.
template <int R, typename Residual>
std::optional<Vector6d> minimumNormSolve(Vector6d q, const Residual& residual,
                                         const std::array<bool, kJointCount>& frozen) {
  constexpr double kMaxStep = 0.2;  // rad
  for (int iter = 0; iter < 200; ++iter) {
    Eigen::Matrix<double, R, 1> r;
    Eigen::Matrix<double, R, kJointCount> jac;
    residual(q, &r, &jac);
    if (!r.allFinite()) return std::nullopt;
    if (r.norm() < 1e-10) return q;
    for (int j = 0; j < kJointCount; ++j)
      if (frozen[j]) jac.col(j).setZero();
    const Eigen::Matrix<double, R, R> jjt =
        jac * jac.transpose() + 1e-9 * Eigen::Matrix<double, R, R>::Identity();
    Vector6d step = -jac.transpose() * jjt.ldlt().solve(r);
    const double big = step.cwiseAbs().maxCoeff();
    if (big > kMaxStep) step *= kMaxStep / big;
    q += step;
  }
  return std::nullopt;
}

Joints toDegrees(const Vector6d& q) {
  Joints out;
  for (int i = 0; i < kJointCount; ++i) out[i] = q[i] * kRadToDeg;
  return out;
}

Vector6d toRadians(const Joints& q) {
  Vector6d out;
  for (int i = 0; i < kJointCount; ++i) out[i] = q[i] * kDegToRad;
  return out;
}

// Frame of the flange with Jets: derivative of everything with respect to the six joints.
Frame<Jet6> flangeJet(const CellModel& cell, const Vector6d& q_rad, const Joints& delta_deg) {
  // A calibrated robot's compliance turns joints 2 and 3 with the pose: its change with the
  // joints is far below what the Gauss-Newton steps need, so the deflection is a constant here.
  const Joints sag = complianceDeflectionDeg(cell.robot, toDegrees(q_rad));
  Jet6 joints[kJointCount];
  for (int i = 0; i < kJointCount; ++i)
    joints[i] = Jet6(q_rad[i] + (delta_deg[i] + sag[i]) * kDegToRad, i);
  return flangePose(cell.robot, joints);
}

}  // namespace

std::optional<Joints> aimLaser(const CellModel& cell, const Eigen::Vector3d& target,
                               const Eigen::Vector3d& beam, double standoff_mm, const Joints& seed,
                               double margin_deg, bool joint1_fixed) {
  const Eigen::Vector3d b = beam.normalized();
  const Eigen::Vector3d origin = target - standoff_mm * b;
  // Direction errors weigh as millimetres at this lever arm.
  const double w = 500.0;
  const double kappa[kLaserParamCount] = {0, 0, 0, 0};
  Eigen::Vector3d p_e, d_e;
  cell.laser.line(kappa, &p_e, &d_e);
  auto residual = [&](const Vector6d& q, Eigen::Matrix<double, 6, 1>* r,
                      Eigen::Matrix<double, 6, kJointCount>* jac) {
    const Frame<Jet6> f = flangeJet(cell, q, Joints{});
    const Vec3<Jet6> d = f.R * d_e.cast<Jet6>();
    const Vec3<Jet6> p = f.apply(p_e.cast<Jet6>());
    for (int k = 0; k < 3; ++k) {
      const Jet6 rd = (d[k] - Jet6(b[k])) * w;
      const Jet6 rp = p[k] - Jet6(origin[k]);
      (*r)[k] = rd.a;
      (*r)[3 + k] = rp.a;
      jac->row(k) = rd.v.transpose();
      jac->row(3 + k) = rp.v.transpose();
    }
  };
  std::array<bool, kJointCount> frozen{};
  frozen[0] = joint1_fixed;
  const auto q = minimumNormSolve<6>(toRadians(seed), residual, frozen);
  if (!q) return std::nullopt;
  const Joints deg = toDegrees(*q);
  if (!cell.robot.withinLimits(deg, margin_deg)) return std::nullopt;
  return deg;
}

std::optional<Joints> servoOnto(const CellModel& cell, const CalibrationParameters& params,
                                const Eigen::Vector3d& point, const Joints& start) {
  Eigen::Vector3d p_e, d_e;
  cell.laser.line(params.laser.data(), &p_e, &d_e);
  const Joints delta = params.offsetsDeg();
  auto residual = [&](const Vector6d& q, Eigen::Matrix<double, 3, 1>* r,
                      Eigen::Matrix<double, 3, kJointCount>* jac) {
    const Frame<Jet6> f = flangeJet(cell, q, delta);
    const Vec3<Jet6> d = f.R * d_e.cast<Jet6>();
    const Vec3<Jet6> w = point.cast<Jet6>() - f.apply(p_e.cast<Jet6>());
    const Vec3<Jet6> miss = w - w.dot(d) * d;  // perpendicular miss of the line
    for (int k = 0; k < 3; ++k) {
      (*r)[k] = miss[k].a;
      jac->row(k) = miss[k].v.transpose();
    }
  };
  const auto q = minimumNormSolve<3>(toRadians(start), residual, {});
  if (!q) return std::nullopt;
  return toDegrees(*q);
}

namespace {

Prediction predictSeveralPlacements(const CellModel& cell, const std::vector<Pose>& poses,
                                    const CalibrationParameters& at, double sigma_mm,
                                    const ModelTolerances& tolerances) {
  // As the solve by default: the sag counted, not identified (docs/maths.md section 8).
  const PlacementLayout layout(poses, cell.robot, false);
  const auto targets = placementTargets(cell, poses, layout, at, false);
  // Planned poses aim the nominal lines exactly at their centres: the structural Jacobian.
  const Eigen::MatrixXd jac = placementJacobian(cell, poses, layout, at, targets, sigma_mm, false);
  const BaseParameters base = analyseBaseParameters(jac, layout);
  Prediction out;
  out.placements = layout.count();
  out.rank = base.count;
  Eigen::MatrixXd cov = baseCovariance(jac, base, &out.condition_number);
  cov += detail::placementModelCovariance(
      cell, poses, layout, base, jac,
      cov.unaryExpr([](double x) { return std::isfinite(x) ? x : 0.0; }), tolerances);
  constexpr double kMeaningfulDeg = 0.5;  // as with one placement
  double sum = 0;
  for (int k = 0; k < kIdentifiedCount; ++k) {
    const double unit = k < kOffsetCount ? kRadToDeg : 1.0;
    const double sigma = std::sqrt(cov(k, k)) * unit;
    const bool ok = base.identified[k] && (k >= kOffsetCount || sigma <= kMeaningfulDeg);
    out.sigma.push_back(base.identified[k] ? sigma : NAN);
    out.identifiable.push_back(ok);
    out.reason.push_back(ok ? std::string()
                         : base.identified[k]
                             ? "determined only to " + std::to_string(sigma) + " deg"
                             : base.reason[k]);
    if (k < kOffsetCount) sum += ok ? sigma * sigma : INFINITY;
  }
  out.rms_offset_sigma_deg = std::sqrt(sum / kOffsetCount);
  for (int l = 0; l < kLinkParameterCount; ++l) {
    const int k = PlacementLayout::firstLink() + l;
    out.link_identifiable.push_back(base.identified[k]);
    out.link_sigma.push_back(
        base.identified[k] ? std::sqrt(cov(k, k)) * (l % 3 == 2 ? kRadToDeg : 1.0) : NAN);
    out.link_reason.push_back(base.reason[k]);
  }
  return out;
}

}  // namespace

Prediction predictUncertainty(const CellModel& cell, const std::vector<Pose>& poses,
                              const CalibrationParameters& at, double sigma_mm,
                              const ModelTolerances& tolerances) {
  // As the solve: several placements with one sigma for every pose.
  if (placementCount(poses) > 1)
    return predictSeveralPlacements(atDetector(cell), poses, at, sigma_mm, tolerances);
  if (cell.noise.perPose()) sigma_mm = cell.noise.referenceMm();
  const Eigen::MatrixXd jac = pointToLineJacobian(cell, poses, at, sigma_mm, false);
  // A plan predicts; whether its accuracy is enough is the solve's verdict. Here an offset counts
  // as determined up to the half degree beyond which a value means nothing.
  constexpr double kMeaningfulDeg = 0.5;
  const Identifiability id = analyseIdentifiability(
      jac, cell, poses, at, 1.0, kMeaningfulDeg,
      "the largest sigma at which an offset's value means anything (whether the plan reaches the "
      "calibration's required accuracy is the daemon's verdict on it)");
  Eigen::MatrixXd cov = id.unit_covariance;  // jac is in noise sigmas: this is the covariance
  if (tolerances.counted()) {
    // As the solve: the link errors' (and sag's) consider covariance, with the misses in noise
    // sigmas.
    const Eigen::MatrixXd u = cov.unaryExpr([](double x) { return std::isfinite(x) ? x : 0.0; });
    const Eigen::MatrixXd s =
        u * jac.transpose() * detail::linkSpread(cell, poses, at, false, tolerances) / sigma_mm;
    if (s.allFinite()) cov += s * s.transpose();
  }
  Prediction out;
  out.rank = id.rank;
  out.condition_number = id.condition_number;
  double sum = 0;
  for (int k = 0; k < kIdentifiedCount; ++k) {
    const double unit = k < kOffsetCount ? kRadToDeg : 1.0;
    out.sigma.push_back(std::sqrt(cov(k, k)) * unit);
    out.identifiable.push_back(id.identifiable[k]);
    out.reason.push_back(id.reason[k]);
    if (k < kOffsetCount) sum += id.identifiable[k] ? out.sigma[k] * out.sigma[k] : INFINITY;
  }
  out.rms_offset_sigma_deg = std::sqrt(sum / kOffsetCount);
  return out;
}

Pattern parsePattern(const std::string& text) {
  std::string t = text;
  std::transform(t.begin(), t.end(), t.begin(), ::tolower);
  if (t == "i" || t == "1") return Pattern::kI;
  if (t == "ii" || t == "2") return Pattern::kII;
  if (t == "mixed") return Pattern::kMixed;
  if (t == "optimal") return Pattern::kOptimal;
  throw InputError("unknown pattern '" + text + "': use I, II, mixed or optimal");
}

std::string patternName(Pattern p) {
  switch (p) {
    case Pattern::kI:
      return "I";
    case Pattern::kII:
      return "II";
    case Pattern::kMixed:
      return "mixed";
    case Pattern::kOptimal:
      return "optimal";
  }
  return "?";
}

std::string PlanOptions::validate() const {
  std::ostringstream s;
  if (poses < kMinimumPoses)
    s << "at least " << kMinimumPoses << " poses are needed (8 or more recommended); ";
  if (poses > kMaxPlanPoses)
    s << "more than " << kMaxPlanPoses << " poses is not a calibration plan; ";
  if (!(noise_mm > 0)) s << "the noise level must be positive; ";
  if (!(standoff_min_mm > 0 && standoff_max_mm > standoff_min_mm))
    s << "the stand-off range must be positive and increasing; ";
  if (!(margin_deg >= 0)) s << "the joint-limit margin must not be negative; ";
  if (!(max_incidence_deg > 0 && max_incidence_deg < 90))
    s << "the largest incidence angle must lie between 0 and 90 deg; ";
  if (!(sweep_deg > 0 && sweep_deg < 90)) s << "the sweep must lie between 0 and 90 deg; ";
  if (!(psd_normal.norm() > 0.5)) s << "the PSD normal must be a non-zero vector; ";
  if (static_cast<int>(more_placements.size()) + 1 > kMaxPlacements)
    s << "at most " << kMaxPlacements << " placements; ";
  for (const auto& c : more_placements)
    if (!c.allFinite()) s << "every placement's centre must be finite; ";
  std::string out = s.str();
  if (!out.empty()) out.resize(out.size() - 2);
  return out;
}

namespace {

std::vector<Joints> seedsFor(const Eigen::Vector3d& target) {
  const double q1 = std::atan2(target.y(), target.x()) * kRadToDeg;
  std::vector<Joints> seeds;
  // Wrist seeds: both signs of joint 5 (away from the 4/6 singularity), three joint-4 turns,
  // and three joint-6 turns so that the roll about the beam varies (a laser along the flange
  // axis would otherwise keep joint 6 still, and delta5 would trade against its tilt).
  for (double q6 : {0.0, 120.0, -120.0})
    for (double q5 : {45.0, -45.0})
      for (double q4 : {0.0, 90.0, -90.0}) seeds.push_back({q1, 10, 0, q4, q5, q6});
  return seeds;
}

std::optional<Joints> aimFromSeeds(const CellModel& cell, const Eigen::Vector3d& target,
                                   const Eigen::Vector3d& beam, double standoff,
                                   const PlanOptions& o) {
  for (const Joints& seed : seedsFor(target))
    if (auto q = aimLaser(cell, target, beam, standoff, seed, o.margin_deg,
                          o.joint1_fixed && o.pattern == Pattern::kII))
      return q;
  return std::nullopt;
}

// Beams tilted about one base axis through the vertical, stand-offs spread over the range in
// an order unrelated to the tilt (so that neither trap of docs/maths.md is walked into).
std::vector<Pose> sweepPattern(const CellModel& cell, const Eigen::Vector3d& target, int n,
                               const Eigen::Vector3d& axis, const PlanOptions& o) {
  std::vector<Pose> poses;
  for (int i = 0; i < n; ++i) {
    const double phi = (-o.sweep_deg + 2 * o.sweep_deg * i / (n - 1)) * kDegToRad;
    const Eigen::Vector3d beam = Eigen::AngleAxisd(phi, axis) * Eigen::Vector3d(0, 0, -1);
    const double frac = n > 1 ? static_cast<double>((i * 3) % n) / (n - 1) : 0.5;
    const double planned = o.standoff_min_mm + (o.standoff_max_mm - o.standoff_min_mm) * frac;
    // Out of reach at the planned stand-off: try the others of the range, nearest first.
    std::vector<double> tries{planned};
    for (int k = 0; k <= 8; ++k)
      tries.push_back(o.standoff_min_mm + (o.standoff_max_mm - o.standoff_min_mm) * k / 8);
    std::stable_sort(tries.begin() + 1, tries.end(), [&](double a, double b) {
      return std::abs(a - planned) < std::abs(b - planned);
    });
    for (double standoff : tries)
      if (auto q = aimFromSeeds(cell, target, beam, standoff, o)) {
        poses.push_back({*q, {}, 0});
        break;
      }
  }
  return poses;
}

// What one candidate pose adds to a plan: its information J_i^T J_i and, with the link
// tolerances counted, J_i^T G_i (G_i: its misses' derivatives by the link parameters times their
// tolerances, in noise sigmas), whose sum over the plan is what the links move the estimate by.
using InfoMatrix = Eigen::Matrix<double, kUnknownCount, kUnknownCount>;
// a, d, alpha per joint and the sag of joints 2 and 3 (zero when not counted)
using LinkMatrix = Eigen::Matrix<double, kUnknownCount, 3 * kJointCount + kComplianceCount>;
struct CandidateInfo {
  std::vector<InfoMatrix> info;
  std::vector<LinkMatrix> link;  // empty: the model taken as exact
};

// A-optimal selection of n poses from the candidates: minimise the summed variance of
// delta2..delta5, plus a tenth of the laser's (slopes as radians, offsets as radians at a 600 mm
// lever arm) so that a set leaving the laser undetermined is never chosen; the target is a
// nuisance. The variance is the total the solve reports: the statistical part M^-1 and, with the
// link tolerances, their consider part M^-1 C C^T M^-1 (C the summed J_i^T G_i), which at one
// placement is the larger. Greedy start and random starts, each improved by exchange passes
// (Fedorov); the best wins. Deterministic: the random starts are seeded.
std::vector<int> selectOptimal(const CandidateInfo& candidates, int n) {
  using Mat = InfoMatrix;
  const std::vector<Mat>& info = candidates.info;
  const bool with_links = !candidates.link.empty();
  const int count = static_cast<int>(info.size());
  Mat ridge = Mat::Zero();
  for (const auto& m : info) ridge += m;
  // Keeps a rank-deficient sum invertible: its null directions then cost about 1e9 times more.
  ridge = 1e-9 * ridge.diagonal().mean() * Mat::Identity();
  // A plan's sums: its information and, with the links, its C.
  struct Sums {
    Mat info = Mat::Zero();
    LinkMatrix link = LinkMatrix::Zero();
  };
  const auto add = [&](Sums sums, int c, double sign) {
    sums.info += sign * info[c];
    if (with_links) sums.link += sign * candidates.link[c];
    return sums;
  };
  const Sums none;
  auto criterion = [&](const Sums& sums) {
    const Eigen::LDLT<Mat> ldlt(sums.info + ridge);
    if (ldlt.info() != Eigen::Success) return std::numeric_limits<double>::infinity();
    Mat inv = ldlt.solve(Mat::Identity());
    if (with_links) {  // only the diagonal of the offsets' and the laser's rows is summed
      const Eigen::Matrix<double, kIdentifiedCount, LinkMatrix::ColsAtCompileTime> moved =
          inv.topRows<kIdentifiedCount>() * sums.link;
      for (int k = 0; k < kIdentifiedCount; ++k) inv(k, k) += moved.row(k).squaredNorm();
    }
    double t = 0;
    for (int k = 0; k < kOffsetCount; ++k) t += inv(k, k);
    t += 0.1 * (inv(4, 4) + inv(5, 5) + (inv(6, 6) + inv(7, 7)) / (600.0 * 600.0));
    return t > 0 && std::isfinite(t) ? t : std::numeric_limits<double>::infinity();
  };
  auto sum = [&](const std::vector<int>& set) {
    Sums total = none;
    for (int c : set) total = add(std::move(total), c, 1);
    return total;
  };
  auto improve = [&](std::vector<int> chosen) {
    Sums total = sum(chosen);
    double current = criterion(total);
    for (int pass = 0; pass < 20; ++pass) {
      bool improved = false;
      for (int slot = 0; slot < n; ++slot) {
        const Sums without = add(total, chosen[slot], -1);
        int best = -1;
        double best_value = current * (1 - 1e-9);
        for (int c = 0; c < count; ++c) {
          if (std::find(chosen.begin(), chosen.end(), c) != chosen.end()) continue;
          const double v = criterion(add(without, c, 1));
          if (v < best_value) best_value = v, best = c;
        }
        if (best >= 0) {
          total = add(without, best, 1);
          chosen[slot] = best;
          current = best_value;
          improved = true;
        }
      }
      if (!improved) break;
    }
    return std::make_pair(current, chosen);
  };

  std::vector<int> greedy;
  Sums total = none;
  for (int slot = 0; slot < n; ++slot) {
    int best = -1;
    double best_value = std::numeric_limits<double>::infinity();
    for (int c = 0; c < count; ++c) {
      if (std::find(greedy.begin(), greedy.end(), c) != greedy.end()) continue;
      const double v = criterion(add(total, c, 1));
      if (v < best_value) best_value = v, best = c;
    }
    if (best < 0) best = slot;  // nothing finite yet: any pose will do as a start
    greedy.push_back(best);
    total = add(std::move(total), best, 1);
  }
  auto best = improve(greedy);
  std::mt19937 rng(12345);
  for (int restart = 0; restart < 3; ++restart) {
    std::vector<int> all(count);
    std::iota(all.begin(), all.end(), 0);
    std::shuffle(all.begin(), all.end(), rng);
    auto candidate = improve(std::vector<int>(all.begin(), all.begin() + n));
    if (candidate.first < best.first) best = candidate;
  }
  return best.second;
}

}  // namespace

double tourSeconds(const std::vector<Pose>& poses, const TravelTime& travel_s) {
  double total = 0;
  for (std::size_t i = 1; i < poses.size(); ++i)
    total += travel_s(poses[i - 1].q_deg, poses[i].q_deg);
  return total;
}

void orderForTravel(std::vector<Pose>& poses, const TravelTime& travel_s) {
  const int n = static_cast<int>(poses.size());
  if (n < 3 || !travel_s) return;
  Eigen::MatrixXd cost(n, n);
  for (int i = 0; i < n; ++i)
    for (int j = 0; j < n; ++j) cost(i, j) = i == j ? 0 : travel_s(poses[i].q_deg, poses[j].q_deg);
  const auto length = [&](const std::vector<int>& tour) {
    double total = 0;
    for (int k = 1; k < n; ++k) total += cost(tour[k - 1], tour[k]);
    return total;
  };
  // Reversing tour[i..j] changes only the legs into i and out of j (an open tour: the first and
  // last poses have one leg each); the costs are used as if symmetric, as a joint move's is.
  const auto twoOpt = [&](std::vector<int>& tour) {
    for (bool improved = true; improved;) {
      improved = false;
      for (int i = 0; i < n - 1; ++i)
        for (int j = i + 1; j < n; ++j) {
          const double before = (i > 0 ? cost(tour[i - 1], tour[i]) : 0) +
                                (j < n - 1 ? cost(tour[j], tour[j + 1]) : 0);
          const double after = (i > 0 ? cost(tour[i - 1], tour[j]) : 0) +
                               (j < n - 1 ? cost(tour[i], tour[j + 1]) : 0);
          if (after < before - 1e-9) {
            std::reverse(tour.begin() + i, tour.begin() + j + 1);
            improved = true;
          }
        }
    }
  };
  // Moving a stretch of one to three poses elsewhere in the tour, either way round (or-opt):
  // what reversals alone cannot reach.
  const auto orOpt = [&](std::vector<int>& tour) {
    const double current = length(tour);
    for (int size = 1; size <= 3; ++size)
      for (int from = 0; from + size <= n; ++from) {
        std::vector<int> rest = tour;
        rest.erase(rest.begin() + from, rest.begin() + from + size);
        for (int to = 0; to <= static_cast<int>(rest.size()); ++to)
          for (const bool reversed : {false, true}) {
            std::vector<int> candidate = rest;
            candidate.insert(candidate.begin() + to, tour.begin() + from,
                             tour.begin() + from + size);
            if (reversed) std::reverse(candidate.begin() + to, candidate.begin() + to + size);
            if (length(candidate) < current - 1e-9) {
              tour = std::move(candidate);
              return true;
            }
          }
      }
    return false;
  };
  std::vector<int> best(n);
  std::iota(best.begin(), best.end(), 0);
  double best_length = length(best);
  // Or-opt costs n^3 a pass: plans of more poses than a session has keep the reversals alone,
  // from a few starts.
  constexpr int kMostPolished = 40;
  const bool polish = n <= kMostPolished;
  for (int start = 0; start < n; start += polish ? 1 : n / 4) {
    std::vector<int> tour{start};
    std::vector<bool> visited(n, false);
    visited[start] = true;
    while (static_cast<int>(tour.size()) < n) {
      int next = -1;
      for (int c = 0; c < n; ++c)
        if (!visited[c] && (next < 0 || cost(tour.back(), c) < cost(tour.back(), next))) next = c;
      visited[next] = true;
      tour.push_back(next);
    }
    do twoOpt(tour);
    while (polish && orOpt(tour));
    if (const double l = length(tour); l < best_length - 1e-9) best_length = l, best = tour;
  }
  std::vector<Pose> ordered;
  ordered.reserve(n);
  for (int k : best) ordered.push_back(poses[k]);
  poses = std::move(ordered);
}

std::vector<Eigen::Vector3d> defaultPlacements(const Eigen::Vector3d& first, int count) {
  if (count < 1 || count > kMaxDefaultPlacements)
    throw InputError("the default placements are 1 to " + std::to_string(kMaxDefaultPlacements) +
                     "; give the centres of more");
  static const double turn_deg[kMaxDefaultPlacements] = {0, 50, -50, 100, -100};
  static const double raise_mm[kMaxDefaultPlacements] = {0, 200, -200, -200, 200};
  std::vector<Eigen::Vector3d> out;
  for (int k = 1; k < count; ++k)
    out.push_back(Eigen::AngleAxisd(turn_deg[k] * kDegToRad, Eigen::Vector3d::UnitZ()) * first +
                  Eigen::Vector3d(0, 0, raise_mm[k]));
  return out;
}

Plan planPoses(const CellModel& cell, const Eigen::Vector3d& target, const PlanOptions& given) {
  // Several placements are planned, predicted and solved with one sigma for every pose.
  if (!given.more_placements.empty() && cell.noise.perPose())
    return planPoses(atDetector(cell), target, given);
  // With the noise per pose, each candidate is weighed by its own covariance, in the model's
  // reference sigma.
  PlanOptions o = given;
  if (cell.noise.perPose()) o.noise_mm = cell.noise.referenceMm();
  if (const std::string problem = o.validate(); !problem.empty())
    throw InputError("plan options: " + problem);
  if (!o.more_placements.empty()) {
    // Each placement planned on its own, aimed at its centre; the prediction is the joint one.
    PlanOptions one = o;
    one.more_placements.clear();
    // Several placements identify the link errors together: a placement's poses are chosen for
    // what they measure, not for the link errors one placement alone would be left with.
    one.tolerances = {};
    Plan plan;
    std::vector<Eigen::Vector3d> centres{target};
    centres.insert(centres.end(), o.more_placements.begin(), o.more_placements.end());
    std::ostringstream what;
    what << centres.size() << " PSD placements, " << o.poses << " poses at each:";
    for (std::size_t p = 0; p < centres.size(); ++p) {
      Plan part;
      try {
        part = planPoses(cell, centres[p], one);
      } catch (const InputError& e) {
        throw InputError("placement " + std::to_string(p + 1) + ": " + e.what());
      }
      for (Pose pose : part.poses) {
        pose.placement = static_cast<int>(p + 1);
        plan.poses.push_back(pose);
      }
      plan.candidates_considered += part.candidates_considered;
      what << (p ? "; " : " ") << "placement " << p + 1 << " at (" << centres[p].x() << ", "
           << centres[p].y() << ", " << centres[p].z() << ") mm, " << part.description;
    }
    CalibrationParameters at;
    plan.prediction = predictUncertainty(cell, plan.poses, at, o.noise_mm, o.tolerances);
    plan.description = what.str();
    return plan;
  }
  if (!target.allFinite()) throw InputError("the target point must be finite");
  CalibrationParameters at;
  at.target_mm = target;
  Plan plan;
  std::ostringstream what;
  const Eigen::Vector3d normal = o.psd_normal.normalized();
  switch (o.pattern) {
    case Pattern::kI:
      plan.poses = sweepPattern(cell, target, o.poses, Eigen::Vector3d::UnitX(), o);
      what << "pattern I: beams tilted about the base x-axis, +-" << o.sweep_deg << " deg";
      break;
    case Pattern::kII:
      plan.poses = sweepPattern(cell, target, o.poses, Eigen::Vector3d::UnitY(), o);
      what << "pattern II: beams tilted about the base y-axis, +-" << o.sweep_deg << " deg"
           << (o.joint1_fixed ? ", joint 1 held constant" : "");
      break;
    case Pattern::kMixed: {
      plan.poses = sweepPattern(cell, target, o.poses / 2, Eigen::Vector3d::UnitX(), o);
      auto second = sweepPattern(cell, target, o.poses - o.poses / 2, Eigen::Vector3d::UnitY(), o);
      plan.poses.insert(plan.poses.end(), second.begin(), second.end());
      what << "mixed: " << o.poses / 2 << " poses of pattern I, " << o.poses - o.poses / 2
           << " of pattern II";
      break;
    }
    case Pattern::kOptimal: {
      // Candidates: beams within the incidence cone about the PSD normal, stand-offs across
      // the range, wrist configurations from several seeds.
      const Eigen::Vector3d u = normal.unitOrthogonal(), v = normal.cross(u);
      std::vector<Pose> candidates;
      for (double tilt = 0; tilt <= o.max_incidence_deg + 1e-9; tilt += o.max_incidence_deg / 4)
        for (double az = 0; az < 360 - 1e-9; az += tilt == 0 ? 360 : 30) {
          const double t = tilt * kDegToRad, a = az * kDegToRad;
          const Eigen::Vector3d toward_laser =
              std::cos(t) * normal + std::sin(t) * (std::cos(a) * u + std::sin(a) * v);
          for (int k = 0; k < 4; ++k) {
            const double s = o.standoff_min_mm + (o.standoff_max_mm - o.standoff_min_mm) * k / 3;
            for (const Joints& seed : seedsFor(target)) {
              const auto q = aimLaser(cell, target, -toward_laser, s, seed, o.margin_deg);
              if (!q) continue;
              bool duplicate = false;
              for (const auto& c : candidates) {
                double d = 0;
                for (int j = 0; j < kJointCount; ++j)
                  d = std::max(d, std::abs(c.q_deg[j] - (*q)[j]));
                duplicate = duplicate || d < 1.0;
              }
              if (!duplicate) candidates.push_back({*q, {}, 0});
            }
          }
        }
      plan.candidates_considered = static_cast<int>(candidates.size());
      if (static_cast<int>(candidates.size()) < o.poses)
        throw InputError("only " + std::to_string(candidates.size()) +
                         " reachable poses aim at the target; " + std::to_string(o.poses) +
                         " were asked for (move the target or widen the stand-off range)");
      const Eigen::MatrixXd jac = pointToLineJacobian(cell, candidates, at, o.noise_mm, false);
      const bool with_links = o.tolerances.counted();
      const Eigen::MatrixXd spread =
          with_links
              ? Eigen::MatrixXd(detail::linkSpread(cell, candidates, at, false, o.tolerances) /
                                o.noise_mm)
              : Eigen::MatrixXd();
      CandidateInfo info;
      for (std::size_t i = 0; i < candidates.size(); ++i) {
        const auto rows = jac.middleRows<2>(2 * i);
        info.info.push_back(rows.transpose() * rows);
        if (!with_links) continue;
        LinkMatrix link = LinkMatrix::Zero();
        link.leftCols(spread.cols()) = rows.transpose() * spread.middleRows<2>(2 * i);
        info.link.push_back(link);
      }
      for (int idx : selectOptimal(info, o.poses)) plan.poses.push_back(candidates[idx]);
      what << "optimal: the " << o.poses << " of " << candidates.size()
           << " reachable candidate poses that minimise the predicted "
           << (with_links ? "total (noise and link tolerances) " : "")
           << "variance of delta2..delta5";
      break;
    }
  }
  if (static_cast<int>(plan.poses.size()) < o.poses)
    throw InputError("only " + std::to_string(plan.poses.size()) + " of the " +
                     std::to_string(o.poses) + " poses of " + patternName(o.pattern) +
                     " are reachable inside the joint limits (less a " +
                     std::to_string(o.margin_deg) + " deg margin); move the target or change " +
                     "the stand-off range or sweep");
  if (o.travel_s) {
    orderForTravel(plan.poses, o.travel_s);
    what << "; in the order of least travel";
  }
  plan.prediction = predictUncertainty(cell, plan.poses, at, o.noise_mm, o.tolerances);
  plan.description = what.str();
  return plan;
}

}  // namespace zerocal
