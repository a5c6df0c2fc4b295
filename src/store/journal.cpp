#include "zerocal/store/journal.h"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <ctime>
#include <filesystem>
#include <fstream>
#include <limits>
#include <map>
#include <mutex>
#include <sstream>

#include "zerocal/daemon/logging.h"
#include "zerocal/io/durable_file.h"

namespace zerocal {
namespace {

namespace fs = std::filesystem;
using Json = nlohmann::json;

constexpr const char* kFaultsFile = "faults.jsonl";

[[noreturn]] void fail(const std::string& what, int error) {
  throw JournalError(what + ": " + std::strerror(error));
}

// The whole file; nullopt when it does not exist. Throws JournalError when it cannot be read.
std::optional<std::string> readWholeFile(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) {
    std::error_code ec;
    if (!fs::exists(path, ec)) return std::nullopt;
    throw JournalError("cannot read " + path);
  }
  std::ostringstream buffer;
  buffer << in.rdbuf();
  return buffer.str();
}

// nlohmann writes a NaN as null; read back, null is NaN again.
double numberOrNan(const Json& j) {
  return j.is_null() ? std::numeric_limits<double>::quiet_NaN() : j.get<double>();
}

// What no detector and no arm can read. PSDs are at most a few tens of mm on a side (the
// largest lateral-effect ones sold are 45 mm square, the cell's is a fraction of that); a spot
// further than this from the centre is on none, and a recorded spot is within the map's valid
// zone, typically +-0.6 mm. Joints: kMaxJointTravelDeg, two turns either way.
constexpr double kMaxSpotMm = 50;

// An integer member that fits T. nlohmann would convert a float (1e300) or a negative number
// with a cast whose result is undefined or wrapped; a journal line holds only what append() wrote.
template <class T>
void integerMember(const Json& j, const char* key, T& out) {
  const Json& v = j.at(key);
  if (!v.is_number_integer()) throw JournalError(std::string(key) + " is not an integer");
  const bool fits =
      v.is_number_unsigned()
          ? v.get<std::uint64_t>() <= static_cast<std::uint64_t>(std::numeric_limits<T>::max())
          : v.get<std::int64_t>() >= std::numeric_limits<T>::min() &&
                v.get<std::int64_t>() <= std::numeric_limits<T>::max();
  if (!fits) throw JournalError(std::string(key) + " is out of range");
  out = static_cast<T>(v.get<std::int64_t>());
}

// Finite and within +-bound (lo: 0 for a standard error).
void plausible(double value, double lo, double bound, const std::string& what) {
  if (!(std::isfinite(value) && value >= lo && value <= bound))
    throw JournalError("pose record: " + what + " is not a value a robot or detector can have");
}

void checkPlausible(const PoseRecord& r) {
  for (int i = 0; i < kJointCount; ++i)
    plausible(r.joints_deg[i], -kMaxJointTravelDeg, kMaxJointTravelDeg,
              "joints_deg[" + std::to_string(i) + "]");
  plausible(r.reading.spot.u_mm, -kMaxSpotMm, kMaxSpotMm, "u_mm");
  plausible(r.reading.spot.v_mm, -kMaxSpotMm, kMaxSpotMm, "v_mm");
  plausible(r.reading.se.u_mm, 0, kMaxSpotMm, "u_se_mm");
  plausible(r.reading.se.v_mm, 0, kMaxSpotMm, "v_se_mm");
  const auto& s = r.servo;
  for (double x : {s.move_s, s.acquisition_s, s.servo_s, s.settle_s, s.final_error_um})
    if (!std::isfinite(x)) throw JournalError("pose record: a servo value is not finite");
  for (const SpotPathPoint& point : r.servo_path) {
    if (!std::isfinite(point.t_s))
      throw JournalError("pose record: a servo_path time is not finite");
    plausible(point.spot.u_mm, -kMaxSpotMm, kMaxSpotMm, "servo_path u");
    plausible(point.spot.v_mm, -kMaxSpotMm, kMaxSpotMm, "servo_path v");
  }
}

bool allFinite(const PoseRecord& r) {
  for (double q : r.joints_deg)
    if (!std::isfinite(q)) return false;
  const auto& s = r.servo;
  if (!r.reading.spot.finite() || !r.reading.se.finite()) return false;
  for (double x : {s.move_s, s.acquisition_s, s.servo_s, s.settle_s, s.final_error_um})
    if (!std::isfinite(x)) return false;
  for (const SpotPathPoint& point : r.servo_path)
    if (!std::isfinite(point.t_s) || !point.spot.finite()) return false;
  return true;
}

}  // namespace

