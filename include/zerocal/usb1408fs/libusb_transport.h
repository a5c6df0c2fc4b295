// UsbTransport over libusb-1.0: a near pass-through, each method one or two libusb calls plus the
// mapping of libusb's error codes onto errors.h.
#pragma once

#include <memory>
#include <string>
#include <vector>

#include "zerocal/usb1408fs/transport.h"

struct libusb_context;
struct libusb_device_handle;
struct libusb_transfer;

namespace zerocal::usb1408fs {

class LibusbTransport final : public UsbTransport {
 public:
  // Opens the first USB-1408FS (VID:PID 09db:00a1) or, when `serial` is not empty, the one whose
  // serial-number string equals it; detaches the kernel HID driver where it can (a failed detach
  // is not fatal) and claims interfaces 0..3.
  // Throws DeviceNotFoundError (names VID:PID and the udev rule), PermissionError, UsbError.
  static std::unique_ptr<LibusbTransport> open(const std::string& serial = {});
  ~LibusbTransport() override;

  void controlOut(std::uint8_t request_type, std::uint8_t request, std::uint16_t value,
                  std::uint16_t index, const std::uint8_t* data, std::size_t length,
                  std::chrono::milliseconds timeout) override;
  std::size_t interruptIn(std::uint8_t endpoint, std::uint8_t* data, std::size_t capacity,
                          std::chrono::milliseconds timeout) override;
  void startStream(const std::uint8_t* endpoints, std::size_t endpoint_count,
                   std::size_t transfers_per_endpoint, std::size_t packet_size,
                   StreamSink& sink) override;
  void pollStream(std::chrono::milliseconds timeout) override;
  void stopStream() noexcept override;

  // Throws the errors.h class for a libusb_error code, with `what` as context.
  [[noreturn]] static void raise(int libusb_code, const std::string& what);

 private:
  struct Slot {
    LibusbTransport* owner = nullptr;
    libusb_transfer* transfer = nullptr;
    std::vector<unsigned char> buffer;
    bool in_flight = false;
  };
  LibusbTransport(libusb_context* context, libusb_device_handle* handle, int claimed);
  static void onTransfer(libusb_transfer* transfer);
  void freeSlots() noexcept;

  libusb_context* context_;
  libusb_device_handle* handle_;
  int claimed_;
  std::vector<std::unique_ptr<Slot>> slots_;
  StreamSink* sink_ = nullptr;
  bool streaming_ = false;
  std::uint64_t completions_ = 0;
};

}  // namespace zerocal::usb1408fs
