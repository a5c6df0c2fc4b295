// Where the spot will land at the next planned pose, learned from the poses already servoed.
//
// The planner aims the nominal model at the taught PSD centre; joint offsets of up to a degree,
// the laser's mounting error and the teaching error put the real spot tens of millimetres away,
// more than a short search covers. Every servoed pose says where the real beam went, so a
// damped Gauss-Newton fit of the same unknowns as the solver (delta2..delta5, the laser's four
// parameters, the PSD centre, and delta1, delta6 which the solver cannot separate but which move
// the spot all the same) predicts the next miss; the servo's search then starts there.
// With few poses the fit is under-determined; the damping pulls each unknown towards its nominal
// value in units of its expected spread, so the prediction degrades gracefully to "no idea".
//
// Runs between poses, not in the servo cycle: it allocates.
#pragma once

#include <Eigen/Core>
#include <vector>

#include "zerocal/calib/cell_model.h"
#include "zerocal/psd/spot.h"

namespace zerocal::servo {

// delta1..delta6 (rad), the laser's four parameters, the centre's offset from the taught one (mm).
using PredictorState = Eigen::Matrix<double, 13, 1>;

class SpotPredictor {
 public:
  SpotPredictor(const CellModel& cell, const Eigen::Vector3d& taught_centre_mm);

  // Starts from the cell as an earlier calibration found it, whose joint offsets have since been
  // written to the controller (a verification): its laser line and PSD centre (`found.target_mm`,
  // base frame) are then known to a fraction of a millimetre, delta1 and delta6 are in them (the
  // solver's line and centre absorb both), and delta2..delta5 are expected near zero but keep
  // their full spread: a wrong transmission doubles an offset instead of removing it. From here
  // on predictions are made from the first pose.
  void startFrom(const CalibrationParameters& found);
  // A session that re-measures an earlier one's poses (a check, a restore or a verification
  // against its reference; each with its joints and reading): at joints near one of them the
  // spot is expected where that session read it, moved by what this session's poses show the
  // zeros to have changed by since (fitted from the first pose on, held towards no change). A
  // reading there is as good a prediction as the arm's scatter, where the cell's model misses
  // by its link errors (0.1..0.3 mm). Predictions are made from the first pose.
  void expectReadingsOf(const std::vector<Pose>& earlier);
  // The spot at q is predicted from an earlier reading moved by at most kNearReadingMm: as good
  // as the arm's scatter (the model's error in so small a move is a few micrometres).
  bool predictsFromReading(const Joints& q_deg) const;
  static constexpr double kNearReadingMm = 0.5;
  // A servoed pose: controller joints and the reading there (PSD frame, mm).
  void addPose(const Joints& q_deg, const PsdSpot& spot);
  // Where the spot is expected on the PSD (PSD frame, mm) at controller joints q.
  PsdSpot predict(const Joints& q_deg) const;
  // Where a search should start: predict() once kConfidentPoses poses are in, else (0, 0). One
  // pose helped on average with 5e-4 deg of repeatability, but with 0.02 mm (1.5e-3 deg) it sent
  // seed 40's second search more than 60 mm from the spot (spot not found); from two poses on,
  // 30 of 30 worlds (seeds 11..40) and 10 of 10 (1..10) complete (`zerocal-lab experiment cell`).
  PsdSpot searchCentre(const Joints& q_deg) const;
  // Joints near `planned` where the spot is predicted on the PSD's centre: `planned` moved along
  // the image Jacobian's pseudo-inverse (damping_mm as the servo's) until the prediction is
  // there. The planned move then ends on the detector instead of tens of millimetres off it, and
  // the search's walk to the prediction (in steps of at most the servo's max_step_deg) is not
  // needed. `planned` itself until confident(); the caller checks the limits.
  Joints aimedJoints(const Joints& planned, double damping_mm) const;
  static constexpr int kConfidentPoses = 2;
  int poseCount() const { return static_cast<int>(poses_.size()); }
  bool confident() const {
    return started_from_calibration_ || !earlier_.empty() || poseCount() >= kConfidentPoses;
  }

 private:
  // An earlier session's pose: its joints, its reading (PSD frame, mm).
  struct Earlier {
    Joints q_deg;
    Eigen::Vector2d spot;
  };
  void refit();
  void refitChange();
  Eigen::Vector2d spot(const PredictorState& x, const Joints& q) const;
  // The prediction at q: from the fitted model, or from the nearest earlier reading.
  Eigen::Vector2d predicted(const Joints& q) const;
  // The earlier pose whose joints are nearest q's, within kMostAimDeg; null when none is.
  const Earlier* nearestEarlier(const Joints& q) const;
  // The spot at q of the nominal cell with the zeros changed by change_ (rad), less the earlier
  // reading's nominal spot: what the earlier reading is moved by.
  Eigen::Vector2d changeAt(const Earlier& e, const Joints& q, const PredictorState& change) const;

  CellModel cell_;
  Eigen::Vector3d centre_;
  std::vector<std::pair<Joints, Eigen::Vector2d>> poses_;
  PredictorState x_ = PredictorState::Zero();
  // The prior: its mean (zero, the nominal cell, unless startFrom) and spread (one sigma).
  PredictorState prior_ = PredictorState::Zero();
  PredictorState spread_;
  bool started_from_calibration_ = false;
  std::vector<Earlier> earlier_;
  PredictorState change_ = PredictorState::Zero();  // delta1..delta6 since the earlier session
};

}  // namespace zerocal::servo
