#include "zerocal/store/data_folder_lock.h"

#include <fcntl.h>
#include <sys/file.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <filesystem>
#include <fstream>

#include "zerocal/error.h"

namespace zerocal {

DataFolderLock::DataFolderLock(const std::string& data_dir) {
  std::error_code ec;
  std::filesystem::create_directories(data_dir, ec);
  if (ec) throw FileError("cannot create the data folder " + data_dir + ": " + ec.message());
  const std::string path = data_dir + "/" + kDataFolderLockName;
  fd_ = ::open(path.c_str(), O_RDWR | O_CREAT | O_CLOEXEC, 0644);
  if (fd_ < 0)
    throw FileError("cannot open the data folder's lock " + path + ": " + std::strerror(errno));
  if (::flock(fd_, LOCK_EX | LOCK_NB) != 0) {
    const int why = errno;
    ::close(fd_);
    fd_ = -1;
    if (why != EWOULDBLOCK)
      throw FileError("cannot lock the data folder " + data_dir + ": " + std::strerror(why));
    std::ifstream in(path);
    std::string pid;
    in >> pid;
    throw FileError("another zerocald (" + (pid.empty() ? "its process unknown" : "pid " + pid) +
                    ") uses the data folder " + data_dir +
                    ": one daemon per data folder (stop it, or give this one another "
                    "session.data_dir)");
  }
  // The holder's name for the message above: written after the lock is held, so that it is ours.
  const std::string pid = std::to_string(::getpid()) + "\n";
  if (::ftruncate(fd_, 0) != 0 || ::pwrite(fd_, pid.data(), pid.size(), 0) < 0) {
    // The lock holds without the name; only another daemon's message would lack it.
  }
}

DataFolderLock::~DataFolderLock() {
  if (fd_ >= 0) ::close(fd_);  // closing the last descriptor drops the flock
}

}  // namespace zerocal
