#include "umockdev_board.h"

#include <linux/usbdevice_fs.h>
#include <sys/ioctl.h>
#include <umockdev.h>

#include <algorithm>
#include <cerrno>
#include <cstring>
#include <stdexcept>

namespace zerocal::sim {
namespace {

// Inferred descriptors (no lsusb dump of a real unit is known): full-speed, four HID interfaces,
// EP 0x81 + 0x02 on interface 0, scan endpoints 0x83..0x85 on interfaces 1..3, 64-byte packets.
// Replace with `umockdev-record` output once a board is at hand.
constexpr const char* kDevice =
    "P: /devices/pci0000:00/0000:00:14.0/usb1/1-2\n"
    "N: bus/usb/001/002\n"
    "E: SUBSYSTEM=usb\n"
    "E: DRIVER=usb\n"
    "E: BUSNUM=001\n"
    "E: DEVNUM=002\n"
    "E: DEVNAME=/dev/bus/usb/001/002\n"
    "E: DEVTYPE=usb_device\n"
    "E: PRODUCT=9db/a1/100\n"
    "A: idVendor=09db\\n\n"
    "A: idProduct=00a1\\n\n"
    "A: serial=01A2B3C4\\n\n"
    "A: busnum=1\\n\n"
    "A: devnum=2\\n\n"
    "A: bConfigurationValue=1\\n\n"
    "A: bNumConfigurations=1\\n\n"
    "A: speed=12\\n\n"
    "H: descriptors=1201000200000040db09a1000001010203010902740004010080320904000002030000000"
    "921110100012220000705810340000107050203400001090401000103000000092111010001222000070583"
    "034000010904020001030000000921110100012220000705840340000109040300010300000009211101000"
    "122200007058503400001\n";

std::u16string stringDescriptor(int index) {
  switch (index) {
    case 1:
      return u"Measurement Computing";
    case 2:
      return u"USB-1408FS";
    case 3:
      return u"01A2B3C4";
    default:
      return u"";
  }
}

}  // namespace

UmockdevBoard::UmockdevBoard(bool with_device) : start_(std::chrono::steady_clock::now()) {
  testbed_ = umockdev_testbed_new();
  if (!umockdev_in_mock_environment()) {
    g_object_unref(testbed_);
    throw std::runtime_error("not running under umockdev-wrapper: run this test through ctest");
  }
  handler_ = umockdev_ioctl_base_new();
  g_signal_connect(handler_, "handle-ioctl", G_CALLBACK(&UmockdevBoard::onIoctl), this);
  if (with_device) {
    GError* error = nullptr;
    // The handler goes first so that the node answers the moment libusb can see it.
    if (!umockdev_testbed_attach_ioctl(testbed_, "/dev/bus/usb/001/002", handler_, &error) ||
        !umockdev_testbed_add_from_string(testbed_, kDevice, &error)) {
      const std::string message = error ? error->message : "unknown error";
      if (error) g_error_free(error);
      throw std::runtime_error("umockdev testbed setup failed: " + message);
    }
  }
}

UmockdevBoard::~UmockdevBoard() {
  {
    std::lock_guard<std::mutex> lock(mutex_);
    for (auto& u : parked_) g_object_unref(u.data);
    for (auto& u : completed_) g_object_unref(u.data);
    parked_.clear();
    completed_.clear();
  }
  g_object_unref(handler_);
  g_object_unref(testbed_);
}

std::string UmockdevBoard::rootDir() const {
  gchar* dir = umockdev_testbed_get_root_dir(testbed_);
  std::string result = dir;
  g_free(dir);
  return result;
}

int UmockdevBoard::urbsSubmitted() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return submitted_;
}

int UmockdevBoard::urbsDiscarded() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return discarded_;
}

int UmockdevBoard::onIoctl(UMockdevIoctlBase*, UMockdevIoctlClient* client, void* self) {
  return static_cast<UmockdevBoard*>(self)->handle(client) ? TRUE : FALSE;
}

void UmockdevBoard::complete(Urb u, int status, int actual_length) {
  u.urb->status = status;
  u.urb->actual_length = actual_length;
  completed_.push_back(u);
}