std::vector<const PoseRecord*> latestRecords(const std::vector<PoseRecord>& records) {
  std::vector<const PoseRecord*> latest;
  for (const PoseRecord& r : records) {
    const auto k = static_cast<std::size_t>(r.planIndex());
    if (latest.size() <= k) latest.resize(k + 1, nullptr);
    latest[k] = &r;
  }
  return latest;
}

Json toJson(const PoseRecord& r) {
  if (!r.measured())
    return Json{{"index", r.index}, {"skipped", r.skipped}, {"recorded_ns", r.recorded_ns}};
  // nlohmann writes doubles in the shortest form that reads back to the same bits.
  Json line{{"index", r.index},
            {"joints_deg", r.joints_deg},
            {"u_mm", r.reading.spot.u_mm},
            {"v_mm", r.reading.spot.v_mm},
            {"u_se_mm", r.reading.se.u_mm},
            {"v_se_mm", r.reading.se.v_mm},
            {"move_started_ns", r.move_started_ns},
            {"recorded_ns", r.recorded_ns},
            {"servo",
             {{"moves", r.servo.moves},
              {"search_moves", r.servo.search_moves},
              {"iterations", r.servo.iterations},
              {"move_s", r.servo.move_s},
              {"acquisition_s", r.servo.acquisition_s},
              {"servo_s", r.servo.servo_s},
              {"settle_s", r.servo.settle_s},
              {"final_error_um", r.servo.final_error_um}}}};
  // No path recorded (a record made without the servo) is no key, as in older journals.
  if (!r.servo_path.empty()) {
    Json& path = line["servo_path"] = Json::array();
    for (const SpotPathPoint& p : r.servo_path)
      path.push_back(Json::array({p.t_s, p.spot.u_mm, p.spot.v_mm}));
  }
  if (r.remeasure_of >= 0) line["remeasure_of"] = r.remeasure_of;
  if (r.placement != 1) line["placement"] = r.placement;
  return line;
}

Json toJson(const PlacementRecord& r) {
  return Json{
      {"placement", r.placement}, {"centre_mm", r.centre_mm}, {"recorded_ns", r.recorded_ns}};
}

PlacementRecord placementRecordFromJson(const Json& j) {
  try {
    PlacementRecord r;
    integerMember(j, "placement", r.placement);
    j.at("centre_mm").get_to(r.centre_mm);
    integerMember(j, "recorded_ns", r.recorded_ns);
    for (const double c : r.centre_mm)
      if (!std::isfinite(c)) throw JournalError("placement record: centre_mm is not finite");
    return r;
  } catch (const Json::exception& e) {
    throw JournalError(std::string("placement record: ") + e.what());
  }
}

int placementInForce(const std::vector<PlacementRecord>& placements) {
  return placements.empty() ? 1 : placements.back().placement;
}

