// A UsbTransport over a Usb1408fsModel, for fast deterministic unit tests of the protocol layer.
// Time is the model's simulated clock: a blocking wait of T ms advances it by at most T ms and
// returns at once, so a test of a one-second scan runs in microseconds.
#pragma once

#include <chrono>
#include <memory>
#include <vector>

#include "zerocal/sim/usb1408fs_model.h"
#include "zerocal/usb1408fs/transport.h"
#include "zerocal/usb1408fs/usb1408fs.h"

namespace zerocal::sim {

class FakeTransport final : public usb1408fs::UsbTransport {
 public:
  // `model` must outlive the transport.
  explicit FakeTransport(Usb1408fsModel& model) : model_(model) {}

  // An Opener for Usb1408fs that behaves like LibusbTransport::open(): DeviceNotFoundError (same
  // message) while the model is unplugged.
  static usb1408fs::Usb1408fs::Opener opener(Usb1408fsModel& model);

  void controlOut(std::uint8_t request_type, std::uint8_t request, std::uint16_t value,
                  std::uint16_t index, const std::uint8_t* data, std::size_t length,
                  std::chrono::milliseconds timeout) override;
  std::size_t interruptIn(std::uint8_t endpoint, std::uint8_t* data, std::size_t capacity,
                          std::chrono::milliseconds timeout) override;
  void startStream(const std::uint8_t* endpoints, std::size_t endpoint_count,
                   std::size_t transfers_per_endpoint, std::size_t packet_size,
                   usb1408fs::StreamSink& sink) override;
  void pollStream(std::chrono::milliseconds timeout) override;
  void stopStream() noexcept override;

  // Simulated bus time per control or command exchange.
  static constexpr std::chrono::microseconds kTransactionTime{125};

 private:
  std::size_t deliverAvailable();
  void advanceBy(std::chrono::nanoseconds dt);

  Usb1408fsModel& model_;
  usb1408fs::StreamSink* sink_ = nullptr;
  std::vector<std::uint8_t> endpoints_;
  std::size_t next_endpoint_ = 0;
  bool streaming_ = false;
};

}  // namespace zerocal::sim
