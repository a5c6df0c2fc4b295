// Failures of the USB-1408FS link, worded for the technician at the cell. Every class is a
// LinkError of its kind (zerocal/cell/link_error.h): the board gone, a timeout or a malformed
// packet is kTransient (reopen), a STALL kRefused, no board or no permission kFatal.
#pragma once

#include <string>

#include "zerocal/cell/link_error.h"

namespace zerocal::usb1408fs {

// Any failure talking to the board. libusbCode() is the libusb_error value, 0 if none applies.
class UsbError : public LinkError {
 public:
  explicit UsbError(const std::string& message, int libusb_code = 0, Kind kind = Kind::kTransient)
      : LinkError(kind, message), libusb_code_(libusb_code) {}
  int libusbCode() const noexcept { return libusb_code_; }

 private:
  int libusb_code_;
};

// No USB-1408FS (VID:PID 09db:00a1, or not the requested serial) is on the bus.
class DeviceNotFoundError : public UsbError {
 public:
  explicit DeviceNotFoundError(const std::string& message, int libusb_code = 0)
      : UsbError(message, libusb_code, Kind::kFatal) {}
};

// The board is there but this user may not open it (the udev rule is missing).
class PermissionError : public UsbError {
 public:
  explicit PermissionError(const std::string& message, int libusb_code = 0)
      : UsbError(message, libusb_code, Kind::kFatal) {}
};

// The board went away (unplugged, reset, hub power). Reopen once it is back.
class DisconnectedError : public UsbError {
 public:
  explicit DisconnectedError(const std::string& message, int libusb_code = 0)
      : UsbError(message, libusb_code, Kind::kTransient) {}
};

// The board refused a request (endpoint halted / STALL handshake).
class StallError : public UsbError {
 public:
  explicit StallError(const std::string& message, int libusb_code = 0)
      : UsbError(message, libusb_code, Kind::kRefused) {}
};

// No answer in time.
class TimeoutError : public UsbError {
 public:
  explicit TimeoutError(const std::string& message, int libusb_code = 0)
      : UsbError(message, libusb_code, Kind::kTransient) {}
};

// A reply or data packet that cannot be right: too short, wrong code, out-of-range field.
class ProtocolError : public UsbError {
 public:
  explicit ProtocolError(const std::string& message, int libusb_code = 0)
      : UsbError(message, libusb_code, Kind::kTransient) {}
};

// The path of the udev rule shipped in config/, quoted by the messages above.
inline constexpr const char* kUdevRulePath = "config/udev/60-zerocal-usb1408fs.rules";

// The texts of the errors every transport raises alike, so that a fake and libusb read the same.
std::string deviceNotFoundMessage(const std::string& serial);
std::string permissionDeniedMessage(const std::string& what);
std::string noDeviceDuring(const std::string& what);

}  // namespace zerocal::usb1408fs
