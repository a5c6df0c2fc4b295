// The PSD measurement chain, whatever board reads it: the conditioning board's X, Y and SUM
// voltages averaged into one reading with its standard error (the board's readout does that,
// e.g. drivers/usb1408fs) -> spot present or not -> spot position in millimetres through a map
// fitted from a stage sweep, marked valid or not.
#pragma once

#include <array>
#include <chrono>
#include <cstddef>
#include <cstdint>
#include <istream>
#include <ostream>
#include <string>
#include <vector>

#include "zerocal/psd/spot.h"

namespace zerocal::psd {

// Block means in volts and their standard errors (sample std / sqrt(n)), in volts.
struct VoltageReading {
  double x = 0, y = 0, sum = 0;
  double x_se = 0, y_se = 0, sum_se = 0;
  std::size_t samples = 0;  // per channel
};

// Spot present when SUM exceeds a threshold (volts); hysteresis keeps a spot on the rim from
// flickering.
class SpotDetector {
 public:
  explicit SpotDetector(double on_threshold_v = 0.5, double off_threshold_v = 0.4);
  bool update(const VoltageReading& reading) noexcept;
  bool present() const noexcept { return present_; }

 private:
  double on_, off_;
  bool present_ = false;
};

// One point of a sweep: a known stage position (mm) and the averaged voltages there.
struct SweepPoint {
  PsdSpot spot;  // where the stage put the spot
  double x_v = 0, y_v = 0, sum_v = 0;
};

// Reads a sweep as CSV: a header line naming the columns u_mm, v_mm, x_v, y_v, sum_v (any order,
// other columns ignored), then one row per stage position. Throws zerocal::InputError naming
// every bad line.
std::vector<SweepPoint> readSweepCsv(std::istream& in, const std::string& origin);
// Writes a sweep in the form readSweepCsv reads (header u_mm,v_mm,x_v,y_v,sum_v).
void writeSweepCsv(std::ostream& out, const std::vector<SweepPoint>& sweep);

struct MapFitOptions {
  int degree = 7;                   // total degree of the polynomial in (X, Y)
  double zone_half_width_mm = 0.6;  // sweep points with |u|,|v| within this are fitted
  double min_sum_v = 0.5;           // points with less light are ignored
};

struct MapFitReport {
  std::size_t points_used = 0;
  double rms_residual_mm = 0, max_residual_mm = 0;
  double u_min = 0, u_max = 0, v_min = 0, v_max = 0;  // valid zone (mm)
};

// Voltages -> millimetres: u = sum a_ij X^i Y^j, v = sum b_ij X^i Y^j over i + j <= degree, with
// X, Y scaled to volts / 5.
class PsdMap {
 public:
  // Least-squares fit over the sweep points inside the zone. Throws zerocal::InputError if the
  // sweep has too few usable points, std::invalid_argument for a degree outside 1..12.
  static PsdMap fit(const std::vector<SweepPoint>& sweep, const MapFitOptions& options,
                    MapFitReport* report = nullptr);

  // The reading these voltages make: the spot and its standard errors through the map, SUM,
  // present with enough light (minSumV), in the valid zone when also inside the zone the map was
  // fitted on; time_s is the reader's to stamp.
  PsdReading apply(const VoltageReading& reading) const;
  // Plain-text form for the configuration, and back (throws zerocal::InputError).
  std::string serialize() const;
  static PsdMap parse(const std::string& text);
  // 16 hex digits (FNV-1a of serialize()) that name this map in a result: two results with the
  // same fingerprint were read through the same map, whatever its file was called.
  std::string fingerprint() const;

  // The parts, so that the configuration can store the map in its own format (psd_config.h).
  // fromParts throws std::invalid_argument when the parts do not make a map: degree outside
  // 1..12, coefficient counts other than termCount(degree), an empty or non-finite zone.
  static std::size_t termCount(int degree);
  static PsdMap fromParts(int degree, std::vector<double> u_coeff, std::vector<double> v_coeff,
                          const std::array<double, 4>& zone_mm, double min_sum_v);
  int degree() const noexcept { return degree_; }
  const std::vector<double>& uCoefficients() const noexcept { return u_coeff_; }
  const std::vector<double>& vCoefficients() const noexcept { return v_coeff_; }
  // {u_min, u_max, v_min, v_max} in mm: where the map was fitted, hence valid.
  std::array<double, 4> zone() const noexcept { return {u_min_, u_max_, v_min_, v_max_}; }
  double minSumV() const noexcept { return min_sum_v_; }

 private:
  void evaluate(double x, double y, double& u, double& v, double& du_dx, double& du_dy,
                double& dv_dx, double& dv_dy) const;
  int degree_ = 0;
  std::vector<double> u_coeff_, v_coeff_;
  double u_min_ = 0, u_max_ = 0, v_min_ = 0, v_max_ = 0;
  double min_sum_v_ = 0.5;
};

}  // namespace zerocal::psd
