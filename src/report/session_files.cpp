// Reading a session folder, turning its JSON into a SessionReport, and writing the two files.
#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <map>
#include <sstream>

#include "zerocal/calib/cell_model.h"
#include "zerocal/daemon/journal.h"
#include "zerocal/report/session_report.h"

namespace zerocal::report {
namespace {

namespace fs = std::filesystem;
using Json = nlohmann::json;

Json readJsonFile(const fs::path& path, const std::string& what) {
  std::ifstream in(path);
  if (!in)
    throw ReportError(path.string() + ": cannot open " + what +
                      (fs::exists(path) ? "" : " (no such file)"));
  try {
    return Json::parse(in);
  } catch (const Json::exception& e) {
    throw ReportError(path.string() + ": " + what + " is not valid JSON: " + e.what());
  }
}

// Typed access that names the file and key on failure: a result written by another version must
// say what it lacks, not crash in nlohmann's operator[].
class Reader {
 public:
  Reader(const Json& j, std::string where) : j_(j), where_(std::move(where)) {}
  bool has(const char* key) const { return j_.is_object() && j_.contains(key); }
  const Json& at(const char* key) const {
    if (!has(key)) throw ReportError(where_ + ": '" + key + "' is missing");
    return j_.at(key);
  }
  double number(const char* key) const {
    const Json& v = at(key);
    if (!v.is_number()) throw ReportError(where_ + ": '" + key + "' is not a number");
    return v.get<double>();
  }
  // JSON has no NaN: the writer puts null for an unknown number.
  double numberOrNan(const char* key) const {
    if (!has(key) || j_.at(key).is_null()) return std::nan("");
    return number(key);
  }
  std::optional<double> optionalNumber(const char* key) const {
    if (!has(key) || j_.at(key).is_null()) return std::nullopt;
    return number(key);
  }
  int integer(const char* key) const {
    const Json& v = at(key);
    if (!v.is_number_integer()) throw ReportError(where_ + ": '" + key + "' is not an integer");
    return v.get<int>();
  }
  bool boolean(const char* key) const {
    const Json& v = at(key);
    if (!v.is_boolean()) throw ReportError(where_ + ": '" + key + "' is not true or false");
    return v.get<bool>();
  }
  std::string string(const char* key) const {
    const Json& v = at(key);
    if (!v.is_string()) throw ReportError(where_ + ": '" + key + "' is not a string");
    return v.get<std::string>();
  }
  std::string stringOr(const char* key, const std::string& fallback) const {
    return has(key) && j_.at(key).is_string() ? j_.at(key).get<std::string>() : fallback;
  }
  const Json& array(const char* key) const {
    const Json& v = at(key);
    if (!v.is_array()) throw ReportError(where_ + ": '" + key + "' is not a list");
    return v;
  }
  const std::string& where() const { return where_; }

