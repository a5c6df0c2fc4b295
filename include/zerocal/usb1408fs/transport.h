// The seam directly at the libusb calls. The protocol above it (Usb1408fs) is tested against a
// simulated board through a fake; the libusb implementation below it stays a near pass-through, so
// that what is not unit-tested is little more than libusb itself.
#pragma once

#include <chrono>
#include <cstddef>
#include <cstdint>

namespace zerocal::usb1408fs {

// Outcome of one streamed interrupt-IN transfer, mirroring libusb_transfer_status.
enum class TransferStatus {
  kCompleted,
  kError,
  kTimedOut,
  kCancelled,
  kStall,
  kNoDevice,
  kOverflow
};

// Receives streamed packets. Called from inside UsbTransport::pollStream() (libusb's event
// handling), in the order the transfers completed; must not throw and should not block.
class StreamSink {
 public:
  virtual ~StreamSink() = default;
  virtual void onPacket(std::uint8_t endpoint, const std::uint8_t* data, std::size_t length,
                        TransferStatus status) noexcept = 0;
};

// Every method throws a UsbError subclass (errors.h) on failure: DisconnectedError when the
// device is gone, StallError on a STALL, TimeoutError when the timeout expires, UsbError otherwise.
class UsbTransport {
 public:
  virtual ~UsbTransport() = default;

  // Control transfer from host to device on EP0 (HID SET_REPORT for every command).
  virtual void controlOut(std::uint8_t request_type, std::uint8_t request, std::uint16_t value,
                          std::uint16_t index, const std::uint8_t* data, std::size_t length,
                          std::chrono::milliseconds timeout) = 0;

  // Synchronous interrupt-IN transfer; returns the number of bytes received (<= capacity).
  virtual std::size_t interruptIn(std::uint8_t endpoint, std::uint8_t* data, std::size_t capacity,
                                  std::chrono::milliseconds timeout) = 0;

  // Starts streaming: transfers_per_endpoint asynchronous interrupt-IN transfers of packet_size
  // bytes in flight on each endpoint, each resubmitted as soon as the sink has seen it. All
  // buffers are allocated here, none afterwards; a stream of the same shape as the previous one
  // may reuse its buffers and allocate none. The sink must outlive stopStream().
  virtual void startStream(const std::uint8_t* endpoints, std::size_t endpoint_count,
                           std::size_t transfers_per_endpoint, std::size_t packet_size,
                           StreamSink& sink) = 0;

  // Handles completions for at most `timeout`, delivering packets to the sink.
  virtual void pollStream(std::chrono::milliseconds timeout) = 0;

  // Cancels every transfer in flight and waits for them to come back. Never throws; safe to call
  // when no stream runs and after the device has gone.
  virtual void stopStream() noexcept = 0;
};

}  // namespace zerocal::usb1408fs
