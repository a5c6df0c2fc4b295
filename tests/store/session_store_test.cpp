// The store's start-up housekeeping: what interrupted atomic writes left in the session folders.
#include "zerocal/store/session_store.h"

#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>

#include "temp_dir.h"

namespace zerocal {
namespace {

namespace fs = std::filesystem;

TEST(SessionStore, RemovesTheTemporariesOfInterruptedWritesFromSessionFoldersAndNothingElse) {
  const testing::TempDir dir("zerocal-store");
  const fs::path session = fs::path(dir.path) / "20261122T070000Z";
  const fs::path other = fs::path(dir.path) / "20261122T080000Z";
  fs::create_directories(session);
  fs::create_directories(other);
  for (const char* name : {"session.json", "journal.jsonl", "result.json"})
    std::ofstream(session / name) << "{}\n";
  std::ofstream(session / "report.html.tmp") << "<html><body>cut sho";
  std::ofstream(other / "result.json.tmp") << "{\"conv";
  std::ofstream(fs::path(dir.path) / "notes.tmp") << "not in a session folder\n";
  fs::create_directories(session / "images.tmp");  // a folder: not a write of the store's

  const std::vector<std::string> removed = SessionStore(dir.path).removeStaleTemporaries();
  EXPECT_EQ(removed, (std::vector<std::string>{(session / "report.html.tmp").string(),
                                               (other / "result.json.tmp").string()}));
  EXPECT_FALSE(fs::exists(session / "report.html.tmp"));
  EXPECT_FALSE(fs::exists(other / "result.json.tmp"));
  for (const char* name : {"session.json", "journal.jsonl", "result.json"})
    EXPECT_TRUE(fs::exists(session / name)) << name;
  EXPECT_TRUE(fs::exists(fs::path(dir.path) / "notes.tmp"));
  EXPECT_TRUE(fs::is_directory(session / "images.tmp"));
  EXPECT_TRUE(SessionStore(dir.path).removeStaleTemporaries().empty());
  EXPECT_TRUE(SessionStore(dir.path + "/missing").removeStaleTemporaries().empty());
}

}  // namespace
}  // namespace zerocal