 private:
  const Json& j_;
  std::string where_;
};

std::vector<double> numbers(const Json& list, std::size_t expected, const std::string& where) {
  if (!list.is_array() || list.size() != expected)
    throw ReportError(where + ": expected a list of " + std::to_string(expected) + " numbers");
  std::vector<double> out;
  for (const Json& v : list) {
    if (v.is_null()) {
      out.push_back(std::nan(""));
      continue;
    }
    if (!v.is_number()) throw ReportError(where + ": expected a list of numbers");
    out.push_back(v.get<double>());
  }
  return out;
}

// The servo path of one journal line, when the recorder wrote one: [[t_s, u_mm, v_mm], ...].
std::optional<std::vector<ServoSample>> servoPath(const Json& line, int pose) {
  if (!line.contains("servo_path") || line.at("servo_path").is_null()) return std::nullopt;
  const std::string where = "journal.jsonl pose " + std::to_string(pose) + " servo_path";
  const Json& path = line.at("servo_path");
  if (!path.is_array()) throw ReportError(where + ": not a list");
  std::vector<ServoSample> samples;
  for (const Json& s : path) {
    const auto v = numbers(s, 3, where + " sample " + std::to_string(samples.size() + 1));
    samples.push_back({v[0], v[1], v[2]});
  }
  return samples;
}

void writeAtomically(const fs::path& path, const std::string& text) {
  const fs::path temporary = path.string() + ".tmp";
  {
    std::ofstream out(temporary, std::ios::binary | std::ios::trunc);
    out << text;
    out.flush();
    if (!out) throw ReportError(temporary.string() + ": cannot write");
  }
  // A reader (a browser refreshing the page) sees the old file or the new one, never half.
  if (std::rename(temporary.c_str(), path.c_str()) != 0) {
    const int error = errno;
    std::remove(temporary.c_str());
    throw ReportError(path.string() + ": cannot write: " + std::strerror(error));
  }
}

}  // namespace

SessionFiles readSessionFiles(const std::string& session_dir) {
  const fs::path dir(session_dir);
  if (!fs::is_directory(dir)) throw ReportError(session_dir + ": not a session folder");
  SessionFiles files;
  files.dir = session_dir;
  files.session = readJsonFile(dir / "session.json", "the session file");
  if (!fs::exists(dir / "result.json"))
    throw ReportError((dir / "result.json").string() +
                      ": no result: the session is unfinished or its solve failed, so there is "
                      "nothing to report yet");
  files.result = readJsonFile(dir / "result.json", "the result");
  // readJournal's checks (indices 0, 1, 2, ..., no bad line but a torn last one) first; then the
  // same committed lines again as JSON, for members PoseRecord does not carry (servo_path).
  const fs::path journal_path = dir / "journal.jsonl";
  if (!fs::exists(journal_path))
    throw ReportError(journal_path.string() + ": no journal: the recorded poses are missing");
  const JournalContents contents = readJournal(journal_path.string());
  std::ifstream in(journal_path);
  std::string line;
  while (files.journal.size() < contents.records.size() && std::getline(in, line))
    files.journal.push_back(Json::parse(line));
  return files;
}

SessionReport parseSession(const SessionFiles& files) {
  SessionReport r;
  r.dir = files.dir;
  const Reader session(files.session, "session.json");
  const Reader result(files.result, "result.json");
  r.session_id = session.string("id");
  if (result.has("session") && result.string("session") != r.session_id)
    throw ReportError("result.json belongs to session '" + result.string("session") +
                      "', session.json to '" + r.session_id + "'");
  const Json* plan =
      session.has("plan") && session.at("plan").is_object() ? &session.at("plan") : nullptr;
  if (plan) r.plan_description = Reader(*plan, "session.json plan").stringOr("description", "");

  if (result.has("verdict")) {
    const Reader v(result.at("verdict"), "result.json verdict");
    r.usable = v.boolean("usable");
    for (const Json& reason : v.array("reasons")) {
      if (!reason.is_string()) throw ReportError("result.json verdict.reasons: not a string");
      r.refusal_reasons.push_back(reason.get<std::string>());
    }
  }
  if (result.has("suspect_poses"))
    for (const Json& e : result.array("suspect_poses")) {
      const Reader s(e, "result.json suspect_poses");
      r.suspect_poses.push_back({s.integer("pose"), s.integer("line"), s.string("reason"),
                                 s.numberOrNan("chi2_without")});
    }
  r.converged = result.boolean("converged");
  r.message = result.stringOr("message", "");
  r.cost = result.stringOr("cost", "");
  r.model = result.stringOr("model", "");
  r.noise_source = result.stringOr("noise_source", "");
  r.solved_poses = result.integer("poses");
  r.rank = result.integer("rank");
  r.dof = result.integer("dof");
  r.condition_number = result.numberOrNan("condition_number");
  r.noise_mm = result.numberOrNan("noise_mm");
  r.rms_miss_mm = result.numberOrNan("rms_miss_mm");
  r.chi2_per_dof = result.optionalNumber("chi2_per_dof");
  r.chi2_p_value = result.optionalNumber("chi2_p_value");
  r.cell_time_s = result.optionalNumber("cell_time_s");
  r.simulated = result.has("truth") && result.at("truth").is_object();
  if (result.has("cell")) {
    const Reader cell(result.at("cell"), "result.json cell");
    if (cell.has("controller")) {
      const Reader c(cell.at("controller"), "result.json cell.controller");
      r.robot = {c.stringOr("serial", ""), c.stringOr("software_version", ""),
                 c.stringOr("robot_type", "")};
    }
    r.psd_map = cell.stringOr("psd_map", "");
  }
  r.zerocal_version = result.stringOr("zerocal_version", "");
  if (result.has("finished_unix_s")) {
    const Json& t = result.at("finished_unix_s");
    if (!t.is_number_integer())
      throw ReportError("result.json: 'finished_unix_s' is not an integer");
    r.finished_unix_s = t.get<std::int64_t>();
  }

  const Json& params = result.at("parameters");
  if (!params.is_object()) throw ReportError("result.json: 'parameters' is not an object");
  // The solver's order (offsets, then the laser), not JSON's alphabetical one.
  std::vector<std::string> names;
  for (int k = 0; k < kIdentifiedCount; ++k) names.push_back(unknownName(k));
  for (const auto& [name, value] : params.items())
    if (std::find(names.begin(), names.end(), name) == names.end()) names.push_back(name);
  for (const std::string& name : names) {
    if (!params.contains(name))
      throw ReportError("result.json: parameter '" + name + "' is missing");
    const Reader p(params.at(name), "result.json parameters." + name);
    ParameterRow row;
    row.name = name;
    row.identifiable = p.boolean("identifiable");
    row.reason = p.stringOr("reason", "");
    row.value = p.numberOrNan("value");
    row.sigma = p.numberOrNan("sigma");
    row.ci95_low = row.ci95_high = std::nan("");
    if (p.has("ci95") && !p.at("ci95").is_null()) {
      const auto ci = numbers(p.at("ci95"), 2, p.where() + ".ci95");
      row.ci95_low = ci[0];
      row.ci95_high = ci[1];
    }
    if (plan && plan->contains("predicted") && (*plan)["predicted"].contains(name))
      row.predicted_sigma =
          Reader((*plan)["predicted"][name], "session.json plan.predicted." + name)
              .optionalNumber("sigma");
    if (r.simulated && files.result["truth"].contains(name))
      row.truth = Reader(files.result["truth"], "result.json truth").optionalNumber(name.c_str());
    r.parameters.push_back(row);
  }
  for (const Json& n : result.array("not_identifiable")) {
    const Reader e(n, "result.json not_identifiable");
    r.not_identifiable.push_back({e.string("name"), e.string("reason")});
  }
  const auto target = numbers(result.at("target_mm"), 3, "result.json target_mm");
  const auto target_sigma = numbers(result.at("target_sigma_mm"), 3, "result.json target_sigma_mm");
  for (int k = 0; k < 3; ++k) r.target_mm[k] = target[k], r.target_sigma_mm[k] = target_sigma[k];

  // Poses: every journal line, with the solve's residual where the pose was solved. Held-out
  // poses (validation) are not in the solve, so the residual list skips them.
  std::vector<int> held_out;
  if (result.has("validation")) {
    const Reader v(result.at("validation"), "result.json validation");
    Validation validation;
    validation.rms_before_mm = v.number("rms_before_mm");
    validation.rms_after_mm = v.number("rms_after_mm");
    for (const Json& p : v.array("poses")) {
      const Reader e(p, "result.json validation.poses");
      HeldOutRow row;
      row.pose = e.integer("pose");
      row.before_mm = Reader(e.at("before"), e.where() + ".before").number("on_psd_norm_mm");
      const Reader after(e.at("after"), e.where() + ".after");
      row.after_mm = after.number("on_psd_norm_mm");
      row.after_miss_mm = after.number("miss_mm");
      const auto uv = numbers(after.at("on_psd_mm"), 2, after.where() + ".on_psd_mm");
      row.after_uv_mm = {uv[0], uv[1]};
      held_out.push_back(row.pose);
      validation.poses.push_back(row);
    }
    r.validation = validation;
  }
  const int journal_poses = static_cast<int>(files.journal.size());
  std::vector<PoseRecord> records;
  for (int i = 0; i < journal_poses; ++i) {
    try {
      records.push_back(poseRecordFromJson(files.journal[i]));
    } catch (const JournalError& e) {
      throw ReportError("journal.jsonl pose " + std::to_string(i + 1) + ": " + e.what());
    }
  }
  // Each plan pose's latest line is the one solved (a pose measured again replaces its first
  // measurement); the residuals are in plan order.
  std::map<int, int> latest;  // plan pose (0-based) -> its latest line
  for (int i = 0; i < journal_poses; ++i) latest[records[i].planIndex()] = i;
  std::map<int, int> residual_of;  // line -> its residual
  int measured_poses = 0;
  for (const auto& [plan_index, line] : latest) {
    if (!records[line].measured()) continue;
    ++measured_poses;
    if (std::find(held_out.begin(), held_out.end(), plan_index + 1) == held_out.end())
      residual_of[line] = static_cast<int>(residual_of.size());
  }
  if (r.solved_poses + static_cast<int>(held_out.size()) != measured_poses)
    throw ReportError("result.json solved " + std::to_string(r.solved_poses) + " poses" +
                      (held_out.empty() ? "" : " and held out " + std::to_string(held_out.size())) +
                      ", but journal.jsonl has " + std::to_string(measured_poses) +
                      " measured ones: the files do not belong together");
  const Json& residuals = result.array("pose_residuals");
  if (static_cast<int>(residuals.size()) != r.solved_poses)
    throw ReportError("result.json: " + std::to_string(residuals.size()) + " pose_residuals for " +
                      std::to_string(r.solved_poses) + " poses");
  if (result.has("remeasured"))
    for (const Json& pose : result.array("remeasured")) {
      if (!pose.is_number_integer()) throw ReportError("result.json remeasured: not a pose number");
      r.remeasured.push_back(pose.get<int>());
    }
  for (int i = 0; i < journal_poses; ++i) {
    const PoseRecord& record = records[i];
    PoseRow row;
    row.pose = record.planIndex() + 1;
    row.again = record.remeasure_of >= 0;
    if (!record.measured()) {
      row.solved = false;
      row.skipped = record.skipped;
      r.poses.push_back(std::move(row));
      continue;
    }
    for (int j = 0; j < 6; ++j) row.joints_deg[j] = record.joints_deg[j];
    row.u_mm = record.u_mm;
    row.v_mm = record.v_mm;
    row.servo_path = servoPath(files.journal[i], row.pose);
    row.superseded = latest[record.planIndex()] != i;
    const auto residual = residual_of.find(i);
    row.solved = residual != residual_of.end();
    if (row.solved) {
      const Reader p(residuals[residual->second], "result.json pose_residuals");
      const auto miss = numbers(p.at("miss_mm"), 2, p.where() + ".miss_mm");
      row.miss_um = std::hypot(miss[0], miss[1]) * 1000;
      row.normalised = p.numberOrNan("normalised");
      row.outlier = p.boolean("outlier");
      row.standoff_mm = p.numberOrNan("standoff_mm");
    }
    r.poses.push_back(std::move(row));
  }
  return r;
}

void writeSessionReport(const std::string& session_dir) {
  const SessionReport report = parseSession(readSessionFiles(session_dir));
  const fs::path dir(session_dir);
  writeAtomically(dir / "summary.txt", summaryText(report));
  writeAtomically(dir / "report.html", reportHtml(report));
}

std::string escapeHtml(const std::string& text) {
  std::string out;
  out.reserve(text.size());
  for (const char c : text) {
    switch (c) {
      case '&':
        out += "&amp;";
        break;
      case '<':
        out += "&lt;";
        break;
      case '>':
        out += "&gt;";
        break;
      case '"':
        out += "&quot;";
        break;
      case '\'':
        out += "&#39;";
        break;
      default:
        out += c;
    }
  }
  return out;
}

}  // namespace zerocal::report
