#include "zerocal/daemon/logging.h"

#include <fcntl.h>
#include <gtest/gtest.h>
#include <sys/socket.h>
#include <sys/stat.h>
#include <sys/un.h>
#include <systemd/sd-journal.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <sstream>
#include <vector>

namespace zerocal {
namespace {

namespace fs = std::filesystem;

TEST(LoggingTest, NamedLoggersAreSharedAndFollowTheConfiguredLevelAndDirectory) {
  const fs::path dir = fs::temp_directory_path() / ("zerocal-log-" + std::to_string(::getpid()));
  fs::remove_all(dir);
  auto early = makeLogger("early");  // made before initLogging: rewired by it
  EXPECT_EQ(makeLogger("early"), early);

  LoggingConfig config;
  config.level = LogLevel::kWarn;
  config.directory = (dir / "logs").string();
  initLogging(config);
  auto later = makeLogger("later");
  EXPECT_EQ(early->level(), spdlog::level::warn);
  EXPECT_EQ(later->level(), spdlog::level::warn);
  early->info("not written");
  early->warn("written by early");
  later->error("written by later");
  early->flush();
  later->flush();

  std::ifstream in(dir / "logs" / "zerocald.log");
  std::stringstream text;
  text << in.rdbuf();
  EXPECT_EQ(text.str().find("not written"), std::string::npos) << text.str();
  EXPECT_NE(text.str().find("[early] [warning] written by early"), std::string::npos) << text.str();
  EXPECT_NE(text.str().find("[later] [error] written by later"), std::string::npos) << text.str();

  initLogging(LoggingConfig{});  // back to stderr, so the file can go
  fs::remove_all(dir);
}

TEST(LoggingTest, UnusableDirectoryThrows) {
  const fs::path file =
      fs::temp_directory_path() / ("zerocal-log-file-" + std::to_string(::getpid()));
  std::ofstream(file) << "x";
  LoggingConfig config;
  config.directory = (file / "logs").string();
  EXPECT_THROW(initLogging(config), Error);
  fs::remove(file);
}

TEST(LoggingTest, LevelNamesMatchSpdlog) {
  EXPECT_EQ(toSpdlogLevel(LogLevel::kTrace), spdlog::level::trace);
  EXPECT_EQ(toSpdlogLevel(LogLevel::kError), spdlog::level::err);
  EXPECT_EQ(toSpdlogLevel(LogLevel::kOff), spdlog::level::off);
  EXPECT_EQ(logLevelName(LogLevel::kWarn), "warn");
}

// Sends stderr to `file` (made anew) and returns the descriptor to restore it from (dup2), or -1.
int stderrTo(const fs::path& file) {
  std::fflush(stderr);
  const int fd = ::open(file.c_str(), O_CREAT | O_TRUNC | O_WRONLY, 0600);
  if (fd < 0) return -1;
  const int saved = ::dup(2);
  ::dup2(fd, 2);
  ::close(fd);
  return saved;
}

// Under systemd, stderr is a stream to journald, named by JOURNAL_STREAM=<device>:<inode>.
TEST(LoggingTest, StderrIsTheJournalOnlyWhenItIsTheStreamJournalStreamNames) {
  const fs::path file =
      fs::temp_directory_path() / ("zerocal-journal-" + std::to_string(::getpid()));
  const int saved = stderrTo(file);
  ASSERT_GE(saved, 0);
  struct stat st {};
  ::fstat(2, &st);
  const std::string stream = std::to_string(st.st_dev) + ":" + std::to_string(st.st_ino);
  ::setenv("JOURNAL_STREAM", stream.c_str(), 1);
  const bool journal = stderrIsJournal();
  ::setenv("JOURNAL_STREAM", (std::to_string(st.st_dev) + ":1").c_str(), 1);
  const bool other_stream = stderrIsJournal();  // stderr redirected elsewhere under the unit
  ::dup2(saved, 2);
  ::close(saved);
  ::unsetenv("JOURNAL_STREAM");
  fs::remove(file);
  EXPECT_TRUE(journal);
  EXPECT_FALSE(other_stream);
}

// What the journal received, a line's fields each as "NAME=value".
std::vector<std::vector<std::string>> sent;
int sendResult = 0;

int captureJournal(const iovec* fields, int count) {
  std::vector<std::string> line;
  for (int i = 0; i < count; ++i)
    line.emplace_back(static_cast<const char*>(fields[i].iov_base), fields[i].iov_len);
  sent.push_back(line);
  return sendResult;
}

TEST(LoggingTest, ToTheJournalEachLineCarriesItsPriorityIdentifierAndTheRunningSession) {
  sent.clear();
  sendResult = 0;
  LoggingConfig config;
  config.level = LogLevel::kDebug;
  initLogging(config, captureJournal);
  auto log = makeLogger("journal-test");
  log->debug("planning");
  log->warn("spot lost");
  {
    LoggedSession session("20261207T012200Z");
    log->info("connecting");
    session.setRobot("6400-100123");
    {
      LoggedSession verification("20261207T013000Z");
      log->info("verifying");
    }
    log->error("link down");
  }
  log->critical("worker stuck");
  initLogging(LoggingConfig{});

  using Line = std::vector<std::string>;
  ASSERT_EQ(sent.size(), 6u);
  EXPECT_EQ(sent[0],
            (Line{"MESSAGE=[journal-test] planning", "PRIORITY=7", "SYSLOG_IDENTIFIER=zerocald"}));
  EXPECT_EQ(sent[1],
            (Line{"MESSAGE=[journal-test] spot lost", "PRIORITY=4", "SYSLOG_IDENTIFIER=zerocald"}));
  EXPECT_EQ(sent[2], (Line{"MESSAGE=[journal-test] connecting", "PRIORITY=6",
                           "SYSLOG_IDENTIFIER=zerocald", "SESSION_ID=20261207T012200Z"}));
  EXPECT_EQ(sent[3], (Line{"MESSAGE=[journal-test] verifying", "PRIORITY=6",
                           "SYSLOG_IDENTIFIER=zerocald", "SESSION_ID=20261207T013000Z"}));
  EXPECT_EQ(sent[4],
            (Line{"MESSAGE=[journal-test] link down", "PRIORITY=3", "SYSLOG_IDENTIFIER=zerocald",
                  "SESSION_ID=20261207T012200Z", "ROBOT=6400-100123"}))
      << "the session around the verification again after it";
  EXPECT_EQ(sent[5], (Line{"MESSAGE=[journal-test] worker stuck", "PRIORITY=2",
                           "SYSLOG_IDENTIFIER=zerocald"}))
      << "the session's fields end with it";
}

TEST(LoggingTest, ALineTheJournalRefusesGoesToStderr) {
  const fs::path file =
      fs::temp_directory_path() / ("zerocal-journal-down-" + std::to_string(::getpid()));
  const int saved = stderrTo(file);
  ASSERT_GE(saved, 0);
  sent.clear();
  sendResult = -111;  // -ECONNREFUSED: journald stopped
  initLogging(LoggingConfig{}, captureJournal);
  makeLogger("journal-test")->warn("spot lost");
  initLogging(LoggingConfig{});
  std::fflush(stderr);
  ::dup2(saved, 2);
  ::close(saved);
  sendResult = 0;

  std::ifstream in(file);
  std::stringstream text;
  text << in.rdbuf();
  fs::remove(file);
  EXPECT_EQ(sent.size(), 1u);
  EXPECT_EQ(text.str(), "[journal-test] spot lost\n");
}

// journald's own socket, played by the test where it can be (no journald here, and the right to
// make /run/systemd/journal): libsystemd's sd_journal_sendv is the peer the daemon speaks to.
TEST(LoggingTest, SdJournalSendvDeliversTheFieldsToJournaldsSocket) {
  const fs::path folder = "/run/systemd/journal";
  const fs::path socket_path = folder / "socket";
  std::error_code ec;
  if (fs::exists(socket_path, ec)) GTEST_SKIP() << "a journald runs here: not played by a test";
  const bool made_folder = !fs::exists(folder, ec);
  fs::create_directories(folder, ec);
  const int sock = ::socket(AF_UNIX, SOCK_DGRAM | SOCK_CLOEXEC, 0);
  ASSERT_GE(sock, 0);
  sockaddr_un address{};
  address.sun_family = AF_UNIX;
  std::snprintf(address.sun_path, sizeof address.sun_path, "%s", socket_path.c_str());
  if (ec || ::bind(sock, reinterpret_cast<const sockaddr*>(&address), sizeof address) != 0) {
    ::close(sock);
    GTEST_SKIP() << "cannot play journald here (" << socket_path << " cannot be made)";
  }
  initLogging(LoggingConfig{}, sd_journal_sendv);
  {
    LoggedSession session("20261207T012200Z");
    session.setRobot("6400-100123");
    makeLogger("journal-test")->warn("spot lost");
  }
  initLogging(LoggingConfig{});
  char datagram[4096];
  const ssize_t size = ::recv(sock, datagram, sizeof datagram, MSG_DONTWAIT);
  ::close(sock);
  fs::remove(socket_path, ec);
  if (made_folder) fs::remove_all("/run/systemd", ec);
  ASSERT_GT(size, 0);
  // The native protocol: one "NAME=value\n" per field.
  const std::string text(datagram, static_cast<std::size_t>(size));
  EXPECT_NE(text.find("MESSAGE=[journal-test] spot lost\n"), std::string::npos) << text;
  EXPECT_NE(text.find("PRIORITY=4\n"), std::string::npos) << text;
  EXPECT_NE(text.find("SYSLOG_IDENTIFIER=zerocald\n"), std::string::npos) << text;
  EXPECT_NE(text.find("SESSION_ID=20261207T012200Z\n"), std::string::npos) << text;
  EXPECT_NE(text.find("ROBOT=6400-100123\n"), std::string::npos) << text;
}

TEST(LoggingTest, NoOrAMalformedJournalStreamIsNotTheJournal) {
  ::unsetenv("JOURNAL_STREAM");
  EXPECT_FALSE(stderrIsJournal());
  ::setenv("JOURNAL_STREAM", "not-a-stream", 1);
  EXPECT_FALSE(stderrIsJournal());
  ::unsetenv("JOURNAL_STREAM");
}

}  // namespace
}  // namespace zerocal