PoseRecord poseRecordFromJson(const Json& j) {
  try {
    PoseRecord r;
    integerMember(j, "index", r.index);
    if (j.contains("skipped")) {
      j.at("skipped").get_to(r.skipped);
      integerMember(j, "recorded_ns", r.recorded_ns);
      if (r.skipped.empty()) throw JournalError("pose record: skipped without a reason");
      return r;
    }
    j.at("joints_deg").get_to(r.joints_deg);
    j.at("u_mm").get_to(r.reading.spot.u_mm);
    j.at("v_mm").get_to(r.reading.spot.v_mm);
    j.at("u_se_mm").get_to(r.reading.se.u_mm);
    j.at("v_se_mm").get_to(r.reading.se.v_mm);
    r.reading.spot_present = r.reading.in_valid_zone = true;
    integerMember(j, "move_started_ns", r.move_started_ns);
    integerMember(j, "recorded_ns", r.recorded_ns);
    const Json& s = j.at("servo");
    integerMember(s, "moves", r.servo.moves);
    integerMember(s, "iterations", r.servo.iterations);
    s.at("move_s").get_to(r.servo.move_s);
    s.at("acquisition_s").get_to(r.servo.acquisition_s);
    s.at("servo_s").get_to(r.servo.servo_s);
    s.at("settle_s").get_to(r.servo.settle_s);
    s.at("final_error_um").get_to(r.servo.final_error_um);
    // Added later: journals written before have neither.
    if (s.contains("search_moves")) integerMember(s, "search_moves", r.servo.search_moves);
    if (j.contains("servo_path"))
      for (const auto& point : j.at("servo_path").get<std::vector<std::array<double, 3>>>())
        r.servo_path.push_back({point[0], {point[1], point[2]}});
    if (j.contains("placement")) {
      integerMember(j, "placement", r.placement);
      if (r.placement < 1) throw JournalError("pose record: placement must be 1 or more");
    }
    if (j.contains("remeasure_of")) {
      integerMember(j, "remeasure_of", r.remeasure_of);
      if (r.remeasure_of < 0 || r.remeasure_of >= r.index)
        throw JournalError("pose record: remeasure_of " + std::to_string(r.remeasure_of) +
                           " is not an earlier line");
    }
    // A number no arm or detector can have is damage, not a measurement.
    checkPlausible(r);
    return r;
  } catch (const Json::exception& e) {
    throw JournalError(std::string("pose record: ") + e.what());
  }
}

JournalContents readJournal(const std::string& path) {
  const std::optional<std::string> file = readWholeFile(path);
  if (!file) return {};
  return parseJournal(*file, path);
}

JournalContents parseJournal(const std::string& text, const std::string& path) {
  JournalContents out;

  std::size_t start = 0;
  int line_number = 0;
  while (start < text.size()) {
    ++line_number;
    const std::size_t newline = text.find('\n', start);
    const bool last = newline == std::string::npos || newline + 1 == text.size();
    const std::string line =
        text.substr(start, (newline == std::string::npos ? text.size() : newline) - start);
    std::string problem;
    PoseRecord record;
    std::optional<PlacementRecord> placement;  // a placement line instead of a pose
    if (newline == std::string::npos) {
      // append() acknowledges a pose only after its newline is on disk, so a line without one
      // was never acknowledged, however complete it looks.
      problem = "no newline";
    } else {
      try {
        const Json j = Json::parse(line);
        if (j.is_object() && !j.contains("index") && j.contains("placement"))
          placement = placementRecordFromJson(j);
        else
          record = poseRecordFromJson(j);
      } catch (const std::exception& e) {
        problem = e.what();
      }
    }
    if (!problem.empty()) {
      if (!last) throw JournalError(path + ":" + std::to_string(line_number) + ": " + problem);
      out.dropped = path + ":" + std::to_string(line_number) + ": dropped a torn last line (" +
                    std::to_string(line.size()) + " bytes, " + problem + ")";
      makeLogger("journal")->warn("{}", out.dropped);
      break;
    }
    const std::string where = path + ":" + std::to_string(line_number) + ": ";
    if (placement) {
      if (placement->placement != placementInForce(out.placements) + 1)
        throw JournalError(where + "placement " + std::to_string(placement->placement) + " where " +
                           std::to_string(placementInForce(out.placements) + 1) + " was due");
      placement->first_index = out.nextIndex();
      out.placements.push_back(*placement);
      out.committed_bytes = newline + 1;
      start = newline + 1;
      continue;
    }
    if (record.measured() && record.placement != placementInForce(out.placements))
      throw JournalError(where + "pose at placement " + std::to_string(record.placement) +
                         " while the PSD is at placement " +
                         std::to_string(placementInForce(out.placements)));
    if (record.index != out.nextIndex())
      throw JournalError(path + ":" + std::to_string(line_number) + ": pose index " +
                         std::to_string(record.index) + " where " +
                         std::to_string(out.nextIndex()) + " was due");
    record.line = line_number;
    out.records.push_back(record);
    out.committed_bytes = newline + 1;
    start = newline + 1;
  }
  return out;
}

