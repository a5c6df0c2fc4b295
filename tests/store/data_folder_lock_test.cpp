#include "zerocal/store/data_folder_lock.h"

#include <gtest/gtest.h>
#include <sys/wait.h>
#include <unistd.h>

#include <fstream>
#include <optional>
#include <string>

#include "temp_dir.h"
#include "zerocal/error.h"

namespace zerocal {
namespace {

std::string refusal(const std::string& data_dir) {
  try {
    DataFolderLock second(data_dir);
  } catch (const FileError& e) {
    return e.what();
  }
  return "";
}

TEST(DataFolderLock, OneDaemonPerDataFolderAndTheSecondIsToldWhoHasIt) {
  const testing::TempDir dir("zerocal-lock");
  const std::string data = dir.path + "/sessions";  // not there yet: made
  std::optional<DataFolderLock> first(std::in_place, data);
  std::ifstream holder(data + "/" + kDataFolderLockName);
  std::string pid;
  holder >> pid;
  EXPECT_EQ(pid, std::to_string(::getpid()));
  const std::string why = refusal(data);
  EXPECT_NE(why.find("another zerocald (pid " + pid + ") uses the data folder " + data),
            std::string::npos)
      << why;
  EXPECT_NE(why.find("session.data_dir"), std::string::npos) << why;
  // Another folder is another daemon's.
  EXPECT_EQ(refusal(dir.path + "/other"), "");
  first.reset();
  EXPECT_EQ(refusal(data), "");  // released with its holder
}

TEST(DataFolderLock, AHolderKilledLeavesNoStaleLock) {
  const testing::TempDir dir("zerocal-lock");
  int ready[2];
  ASSERT_EQ(::pipe(ready), 0);
  const pid_t child = ::fork();
  ASSERT_GE(child, 0);
  if (child == 0) {
    DataFolderLock held(dir.path);
    const char byte = 1;
    if (::write(ready[1], &byte, 1) != 1) ::_exit(2);
    ::pause();  // until killed
    ::_exit(0);
  }
  char byte = 0;
  ASSERT_EQ(::read(ready[0], &byte, 1), 1);
  EXPECT_NE(refusal(dir.path), "");  // the child holds it
  ::kill(child, SIGKILL);
  int status = 0;
  ::waitpid(child, &status, 0);
  EXPECT_EQ(refusal(dir.path), "");
  ::close(ready[0]);
  ::close(ready[1]);
}

}  // namespace
}  // namespace zerocal
