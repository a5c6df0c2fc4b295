// zerocald as a process, driven through its control port like a technician's terminal: kill -9
// in the middle of a session, restart, resume (no pose lost or repeated, the result as good as an
// uninterrupted one); and SIGTERM during a session (the robot stopped, the journal complete, exit
// 0). The simulated cell is paced at 1/20 of real time so that a session lasts a few seconds.
#include <fcntl.h>
#include <gtest/gtest.h>
#include <signal.h>
#include <spawn.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <filesystem>
#include <fstream>
#include <regex>
#include <sstream>
#include <thread>

#include "../support/temp_dir.h"
#include "stored_plan.h"
#include "zerocal/control/client.h"

extern char** environ;

namespace zerocal {
namespace {

using namespace std::chrono_literals;
using control::CommandError;
using control::ControlClient;

// The folder's name says which test left it, should one outlive its test.
struct TempDir : testing::TempDir {
  TempDir() : testing::TempDir("zerocal-process") {}
};
using testing::readFile;

std::vector<int> journalIndices(const std::string& path) {
  std::vector<int> indices;
  std::ifstream in(path);
  for (std::string line; std::getline(in, line);)
    indices.push_back(nlohmann::json::parse(line)["index"].get<int>());
  return indices;
}

// One zerocald process on the simulated cell, its output in a log file, its control port read
// from the log ("control port listening on 127.0.0.1:PORT").
class Daemon {
 public:
  Daemon(const std::string& dir, const std::string& name,
         const std::vector<std::string>& extra_args = {})
      : log_(dir + "/" + name + ".log") {
    // The ideal world: the resumed result is checked against the truth, which the realistic
    // world's model errors would blur (docs/simulated-cell.md). Its sessions run on the optimal
    // plan for that world, stored: the daemon as a process is tested here, not its planner.
    std::vector<std::string> args = {ZEROCALD,
                                     "--sim",
                                     "--ideal-world",
                                     "--seed",
                                     "4",
                                     "--config",
                                     "/dev/null",
                                     "--data-dir",
                                     dir + "/sessions",
                                     "--set",
                                     "control.token_file=" + dir + "/token",
                                     "--set",
                                     "control.port=0",
                                     "--set",
                                     "web.port=0",  // --sim serves the web terminal too
                                     "--set",
                                     "backend.sim_pace=0.05",
                                     "--set",
                                     "session.plan=file",
                                     "--set",
                                     "session.plan_file=" + testing::storedPlanPath("ideal-4")};
    args.insert(args.end(), extra_args.begin(), extra_args.end());
    std::vector<char*> argv;
    for (const std::string& a : args) argv.push_back(const_cast<char*>(a.c_str()));
    argv.push_back(nullptr);
    posix_spawn_file_actions_t actions;
    posix_spawn_file_actions_init(&actions);
    posix_spawn_file_actions_addopen(&actions, 1, log_.c_str(), O_WRONLY | O_CREAT | O_APPEND,
                                     0600);
    posix_spawn_file_actions_adddup2(&actions, 1, 2);
    if (posix_spawn(&pid_, ZEROCALD, &actions, nullptr, argv.data(), environ) != 0)
      throw std::runtime_error("cannot start zerocald");
    posix_spawn_file_actions_destroy(&actions);
    static const std::regex kListening("control port listening on 127\\.0\\.0\\.1:([0-9]+)");
    for (int i = 0; i < 1000 && port_ == 0; ++i) {
      std::smatch m;
      const std::string text = readFile(log_);
      if (std::regex_search(text, m, kListening)) port_ = std::stoi(m[1]);
      if (port_ != 0) break;
      int status = 0;
      if (::waitpid(pid_, &status, WNOHANG) == pid_) {
        pid_ = -1;
        throw std::runtime_error("zerocald exited at start (exit " +
                                 std::to_string(WIFEXITED(status) ? WEXITSTATUS(status) : -1) +
                                 "): " + readFile(log_));
      }
      std::this_thread::sleep_for(10ms);
    }
    if (port_ == 0) throw std::runtime_error("zerocald did not listen: " + readFile(log_));
  }
  ~Daemon() {
    if (pid_ > 0) {
      ::kill(pid_, SIGKILL);
      ::waitpid(pid_, nullptr, 0);
    }
  }
  // Sends the signal and returns the exit status (or 128 + the signal that ended it).
  int signalAndWait(int signal) {
    ::kill(pid_, signal);
    int status = 0;
    ::waitpid(pid_, &status, 0);
    pid_ = -1;
    return WIFEXITED(status) ? WEXITSTATUS(status) : 128 + WTERMSIG(status);
  }
  std::uint16_t port() const { return port_; }
  std::string log() const { return readFile(log_); }