void UmockdevBoard::controlTransfer(Urb& u) {
  // The buffer lives in this very process (the client is libusb in the test), so the setup packet
  // and data are read and written in place, as umockdev's own usbfs tests do.
  auto* buffer = static_cast<std::uint8_t*>(u.urb->buffer);
  const std::uint8_t request_type = buffer[0], request = buffer[1];
  const std::uint16_t value = static_cast<std::uint16_t>(buffer[2] | (buffer[3] << 8));
  const std::uint16_t index = static_cast<std::uint16_t>(buffer[4] | (buffer[5] << 8));
  const std::uint16_t length = static_cast<std::uint16_t>(buffer[6] | (buffer[7] << 8));
  if (request_type == 0x80 && request == 0x06 && (value >> 8) == 0x03) {  // GET_DESCRIPTOR string
    std::uint8_t reply[64] = {};
    std::size_t n;
    if ((value & 0xFF) == 0) {
      n = 4;
      reply[0] = 4, reply[1] = 3, reply[2] = 0x09, reply[3] = 0x04;  // en-US
    } else {
      const std::u16string text = stringDescriptor(value & 0xFF);
      n = 2 + 2 * text.size();
      reply[0] = static_cast<std::uint8_t>(n), reply[1] = 3;
      for (std::size_t i = 0; i < text.size(); ++i) {
        reply[2 + 2 * i] = static_cast<std::uint8_t>(text[i] & 0xFF);
        reply[3 + 2 * i] = static_cast<std::uint8_t>(text[i] >> 8);
      }
    }
    n = std::min<std::size_t>(n, length);
    std::memcpy(buffer + 8, reply, n);
    complete(u, 0, static_cast<int>(n));
    return;
  }
  if (request_type & 0x80) {
    complete(u, -EPIPE, 0);
    return;
  }
  switch (model_.controlOut(request_type, request, value, index, buffer + 8, length)) {
    case Usb1408fsModel::Result::kOk:
      complete(u, 0, length);
      return;
    case Usb1408fsModel::Result::kStall:
      complete(u, -EPIPE, 0);
      return;
    case Usb1408fsModel::Result::kNoDevice:
      complete(u, -ENODEV, 0);
      return;
  }
}

void UmockdevBoard::fillParked() {
  model_.advanceTo(std::chrono::steady_clock::now() - start_);
  for (auto it = parked_.begin(); it != parked_.end();) {
    usbdevfs_urb* urb = it->urb;
    std::optional<Usb1408fsModel::Packet> packet;
    Usb1408fsModel::Result result = Usb1408fsModel::Result::kOk;
    if (!model_.connected()) {
      result = Usb1408fsModel::Result::kNoDevice;
    } else if (urb->endpoint == 0x81) {
      packet = model_.takeReply();
    } else {
      result = model_.takeScanPacket(urb->endpoint, packet);
    }
    if (result == Usb1408fsModel::Result::kOk && !packet) {
      ++it;
      continue;
    }
    Urb u = *it;
    it = parked_.erase(it);
    if (result == Usb1408fsModel::Result::kNoDevice) {
      complete(u, -ENODEV, 0);
    } else if (result == Usb1408fsModel::Result::kStall) {
      complete(u, -EPIPE, 0);
    } else {
      const int n = std::min<int>(static_cast<int>(packet->length), urb->buffer_length);
      std::memcpy(urb->buffer, packet->bytes.data(), static_cast<std::size_t>(n));
      complete(u, packet->length > static_cast<std::size_t>(n) ? -EOVERFLOW : 0, n);
    }
  }
}