Journal::Journal(const std::string& path) : path_(path) {
  JournalContents contents = readJournal(path);
  records_ = std::move(contents.records);
  placements_ = std::move(contents.placements);
  dropped_ = std::move(contents.dropped);

  const fs::path file(path);
  const std::string folder = file.parent_path().empty() ? "." : file.parent_path().string();
  std::error_code ec;
  const bool existed = fs::exists(file, ec);
  try {
    makeDirsDurably(folder);
    fd_ = ::open(path.c_str(), O_WRONLY | O_CREAT | O_APPEND | O_CLOEXEC, 0644);
    if (fd_ < 0) fail("cannot open journal " + path, errno);
    if (!existed) syncFolder(folder);
    if (!dropped_.empty()) {
      // Cut the torn tail so the next record does not continue the fragment's line.
      if (::ftruncate(fd_, static_cast<off_t>(contents.committed_bytes)) != 0)
        fail("cannot truncate journal " + path, errno);
      writeAllDurably(fd_, "", path);  // the truncation, synced
    }
  } catch (const FileError& e) {
    if (fd_ >= 0) ::close(fd_);
    fd_ = -1;
    throw JournalError(e.what());
  } catch (...) {
    if (fd_ >= 0) ::close(fd_);
    fd_ = -1;
    throw;
  }
}

Journal::~Journal() {
  if (fd_ >= 0) ::close(fd_);
}

const PoseRecord& Journal::append(const PoseRecord& record) {
  if (broken_) throw JournalError("journal " + path_ + " is unusable after a failed write");
  if (record.index != nextIndex())
    throw JournalError("journal " + path_ + ": pose index " + std::to_string(record.index) +
                       " where " + std::to_string(nextIndex()) + " is due");
  if (!allFinite(record))
    throw JournalError("journal " + path_ + ": pose " + std::to_string(record.index) +
                       " has a value that is not a finite number");
  if (record.measured() && record.placement != placement())
    throw JournalError("journal " + path_ + ": pose " + std::to_string(record.index) +
                       " at placement " + std::to_string(record.placement) +
                       " while the PSD is at placement " + std::to_string(placement()));
  writeLine(toJson(record).dump() + "\n");
  records_.push_back(record);
  // Every committed line is a pose's or a placement's.
  records_.back().line = static_cast<int>(records_.size() + placements_.size());
  return records_.back();
}

void Journal::append(const PlacementRecord& record) {
  if (record.placement != placement() + 1)
    throw JournalError("journal " + path_ + ": placement " + std::to_string(record.placement) +
                       " where " + std::to_string(placement() + 1) + " is due");
  for (const double c : record.centre_mm)
    if (!std::isfinite(c))
      throw JournalError("journal " + path_ + ": placement centre is not a finite number");
  writeLine(toJson(record).dump() + "\n");
  PlacementRecord kept = record;
  kept.first_index = nextIndex();
  placements_.push_back(kept);
}

void Journal::writeLine(const std::string& line) {
  if (broken_) throw JournalError("journal " + path_ + " is unusable after a failed write");
  try {
    // One write() per line: with O_APPEND a crash leaves at most this line torn.
    writeAllDurably(fd_, line, path_);
  } catch (const FileError& e) {
    // What reached the disk is unknown; only a re-open (which re-reads) may continue.
    broken_ = true;
    throw JournalError(e.what());
  }
}

