// Pose planning: joint sets that aim the laser at a nominal target, and the uncertainty they
// will give, before any robot moves.
#pragma once

#include <Eigen/Core>
#include <functional>
#include <optional>
#include <string>
#include <vector>

#include "zerocal/calib/cell_model.h"
#include "zerocal/results/plan.h"

namespace zerocal {

// Joints that put the nominal laser's point at `target - standoff * beam` with its direction
// along `beam` (unit, pointing from laser to target), found by damped Gauss-Newton from `seed`
// (minimum-norm steps, so the free roll about the beam stays near the seed's). With
// `joint1_fixed`, joint 1 keeps the seed's value. Empty when it does not converge or ends
// outside the limits less margin_deg.
std::optional<Joints> aimLaser(const CellModel& cell, const Eigen::Vector3d& target,
                               const Eigen::Vector3d& beam, double standoff_mm, const Joints& seed,
                               double margin_deg, bool joint1_fixed = false);

// Joints near `start` for which the line of the given (true) parameters passes through `point`:
// what a perfect PSD servo would record. Minimum-norm steps over all six joints.
std::optional<Joints> servoOnto(const CellModel& cell, const CalibrationParameters& params,
                                const Eigen::Vector3d& point, const Joints& start);

// The Cramer-Rao bound of the point-to-line model at the given poses, with the target as a
// nuisance parameter (the 8 x 8 block of the 11 x 11 inverse information), for sigma_mm. With
// poses at several placements, that of the several-placement model: each placement's centre a
// nuisance, the link errors identified where the base-parameter analysis keeps them (their
// sigmas in link_sigma); the centres are where each placement's nominal lines cross.
// `tolerances`: what the solve will count beside the noise (SolveOptions::model, the robot
// model's own), added as the solve adds them (its consider covariance), so
// that the prediction is what the solve will report; zero: the noise alone.
Prediction predictUncertainty(const CellModel& cell, const std::vector<Pose>& poses,
                              const CalibrationParameters& at, double sigma_mm,
                              const ModelTolerances& tolerances = {});

enum class Pattern { kI, kII, kMixed, kOptimal };
// "I", "II", "mixed", "optimal" (case-insensitive for the roman numerals); throws InputError.
Pattern parsePattern(const std::string& text);
std::string patternName(Pattern p);

// Seconds the robot takes to move from one joint set to another.
using TravelTime = std::function<double(const Joints& from, const Joints& to)>;

// Puts the poses in the order that visits them all in the least time: an open tour (the robot's
// pose before the first is not known when planning), the best of a nearest-neighbour tour from
// every pose, each improved by reversing stretches (2-opt) and moving them (or-opt) until
// neither shortens it. The poses are unchanged, only their order: half the cell time of a
// calibration is moves between poses, and the optimal selection's order crosses the workspace.
void orderForTravel(std::vector<Pose>& poses, const TravelTime& travel_s);
// The time of visiting the poses in their order.
double tourSeconds(const std::vector<Pose>& poses, const TravelTime& travel_s);

struct PlanOptions {
  Pattern pattern = Pattern::kOptimal;
  int poses = 8;
  double noise_mm = 0.05 / 1.7320508075688772;  // uniform +-0.05 mm
  double standoff_min_mm = 300, standoff_max_mm = 800;
  double margin_deg = 5;                                  // kept from every joint limit
  double max_incidence_deg = 60;                          // beam angle from the PSD normal
  Eigen::Vector3d psd_normal = Eigen::Vector3d::UnitZ();  // the PSD faces up by default
  double sweep_deg = 45;                                  // patterns I and II: beam tilt range, +-
  bool joint1_fixed = false;  // pattern II only: hold joint 1 exactly constant
  // More PSD placements: the centres (base frame, mm) of placements 2, 3, ...; the target given
  // to planPoses is placement 1's. `poses` are planned at each placement (the same pattern,
  // aimed at that centre), each pose carrying its placement number. Empty: one placement.
  std::vector<Eigen::Vector3d> more_placements;
  // The controller's time for a move between two poses (s). Given, each placement's poses are
  // visited in the order that takes least time (orderForTravel); empty, in the order chosen.
  TravelTime travel_s;
  // What the solve will count beside the noise, for the plan's prediction (predictUncertainty).
  ModelTolerances tolerances;
  std::string validate() const;
};

// A default spread of `count` PSD placements (1..kMaxDefaultPlacements) around the first, on
// the robot's side of the cell: the first is `first`; the others turned about the base z axis
// by +-50 and +-100 deg and raised or lowered 200 mm, so that the arm reaches them with its
// upper arm and forearm in different configurations. Returns placements 2..count's centres.
// Throws InputError for a count outside the range.
std::vector<Eigen::Vector3d> defaultPlacements(const Eigen::Vector3d& first, int count);

// Throws InputError when the options are invalid or too few reachable poses exist.
Plan planPoses(const CellModel& cell, const Eigen::Vector3d& target, const PlanOptions& options);

}  // namespace zerocal
