// zerocald under systemd's service protocol, with a datagram socket standing in for the service
// manager's NOTIFY_SOCKET: READY=1 comes only once the control port accepts connections, the
// watchdog is fed (WATCHDOG_USEC), and SIGTERM says STOPPING=1 before a clean exit.
#include <fcntl.h>
#include <gtest/gtest.h>
#include <poll.h>
#include <signal.h>
#include <spawn.h>
#include <sys/socket.h>
#include <sys/un.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <regex>
#include <sstream>

#include "../support/temp_dir.h"
#include "zerocal/control/client.h"

extern char** environ;

namespace zerocal {
namespace {

using namespace std::chrono_literals;

// The folder's name says which test left it, should one outlive its test.
struct TempDir : testing::TempDir {
  TempDir() : testing::TempDir("zerocal-notify") {}
};
using testing::readFile;

// The next datagram within `timeout`, or nullopt.
std::optional<std::string> receive(int fd, std::chrono::milliseconds timeout) {
  pollfd p{fd, POLLIN, 0};
  if (::poll(&p, 1, static_cast<int>(timeout.count())) <= 0) return std::nullopt;
  char buffer[4096];
  const ssize_t n = ::recv(fd, buffer, sizeof buffer, 0);
  if (n < 0) return std::nullopt;
  return std::string(buffer, static_cast<std::size_t>(n));
}

TEST(ZerocaldUnderSystemd, ReadyOnceThePortListensWatchdogFedStoppingOnSigterm) {
  const TempDir dir;
  {
    std::ofstream token(dir.path + "/token");
    token << "process-test-token\n";
  }
  std::filesystem::permissions(dir.path + "/token", std::filesystem::perms::owner_read);
  const std::string socket_path = dir.path + "/notify";
  const int fd = ::socket(AF_UNIX, SOCK_DGRAM | SOCK_CLOEXEC, 0);
  sockaddr_un addr{};
  addr.sun_family = AF_UNIX;
  socket_path.copy(addr.sun_path, sizeof addr.sun_path - 1);
  ASSERT_EQ(::bind(fd, reinterpret_cast<sockaddr*>(&addr), sizeof addr), 0);

  std::vector<std::string> env = {"NOTIFY_SOCKET=" + socket_path, "WATCHDOG_USEC=200000"};
  for (char** e = environ; *e; ++e)
    if (std::strncmp(*e, "NOTIFY_SOCKET=", 14) && std::strncmp(*e, "WATCHDOG_", 9))
      env.push_back(*e);
  std::vector<char*> envp;
  for (auto& e : env) envp.push_back(e.data());
  envp.push_back(nullptr);
  std::vector<std::string> args = {ZEROCALD,     "--sim",
                                   "--config",   "/dev/null",
                                   "--data-dir", dir.path + "/sessions",
                                   "--set",      "control.token_file=" + dir.path + "/token",
                                   "--set",      "control.port=0",
                                   "--set",      "web.port=0"};
  std::vector<char*> argv;
  for (auto& a : args) argv.push_back(a.data());
  argv.push_back(nullptr);
  const std::string log = dir.path + "/zerocald.log";
  posix_spawn_file_actions_t actions;
  posix_spawn_file_actions_init(&actions);
  posix_spawn_file_actions_addopen(&actions, 2, log.c_str(), O_WRONLY | O_CREAT | O_APPEND, 0600);
  pid_t pid = -1;
  ASSERT_EQ(posix_spawn(&pid, ZEROCALD, &actions, nullptr, argv.data(), envp.data()), 0);
  posix_spawn_file_actions_destroy(&actions);

  std::optional<std::string> ready;
  for (int i = 0; i < 100 && !ready; ++i)
    if (auto m = receive(fd, 100ms); m && m->rfind("READY=1", 0) == 0) ready = m;
  ASSERT_TRUE(ready) << readFile(log);
  std::smatch port;
  ASSERT_TRUE(
      std::regex_search(*ready, port, std::regex("STATUS=serving 127\\.0\\.0\\.1:([0-9]+)")))
      << *ready;
  // READY=1 was sent after the port was bound: a connection succeeds at once.
  control::ControlClient client;
  client.connect("127.0.0.1", static_cast<std::uint16_t>(std::stoi(port[1])), 2s);
  EXPECT_TRUE(client.call("hello", nlohmann::json::object(), 2s).contains("protocol"));

  int fed = 0;
  const auto until = std::chrono::steady_clock::now() + 600ms;
  while (std::chrono::steady_clock::now() < until)
    if (auto m = receive(fd, 50ms); m && *m == "WATCHDOG=1") ++fed;
  EXPECT_GE(fed, 3) << "every 100 ms with WATCHDOG_USEC=200000";

  ::kill(pid, SIGTERM);
  bool stopping = false;
  for (int i = 0; i < 50 && !stopping; ++i)
    if (auto m = receive(fd, 100ms); m && m->rfind("STOPPING=1", 0) == 0) stopping = true;
  EXPECT_TRUE(stopping);
  int status = 0;
  ::waitpid(pid, &status, 0);
  EXPECT_TRUE(WIFEXITED(status) && WEXITSTATUS(status) == 0) << readFile(log);
  EXPECT_NE(readFile(log).find("systemd watchdog every 200 ms"), std::string::npos)
      << readFile(log);
  ::close(fd);
}

}  // namespace
}  // namespace zerocal
