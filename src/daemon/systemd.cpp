#include "zerocal/daemon/systemd.h"

#include <systemd/sd-daemon.h>

#include "zerocal/daemon/logging.h"

namespace zerocal {
namespace {

// sd_notify() returns 0 when NOTIFY_SOCKET is unset, which is the normal case outside systemd;
// a send that fails under systemd is worth a line in the log but not a stop.
void notify(const std::string& message) {
  if (sd_notify(0, message.c_str()) < 0)
    makeLogger("zerocald")->warn("cannot tell systemd '{}'", message);
}

}  // namespace

void notifyReady(const std::string& status) { notify("READY=1\nSTATUS=" + status); }

void notifyStatus(const std::string& status) { notify("STATUS=" + status); }

void notifyStopping(const std::string& status) { notify("STOPPING=1\nSTATUS=" + status); }

std::optional<std::chrono::microseconds> watchdogInterval() {
  std::uint64_t usec = 0;
  if (sd_watchdog_enabled(0, &usec) > 0 && usec > 0) return std::chrono::microseconds(usec);
  return std::nullopt;
}

Watchdog::Watchdog(boost::asio::io_context& io, std::chrono::microseconds interval,
                   StuckCheck stuck)
    : timer_(io), interval_(interval), stuck_(std::move(stuck)) {}

void Watchdog::start() {
  stopped_ = false;
  notify("WATCHDOG=1");
  arm();
}

void Watchdog::stop() {
  stopped_ = true;
  timer_.cancel();
}

void Watchdog::arm() {
  // Half the interval, as sd_watchdog_enabled(3) advises: one late tick does not kill the daemon.
  timer_.expires_after(interval_ / 2);
  timer_.async_wait([this](const boost::system::error_code& ec) {
    if (ec || stopped_) return;  // stopping
    if (const std::optional<std::string> why = stuck_()) {
      if (!reported_)
        makeLogger("zerocald")
            ->critical(
                "{}; the watchdog is no longer fed: systemd restarts "
                "zerocald (every recorded pose is kept: `zerocal resume`)",
                *why);
      reported_ = true;
    } else {
      if (reported_) makeLogger("zerocald")->warn("the stuck thread made progress again");
      reported_ = false;
      notify("WATCHDOG=1");
    }
    arm();
  });
}

}  // namespace zerocal
