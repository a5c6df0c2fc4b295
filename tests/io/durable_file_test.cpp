// The atomic writer of the session files on a full disk: the old file stays, and no temporary is
// left beside it for anyone to take for a session's file.
#include "zerocal/io/durable_file.h"

#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>

#include "temp_dir.h"
#include "zerocal/error.h"

namespace zerocal {
namespace {

namespace fs = std::filesystem;

TEST(DurableFile, AWriteToAFullDiskKeepsTheOldFileAndLeavesNoTemporary) {
  const testing::TempDir dir("zerocal-durable");
  const std::string path = dir.path + "/result.json";
  writeFileDurably(path, "old\n");
  // The temporary on a device that is always full, as a disk is at the end of a long session.
  fs::create_symlink("/dev/full", path + ".tmp");
  try {
    writeFileDurably(path, std::string(1 << 16, 'x'));
    FAIL() << "a write to a full disk succeeded";
  } catch (const FileError& e) {
    EXPECT_NE(std::string(e.what()).find("No space left on device"), std::string::npos) << e.what();
  }
  EXPECT_FALSE(fs::exists(fs::symlink_status(path + ".tmp")));
  EXPECT_EQ(testing::readFile(path), "old\n");
  EXPECT_TRUE(fs::exists("/dev/full"));
}

}  // namespace
}  // namespace zerocal
