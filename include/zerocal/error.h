// The one exception hierarchy of zerocal. Setup, configuration, input and link failures throw
// one of these; the solver returns a report instead, and the servo cycle never throws.
#pragma once

#include <stdexcept>
#include <string>
#include <vector>

namespace zerocal {

class Error : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

// A file or option a person wrote is wrong. Carries every problem found, not just the first,
// so that one round of editing fixes them all.
class ConfigError : public Error {
 public:
  ConfigError(const std::string& origin, std::vector<std::string> problems);
  const std::vector<std::string>& problems() const noexcept { return problems_; }

 private:
  std::vector<std::string> problems_;
};

// Measured data (a joint-set file, a sweep) cannot be used as given.
class InputError : public Error {
 public:
  using Error::Error;
};

// A file or folder cannot be written, synced or read back as it must be.
class FileError : public Error {
 public:
  using Error::Error;
};

}  // namespace zerocal
