// The daemon's side of sd_notify, against a datagram socket standing in for systemd's
// NOTIFY_SOCKET: readiness and status lines, and a watchdog fed only while nothing is stuck.
#include "zerocal/daemon/systemd.h"

#include <gtest/gtest.h>
#include <sys/socket.h>
#include <sys/un.h>
#include <unistd.h>

#include <atomic>
#include <cstdlib>
#include <filesystem>
#include <string>
#include <vector>

namespace zerocal {
namespace {

using namespace std::chrono_literals;

// A bound AF_UNIX datagram socket whose path is NOTIFY_SOCKET while it lives.
class NotifySocket {
 public:
  NotifySocket() {
    path_ =
        (std::filesystem::temp_directory_path() / ("zerocal-notify-" + std::to_string(::getpid())))
            .string();
    ::unlink(path_.c_str());
    fd_ = ::socket(AF_UNIX, SOCK_DGRAM | SOCK_CLOEXEC | SOCK_NONBLOCK, 0);
    sockaddr_un addr{};
    addr.sun_family = AF_UNIX;
    path_.copy(addr.sun_path, sizeof addr.sun_path - 1);
    if (fd_ < 0 || ::bind(fd_, reinterpret_cast<sockaddr*>(&addr), sizeof addr) != 0)
      throw std::runtime_error("cannot bind " + path_);
    ::setenv("NOTIFY_SOCKET", path_.c_str(), 1);
  }
  ~NotifySocket() {
    ::unsetenv("NOTIFY_SOCKET");
    ::close(fd_);
    ::unlink(path_.c_str());
  }
  // Every message received so far.
  std::vector<std::string> drain() {
    std::vector<std::string> messages;
    char buffer[4096];
    for (;;) {
      const ssize_t n = ::recv(fd_, buffer, sizeof buffer, 0);
      if (n < 0) break;
      messages.emplace_back(buffer, static_cast<std::size_t>(n));
    }
    return messages;
  }

 private:
  std::string path_;
  int fd_ = -1;
};

int count(const std::vector<std::string>& messages, const std::string& text) {
  int n = 0;
  for (const auto& m : messages) n += m == text;
  return n;
}

TEST(Systemd, ReadyStatusAndStoppingReachTheNotifySocket) {
  NotifySocket socket;
  notifyReady("serving 127.0.0.1:7450");
  notifyStatus("session 1 servoing");
  notifyStopping("stopping");
  const auto messages = socket.drain();
  ASSERT_EQ(messages.size(), 3u);
  EXPECT_EQ(messages[0], "READY=1\nSTATUS=serving 127.0.0.1:7450");
  EXPECT_EQ(messages[1], "STATUS=session 1 servoing");
  EXPECT_EQ(messages[2], "STOPPING=1\nSTATUS=stopping");
}

TEST(Systemd, WithoutNotifySocketNothingHappens) {
  ::unsetenv("NOTIFY_SOCKET");
  notifyReady("serving");  // no socket, no error, no throw
  ::unsetenv("WATCHDOG_USEC");
  EXPECT_FALSE(watchdogInterval().has_value());
}

TEST(Systemd, WatchdogIntervalComesFromWatchdogUsec) {
  ::setenv("WATCHDOG_USEC", "30000000", 1);
  ::setenv("WATCHDOG_PID", std::to_string(::getpid()).c_str(), 1);
  ASSERT_TRUE(watchdogInterval().has_value());
  EXPECT_EQ(*watchdogInterval(), 30s);
  ::setenv("WATCHDOG_PID", "1", 1);  // another process's watchdog
  EXPECT_FALSE(watchdogInterval().has_value());
  ::unsetenv("WATCHDOG_USEC");
  ::unsetenv("WATCHDOG_PID");
}

TEST(Systemd, TheWatchdogIsFedWhileNothingIsStuckAndStarvesWhileSomethingIs) {
  NotifySocket socket;
  boost::asio::io_context io;
  std::atomic<bool> stuck{false};
  // A datagram socket queues about ten messages before the sender blocks: each phase below sends
  // at most six (one every 30 ms), and the test reads them between phases.
  Watchdog watchdog(io, 60ms, [&]() -> std::optional<std::string> {
    if (stuck) return std::string("the worker is stuck");
    return std::nullopt;
  });
  watchdog.start();
  io.run_for(150ms);
  EXPECT_GE(count(socket.drain(), "WATCHDOG=1"), 4);  // at start, then every 30 ms

  stuck = true;
  io.restart();
  io.run_for(150ms);
  EXPECT_LE(count(socket.drain(), "WATCHDOG=1"), 1);  // at most the tick that was due
  io.restart();
  io.run_for(150ms);
  EXPECT_EQ(count(socket.drain(), "WATCHDOG=1"), 0);

  stuck = false;  // progress again: fed again
  io.restart();
  io.run_for(150ms);
  EXPECT_GE(count(socket.drain(), "WATCHDOG=1"), 3);

  watchdog.stop();
  io.restart();
  io.run_for(100ms);
  EXPECT_EQ(count(socket.drain(), "WATCHDOG=1"), 0);
}

}  // namespace
}  // namespace zerocal