 private:
  std::string log_;
  pid_t pid_ = -1;
  std::uint16_t port_ = 0;
};

class ZerocaldProcess : public ::testing::Test {
 protected:
  ZerocaldProcess() {
    std::ofstream(dir_.path + "/token") << "k3rn3l-t0ken-for-the-test\n";
    ::chmod((dir_.path + "/token").c_str(), 0600);
  }
  static void connect(ControlClient& c, const Daemon& d) {
    c.connect("127.0.0.1", d.port());
    c.authenticate("k3rn3l-t0ken-for-the-test");
  }
  std::string journalOf(const std::string& id) {
    return dir_.path + "/sessions/" + id + "/journal.jsonl";
  }
  // Polls status until the session is no longer active; returns the last status.
  nlohmann::json waitEnd(ControlClient& c, std::chrono::seconds limit) {
    const auto deadline = std::chrono::steady_clock::now() + limit;
    for (;;) {
      const nlohmann::json s = c.call("status")["status"];
      const std::string state = s["state"];
      if (state == "done" || state == "aborted" || state == "faulted" || state == "idle") return s;
      if (std::chrono::steady_clock::now() > deadline) return s;
      std::this_thread::sleep_for(20ms);
    }
  }
  TempDir dir_;
};

TEST_F(ZerocaldProcess, Kill9MidSessionThenRestartAndResumeLosesAndRepeatsNothing) {
  std::string id;
  std::size_t recorded = 0;
  {
    Daemon first(dir_.path, "first");
    ControlClient c;
    connect(c, first);
    id = c.call("start")["session"];
    // Three poses on disk, then kill -9: no chance to tidy up.
    for (int i = 0; i < 3000 && journalIndices(journalOf(id)).size() < 3; ++i)
      std::this_thread::sleep_for(5ms);
    EXPECT_EQ(first.signalAndWait(SIGKILL), 128 + SIGKILL);
    recorded = journalIndices(journalOf(id)).size();
    ASSERT_GE(recorded, 3u);
    ASSERT_LT(recorded, 8u) << "the session finished before the kill";
  }
  Daemon second(dir_.path, "second");
  EXPECT_NE(second.log().find("unfinished"), std::string::npos) << second.log();
  ControlClient c;
  connect(c, second);
  EXPECT_EQ(c.call("resume")["session"], id);  // the latest unfinished one
  const nlohmann::json end = waitEnd(c, 120s);
  ASSERT_EQ(end["state"], "done") << end.dump();

  std::vector<int> expected(8);
  for (int i = 0; i < 8; ++i) expected[i] = i;
  EXPECT_EQ(journalIndices(journalOf(id)), expected);
  const nlohmann::json result = c.call("result", {{"session", id}})["result"];
  EXPECT_EQ(result["resumed_from"].get<std::size_t>(), recorded);
  for (const char* name : {"delta2_deg", "delta3_deg", "delta4_deg", "delta5_deg"}) {
    const double error =
        result["parameters"][name]["value"].get<double>() - result["truth"][name].get<double>();
    EXPECT_LT(std::abs(error), 3 * result["parameters"][name]["sigma"].get<double>()) << name;
  }
  EXPECT_EQ(second.signalAndWait(SIGTERM), 0);
}

// kill -9 while a session waits for the PSD to be moved: the restarted daemon's resume waits
// again (nothing measured with the PSD where it was), and `continue` finishes the session at both
// placements.
TEST_F(ZerocaldProcess, Kill9WhileWaitingForThePsdWaitsAgainOnResume) {
  const std::vector<std::string> two_placements = {
      "--set", "session.plan=optimal", "--set", "session.plan_file=\"\"",
      "--set", "session.placements=2", "--set", "session.poses=8"};
  const auto untilWaitingOrEnded = [](ControlClient& c) {
    const auto deadline = std::chrono::steady_clock::now() + 120s;
    for (;;) {
      const nlohmann::json s = c.call("status")["status"];
      if (s["state"] == "awaiting_placement" || !s["active"].get<bool>() ||
          std::chrono::steady_clock::now() > deadline)
        return s;
      std::this_thread::sleep_for(20ms);
    }
  };
  const auto lines = [this](const std::string& id) {
    std::vector<nlohmann::json> out;
    std::ifstream in(journalOf(id));
    for (std::string line; std::getline(in, line);) out.push_back(nlohmann::json::parse(line));
    return out;
  };
  std::string id;
  {
    Daemon first(dir_.path, "first", two_placements);
    ControlClient c;
    connect(c, first);
    id = c.call("start", nlohmann::json::object(), 60s)["session"];
    const nlohmann::json waiting = untilWaitingOrEnded(c);
    ASSERT_EQ(waiting["state"], "awaiting_placement") << waiting.dump();
    EXPECT_EQ(waiting["next_placement"], 2);
    EXPECT_EQ(first.signalAndWait(SIGKILL), 128 + SIGKILL);
  }
  ASSERT_EQ(lines(id).size(), 8u);  // placement 1's poses, no move of the PSD
  Daemon second(dir_.path, "second", two_placements);
  ControlClient c;
  connect(c, second);
  EXPECT_EQ(c.call("resume")["session"], id);
  const nlohmann::json again = untilWaitingOrEnded(c);
  ASSERT_EQ(again["state"], "awaiting_placement") << again.dump();
  EXPECT_EQ(again["recorded"], 8);
  EXPECT_EQ(lines(id).size(), 8u);
  EXPECT_EQ(c.call("continue")["session"], id);
  const nlohmann::json end = waitEnd(c, 120s);
  ASSERT_EQ(end["state"], "done") << end.dump();
  const std::vector<nlohmann::json> journal = lines(id);
  ASSERT_GE(journal.size(), 17u);
  EXPECT_FALSE(journal[8].contains("index"));  // the move of the PSD, then placement 2's poses
  EXPECT_EQ(journal[8]["placement"], 2);
  EXPECT_EQ(journal[9]["placement"], 2);
  EXPECT_EQ(c.call("result", {{"session", id}})["result"]["placements"].size(), 2u);
  EXPECT_EQ(second.signalAndWait(SIGTERM), 0);
}

TEST_F(ZerocaldProcess, SigtermDuringASessionStopsTheRobotKeepsTheJournalAndExitsCleanly) {
  Daemon daemon(dir_.path, "daemon");
  ControlClient c;
  connect(c, daemon);
  const std::string id = c.call("start")["session"];
  for (int i = 0; i < 3000 && journalIndices(journalOf(id)).empty(); ++i)
    std::this_thread::sleep_for(5ms);
  const auto signalled = std::chrono::steady_clock::now();
  EXPECT_EQ(daemon.signalAndWait(SIGTERM), 0);
  EXPECT_LT(std::chrono::steady_clock::now() - signalled, 10s);
  const std::string log = daemon.log();
  EXPECT_NE(log.find("signal 15"), std::string::npos) << log;
  EXPECT_NE(log.find("aborted"), std::string::npos) << log;
  const std::vector<int> indices = journalIndices(journalOf(id));
  ASSERT_FALSE(indices.empty());
  EXPECT_LT(indices.size(), 8u);
  for (std::size_t i = 0; i < indices.size(); ++i) EXPECT_EQ(indices[i], static_cast<int>(i));
  EXPECT_FALSE(std::filesystem::exists(dir_.path + "/sessions/" + id + "/result.json"));
}

// zerocal-sim as its own process: the controller outlives a killed daemon, as a real one does.
class SimProcess {
 public:
  explicit SimProcess(const std::string& dir) : out_(dir + "/sim.out") {
    std::vector<std::string> args = {ZEROCAL_SIM,     "--port", "0",    "--seed",      "4",
                                     "--ideal-world", "--pace", "0.03", "--restart-s", "30"};
    std::vector<char*> argv;
    for (const std::string& a : args) argv.push_back(const_cast<char*>(a.c_str()));
    argv.push_back(nullptr);
    posix_spawn_file_actions_t actions;
    posix_spawn_file_actions_init(&actions);
    posix_spawn_file_actions_addopen(&actions, 1, out_.c_str(), O_WRONLY | O_CREAT | O_APPEND,
                                     0600);
    posix_spawn_file_actions_adddup2(&actions, 1, 2);
    if (posix_spawn(&pid_, ZEROCAL_SIM, &actions, nullptr, argv.data(), environ) != 0)
      throw std::runtime_error("cannot start zerocal-sim");
    posix_spawn_file_actions_destroy(&actions);
    static const std::regex kListening("zerocal-sim listening on .*:([0-9]+)");
    for (int i = 0; i < 1000 && port_ == 0; ++i) {
      std::smatch m;
      const std::string text = readFile(out_);
      if (std::regex_search(text, m, kListening)) port_ = std::stoi(m[1]);
      std::this_thread::sleep_for(10ms);
    }
    if (port_ == 0) throw std::runtime_error("zerocal-sim did not listen: " + readFile(out_));
  }
  ~SimProcess() {
    ::kill(pid_, SIGKILL);
    ::waitpid(pid_, nullptr, 0);
  }
  // The external simulator's cell clock is the steady clock: the servo's settling would wait in
  // wall time, for an ideal world that needs none (as in zerocal-lab experiment apply).
  std::vector<std::string> daemonArgs() const {
    return {"--set", "backend.sim_host=\"127.0.0.1\"",
            "--set", "backend.sim_port=" + std::to_string(port_),
            "--set", "servo.settle_s=0"};
  }

