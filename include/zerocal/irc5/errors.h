// Failures of the link to the robot controller. Each kind is its own type so that the daemon can
// react differently: a bad-message reply is a bug in the request, a timeout or a dropped
// connection calls for a reconnect, a refused target must never be retried.
#pragma once

#include <string>

#include "zerocal/error.h"

namespace zerocal {

// Base of every controller-link failure.
class LinkError : public Error {
 public:
  using Error::Error;
};

// The controller answered ok = 0: unknown code, wrong parameter count, target outside its joint
// bounds, or an unsupported command. The connection stays usable.
class BadMessageError : public LinkError {
 public:
  BadMessageError(int code, const std::string& detail)
      : LinkError("controller refused request " + std::to_string(code) +
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
  using LinkError::LinkError;
};

// No complete reply before the request's deadline. The client closes the connection, since a
// late reply would otherwise be taken as the answer to the next request.
class TimeoutError : public LinkError {
 public:
  using LinkError::LinkError;
};

// The connection could not be made, was closed by the controller, or is not open.
class ConnectionError : public LinkError {
 public:
  using LinkError::LinkError;
};

// The client refused to send a request: a target outside the robot file's joint limits, a step
// larger than the configured maximum, or a request that breaks the wire format (over 80
// characters, missing '#'). Nothing was sent; the connection stays usable.
class RequestRefusedError : public LinkError {
 public:
  using LinkError::LinkError;
};

}  // namespace zerocal
