// The one failure of a link to the cell's devices (the robot controller, the PSD readout), with
// what the caller may do about it. Each driver throws its own subclasses, worded for the
// technician, each with its kind; the session decides by the kind alone, never by the driver's
// classes.
#pragma once

#include <string>

#include "zerocal/error.h"

namespace zerocal {

class LinkError : public Error {
 public:
  enum class Kind {
    // The link may work again after a reconnect (or a reopen): a dropped connection, a deadline
    // missed, a stream out of step, a device unplugged.
    kTransient,
    // The device or the driver refused this request; nothing was done and the link stays usable.
    // The request must never be retried as it was.
    kRefused,
    // Nothing will help but a person: no such device, no permission, a device that cannot be
    // the one configured.
    kFatal,
  };
  LinkError(Kind kind, const std::string& message) : Error(message), kind_(kind) {}
  Kind kind() const noexcept { return kind_; }

 private:
  Kind kind_;
};

inline const char* linkErrorKindName(LinkError::Kind kind) noexcept {
  switch (kind) {
    case LinkError::Kind::kTransient:
      return "transient";
    case LinkError::Kind::kRefused:
      return "refused";
    case LinkError::Kind::kFatal:
      return "fatal";
  }
  return "?";
}

}  // namespace zerocal
