// One daemon per data folder: two zerocald on one folder would write the same sessions' files and
// the same robot's record (record.sqlite) at once, and each would take the other's half-written
// files for debris. The first to start holds the folder's lock for as long as it runs; the kernel
// drops it when the process ends, however it ends (kill -9 included), so no stale lock is left.
#pragma once

#include <string>

namespace zerocal {

// The lock file's name in the data folder.
inline constexpr const char* kDataFolderLockName = ".zerocald.lock";

class DataFolderLock {
 public:
  // Creates the data folder if needed and takes its lock (an exclusive flock of
  // <data_dir>/.zerocald.lock, which then names this process). Throws FileError when another
  // process holds it (naming that process as its lock file does) or the file cannot be made.
  explicit DataFolderLock(const std::string& data_dir);
  ~DataFolderLock();
  DataFolderLock(const DataFolderLock&) = delete;
  DataFolderLock& operator=(const DataFolderLock&) = delete;

 private:
  int fd_ = -1;
};

}  // namespace zerocal
