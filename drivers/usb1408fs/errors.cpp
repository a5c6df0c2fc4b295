#include "zerocal/usb1408fs/errors.h"

namespace zerocal::usb1408fs {
namespace {

// A literal, not a std::string, so that the messages work during static initialisation too.
constexpr const char* kIdentity = "Measurement Computing USB-1408FS (USB VID:PID 09db:00a1)";

// The rule gives the board to group zerocal (and the user at the seat), so both halves matter.
std::string udevAdvice() {
  return std::string("the udev rule (installed with zerocal; from a source tree, copy ") +
         kUdevRulePath +
         " into /etc/udev/rules.d/) gives the board to group zerocal: add this user to it "
         "(`sudo usermod -aG zerocal $USER`, then log in again), run `sudo udevadm control "
         "--reload-rules && sudo udevadm trigger`, and replug the board";
}

}  // namespace

std::string deviceNotFoundMessage(const std::string& serial) {
  return std::string("no ") + kIdentity + (serial.empty() ? "" : " with serial number " + serial) +
         " found. Check the cable and power, and `lsusb -d 09db:00a1`; if it is listed, " +
         udevAdvice();
}

std::string permissionDeniedMessage(const std::string& what) {
  return std::string("permission denied on the ") + kIdentity + " (" + what +
         ", LIBUSB_ERROR_ACCESS): this user may not open it; " + udevAdvice();
}

std::string noDeviceDuring(const std::string& what) {
  return std::string("the ") + kIdentity + " went away during " + what +
         " (LIBUSB_ERROR_NO_DEVICE): unplugged or reset; reconnect it, then reopen the link";
}

}  // namespace zerocal::usb1408fs
