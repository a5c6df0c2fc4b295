// zerocal-sim as its own process: the cell can be killed and restarted from outside, and the
// client reconnects to the new one.
#include <gtest/gtest.h>
#include <signal.h>
#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cstdio>
#include <string>
#include <vector>

#include "zerocal/irc5/irc5_client.h"
#include "zerocal/model/builtin.h"

extern char** environ;

namespace zerocal {
namespace {

// A started zerocal-sim; the destructor stops it with SIGTERM.
class SimProcess {
 public:
  explicit SimProcess(const std::string& port) {
    int out[2];
    if (::pipe(out) != 0) return;
    posix_spawn_file_actions_t actions;
    posix_spawn_file_actions_init(&actions);
    posix_spawn_file_actions_adddup2(&actions, out[1], STDOUT_FILENO);
    posix_spawn_file_actions_addclose(&actions, out[0]);
    std::vector<std::string> args = {ZEROCAL_SIM_PATH, "--port", port, "--seed", "5"};
    std::vector<char*> argv;
    for (auto& a : args) argv.push_back(a.data());
    argv.push_back(nullptr);
    if (posix_spawn(&pid_, ZEROCAL_SIM_PATH, &actions, nullptr, argv.data(), environ) != 0)
      pid_ = -1;
    posix_spawn_file_actions_destroy(&actions);
    ::close(out[1]);
    // "zerocal-sim listening on 127.0.0.1:PORT"; EOF if the program failed to start.
    FILE* in = ::fdopen(out[0], "r");
    char line[256] = {};
    if (in && std::fgets(line, sizeof line, in)) {
      const std::string text(line);
      port_ = std::stoi(text.substr(text.rfind(':') + 1));
    }
    if (in) std::fclose(in);
  }
  ~SimProcess() { stop(); }
  int port() const { return port_; }
  // SIGTERM, then the exit status (0 when it shut down cleanly).
  int stop() {
    if (pid_ <= 0) return -1;
    ::kill(pid_, SIGTERM);
    int status = 0;
    ::waitpid(pid_, &status, 0);
    pid_ = -1;
    return WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  }

 private:
  pid_t pid_ = -1;
  int port_ = 0;
};

TEST(SimProcess, KilledAndRestartedCellIsReachedAgainByReconnect) {
  SimProcess first("0");
  ASSERT_GT(first.port(), 0);
  Irc5Options o;
  o.host = "127.0.0.1";
  o.port = static_cast<std::uint16_t>(first.port());
  o.robot = builtinIrb1600();
  o.reconnect_attempts = 5;
  o.backoff_initial = std::chrono::milliseconds(20);
  Irc5Client client(o);
  client.connect();
  client.moveJoints({0, 0, 0, 0, 30, 5});
  EXPECT_EQ(first.stop(), 0);  // SIGTERM: clean exit
  EXPECT_THROW(client.readJoints(), ConnectionError);

  SimProcess second(std::to_string(first.port()));
  ASSERT_EQ(second.port(), first.port());
  client.reconnect();
  EXPECT_EQ(client.readJoints()[5], 0.0);  // a fresh controller, back at its start joints
}

}  // namespace
}  // namespace zerocal
