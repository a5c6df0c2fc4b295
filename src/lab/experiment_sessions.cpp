#include "experiment_sessions.h"

#include <unistd.h>

#include <filesystem>

#include "zerocal/error.h"
#include "zerocal/service/daemon_setup.h"

namespace zerocal::lab {

ExperimentDir::ExperimentDir(const std::string& prefix) {
  std::string pattern = (std::filesystem::temp_directory_path() / (prefix + "-XXXXXX")).string();
  if (!::mkdtemp(pattern.data())) throw Error("cannot create a folder for the sessions");
  path_ = pattern;
}

ExperimentDir::~ExperimentDir() {
  std::error_code ec;
  std::filesystem::remove_all(path_, ec);
}

void addSeededWorldOptions(CLI::App* cmd, int& worlds, std::uint64_t& seed0,
                           std::vector<std::string>& overrides, bool& json, bool& ideal_world) {
  cmd->add_option("--worlds", worlds, "number of seeded worlds")
      ->default_val(worlds)
      ->check(CLI::Range(1, 10000));
  cmd->add_option("--seed0", seed0, "seed of the first world (then seed0+1, ...)")
      ->default_val(seed0);
  cmd->add_option("--set", overrides,
                  "override one daemon configuration key: section.key=value (repeatable; not the "
                  "keys the experiment sets per session)");
  cmd->add_flag("--json", json, "print one JSON object instead of text");
  cmd->add_flag("--ideal-world", ideal_world,
                "the seeds' ideal worlds (exact arm, no warming, no gross errors) instead of the "
                "realistic ones (docs/simulated-cell.md)");
}

DaemonConfig experimentConfig(const char* origin, bool ideal_world,
                              const std::vector<std::string>& overrides,
                              const std::vector<std::string>& per_session, const std::string& why,
                              std::vector<std::string> problems) {
  for (const std::string& o : overrides) {
    const std::string key = o.substr(0, o.find('='));
    for (const std::string& k : per_session)
      if (key == k)
        problems.push_back(key + ": the experiment sets it for each session (" + why + ")");
  }
  if (!problems.empty()) throw ConfigError(origin, problems);
  DaemonConfig config;
  ConfigOrigins origins;
  if (ideal_world) applyConfigOverride(config, "backend.sim_ideal_world=true", origins, problems);
  for (const std::string& o : overrides) applyConfigOverride(config, o, origins, problems);
  for (const std::string& p : validateDaemonConfig(config, origins)) problems.push_back(p);
  if (!problems.empty()) throw ConfigError(origin, problems);
  return config;
}

ExperimentSession runExperimentSession(const DaemonConfig& config, SessionKind kind, bool apply) {
  service::ManagerSettings settings = service::managerSettingsOf(config);
  settings.write_reports = nullptr;  // figures only
  const std::unique_ptr<CellBackend> backend = service::makeBackend(config);
  service::SessionManager manager(*backend, settings);
  ExperimentSession out;
  try {
    service::StartRequest request = manager.defaultRequest();
    request.kind = kind;
    request.even_if_not_usable = true;
    manager.start(request);
  } catch (const service::Refused& e) {
    out.message = std::string(sessionKindName(kind)) + " refused: " + e.what();
    return out;
  }
  const service::SessionStatus end = manager.waitIdle();
  out.id = end.session_id;
  out.cell_time_s = end.cell_time_s;
  if (end.state != service::SessionState::kDone) {
    out.message = std::string(sessionKindName(kind)) + " " + service::stateName(end.state) + ": " +
                  end.message;
    return out;
  }
  out.result = manager.result(out.id);
  out.completed = out.result.truth.has_value();
  if (!out.completed) out.message = "session " + out.id + " has no truth";
  if (!apply || !out.completed) return out;
  try {
    manager.apply({out.id, true});
  } catch (const service::Refused& e) {
    out.apply = std::string("not applied: ") + e.what();
    return out;
  }
  out.apply = manager.waitIdle().apply;
  out.verified = out.apply.rfind("session " + out.id + " verified", 0) == 0;
  for (const SessionInfo& s : manager.sessions())
    if (s.kind == SessionKind::kVerification && s.verifies == out.id && s.finished)
      out.verification = manager.result(s.id);
  return out;
}

std::array<double, kOffsetCount> offsetDifference(const std::array<double, kOffsetCount>& a,
                                                  const std::array<double, kOffsetCount>& b) {
  std::array<double, kOffsetCount> d{};
  for (int k = 0; k < kOffsetCount; ++k) d[k] = a[k] - b[k];
  return d;
}

}  // namespace zerocal::lab
