// What the experiments on the simulated cell share: a fresh folder for their sessions, and one
// session run as `zerocald --sim --once --kind K [--apply]` runs it (a backend and a session
// manager of its own in the configured data folder: each session its own noise, the arm as warm
// as configured), its truth from its result.json.
#pragma once

#include <CLI/CLI.hpp>
#include <array>
#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "zerocal/daemon/config.h"
#include "zerocal/results/result_file.h"

namespace zerocal::lab {

// A fresh folder under the temporary directory named `prefix`-XXXXXX, removed with everything in
// it when destroyed: an experiment keeps its figures, not its sessions.
class ExperimentDir {
 public:
  explicit ExperimentDir(const std::string& prefix);
  ~ExperimentDir();
  ExperimentDir(const ExperimentDir&) = delete;
  ExperimentDir& operator=(const ExperimentDir&) = delete;
  const std::string& path() const { return path_; }

 private:
  std::string path_;
};

// The options of every experiment on seeded worlds: --worlds, --seed0, --set, --json and
// --ideal-world, bound to the experiment's arguments.
void addSeededWorldOptions(CLI::App* cmd, int& worlds, std::uint64_t& seed0,
                           std::vector<std::string>& overrides, bool& json, bool& ideal_world);

// The daemon's configuration the experiment's sessions start from: the compiled defaults, the
// seeds' ideal worlds when asked, then `overrides`, validated. An override of a key in
// `per_session` (which the experiment sets for each session, and would overwrite unseen) is
// refused saying `why`; `problems` holds the experiment's own argument problems so far. Throws
// ConfigError from `origin` with every problem.
DaemonConfig experimentConfig(const char* origin, bool ideal_world,
                              const std::vector<std::string>& overrides,
                              const std::vector<std::string>& per_session, const std::string& why,
                              std::vector<std::string> problems);

// One session's end as the experiment reads it.
struct ExperimentSession {
  bool completed = false;
  std::string id, message;  // message: why not completed
  ResultFile result;
  double cell_time_s = 0;
  // The online apply of a restore: the status' sentence, whether it was verified, and the
  // verification's result (its truth: the arm's zeros after the apply).
  std::string apply;
  bool verified = false;
  std::optional<ResultFile> verification;
};

// Runs one session of `kind` on the simulated cell `config` describes, planned even where its
// prediction says not usable (what it gives is measured; its verdict is judged), and with
// `apply` its online apply, confirmed. Never throws for a session that is refused or fails: that
// is in `message`.
ExperimentSession runExperimentSession(const DaemonConfig& config, SessionKind kind, bool apply);

// a - b per offset.
std::array<double, kOffsetCount> offsetDifference(const std::array<double, kOffsetCount>& a,
                                                  const std::array<double, kOffsetCount>& b);

}  // namespace zerocal::lab
