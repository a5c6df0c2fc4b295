// The simulated USB-1408FS behind umockdev's dynamic ioctl handler, so that the real
// LibusbTransport (and libusb's own Linux usbfs code) runs against it with no hardware and no
// root. Must be constructed before libusb_init, in a process started by umockdev-wrapper.
//
// The handler runs on umockdev's worker thread: every access to the model goes through the lock,
// hence withModel().
#pragma once

#include <chrono>
#include <deque>
#include <mutex>
#include <string>

#include "zerocal/sim/usb1408fs_model.h"

typedef struct _UMockdevTestbed UMockdevTestbed;
typedef struct _UMockdevIoctlBase UMockdevIoctlBase;
typedef struct _UMockdevIoctlClient UMockdevIoctlClient;
typedef struct _UMockdevIoctlData UMockdevIoctlData;
struct usbdevfs_urb;

namespace zerocal::sim {

class UmockdevBoard {
 public:
  // Adds a USB-1408FS (bus 1, device 2, serial "01A2B3C4") to a fresh testbed unless
  // `with_device` is false (an empty bus).
  explicit UmockdevBoard(bool with_device = true);
  ~UmockdevBoard();
  UmockdevBoard(const UmockdevBoard&) = delete;
  UmockdevBoard& operator=(const UmockdevBoard&) = delete;

  template <typename F>
  auto withModel(F&& f) {
    std::lock_guard<std::mutex> lock(mutex_);
    return f(model_);
  }
  std::string devnode() const { return "/dev/bus/usb/001/002"; }
  // Where the testbed keeps its files (the devnode is rootDir() + devnode()).
  std::string rootDir() const;
  int urbsSubmitted() const;
  int urbsDiscarded() const;

 private:
  struct Urb {
    UMockdevIoctlData* data = nullptr;  // our reference to the resolved copy of the URB
    usbdevfs_urb* urb = nullptr;        // inside data
  };
  static int onIoctl(UMockdevIoctlBase* handler, UMockdevIoctlClient* client, void* self);
  bool handle(UMockdevIoctlClient* client);
  void submit(UMockdevIoctlClient* client);
  void controlTransfer(Urb& urb);
  void fillParked();
  void complete(Urb urb, int status, int actual_length);

  mutable std::mutex mutex_;
  Usb1408fsModel model_;
  UMockdevTestbed* testbed_ = nullptr;
  UMockdevIoctlBase* handler_ = nullptr;
  std::chrono::steady_clock::time_point start_;
  std::deque<Urb> parked_;     // IN transfers waiting for the board
  std::deque<Urb> completed_;  // waiting to be reaped
  int submitted_ = 0;
  int discarded_ = 0;
};

}  // namespace zerocal::sim
