#include "zerocal/daemon/logging.h"

#include <gtest/gtest.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <sstream>

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

}  // namespace
}  // namespace zerocal