 private:
  std::string out_;
  pid_t pid_ = -1;
  std::uint16_t port_ = 0;
};

std::vector<nlohmann::json> jsonLines(const std::string& path) {
  std::vector<nlohmann::json> lines;
  std::ifstream in(path);
  for (std::string line; std::getline(in, line);) {
    try {
      lines.push_back(nlohmann::json::parse(line));
    } catch (const nlohmann::json::exception&) {
      break;  // cut short by the kill
    }
  }
  return lines;
}

bool hasStep(const std::vector<nlohmann::json>& lines, const std::string& step) {
  for (const auto& l : lines)
    if (l.value("step", "") == step) return true;
  return false;
}

// kill -9 while the controller holds new, not yet verified values (written, restarting): the next
// daemon finds the apply unfinished in the session's apply.jsonl, restores the backup on the
// controller (which lived on in its own process) and says so in its log, its status and the
// journal; a session run afterwards records the backup as the controller's values. zerocal-sim's
// restart costs 30 simulated seconds, 0.9 s of wall time at its pace (0.03), during which it
// refuses connections: the kill lands inside it, however the apply would have ended (with seed 4
// the change crosses joint 2's seam, and the external simulator cannot update revolution
// counters, so the apply would roll back right after the restart), and the next daemon starts
// while the controller is still restarting and has to wait for it. A session takes about 5 s.
TEST_F(ZerocaldProcess, Kill9DuringAnApplyRecoversTheBackupOnRestart) {
  SimProcess sim(dir_.path);
  std::string id;
  std::vector<nlohmann::json> journal;
  {
    Daemon first(dir_.path, "first", sim.daemonArgs());
    ControlClient c;
    connect(c, first);
    id = c.call("start")["session"];
    const nlohmann::json end = waitEnd(c, 180s);
    ASSERT_EQ(end["state"], "done") << end.dump() << first.log();
    const nlohmann::json result = c.call("result", {{"session", id}})["result"];
    ASSERT_TRUE(result.contains("controller_cal_offset_rad")) << result.dump();
    // Refused without the confirmation, and nothing journalled.
    try {
      c.call("apply", {{"session", id}});
      ADD_FAILURE() << "apply without confirm was accepted";
    } catch (const CommandError& e) {
      EXPECT_EQ(e.code(), "not_confirmed");
    }
    const std::string path = dir_.path + "/sessions/" + id + "/apply.jsonl";
    EXPECT_FALSE(std::filesystem::exists(path));
    EXPECT_EQ(c.call("apply", {{"session", id}, {"confirm", true}})["session"], id);
    // Killed as the controller restarts on the new values: a verification that fails at once
    // (a spot not found after the restart) could end the apply within a poll after "restarted".
    for (int i = 0; i < 6000 && !hasStep(jsonLines(path), "restarting"); ++i)
      std::this_thread::sleep_for(5ms);
    EXPECT_EQ(first.signalAndWait(SIGKILL), 128 + SIGKILL);
    journal = jsonLines(path);
    ASSERT_TRUE(hasStep(journal, "restarting")) << "the apply never restarted the controller";
    ASSERT_FALSE(hasStep(journal, "done")) << "the apply finished before the kill";
  }
  // The transmissions were measured first, and agreed; then the backup.
  ASSERT_EQ(journal.front().value("step", ""), "transmission_check");
  EXPECT_TRUE(journal.front().value("agree", false)) << journal.front().dump();
  ASSERT_GE(journal.size(), 2u);
  ASSERT_EQ(journal[1].value("step", ""), "begin");
  const auto before = journal[1].at("before_rad").get<std::vector<double>>();
  const auto written = journal[1].at("new_rad").get<std::vector<double>>();
  ASSERT_GT(std::abs(written[2] - before[2]), 1e-4) << "the apply changes nothing to recover";

  Daemon second(dir_.path, "second", sim.daemonArgs());
  ControlClient c;
  connect(c, second);
  nlohmann::json status;
  for (int i = 0; i < 6000; ++i) {
    status = c.call("status")["status"];
    if (!status["active"].get<bool>() && status.contains("apply")) break;
    std::this_thread::sleep_for(10ms);
  }
  ASSERT_TRUE(status.contains("apply")) << status.dump();
  EXPECT_NE(status["apply"].get<std::string>().find("recovered"), std::string::npos)
      << status.dump();
  EXPECT_NE(second.log().find("interrupted"), std::string::npos) << second.log();

  const std::vector<nlohmann::json> after =
      jsonLines(dir_.path + "/sessions/" + id + "/apply.jsonl");
  ASSERT_FALSE(after.empty());
  EXPECT_EQ(after.back().value("step", ""), "done");
  EXPECT_EQ(after.back().value("outcome", ""), "recovered");
  bool found_new = false;
  for (const auto& l : after)
    if (l.value("step", "") == "recovering") {
      // The controller held the written values when the daemon came back.
      const auto found = l.at("found_rad").get<std::vector<double>>();
      found_new = std::abs(found[2] - written[2]) < 2e-5;
    }
  EXPECT_TRUE(found_new) << "the controller did not hold the written values at the restart: "
                         << nlohmann::json(after).dump();

  // The controller holds the backup again: a session records it.
  const std::string check = c.call("start")["session"];
  const nlohmann::json end = waitEnd(c, 180s);
  ASSERT_EQ(end["state"], "done") << end.dump() << second.log();
  const auto now = c.call("result", {{"session", check}})["result"]["controller_cal_offset_rad"]
                       .get<std::vector<double>>();
  for (int j = 1; j < 5; ++j) EXPECT_NEAR(now[j], before[j], 2e-5) << "joint " << j + 1;
  EXPECT_EQ(second.signalAndWait(SIGTERM), 0);
}

// A second daemon on a port already served: a configuration error (exit 2) naming the port, not
// a daemon without its port.
// A write cut short (a full disk, a kill between the temporary and its rename) leaves NAME.tmp
// beside a session's files: the daemon removes it at start, says so, and leaves the rest.
TEST_F(ZerocaldProcess, TheTemporariesOfWritesCutShortAreRemovedAtStartAndLogged) {
  const std::string folder = dir_.path + "/sessions/20261122T070000Z";
  std::filesystem::create_directories(folder);
  std::ofstream(folder + "/session.json") << "{}\n";
  std::ofstream(folder + "/report.html.tmp") << "<html><body>cut sho";
  Daemon d(dir_.path, "start");
  EXPECT_NE(
      d.log().find("removed " + folder + "/report.html.tmp, left by a write that did not complete"),
      std::string::npos)
      << d.log();
  EXPECT_FALSE(std::filesystem::exists(folder + "/report.html.tmp"));
  EXPECT_TRUE(std::filesystem::exists(folder + "/session.json"));
  EXPECT_EQ(d.signalAndWait(SIGTERM), 0);
}

TEST_F(ZerocaldProcess, AControlPortInUseIsAConfigurationError) {
  Daemon first(dir_.path, "first");
  const std::string port = std::to_string(first.port());
  // The second with a data folder of its own: on the first's it would stop at the folder's lock.
  const std::string other = dir_.path + "/other";
  std::filesystem::create_directories(other);
  std::filesystem::copy_file(dir_.path + "/token", other + "/token");
  try {
    Daemon second(other, "second", {"--set", "control.port=" + port});
    ADD_FAILURE() << "a second daemon listens on port " << port;
  } catch (const std::runtime_error& e) {
    const std::string what = e.what();
    EXPECT_NE(what.find("(exit 2)"), std::string::npos) << what;
    EXPECT_NE(what.find("control port 127.0.0.1:" + port), std::string::npos) << what;
  }
}

// Runs a program to its end with its output in `log`; its exit status, or 128 + the signal.
int runToEnd(const std::vector<std::string>& args, const std::string& log) {
  std::vector<char*> argv;
  for (const std::string& a : args) argv.push_back(const_cast<char*>(a.c_str()));
  argv.push_back(nullptr);
  posix_spawn_file_actions_t actions;
  posix_spawn_file_actions_init(&actions);
  posix_spawn_file_actions_addopen(&actions, 1, log.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0600);
  posix_spawn_file_actions_adddup2(&actions, 1, 2);
  pid_t pid = -1;
  const int spawned = posix_spawn(&pid, argv[0], &actions, nullptr, argv.data(), environ);
  posix_spawn_file_actions_destroy(&actions);
  if (spawned != 0) return -1;
  int status = 0;
  ::waitpid(pid, &status, 0);
  return WIFEXITED(status) ? WEXITSTATUS(status) : 128 + WTERMSIG(status);
}

// A world file cut short is a configuration error of both programs that read one: exit 2 and
// the file, line and key, never an abort or a parser's bare message.
TEST_F(ZerocaldProcess, ATruncatedWorldFileIsAConfigurationErrorOfBothPrograms) {
  const std::string world = dir_.path + "/w.yaml";
  std::ofstream(world) << "robot: builtin\nnoise:\n  repeatability_deg";
  const std::string sim_log = dir_.path + "/sim.log";
  EXPECT_EQ(runToEnd({ZEROCAL_SIM, "--world", world, "--port", "0"}, sim_log), 2)
      << readFile(sim_log);
  EXPECT_NE(readFile(sim_log).find(world + ":3: noise: must be a map"), std::string::npos)
      << readFile(sim_log);
  const std::string daemon_log = dir_.path + "/zerocald.log";
  EXPECT_EQ(runToEnd({ZEROCALD, "--sim", "--once", "--config", "/dev/null", "--data-dir",
                      dir_.path + "/sessions", "--set", "backend.sim_world=" + world},
                     daemon_log),
            2)
      << readFile(daemon_log);
  EXPECT_NE(readFile(daemon_log).find(world + ":3: noise: must be a map"), std::string::npos)
      << readFile(daemon_log);
}

}  // namespace
}  // namespace zerocal
