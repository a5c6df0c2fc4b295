// Failures of the IRC5 link. Each is a LinkError of its kind (zerocal/cell/link_error.h): a
// bad-message reply or a target the client refuses is kRefused (never retried), a timeout, a
// stream out of step or a dropped connection kTransient (reconnect).
#pragma once

#include <string>

#include "zerocal/cell/link_error.h"

namespace zerocal {

// The controller answered ok = 0: unknown code, wrong parameter count, target outside its joint
// bounds, or an unsupported command. The connection stays usable.
class BadMessageError : public LinkError {
 public:
  BadMessageError(int code, const std::string& detail)
      : LinkError(Kind::kRefused,
                  "controller refused request " + std::to_string(code) +
                      (detail.empty() ? std::string(" (ok = 0)") : " (ok = 0): " + detail)),
        code_(code) {}
  int code() const noexcept { return code_; }

 private:
  int code_;
};

// The reply could not be parsed or answered another request code (the stream is out of step).
// The client closes the connection: the next request needs reconnect().
class ProtocolError : public LinkError {
 public:
  explicit ProtocolError(const std::string& message) : LinkError(Kind::kTransient, message) {}
};

// No complete reply before the request's deadline. The client closes the connection, since a
// late reply would otherwise be taken as the answer to the next request.
class TimeoutError : public LinkError {
 public:
  explicit TimeoutError(const std::string& message) : LinkError(Kind::kTransient, message) {}
};

// The connection could not be made, was closed by the controller, or is not open.
class ConnectionError : public LinkError {
 public:
  explicit ConnectionError(const std::string& message) : LinkError(Kind::kTransient, message) {}
};

// The client refused to send a request: a target outside the robot file's joint limits, a step
// larger than the configured maximum, or a request that breaks the wire format (over 80
// characters, missing '#'). Nothing was sent; the connection stays usable.
class RequestRefusedError : public LinkError {
 public:
  explicit RequestRefusedError(const std::string& message) : LinkError(Kind::kRefused, message) {}
};

}  // namespace zerocal
