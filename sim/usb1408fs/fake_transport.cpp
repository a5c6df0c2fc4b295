#include "zerocal/sim/fake_transport.h"

#include <algorithm>
#include <cstring>

#include "zerocal/usb1408fs/errors.h"

namespace zerocal::sim {

using namespace zerocal::usb1408fs;

namespace {

[[noreturn]] void raiseGone(const char* what) {
  throw DisconnectedError(noDeviceDuring(what), -4 /* LIBUSB_ERROR_NO_DEVICE */);
}

}  // namespace

Usb1408fs::Opener FakeTransport::opener(Usb1408fsModel& model) {
  return [&model]() -> std::unique_ptr<UsbTransport> {
    if (!model.connected()) throw DeviceNotFoundError(deviceNotFoundMessage({}), -5);
    return std::make_unique<FakeTransport>(model);
  };
}

void FakeTransport::advanceBy(std::chrono::nanoseconds dt) { model_.advanceTo(model_.now() + dt); }

void FakeTransport::controlOut(std::uint8_t request_type, std::uint8_t request, std::uint16_t value,
                               std::uint16_t index, const std::uint8_t* data, std::size_t length,
                               std::chrono::milliseconds timeout) {
  advanceBy(kTransactionTime);
  switch (model_.controlOut(request_type, request, value, index, data, length)) {
    case Usb1408fsModel::Result::kOk:
      return;
    case Usb1408fsModel::Result::kStall:
      throw StallError("the USB-1408FS stalled a control transfer (LIBUSB_ERROR_PIPE)", -9);
    case Usb1408fsModel::Result::kNoDevice:
      raiseGone("a control transfer");
  }
}

std::size_t FakeTransport::interruptIn(std::uint8_t endpoint, std::uint8_t* data,
                                       std::size_t capacity, std::chrono::milliseconds timeout) {
  const auto deadline = model_.now() + timeout;
  for (;;) {
    if (!model_.connected()) raiseGone("an interrupt transfer");
    std::optional<Usb1408fsModel::Packet> packet;
    if (endpoint == kReplyEndpoint) {
      packet = model_.takeReply();
    } else if (model_.takeScanPacket(endpoint, packet) == Usb1408fsModel::Result::kStall) {
      throw StallError("the USB-1408FS stalled an interrupt transfer (LIBUSB_ERROR_PIPE)", -9);
    }
    if (packet) {
      if (packet->length > capacity) {
        throw ProtocolError("the USB-1408FS sent more data than asked for (LIBUSB_ERROR_OVERFLOW)");
      }
      std::memcpy(data, packet->bytes.data(), packet->length);
      advanceBy(kTransactionTime);
      return packet->length;
    }
    if (model_.now() >= deadline) {
      throw TimeoutError("the USB-1408FS did not answer in time (LIBUSB_ERROR_TIMEOUT)", -7);
    }
    // Wait for the next thing the model can produce, never past the deadline.
    auto next = model_.nextPacketTime().value_or(deadline);
    model_.advanceTo(std::min(std::max(next, model_.now() + kTransactionTime), deadline));
  }
}

void FakeTransport::startStream(const std::uint8_t* endpoints, std::size_t endpoint_count,
                                std::size_t transfers_per_endpoint, std::size_t packet_size,
                                StreamSink& sink) {
  if (!model_.connected()) raiseGone("starting the scan stream");
  endpoints_.assign(endpoints, endpoints + endpoint_count);
  next_endpoint_ = 0;
  sink_ = &sink;
  streaming_ = true;
}

std::size_t FakeTransport::deliverAvailable() {
  std::size_t delivered = 0;
  while (streaming_) {
    if (!model_.connected()) {
      // Every transfer in flight completes with NO_DEVICE, as libusb reports it.
      streaming_ = false;
      for (std::uint8_t ep : endpoints_) sink_->onPacket(ep, nullptr, 0, TransferStatus::kNoDevice);
      return delivered;
    }
    const std::uint8_t ep = endpoints_[next_endpoint_];
    std::optional<Usb1408fsModel::Packet> packet;
    if (model_.takeScanPacket(ep, packet) == Usb1408fsModel::Result::kStall) {
      streaming_ = false;
      sink_->onPacket(ep, nullptr, 0, TransferStatus::kStall);
      return delivered;
    }
    if (!packet) {
      // The board fills endpoints round-robin, but a dropped packet leaves a hole in the cycle.
      bool any = false;
      for (std::size_t k = 1; k < endpoints_.size() && !any; ++k) {
        const std::size_t e = (next_endpoint_ + k) % endpoints_.size();
        if (model_.scanDataWaiting(endpoints_[e])) {
          next_endpoint_ = e;
          any = true;
        }
      }
      if (!any) return delivered;
      continue;
    }
    next_endpoint_ = (next_endpoint_ + 1) % endpoints_.size();
    sink_->onPacket(ep, packet->bytes.data(), packet->length, TransferStatus::kCompleted);
    ++delivered;
  }
  return delivered;
}

void FakeTransport::pollStream(std::chrono::milliseconds timeout) {
  const auto deadline = model_.now() + timeout;
  for (;;) {
    if (deliverAvailable() > 0 || !streaming_) return;
    if (model_.now() >= deadline) return;
    auto next = model_.nextPacketTime().value_or(deadline);
    model_.advanceTo(
        std::min(std::max(next, model_.now() + std::chrono::nanoseconds(1)), deadline));
  }
}

void FakeTransport::stopStream() noexcept {
  streaming_ = false;
  sink_ = nullptr;
}

}  // namespace zerocal::sim
