// The change of the zeros since a reference (docs/maths.md section 10): a session re-measures
// poses of a reference session, each from the joints the reference recorded, and what it finds is
// the change of delta2..delta5 since then. The link errors the method cannot identify cancel: at
// the same joints they move the beam alike in both sessions, so what is left of them is the
// difference of their effect between the two joint sets, which is counted (as a consider
// covariance) and small. A check re-measures a few poses, a restore all of them.
#pragma once

#include <vector>

#include "zerocal/calib/cell_model.h"
#include "zerocal/calib/solver.h"
#include "zerocal/results/check_judgement.h"
#include "zerocal/results/solve_report.h"

namespace zerocal {

// A reference as the change is measured against it: the poses it recorded (those its solve used)
// and its own solve's parameters (the laser line and the PSD centre it found).
struct ReferenceFit {
  std::vector<Pose> poses;
  CalibrationParameters estimate;
};

// Beyond a millimetre a PSD is not seated again on its base but moved: take a new reference.
constexpr double kMostBaseRepeatabilityMm = 1.0;

struct ChangeOptions {
  // The noise (given, per measurement: each pair of poses has twice its variance), the link and
  // sag tolerances counted, the required accuracy and the gates: as the solve's.
  SolveOptions solve;
  // The PSD stands where the reference had it (on its base in the cell): its centre is the
  // reference's, and the same poses fitted with it free tell whether it moved (the verdict then
  // refuses the change). With psd_remounted, the centre is an unknown of the change (3 more;
  // delta2 is then much less well determined, a turn of joint 2 moving the beams as a move of the
  // centre does), and a centre further than max_psd_shift_mm from the reference's is refused: the
  // poses then no longer see the arm where the reference saw it, and the link errors no longer
  // cancel.
  bool psd_remounted = false;
  double max_psd_shift_mm = 5.0;
  // How closely the PSD's base puts it back where it stood (one sigma per axis, mm, of each
  // seating). The reference and this session are two seatings, so the centre may differ by
  // sqrt(2) of it on each axis, which no pose tells from a turn of joint 2 or 3 (they move every
  // beam alike); it is counted as a consider covariance of the change, in the pose choice, and in
  // the "PSD has moved" test. Not with psd_remounted (the centre is then an unknown).
  double psd_base_repeatability_mm = 0;
  // The arm's thermal state may differ from the reference's: its uniform growth (every link
  // length times 1 + g, 23 ppm per kelvin of an aluminium arm) is an unknown of the change, so
  // that a reference taken warm and a restore taken cold do not bias the zeros (delta3 moves by
  // about 6e-5 deg per ppm on the IRB 1600's plans, docs/simulated-cell.md).
  bool thermal_growth = false;
  // The laser was taken off the flange and put back: its four parameters are unknowns too.
  bool laser_remounted = false;
  // Returns a description of the first problem, or empty when usable.
  std::string validate() const;
};

// The number of unknowns of a change with these options: 4 offsets, the PSD centre's 3 when
// re-mounted, the laser's 4 when re-mounted.
int changeUnknownCount(const ChangeOptions& options);

// The change since `reference` from poses `now`, now[k] re-measuring reference.poses[pairs[k]].
// The report's offsets (parameters delta2..delta5, estimate.delta_rad) are the change since the
// reference, the values that written into the controller bring its zeros back to the
// reference's; its laser and target are the line and PSD centre now; its poses' misses are the
// differences of the pairs. Its verdict says whether each change is known to the required
// accuracy, the misses agree with the noise, and the PSD is where the reference had it. Throws
// InputError for pairs that do not name reference poses, fewer poses than unknowns need, or
// invalid options.
SolveReport solveChange(const CellModel& cell, const ReferenceFit& reference,
                        const std::vector<Pose>& now, const std::vector<int>& pairs,
                        const ChangeOptions& options);

// The predicted one-sigma uncertainty of each offset's change (deg) when the reference poses at
// `pairs` are re-measured (the noise alone: at the same joints the link errors cancel). Infinite
// where the poses do not determine it.
Eigen::Vector4d predictChangeSigma(const CellModel& cell, const ReferenceFit& reference,
                                   const std::vector<int>& pairs, const ChangeOptions& options);

// The reference poses a check re-measures: the fewest (at least `at_least`, and enough for the
// unknowns with a degree of freedom to spare) whose
// predicted sigma of every offset's change is at most `sigma_deg`, chosen greedily for the
// largest gain, in reference order; all of them when even all do not reach it.
std::vector<int> choosePosesForCheck(const CellModel& cell, const ReferenceFit& reference,
                                     const ChangeOptions& options, double sigma_deg,
                                     int at_least = 0);

// A restore whose change is not significant (every offset's within three of its sigmas) has
// nothing to write: its verdict is made not usable, saying so. Otherwise leaves it as it is.
void refuseWithoutChange(SolveReport& change);

// What a check concludes from a change: each zero within `bound_deg` of the reference's with 95%
// confidence (pass); one or more moved beyond the bound by more than three of their sigmas
// (changed, naming them); or neither (marginal).
CheckJudgement judgeCheck(const SolveReport& change, double bound_deg);

}  // namespace zerocal
