#include "record_view.h"

#include <fmt/format.h>

#include <ctime>
#include <string>

namespace zerocal::cli {

using nlohmann::json;

namespace {

const char* const kOffsets[] = {"delta2_deg", "delta3_deg", "delta4_deg", "delta5_deg"};

std::string utc(const json& unix_s) {
  if (!unix_s.is_number()) return "-";
  const std::time_t t = static_cast<std::time_t>(unix_s.get<double>());
  std::tm tm{};
  ::gmtime_r(&t, &tm);
  char text[32];
  std::strftime(text, sizeof text, "%Y-%m-%d %H:%M", &tm);
  return text;
}

std::string verdict(const json& session) {
  const json usable = session.value("usable", json(nullptr));
  if (usable.is_boolean()) return usable.get<bool>() ? "usable" : "NOT USABLE";
  return "no verdict";
}

std::string offsetText(const json& offset) {
  if (!offset.is_object()) return "withheld";
  return fmt::format("{:+.5f} +- {:.5f}", offset.value("value", 0.0), offset.value("sigma", 0.0));
}

std::string valuesText(const json& rad) {
  if (!rad.is_array() || rad.size() != 6) return "-";
  std::string text;
  for (std::size_t j = 1; j <= 4; ++j) {
    text += fmt::format("{}rob1_{} {:.6f}", j > 1 ? " " : "", j + 1, rad[j].get<double>());
  }
  return text;
}

std::string csvField(const std::string& s) {
  if (s.find_first_of(",\"\n\r") == std::string::npos) return s;
  std::string quoted = "\"";
  for (char c : s) quoted += c == '"' ? std::string("\"\"") : std::string(1, c);
  return quoted + "\"";
}

std::string number(const json& v, int decimals) {
  if (!v.is_number()) return "";
  return fmt::format("{:.{}f}", v.get<double>(), decimals);
}

// A table row without the padding after its last column.
std::string trimmed(const std::string& row) {
  std::string s = row;
  const std::size_t end = s.find_last_not_of(' ');
  return s.substr(0, end == std::string::npos ? 0 : end + 1) + "\n";
}

std::string robotLine(const json& robot) {
  return robot.value("robot_type", std::string("?")) + " serial " +
         robot.value("serial", std::string("?"));
}

}  // namespace

void printRobots(const json& robots, std::ostream& out) {
  if (robots.empty()) {
    out << "the record knows no robot yet\n";
    return;
  }
  for (const json& r : robots) {
    out << robotLine(r) << "  software " << r.value("software_version", std::string("?")) << "  "
        << r.value("sessions", 0) << " session" << (r.value("sessions", 0) == 1 ? "" : "s")
        << ", first " << utc(r.value("first_unix_s", json(nullptr))) << ", latest "
        << utc(r.value("last_unix_s", json(nullptr))) << " UTC\n";
  }
}

void printHistory(const json& answer, std::ostream& out) {
  const json& history = answer.at("history");
  out << robotLine(answer.at("robot")) << ": " << history.size() << " session"
      << (history.size() == 1 ? "" : "s") << "\n";
  const std::string head = fmt::format(
      "{:<16}  {:<18} {:<12} {:<10}  {:<20} {:<20} {:<20} {:<20}", "started (UTC)", "session",
      "kind", "verdict", "delta2 (deg)", "delta3 (deg)", "delta4 (deg)", "delta5 (deg)");
  out << trimmed(head);
  for (const json& s : history) {
    const json offsets = s.value("offsets", json::object());
    const std::string line = fmt::format(
        "{:<16}  {:<18} {:<12} {:<10}  {:<20} {:<20} {:<20} {:<20}",
        utc(s.value("started_unix_s", json(nullptr))).c_str(),
        s.value("session", std::string("?")).c_str(), s.value("kind", std::string("?")).c_str(),
        verdict(s).c_str(), offsetText(offsets.value(kOffsets[0], json(nullptr))).c_str(),
        offsetText(offsets.value(kOffsets[1], json(nullptr))).c_str(),
        offsetText(offsets.value(kOffsets[2], json(nullptr))).c_str(),
        offsetText(offsets.value(kOffsets[3], json(nullptr))).c_str());
    out << trimmed(line);
    if (s.contains("model_from"))
      out << "    solved with the calibrated model of " << s.value("model_from", "") << "\n";
    if (s.contains("model_file"))
      out << "    wrote the robot's calibrated model (" << s.value("model_file", "") << ")\n";
    for (const json& e : s.value("events", json::array())) {
      out << "    " << utc(e.value("time_unix_s", json(nullptr))) << "  "
          << e.value("kind", std::string("?")) << " " << e.value("outcome", std::string("?"));
      const std::string before = valuesText(e.value("before_rad", json(nullptr)));
      const std::string after = valuesText(e.value("after_rad", json(nullptr)));
      if (before != "-" || after != "-") {
        if (before == after)
          out << ": controller holds " << before;
        else
          out << ": cal_offset " << before << " -> " << after;
      }
      if (e.contains("verification")) out << " (measured by " << e.value("verification", "") << ")";
      out << "\n";
    }
  }
}

void printHistoryCsv(const json& answer, std::ostream& out) {
  const json& robot = answer.at("robot");
  out << "robot_type,serial,session,started_utc,finished_utc,kind,verifies,usable";
  for (const char* name : kOffsets) out << "," << name << "," << name << "_sigma";
  out << ",cell_time_s,software_version,controller_events,model_from,model_file\n";
  for (const json& s : answer.at("history")) {
    const json usable = s.value("usable", json(nullptr));
    out << csvField(robot.value("robot_type", "")) << "," << csvField(robot.value("serial", ""))
        << "," << csvField(s.value("session", "")) << ","
        << utc(s.value("started_unix_s", json(nullptr))) << ","
        << utc(s.value("finished_unix_s", json(nullptr))) << "," << csvField(s.value("kind", ""))
        << "," << csvField(s.value("verifies", "")) << ","
        << (usable.is_boolean() ? (usable.get<bool>() ? "true" : "false") : "");
    const json offsets = s.value("offsets", json::object());
    for (const char* name : kOffsets) {
      const json o = offsets.value(name, json(nullptr));
      out << "," << (o.is_object() ? number(o["value"], 6) : "") << ","
          << (o.is_object() ? number(o["sigma"], 6) : "");
    }
    std::string events;
    for (const json& e : s.value("events", json::array()))
      events += (events.empty() ? "" : "; ") + e.value("kind", std::string("?")) + " " +
                e.value("outcome", std::string("?"));
    out << "," << number(s.value("cell_time_s", json(nullptr)), 1) << ","
        << csvField(s.value("software_version", "")) << "," << csvField(events) << ","
        << csvField(s.value("model_from", "")) << "," << csvField(s.value("model_file", ""))
        << "\n";
  }
}

}  // namespace zerocal::cli
