#include "zerocal/daemon/logging.h"

#include <fcntl.h>
#include <gtest/gtest.h>
#include <sys/stat.h>
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

// Under systemd, stderr is a stream to journald, named by JOURNAL_STREAM=<device>:<inode>.
TEST(LoggingTest, OnTheJournalsStreamEachLineCarriesItsPriorityAndNoTimestamp) {
  const fs::path file =
      fs::temp_directory_path() / ("zerocal-journal-" + std::to_string(::getpid()));
  std::fflush(stderr);
  const int saved = ::dup(2);
  const int fd = ::open(file.c_str(), O_CREAT | O_TRUNC | O_WRONLY, 0600);
  ASSERT_GE(fd, 0);
  ::dup2(fd, 2);
  ::close(fd);
  struct stat st {};
  ::fstat(2, &st);
  const std::string stream = std::to_string(st.st_dev) + ":" + std::to_string(st.st_ino);
  ::setenv("JOURNAL_STREAM", stream.c_str(), 1);
  const bool journal = stderrIsJournal();
  ::setenv("JOURNAL_STREAM", (std::to_string(st.st_dev) + ":1").c_str(), 1);
  const bool other_stream = stderrIsJournal();  // stderr redirected elsewhere under the unit
  ::setenv("JOURNAL_STREAM", stream.c_str(), 1);

  LoggingConfig config;
  config.level = LogLevel::kDebug;
  initLogging(config);
  auto log = makeLogger("journal-test");
  log->debug("planning");
  log->info("pose 3 recorded");
  log->warn("spot lost");
  log->error("link down");
  log->critical("worker stuck");
  log->flush();

  ::dup2(saved, 2);
  ::close(saved);
  ::unsetenv("JOURNAL_STREAM");
  initLogging(LoggingConfig{});
  EXPECT_TRUE(journal);
  EXPECT_FALSE(other_stream);

  std::ifstream in(file);
  std::vector<std::string> lines;
  for (std::string line; std::getline(in, line);) lines.push_back(line);
  fs::remove(file);
  const std::vector<std::string> expected = {
      "<7>[journal-test] planning", "<6>[journal-test] pose 3 recorded",
      "<4>[journal-test] spot lost", "<3>[journal-test] link down",
      "<2>[journal-test] worker stuck"};
  EXPECT_EQ(lines, expected);
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
