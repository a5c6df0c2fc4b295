#include "zerocal/psd/psd.h"

#include <fmt/format.h>

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <iomanip>
#include <limits>
#include <sstream>
#include <stdexcept>

#include "zerocal/error.h"

namespace zerocal::psd {
namespace {

// Voltages enter the polynomial divided by this, so that powers up to the degree stay near 1 and
// the least-squares problem stays well conditioned.
constexpr double kVoltScale = 5.0;

// Monomials X^i Y^j for i + j <= degree, in a fixed order (by total degree, then by i).
template <typename F>
void forEachTerm(int degree, F&& f) {
  std::size_t k = 0;
  for (int total = 0; total <= degree; ++total) {
    for (int i = total; i >= 0; --i) f(k++, i, total - i);
  }
}

}  // namespace

std::vector<SweepPoint> readSweepCsv(std::istream& in, const std::string& origin) {
  auto split = [](const std::string& line) {
    std::vector<std::string> cells;
    std::string cell;
    std::istringstream row(line);
    while (std::getline(row, cell, ',')) {
      const auto b = cell.find_first_not_of(" \t\r");
      const auto e = cell.find_last_not_of(" \t\r");
      cells.push_back(b == std::string::npos ? "" : cell.substr(b, e - b + 1));
    }
    return cells;
  };
  std::string line;
  if (!std::getline(in, line)) throw InputError(origin + ": empty sweep file");
  const std::vector<std::string> header = split(line);
  const char* names[5] = {"u_mm", "v_mm", "x_v", "y_v", "sum_v"};
  int column[5];
  std::vector<std::string> problems;
  for (int k = 0; k < 5; ++k) {
    column[k] = -1;
    for (std::size_t c = 0; c < header.size(); ++c) {
      if (header[c] == names[k]) column[k] = static_cast<int>(c);
    }
    if (column[k] < 0) problems.push_back(std::string("no column ") + names[k] + " in the header");
  }
  std::vector<SweepPoint> sweep;
  const bool header_ok = problems.empty();
  for (int number = 2; header_ok && std::getline(in, line); ++number) {
    if (line.find_first_not_of(" \t\r") == std::string::npos) continue;
    const std::vector<std::string> cells = split(line);
    double values[5];
    bool ok = true;
    for (int k = 0; k < 5 && ok; ++k) {
      const auto c = static_cast<std::size_t>(column[k]);
      char* end = nullptr;
      values[k] = c < cells.size() ? std::strtod(cells[c].c_str(), &end) : 0.0;
      ok = c < cells.size() && !cells[c].empty() && end && *end == '\0' && std::isfinite(values[k]);
      if (!ok) {
        problems.push_back("line " + std::to_string(number) + ": " + names[k] + " is not a number");
      }
    }
    if (ok) sweep.push_back({{values[0], values[1]}, values[2], values[3], values[4]});
  }
  if (!problems.empty()) {
    std::string message = origin + ": the sweep cannot be used:";
    for (const auto& p : problems) message += "\n  " + p;
    throw InputError(message);
  }
  return sweep;
}

void writeSweepCsv(std::ostream& out, const std::vector<SweepPoint>& sweep) {
  // 0.1 um stage positions and microvolt readings: finer than the stage and the board resolve.
  out << "u_mm,v_mm,x_v,y_v,sum_v\n" << std::fixed;
  for (const SweepPoint& p : sweep) {
    out << std::setprecision(4) << p.spot.u_mm << ',' << p.spot.v_mm << ',' << std::setprecision(6)
        << p.x_v << ',' << p.y_v << ',' << p.sum_v << '\n';
  }
  out.unsetf(std::ios::floatfield);
}

SpotDetector::SpotDetector(double on_threshold_v, double off_threshold_v)
    : on_(on_threshold_v), off_(std::min(off_threshold_v, on_threshold_v)) {}

bool SpotDetector::update(const VoltageReading& reading) noexcept {
  present_ = present_ ? reading.sum > off_ : reading.sum > on_;
  return present_;
}

PsdMap PsdMap::fit(const std::vector<SweepPoint>& sweep, const MapFitOptions& options,
                   MapFitReport* report) {
  if (options.degree < 1 || options.degree > 12) {
    throw std::invalid_argument("PSD map degree must be 1..12, got " +
                                std::to_string(options.degree));
  }
  std::vector<const SweepPoint*> used;
  const double half = options.zone_half_width_mm + 1e-9;  // stage grids land on the limit
  for (const SweepPoint& p : sweep) {
    if (std::abs(p.spot.u_mm) <= half && std::abs(p.spot.v_mm) <= half &&
        p.sum_v >= options.min_sum_v) {
      used.push_back(&p);
    }
  }
  const std::size_t m = termCount(options.degree);
  if (used.size() < 2 * m) {
    throw InputError("the PSD sweep has " + std::to_string(used.size()) +
                     " usable points within +-" + std::to_string(options.zone_half_width_mm) +
                     " mm; a degree-" + std::to_string(options.degree) + " map needs at least " +
                     std::to_string(2 * m));
  }
  Eigen::MatrixXd a(used.size(), m);
  Eigen::VectorXd bu(used.size()), bv(used.size());
  for (std::size_t r = 0; r < used.size(); ++r) {
    const double x = used[r]->x_v / kVoltScale, y = used[r]->y_v / kVoltScale;
    forEachTerm(options.degree, [&](std::size_t k, int i, int j) {
      a(static_cast<Eigen::Index>(r), static_cast<Eigen::Index>(k)) =
          std::pow(x, i) * std::pow(y, j);
    });
    bu(static_cast<Eigen::Index>(r)) = used[r]->spot.u_mm;
    bv(static_cast<Eigen::Index>(r)) = used[r]->spot.v_mm;
  }
  const Eigen::ColPivHouseholderQR<Eigen::MatrixXd> qr(a);
  const Eigen::VectorXd cu = qr.solve(bu), cv = qr.solve(bv);

  PsdMap map;
  map.degree_ = options.degree;
  map.u_coeff_.assign(cu.data(), cu.data() + cu.size());
  map.v_coeff_.assign(cv.data(), cv.data() + cv.size());
  map.min_sum_v_ = options.min_sum_v;
  map.u_min_ = map.v_min_ = std::numeric_limits<double>::infinity();
  map.u_max_ = map.v_max_ = -std::numeric_limits<double>::infinity();
  double sum2 = 0, worst = 0;
  const Eigen::VectorXd ru = a * cu - bu, rv = a * cv - bv;
  for (std::size_t r = 0; r < used.size(); ++r) {
    const double e = std::hypot(ru(static_cast<Eigen::Index>(r)), rv(static_cast<Eigen::Index>(r)));
    sum2 += e * e;
    worst = std::max(worst, e);
    map.u_min_ = std::min(map.u_min_, used[r]->spot.u_mm);
    map.u_max_ = std::max(map.u_max_, used[r]->spot.u_mm);
    map.v_min_ = std::min(map.v_min_, used[r]->spot.v_mm);
    map.v_max_ = std::max(map.v_max_, used[r]->spot.v_mm);
  }
  if (report) {
    report->points_used = used.size();
    report->rms_residual_mm = std::sqrt(sum2 / static_cast<double>(used.size()));
    report->max_residual_mm = worst;
    report->u_min = map.u_min_;
    report->u_max = map.u_max_;
    report->v_min = map.v_min_;
    report->v_max = map.v_max_;
  }
  return map;
}

std::size_t PsdMap::termCount(int degree) {
  // In size_t: a degree read from a file may be any int, and (degree + 1) (degree + 2) overflows
  // an int from degree 46340 on.
  const auto d = static_cast<std::size_t>(degree);
  return degree < 0 ? 0 : (d + 1) * (d + 2) / 2;
}

PsdMap PsdMap::fromParts(int degree, std::vector<double> u_coeff, std::vector<double> v_coeff,
                         const std::array<double, 4>& zone_mm, double min_sum_v) {
  if (degree < 1 || degree > 12) {
    throw std::invalid_argument("PSD map degree must be 1..12, got " + std::to_string(degree));
  }
  const std::size_t m = termCount(degree);
  if (u_coeff.size() != m || v_coeff.size() != m) {
    throw std::invalid_argument("a degree-" + std::to_string(degree) + " PSD map needs " +
                                std::to_string(m) + " coefficients for u and for v");
  }
  // A fitted map's coefficients are millimetres per (volts / 5)^k: a few mm (under 2 for the
  // shipped map). Far beyond that the file is damaged or hand-typed, and the map would turn any
  // reading into nonsense that still looks like a number.
  constexpr double kLargestCoefficient = 1e6;
  for (const auto* coefficients : {&u_coeff, &v_coeff})
    for (double c : *coefficients)
      if (!(std::abs(c) <= kLargestCoefficient))
        throw std::invalid_argument("PSD map coefficient " + std::to_string(c) +
                                    " is not a finite number within +-1e6");
  // A PSD is at most tens of millimetres across.
  constexpr double kLargestZoneMm = 1000;
  for (double z : zone_mm) {
    if (!(std::abs(z) <= kLargestZoneMm))
      throw std::invalid_argument("PSD map zone is not finite, or beyond +-1000 mm");
  }
  if (!(zone_mm[0] < zone_mm[1]) || !(zone_mm[2] < zone_mm[3])) {
    throw std::invalid_argument("PSD map zone is empty (each minimum must be below its maximum)");
  }
  if (!std::isfinite(min_sum_v)) throw std::invalid_argument("PSD map min_sum_v is not finite");
  PsdMap map;
  map.degree_ = degree;
  map.u_coeff_ = std::move(u_coeff);
  map.v_coeff_ = std::move(v_coeff);
  map.u_min_ = zone_mm[0];
  map.u_max_ = zone_mm[1];
  map.v_min_ = zone_mm[2];
  map.v_max_ = zone_mm[3];
  map.min_sum_v_ = min_sum_v;
  return map;
}

void PsdMap::evaluate(double xv, double yv, double& u, double& v, double& du_dx, double& du_dy,
                      double& dv_dx, double& dv_dy) const {
  const double x = xv / kVoltScale, y = yv / kVoltScale;
  u = v = du_dx = du_dy = dv_dx = dv_dy = 0.0;
  forEachTerm(degree_, [&](std::size_t k, int i, int j) {
    const double term = std::pow(x, i) * std::pow(y, j);
    const double dx = i > 0 ? i * std::pow(x, i - 1) * std::pow(y, j) : 0.0;
    const double dy = j > 0 ? j * std::pow(x, i) * std::pow(y, j - 1) : 0.0;
    u += u_coeff_[k] * term;
    v += v_coeff_[k] * term;
    du_dx += u_coeff_[k] * dx;
    du_dy += u_coeff_[k] * dy;
    dv_dx += v_coeff_[k] * dx;
    dv_dy += v_coeff_[k] * dy;
  });
  // Derivatives per volt, not per scaled unit.
  du_dx /= kVoltScale;
  du_dy /= kVoltScale;
  dv_dx /= kVoltScale;
  dv_dy /= kVoltScale;
}

PsdReading PsdMap::apply(const VoltageReading& reading) const {
  PsdReading p;
  p.sum_v = reading.sum;
  p.spot_present = reading.sum >= min_sum_v_;
  if (!p.spot_present) return p;
  double du_dx, du_dy, dv_dx, dv_dy;
  evaluate(reading.x, reading.y, p.spot.u_mm, p.spot.v_mm, du_dx, du_dy, dv_dx, dv_dy);
  p.se.u_mm = std::hypot(du_dx * reading.x_se, du_dy * reading.y_se);
  p.se.v_mm = std::hypot(dv_dx * reading.x_se, dv_dy * reading.y_se);
  const PsdSpot& s = p.spot;
  p.in_valid_zone = s.u_mm >= u_min_ && s.u_mm <= u_max_ && s.v_mm >= v_min_ && s.v_mm <= v_max_;
  return p;
}

std::string PsdMap::fingerprint() const {
  std::uint64_t hash = 0xcbf29ce484222325ULL;
  for (const unsigned char c : serialize()) hash = (hash ^ c) * 0x100000001b3ULL;
  return fmt::format(FMT_STRING("{:016x}"), hash);
}

std::string PsdMap::serialize() const {
  std::ostringstream out;
  out << std::setprecision(17);
  out << "zerocal-psd-map 1\ndegree " << degree_ << "\nzone " << u_min_ << ' ' << u_max_ << ' '
      << v_min_ << ' ' << v_max_ << "\nmin_sum_v " << min_sum_v_ << "\nu";
  for (double c : u_coeff_) out << ' ' << c;
  out << "\nv";
  for (double c : v_coeff_) out << ' ' << c;
  out << '\n';
  return out.str();
}

PsdMap PsdMap::parse(const std::string& text) {
  std::istringstream in(text);
  std::string magic, key;
  int version = 0;
  PsdMap map;
  auto fail = [](const std::string& why) -> PsdMap { throw InputError("PSD map: " + why); };
  if (!(in >> magic >> version) || magic != "zerocal-psd-map" || version != 1) {
    return fail("not a zerocal-psd-map version 1");
  }
  if (!(in >> key >> map.degree_) || key != "degree" || map.degree_ < 1 || map.degree_ > 12) {
    return fail("bad or missing degree");
  }
  if (!(in >> key >> map.u_min_ >> map.u_max_ >> map.v_min_ >> map.v_max_) || key != "zone") {
    return fail("bad or missing zone");
  }
  if (!(in >> key >> map.min_sum_v_) || key != "min_sum_v") return fail("bad or missing min_sum_v");
  const std::size_t m = termCount(map.degree_);
  for (auto* coeff : {&map.u_coeff_, &map.v_coeff_}) {
    if (!(in >> key) || (key != "u" && key != "v")) return fail("missing coefficient line");
    coeff->resize(m);
    for (double& c : *coeff) {
      if (!(in >> c)) return fail("expected " + std::to_string(m) + " coefficients for " + key);
    }
  }
  return map;
}

}  // namespace zerocal::psd
