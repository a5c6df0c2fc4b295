#include "zerocal/control/token.h"

#include <fmt/format.h>
#include <sys/stat.h>

#include <cerrno>
#include <cstring>
#include <fstream>
#include <sstream>

namespace zerocal::control {

std::string loadToken(const std::string& path) {
  if (path.empty())
    throw Error("control.token_file is not set: the control port needs a token file (chmod 600)");
  struct stat st {};
  if (::stat(path.c_str(), &st) != 0)
    throw Error("cannot use the token file " + path + ": " + std::strerror(errno));
  if (!S_ISREG(st.st_mode)) throw Error("the token file " + path + " is not a regular file");
  // The file's group is the set of people who may drive the robot (group zerocal on a cell PC:
  // root:zerocal 0640); others nothing, and nobody but the owner may change it.
  if ((st.st_mode & (S_IWGRP | S_IXGRP | S_IRWXO)) != 0) {
    const std::string mode = fmt::format(FMT_STRING("{:03o}"), st.st_mode & 0777);
    throw Error("the token file " + path + " has mode " + mode +
                ": others may read it or the group may change it; chmod 640 " + path +
                " (readable by its group) or chmod 600 " + path);
  }
  // A token is a line of random characters: a large file is a wrong path, not a token.
  if (st.st_size > kMaxTokenFileBytes)
    throw Error("the token file " + path + " is larger than " + std::to_string(kMaxTokenFileBytes) +
                " bytes: not a token");
  std::ifstream in(path);
  if (!in) throw Error("cannot read the token file " + path);
  std::stringstream text;
  text << in.rdbuf();
  std::string token = text.str();
  const auto first = token.find_first_not_of(" \t\r\n");
  if (first == std::string::npos) throw Error("the token file " + path + " is empty");
  token = token.substr(first, token.find_last_not_of(" \t\r\n") - first + 1);
  if (token.size() < kMinTokenLength)
    throw Error("the token in " + path + " has " + std::to_string(token.size()) +
                " characters; use at least " + std::to_string(kMinTokenLength) +
                " random ones (head -c 24 /dev/urandom | base64)");
  return token;
}

bool tokensEqual(const std::string& given, const std::string& expected) {
  // Every byte of `given` is visited whatever the content; a length mismatch is folded in.
  volatile unsigned char diff = given.size() != expected.size() ? 1 : 0;
  const std::size_t n = expected.empty() ? 0 : expected.size();
  for (std::size_t i = 0; i < given.size(); ++i)
    diff = diff | static_cast<unsigned char>(given[i] ^ (n ? expected[i % n] : 0));
  return diff == 0 && !expected.empty();
}

}  // namespace zerocal::control