Json toJson(const FaultRecord& r) {
  Json samples = Json::array();
  for (const servo::ServoSample& s : r.samples) {
    Json row = Json::array({s.time_s});
    for (double q : s.q_deg) row.push_back(q);
    row.push_back(s.reading.spot.u_mm);
    row.push_back(s.reading.spot.v_mm);
    row.push_back(s.reading.sum_v);
    row.push_back(s.reading.spot_present);
    row.push_back(s.reading.in_valid_zone);
    samples.push_back(std::move(row));
  }
  Json line{{"plan_index", r.plan_index},
            {"status", r.status},
            {"message", r.message},
            {"recorded_ns", r.recorded_ns},
            {"samples", std::move(samples)}};
  if (r.remeasure) line["remeasure"] = true;
  return line;
}

FaultRecord faultRecordFromJson(const Json& j) {
  try {
    FaultRecord r;
    integerMember(j, "plan_index", r.plan_index);
    j.at("status").get_to(r.status);
    j.at("message").get_to(r.message);
    integerMember(j, "recorded_ns", r.recorded_ns);
    if (j.contains("remeasure")) j.at("remeasure").get_to(r.remeasure);
    for (const Json& row : j.at("samples")) {
      if (!row.is_array() || row.size() != 12)
        throw JournalError("fault record: a sample is not a list of 12 values");
      servo::ServoSample s;
      s.time_s = numberOrNan(row[0]);
      for (int i = 0; i < kJointCount; ++i) s.q_deg[i] = numberOrNan(row[1 + i]);
      s.reading.spot = {numberOrNan(row[7]), numberOrNan(row[8])};
      s.reading.sum_v = numberOrNan(row[9]);
      row[10].get_to(s.reading.spot_present);
      row[11].get_to(s.reading.in_valid_zone);
      s.reading.time_s = s.time_s;
      r.samples.push_back(s);
    }
    return r;
  } catch (const Json::exception& e) {
    throw JournalError(std::string("fault record: ") + e.what());
  }
}

std::string faultLogPath(const std::string& journal_path) {
  return (fs::path(journal_path).parent_path() / kFaultsFile).string();
}

void appendFault(const std::string& path, const FaultRecord& record) {
  const std::string line = toJson(record).dump() + "\n";
  const fs::path file(path);
  const std::string folder = file.parent_path().empty() ? "." : file.parent_path().string();
  // A line torn by a crash is cut first, so that this one starts a line of its own.
  const std::optional<std::string> before = readWholeFile(path);
  std::size_t committed = 0;
  if (before) {
    const std::size_t last_newline = before->rfind('\n');
    committed = last_newline == std::string::npos ? 0 : last_newline + 1;
  }
  const int fd = ::open(path.c_str(), O_WRONLY | O_CREAT | O_APPEND | O_CLOEXEC, 0644);
  if (fd < 0) fail("cannot open " + path, errno);
  try {
    if (before && committed != before->size() &&
        ::ftruncate(fd, static_cast<off_t>(committed)) != 0)
      fail("cannot truncate " + path, errno);
    // One write() per line, as in the journal: a crash leaves at most this line torn.
    writeAllDurably(fd, line, path);
    if (!before) syncFolder(folder);
  } catch (const FileError& e) {
    ::close(fd);
    throw JournalError(e.what());
  } catch (...) {
    ::close(fd);
    throw;
  }
  ::close(fd);
}

std::vector<FaultRecord> readFaults(const std::string& path) {
  std::vector<FaultRecord> out;
  const std::optional<std::string> file = readWholeFile(path);
  if (!file) return out;
  const std::string& text = *file;
  std::size_t start = 0;
  for (int line_number = 1; start < text.size(); ++line_number) {
    const std::size_t newline = text.find('\n', start);
    if (newline == std::string::npos) break;  // never acknowledged: a torn last line
    const bool last = newline + 1 == text.size();
    try {
      out.push_back(faultRecordFromJson(Json::parse(text.substr(start, newline - start))));
    } catch (const std::exception& e) {
      if (!last) throw JournalError(path + ":" + std::to_string(line_number) + ": " + e.what());
      break;
    }
    start = newline + 1;
  }
  return out;
}

}  // namespace zerocal
