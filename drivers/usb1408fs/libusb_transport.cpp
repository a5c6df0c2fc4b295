#include "zerocal/usb1408fs/libusb_transport.h"

#include <libusb.h>

#include <chrono>
#include <string>

#include "zerocal/usb1408fs/errors.h"
#include "zerocal/usb1408fs/protocol.h"

namespace zerocal::usb1408fs {
namespace {

// A literal, not a std::string: it may be needed during another translation unit's static
// initialisation.
constexpr const char* kIdentity = "Measurement Computing USB-1408FS (USB VID:PID 09db:00a1)";

TransferStatus mapStatus(int status) {
  switch (status) {
    case LIBUSB_TRANSFER_COMPLETED:
      return TransferStatus::kCompleted;
    case LIBUSB_TRANSFER_TIMED_OUT:
      return TransferStatus::kTimedOut;
    case LIBUSB_TRANSFER_CANCELLED:
      return TransferStatus::kCancelled;
    case LIBUSB_TRANSFER_STALL:
      return TransferStatus::kStall;
    case LIBUSB_TRANSFER_NO_DEVICE:
      return TransferStatus::kNoDevice;
    case LIBUSB_TRANSFER_OVERFLOW:
      return TransferStatus::kOverflow;
    default:
      return TransferStatus::kError;
  }
}

}  // namespace

void LibusbTransport::raise(int code, const std::string& what) {
  const std::string detail = std::string(" (") + libusb_error_name(code) + ")";
  switch (code) {
    case LIBUSB_ERROR_NO_DEVICE:
      throw DisconnectedError(noDeviceDuring(what), code);
    case LIBUSB_ERROR_ACCESS:
      throw PermissionError(permissionDeniedMessage(what), code);
    case LIBUSB_ERROR_PIPE:
      throw StallError(std::string("the ") + kIdentity + " stalled " + what + detail, code);
    case LIBUSB_ERROR_TIMEOUT:
      throw TimeoutError(
          std::string("the ") + kIdentity + " did not answer " + what + " in time" + detail, code);
    case LIBUSB_ERROR_OVERFLOW:
      throw ProtocolError(
          std::string("the ") + kIdentity + " sent more data than asked for in " + what + detail,
          code);
    case LIBUSB_ERROR_BUSY:
      throw UsbError(
          std::string("the ") + kIdentity + " is in use by another program (" + what + ")" + detail,
          code);
    default:
      throw UsbError("USB error in " + what + " with the " + std::string(kIdentity) + detail +
                         ": " + libusb_strerror(static_cast<libusb_error>(code)),
                     code);
  }
}

std::unique_ptr<LibusbTransport> LibusbTransport::open(const std::string& serial) {
  libusb_context* context = nullptr;
  if (int r = libusb_init(&context); r < 0) {
    // Typically no usbfs at all: a container without /dev/bus/usb passed through.
    throw UsbError(std::string("libusb cannot start (") + libusb_error_name(r) +
                       "): is /dev/bus/usb present? A container needs it passed through",
                   r, LinkError::Kind::kFatal);
  }

  libusb_device** list = nullptr;
  const ssize_t count = libusb_get_device_list(context, &list);
  if (count < 0) {
    libusb_exit(context);
    raise(static_cast<int>(count), "listing USB devices");
  }
  libusb_device_handle* handle = nullptr;
  int denied = 0;
  int matching = 0;
  for (ssize_t i = 0; i < count && handle == nullptr; ++i) {
    libusb_device_descriptor desc{};
    if (libusb_get_device_descriptor(list[i], &desc) != 0) continue;
    if (desc.idVendor != kVendorId || desc.idProduct != kProductId) continue;
    ++matching;
    libusb_device_handle* candidate = nullptr;
    const int r = libusb_open(list[i], &candidate);
    if (r == LIBUSB_ERROR_ACCESS) {
      ++denied;
      continue;
    }
    if (r < 0) continue;
    if (!serial.empty()) {
      unsigned char text[128] = {};
      const int n = desc.iSerialNumber == 0
                        ? -1
                        : libusb_get_string_descriptor_ascii(candidate, desc.iSerialNumber, text,
                                                             sizeof text - 1);
      if (n < 0 || serial != reinterpret_cast<const char*>(text)) {
        libusb_close(candidate);
        continue;
      }
    }
    handle = candidate;
  }
  libusb_free_device_list(list, 1);

  if (handle == nullptr) {
    libusb_exit(context);
    if (denied > 0) {
      throw PermissionError(permissionDeniedMessage("opening it"), LIBUSB_ERROR_ACCESS);
    }
    std::string message = deviceNotFoundMessage(serial);
    if (matching > 0) {
      message += " (" + std::to_string(matching) + " USB-1408FS with another serial attached)";
    }
    throw DeviceNotFoundError(message, LIBUSB_ERROR_NOT_FOUND);
  }

  // Auto-detach hands the HID driver back on release. Where it is unsupported, or the kernel
  // driver state cannot be read (some sandboxes), carry on: claiming will tell.
  if (libusb_set_auto_detach_kernel_driver(handle, 1) != LIBUSB_SUCCESS) {
    for (int i = 0; i < kInterfaceCount; ++i) {
      if (libusb_kernel_driver_active(handle, i) == 1) libusb_detach_kernel_driver(handle, i);
    }
  }
  int claimed = 0;
  for (; claimed < kInterfaceCount; ++claimed) {
    const int r = libusb_claim_interface(handle, claimed);
    if (r < 0) {
      for (int j = claimed - 1; j >= 0; --j) libusb_release_interface(handle, j);
      libusb_close(handle);
      libusb_exit(context);
      raise(r, "claiming interface " + std::to_string(claimed));
    }
  }
  return std::unique_ptr<LibusbTransport>(new LibusbTransport(context, handle, claimed));
}

LibusbTransport::LibusbTransport(libusb_context* context, libusb_device_handle* handle, int claimed)
    : context_(context), handle_(handle), claimed_(claimed) {}

LibusbTransport::~LibusbTransport() {
  stopStream();
  freeSlots();
  for (int i = claimed_ - 1; i >= 0; --i) libusb_release_interface(handle_, i);
  libusb_close(handle_);
  libusb_exit(context_);
}

void LibusbTransport::controlOut(std::uint8_t request_type, std::uint8_t request,
                                 std::uint16_t value, std::uint16_t index, const std::uint8_t* data,
                                 std::size_t length, std::chrono::milliseconds timeout) {
  const int r = libusb_control_transfer(
      handle_, request_type, request, value, index, const_cast<unsigned char*>(data),
      static_cast<std::uint16_t>(length), static_cast<unsigned>(timeout.count()));
  if (r < 0) raise(r, "a control transfer");
  if (static_cast<std::size_t>(r) != length) {
    throw ProtocolError(std::string("the ") + kIdentity + " took " + std::to_string(r) + " of " +
                        std::to_string(length) + " command bytes");
  }
}

std::size_t LibusbTransport::interruptIn(std::uint8_t endpoint, std::uint8_t* data,
                                         std::size_t capacity, std::chrono::milliseconds timeout) {
  int transferred = 0;
  const int r = libusb_interrupt_transfer(handle_, endpoint, data, static_cast<int>(capacity),
                                          &transferred, static_cast<unsigned>(timeout.count()));
  if (r < 0) raise(r, "an interrupt transfer on endpoint " + std::to_string(endpoint & 0x7F));
  return static_cast<std::size_t>(transferred);
}

void LibusbTransport::onTransfer(libusb_transfer* transfer) {
  auto* slot = static_cast<Slot*>(transfer->user_data);
  slot->in_flight = false;
  LibusbTransport* self = slot->owner;
  if (!self->streaming_) return;
  ++self->completions_;
  const TransferStatus status = mapStatus(transfer->status);
  self->sink_->onPacket(transfer->endpoint, transfer->buffer,
                        static_cast<std::size_t>(transfer->actual_length), status);
  if (status != TransferStatus::kCompleted || !self->streaming_) return;
  const int r = libusb_submit_transfer(transfer);
  if (r == 0) {
    slot->in_flight = true;
  } else {
    self->sink_->onPacket(
        transfer->endpoint, transfer->buffer, 0,
        r == LIBUSB_ERROR_NO_DEVICE ? TransferStatus::kNoDevice : TransferStatus::kError);
  }
}

void LibusbTransport::startStream(const std::uint8_t* endpoints, std::size_t endpoint_count,
                                  std::size_t transfers_per_endpoint, std::size_t packet_size,
                                  StreamSink& sink) {
  stopStream();
  // A stream of the same shape as the last reuses its transfers and buffers: a scan per PSD
  // reading then allocates nothing of ours after the first.
  const std::size_t count = endpoint_count * transfers_per_endpoint;
  bool reuse = slots_.size() == count;
  for (const auto& slot : slots_) reuse = reuse && slot->buffer.size() == packet_size;
  if (!reuse) freeSlots();
  sink_ = &sink;
  streaming_ = true;
  // Round-robin submission order matches the order in which the board fills the endpoints.
  for (std::size_t k = 0; k < transfers_per_endpoint; ++k) {
    for (std::size_t e = 0; e < endpoint_count; ++e) {
      if (!reuse) {
        auto slot = std::make_unique<Slot>();
        slot->owner = this;
        slot->buffer.resize(packet_size);
        slot->transfer = libusb_alloc_transfer(0);
        if (slot->transfer == nullptr) {
          stopStream();
          throw UsbError("out of memory allocating USB transfers");
        }
        slots_.push_back(std::move(slot));
      }
      Slot* raw = slots_[k * endpoint_count + e].get();
      libusb_fill_interrupt_transfer(raw->transfer, handle_, endpoints[e], raw->buffer.data(),
                                     static_cast<int>(packet_size), &LibusbTransport::onTransfer,
                                     raw, 0);
      if (int r = libusb_submit_transfer(raw->transfer); r < 0) {
        stopStream();
        raise(r, "starting the scan stream");
      }
      raw->in_flight = true;
    }
  }
}

void LibusbTransport::pollStream(std::chrono::milliseconds timeout) {
  // libusb may return from one round of event handling with nothing completed (a spurious
  // wake-up, or a device node that always polls readable); keep going until a packet arrived or
  // the caller's time is really up, so that "nothing for T ms" means what it says.
  const auto deadline = std::chrono::steady_clock::now() + timeout;
  const std::uint64_t before = completions_;
  for (;;) {
    const auto left = std::chrono::duration_cast<std::chrono::microseconds>(
        deadline - std::chrono::steady_clock::now());
    if (left.count() <= 0) return;
    timeval tv{};
    tv.tv_sec = static_cast<long>(left.count() / 1000000);
    tv.tv_usec = static_cast<long>(left.count() % 1000000);
    const int r = libusb_handle_events_timeout_completed(context_, &tv, nullptr);
    if (r < 0 && r != LIBUSB_ERROR_INTERRUPTED) raise(r, "handling scan transfers");
    if (completions_ != before || !streaming_) return;
  }
}

void LibusbTransport::stopStream() noexcept {
  streaming_ = false;
  if (slots_.empty()) return;
  for (auto& slot : slots_) {
    if (slot->in_flight) libusb_cancel_transfer(slot->transfer);
  }
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(1);
  auto busy = [&] {
    for (auto& slot : slots_) {
      if (slot->in_flight) return true;
    }
    return false;
  };
  while (busy() && std::chrono::steady_clock::now() < deadline) {
    timeval tv{0, 10000};
    libusb_handle_events_timeout_completed(context_, &tv, nullptr);
  }
  // Kept for the next stream unless libusb still owns one; then start afresh.
  if (busy()) freeSlots();
}

void LibusbTransport::freeSlots() noexcept {
  for (auto& slot : slots_) {
    // A transfer libusb still owns must not be freed; leaking it is the lesser harm.
    if (slot->in_flight) {
      slot.release();
      continue;
    }
    libusb_free_transfer(slot->transfer);
  }
  slots_.clear();
}

}  // namespace zerocal::usb1408fs