void UmockdevBoard::submit(UMockdevIoctlClient* client) {
  UMockdevIoctlData* arg = umockdev_ioctl_client_get_arg(client);
  Urb u;
  u.data = umockdev_ioctl_data_resolve(arg, 0, sizeof(usbdevfs_urb), nullptr);
  if (u.data == nullptr) {
    umockdev_ioctl_client_complete(client, -1, EFAULT);
    return;
  }
  u.urb = reinterpret_cast<usbdevfs_urb*>(u.data->data);
  if (!model_.connected()) {
    g_object_unref(u.data);
    umockdev_ioctl_client_complete(client, -1, ENODEV);
    return;
  }
  ++submitted_;
  if (u.urb->type == USBDEVFS_URB_TYPE_CONTROL) {
    controlTransfer(u);
  } else if (u.urb->endpoint & 0x80) {
    parked_.push_back(u);
  } else {
    complete(u, 0, u.urb->buffer_length);  // OUT: nothing on this board listens (EP 0x02 unused)
  }
  umockdev_ioctl_client_complete(client, 0, 0);
}

bool UmockdevBoard::handle(UMockdevIoctlClient* client) {
  std::lock_guard<std::mutex> lock(mutex_);
  const unsigned long request = umockdev_ioctl_client_get_request(client);
  UMockdevIoctlData* arg = umockdev_ioctl_client_get_arg(client);
  switch (request) {
    case USBDEVFS_GET_CAPABILITIES: {
      UMockdevIoctlData* d = umockdev_ioctl_data_resolve(arg, 0, sizeof(std::uint32_t), nullptr);
      const std::uint32_t caps = USBDEVFS_CAP_BULK_CONTINUATION | USBDEVFS_CAP_NO_PACKET_SIZE_LIM |
                                 USBDEVFS_CAP_REAP_AFTER_DISCONNECT | USBDEVFS_CAP_ZERO_PACKET;
      std::memcpy(d->data, &caps, sizeof caps);
      umockdev_ioctl_client_complete(client, 0, 0);
      g_object_unref(d);
      return true;
    }
    case USBDEVFS_CLAIMINTERFACE:
    case USBDEVFS_RELEASEINTERFACE:
    case USBDEVFS_CLEAR_HALT:
    case USBDEVFS_RESET:
    case USBDEVFS_RESETEP:
    case USBDEVFS_SETINTERFACE:
    case USBDEVFS_SETCONFIGURATION:
      if (!model_.connected()) {
        umockdev_ioctl_client_complete(client, -1, ENODEV);
      } else {
        umockdev_ioctl_client_complete(client, 0, 0);
      }
      return true;
    case USBDEVFS_GETDRIVER:
    case USBDEVFS_IOCTL:  // USBDEVFS_DISCONNECT wrapped: no kernel driver is bound here
      umockdev_ioctl_client_complete(client, -1, ENODATA);
      return true;
    case USBDEVFS_SUBMITURB:
      submit(client);
      return true;
    case USBDEVFS_REAPURB:
    case USBDEVFS_REAPURBNDELAY: {
      fillParked();
      if (completed_.empty()) {
        umockdev_ioctl_client_complete(client, -1, EAGAIN);
        return true;
      }
      Urb u = completed_.front();
      completed_.pop_front();
      UMockdevIoctlData* ptr = umockdev_ioctl_data_resolve(arg, 0, sizeof(void*), nullptr);
      umockdev_ioctl_data_set_ptr(ptr, 0, u.data);
      umockdev_ioctl_client_complete(client, 0, 0);
      g_object_unref(ptr);
      g_object_unref(u.data);
      return true;
    }
    case USBDEVFS_DISCARDURB: {
      // The argument is the URB's address in the client; without this, libusb's timeouts and
      // cancellations would never come back.
      const unsigned long address = *reinterpret_cast<unsigned long*>(arg->data);
      auto it = std::find_if(parked_.begin(), parked_.end(),
                             [&](const Urb& u) { return u.data->client_addr == address; });
      if (it == parked_.end()) {
        umockdev_ioctl_client_complete(client, -1, EINVAL);
        return true;
      }
      Urb u = *it;
      parked_.erase(it);
      ++discarded_;
      complete(u, -ENOENT, 0);
      umockdev_ioctl_client_complete(client, 0, 0);
      return true;
    }
    default:
      umockdev_ioctl_client_complete(client, -1, ENOTTY);
      return true;
  }
}

}  // namespace zerocal::sim
