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
    j.at("placement").get_to(r.placement);
    j.at("centre_mm").get_to(r.centre_mm);
    j.at("recorded_ns").get_to(r.recorded_ns);
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
    j.at("index").get_to(r.index);
    if (j.contains("skipped")) {
      j.at("skipped").get_to(r.skipped);
      j.at("recorded_ns").get_to(r.recorded_ns);
      if (r.skipped.empty()) throw JournalError("pose record: skipped without a reason");
      return r;
    }
    j.at("joints_deg").get_to(r.joints_deg);
    j.at("u_mm").get_to(r.reading.spot.u_mm);
    j.at("v_mm").get_to(r.reading.spot.v_mm);
    j.at("u_se_mm").get_to(r.reading.se.u_mm);
    j.at("v_se_mm").get_to(r.reading.se.v_mm);
    r.reading.spot_present = r.reading.in_valid_zone = true;
    j.at("move_started_ns").get_to(r.move_started_ns);
    j.at("recorded_ns").get_to(r.recorded_ns);
    const Json& s = j.at("servo");
    s.at("moves").get_to(r.servo.moves);
    s.at("iterations").get_to(r.servo.iterations);
    s.at("move_s").get_to(r.servo.move_s);
    s.at("acquisition_s").get_to(r.servo.acquisition_s);
    s.at("servo_s").get_to(r.servo.servo_s);
    s.at("settle_s").get_to(r.servo.settle_s);
    s.at("final_error_um").get_to(r.servo.final_error_um);
    // Added later: journals written before have neither.
    if (s.contains("search_moves")) s.at("search_moves").get_to(r.servo.search_moves);
    if (j.contains("servo_path"))
      for (const auto& point : j.at("servo_path").get<std::vector<std::array<double, 3>>>())
        r.servo_path.push_back({point[0], {point[1], point[2]}});
    if (j.contains("placement")) {
      j.at("placement").get_to(r.placement);
      if (r.placement < 1) throw JournalError("pose record: placement must be 1 or more");
    }
    if (j.contains("remeasure_of")) {
      j.at("remeasure_of").get_to(r.remeasure_of);
      if (r.remeasure_of < 0 || r.remeasure_of >= r.index)
        throw JournalError("pose record: remeasure_of " + std::to_string(r.remeasure_of) +
                           " is not an earlier line");
    }
    return r;
  } catch (const Json::exception& e) {
    throw JournalError(std::string("pose record: ") + e.what());
  }
}

JournalContents readJournal(const std::string& path) {
  JournalContents out;
  const std::optional<std::string> file = readWholeFile(path);
  if (!file) return out;
  const std::string& text = *file;

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

void Journal::append(const PoseRecord& record) {
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
  for (const FaultSample& s : r.samples) {
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
    j.at("plan_index").get_to(r.plan_index);
    j.at("status").get_to(r.status);
    j.at("message").get_to(r.message);
    j.at("recorded_ns").get_to(r.recorded_ns);
    if (j.contains("remeasure")) j.at("remeasure").get_to(r.remeasure);
    for (const Json& row : j.at("samples")) {
      if (!row.is_array() || row.size() != 12)
        throw JournalError("fault record: a sample is not a list of 12 values");
      FaultSample s;
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
