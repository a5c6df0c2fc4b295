#include "report_command.h"

#include <iostream>
#include <nlohmann/json.hpp>

#include "lab_exit.h"
#include "zerocal/model/kinematics.h"
#include "zerocal/report/session_report.h"

namespace zerocal::lab {

void addReportCommand(CLI::App& app, ReportCommand& command) {
  command.report = app.add_subcommand(
      "report", "(re)write summary.txt and report.html of a session folder and print the summary");
  command.report
      ->add_option("session-dir", command.session_dir, "the session folder (<data_dir>/<id>)")
      ->required();
  command.report->add_flag(
      "--json", command.json,
      "print the paths and the offsets as one JSON object instead of the summary");
}

int runReportCommand(const ReportCommand& command) {
  if (!command.report->parsed()) return -1;
  const std::string& dir = command.session_dir;
  report::writeSessionReport(dir);
  const report::SessionReport r = report::parseSession(report::readSessionFiles(dir));
  if (!command.json) {
    std::cout << report::summaryText(r);
    return kOk;
  }
  nlohmann::json j{{"session", r.session.id},
                   {"summary", dir + "/summary.txt"},
                   {"report", dir + "/report.html"},
                   {"converged", r.solve().converged},
                   {"offsets", nlohmann::json::object()}};
  for (const auto& p : r.parameters) {
    if (p.name.rfind("delta", 0) != 0) continue;
    j["offsets"][p.name] = p.identifiable
                               ? nlohmann::json{{"value_deg", p.value},
                                                {"value_rad", p.value * kDegToRad},
                                                {"sigma_deg", p.sigma},
                                                {"ci95_deg", {p.ci95_low, p.ci95_high}}}
                               : nlohmann::json{{"identifiable", false}, {"reason", p.reason}};
  }
  std::cout << j.dump(2) << "\n";
  return kOk;
}

}  // namespace zerocal::lab
