#include "zerocal/io/durable_file.h"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <filesystem>

#include "zerocal/error.h"

namespace zerocal {
namespace {

namespace fs = std::filesystem;

[[noreturn]] void fail(const std::string& what, int error) {
  throw FileError(what + ": " + std::strerror(error));
}

}  // namespace

void writeAllDurably(int fd, const std::string& data, const std::string& path) {
  std::size_t done = 0;
  while (done < data.size()) {
    const ssize_t n = ::write(fd, data.data() + done, data.size() - done);
    if (n < 0) {
      if (errno == EINTR) continue;
      fail("cannot write " + path, errno);
    }
    done += static_cast<std::size_t>(n);
  }
  while (::fsync(fd) != 0)
    if (errno != EINTR) fail("cannot fsync " + path, errno);
}

void syncFolder(const std::string& dir) {
  const int fd = ::open(dir.c_str(), O_RDONLY | O_DIRECTORY | O_CLOEXEC);
  if (fd < 0) fail("cannot open folder " + dir, errno);
  const int result = ::fsync(fd);
  const int error = errno;
  ::close(fd);
  if (result != 0) fail("cannot fsync folder " + dir, error);
}

void makeDirsDurably(const std::string& dir) {
  if (dir.empty()) return;
  std::error_code ec;
  if (fs::is_directory(dir, ec)) return;
  const fs::path parent = fs::path(dir).parent_path();
  if (!parent.empty() && parent != fs::path(dir)) makeDirsDurably(parent.string());
  if (::mkdir(dir.c_str(), 0755) != 0 && errno != EEXIST)
    fail("cannot create folder " + dir, errno);
  syncFolder(parent.empty() ? "." : parent.string());
}

void writeFileDurably(const std::string& path, const std::string& text) {
  const std::string temporary = path + ".tmp";
  const int fd = ::open(temporary.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0644);
  if (fd < 0) fail("cannot create " + temporary, errno);
  // On failure (a full disk, typically) the temporary goes: the old file stays as it was and
  // nothing half-written is left beside it.
  try {
    writeAllDurably(fd, text, temporary);
  } catch (...) {
    ::close(fd);
    ::unlink(temporary.c_str());
    throw;
  }
  ::close(fd);
  if (::rename(temporary.c_str(), path.c_str()) != 0) {
    const int error = errno;
    ::unlink(temporary.c_str());
    fail("cannot rename to " + path, error);
  }
  const fs::path parent = fs::path(path).parent_path();
  syncFolder(parent.empty() ? "." : parent.string());
}

}  // namespace zerocal
