// The real libusb transport against the simulated board through umockdev's dynamic ioctl
// handler: enumeration, open by serial, claim, control and interrupt transfers, asynchronous
// streaming with several transfers in flight, cancellation, stalls, timeouts and unplugging.
// Runs under umockdev-wrapper (see CMakeLists.txt). Timeouts stay short because libusb
// busy-polls a mocked device node.
#include <fcntl.h>
#include <ftw.h>
#include <gmock/gmock.h>
#include <grp.h>
#include <gtest/gtest.h>
#include <libusb.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cstdio>
#include <cstdlib>
#include <cstring>

#include "allocation_counter.h"
#include "umockdev_board.h"
#include "zerocal/usb1408fs/libusb_transport.h"
#include "zerocal/usb1408fs/psd_chain.h"
#include "zerocal/usb1408fs/usb1408fs.h"

namespace zerocal::usb1408fs {
namespace {

using sim::UmockdevBoard;
using sim::Usb1408fsModel;
using ::testing::ElementsAre;
using ::testing::HasSubstr;
using namespace std::chrono_literals;

Channel diff(int c, Range r) { return {c, InputMode::kDifferential, r}; }
Channel se(int c) { return {c, InputMode::kSingleEnded, Range::kBip10V}; }

double testVolts(const Channel& ch, double /*t*/) {
  if (ch.mode == InputMode::kSingleEnded) return 1.5 - 0.7 * ch.number;
  return 0.41 * fullScaleVolts(ch) + 0.02 * ch.number;
}

double lsb(const Channel& ch) { return fullScaleVolts(ch) / 8191.0; }

Usb1408fs::Options shortTimeouts() {
  Usb1408fs::Options options;
  options.command_timeout = 150ms;
  options.scan_data_timeout = 300ms;
  return options;
}

Usb1408fs::Opener realOpener(std::string serial = {}) {
  return [serial] { return LibusbTransport::open(serial); };
}

class Collector : public ScanConsumer {
 public:
  explicit Collector(std::size_t channels) : values(channels) {}
  void onScanData(const ScanBlock& block) noexcept override {
    for (std::size_t i = 0; i < block.count; ++i) {
      values[(block.first_channel + i) % values.size()].push_back(block.volts[i]);
    }
  }
  void onPacketsLost(std::uint32_t n, std::uint16_t index) noexcept override {
    losses.emplace_back(n, index);
  }
  std::vector<std::vector<double>> values;
  std::vector<std::pair<std::uint32_t, std::uint16_t>> losses;
};

// When started as the helper of PermissionDeniedNamesTheUdevRule (an unprivileged process in the
// parent's testbed), try to open the board and report through the exit status, before gtest runs.
constexpr const char* kPermissionChildEnv = "ZEROCAL_UMOCKDEV_PERMISSION_CHILD";
const struct PermissionChild {
  PermissionChild() {
    if (std::getenv(kPermissionChildEnv) == nullptr) return;
    int code = 3;
    try {
      LibusbTransport::open();
      code = 1;
    } catch (const PermissionError& e) {
      const std::string what = e.what();
      code = what.find("09db:00a1") != std::string::npos &&
                     what.find("config/udev/60-zerocal-usb1408fs.rules") != std::string::npos
                 ? 0
                 : 2;
      std::fprintf(stderr, "child: %s\n", e.what());
    } catch (const std::exception& e) {
      std::fprintf(stderr, "child: %s\n", e.what());
      code = 4;
    }
    std::_Exit(code);
  }
} permission_child;

class UmockdevTest : public ::testing::Test {
 protected:
  UmockdevTest() {
    board_.withModel([](Usb1408fsModel& m) { m.setAnalogSource(testVolts); });
  }
  UmockdevBoard board_;
};

TEST(UmockdevEmptyBus, NoDeviceNamesVidPidAndUdevRule) {
  UmockdevBoard empty(false);
  try {
    LibusbTransport::open();
    FAIL() << "opened a board that is not there";
  } catch (const DeviceNotFoundError& e) {
    EXPECT_THAT(e.what(), HasSubstr("09db:00a1"));
    EXPECT_THAT(e.what(), HasSubstr("config/udev/60-zerocal-usb1408fs.rules"));
    EXPECT_EQ(e.libusbCode(), LIBUSB_ERROR_NOT_FOUND);
  }
}

TEST_F(UmockdevTest, OpensBySerialReadsCalibrationAndConverts) {
  Usb1408fs dev(realOpener("01A2B3C4"), shortTimeouts());
  board_.withModel([&](Usb1408fsModel& m) {
    const Channel ch = diff(2, Range::kBip2_5V);
    EXPECT_DOUBLE_EQ(dev.calibration(ch).slope, m.calibration(ch).slope);
    EXPECT_DOUBLE_EQ(dev.calibration(ch).intercept, m.calibration(ch).intercept);
    EXPECT_EQ(m.memoryWriteAttempts(), 0);
    return 0;
  });
  for (const Channel& ch : {diff(0, Range::kBip20V), diff(3, Range::kBip1V), se(0), se(7)}) {
    EXPECT_NEAR(dev.readVolts(ch), testVolts(ch, 0), lsb(ch));
  }
}

TEST_F(UmockdevTest, WrongSerialIsNotFound) {
  try {
    LibusbTransport::open("NOPE");
    FAIL();
  } catch (const DeviceNotFoundError& e) {
    EXPECT_THAT(e.what(), HasSubstr("serial number NOPE"));
    EXPECT_THAT(e.what(), HasSubstr("1 USB-1408FS with another serial attached"));
  }
}

TEST_F(UmockdevTest, CommandBytesReachTheBoard) {
  Usb1408fs dev(realOpener(), shortTimeouts());
  board_.withModel([](Usb1408fsModel& m) {
    m.clearCommandLog();
    m.setStatus(0x000A);
    m.setDigitalInputs(0x5A, 0);
    return 0;
  });
  EXPECT_EQ(dev.status(), 0x000A);
  dev.blinkLed();
  dev.configureDigitalPort(DigitalPort::kB, DigitalDirection::kOutput);
  dev.writeDigital(DigitalPort::kB, 0x81);
  EXPECT_THAT(dev.readDigital(), ElementsAre(0x5A, 0x81));
  dev.readRaw(se(4));
  board_.withModel([](Usb1408fsModel& m) {
    const auto& log = m.commandLog();
    EXPECT_EQ(log.size(), 6u);
    if (log.size() != 6u) return 0;
    EXPECT_THAT(log[0].data, ElementsAre(0x44, 0, 0));
    EXPECT_THAT(log[1].data, ElementsAre(0x40));
    EXPECT_THAT(log[2].data, ElementsAre(0x01, 1, 0));
    EXPECT_THAT(log[3].data, ElementsAre(0x04, 1, 0x81));
    EXPECT_THAT(log[4].data, ElementsAre(0x03));
    EXPECT_THAT(log[5].data, ElementsAre(0x10, 12, 0));
    for (const auto& c : log) {
      EXPECT_EQ(c.request_type, 0x21);
      EXPECT_EQ(c.request, 0x09);
      EXPECT_EQ(c.value, 0x0200 | c.data[0]);
    }
    EXPECT_EQ(m.blinkCount(), 1);
    return 0;
  });
}

TEST_F(UmockdevTest, MissingReplyTimesOutThroughLibusbCancellation) {
  Usb1408fs dev(realOpener(), shortTimeouts());
  const int discarded_before = board_.urbsDiscarded();
  board_.withModel([](Usb1408fsModel& m) {
    m.muteNextReplies(1);
    return 0;
  });
  try {
    dev.status();
    FAIL();
  } catch (const TimeoutError& e) {
    EXPECT_THAT(e.what(), HasSubstr("no reply from the USB-1408FS to GET_STATUS (0x44)"));
    EXPECT_EQ(e.libusbCode(), LIBUSB_ERROR_TIMEOUT);
  }
  EXPECT_GT(board_.urbsDiscarded(), discarded_before);
  board_.withModel([](Usb1408fsModel& m) {
    m.queueReply({0x21, 1, 2, 3, 4});  // a stale report on the way
    return 0;
  });
  EXPECT_NEAR(dev.readVolts(se(1)), testVolts(se(1), 0), lsb(se(1)));
}

TEST_F(UmockdevTest, StallBecomesStallError) {
  Usb1408fs dev(realOpener(), shortTimeouts());
  board_.withModel([](Usb1408fsModel& m) {
    m.stallNextCommand(cmd::kBlinkLed);
    return 0;
  });
  try {
    dev.blinkLed();
    FAIL();
  } catch (const StallError& e) {
    EXPECT_THAT(e.what(), HasSubstr("BLINK_LED (0x40)"));
    EXPECT_EQ(e.libusbCode(), LIBUSB_ERROR_PIPE);
  }
  dev.blinkLed();
}

TEST_F(UmockdevTest, HardwarePacedScanWithTransfersInFlight) {
  Usb1408fs dev(realOpener(), shortTimeouts());
  const std::vector<Channel> channels = {diff(0, Range::kBip10V), diff(1, Range::kBip4V),
                                         diff(2, Range::kBip2V)};
  Collector sink(channels.size());
  board_.withModel([](Usb1408fsModel& m) {
    m.dropScanPackets(4, 2);
    return 0;
  });
  const int submitted_before = board_.urbsSubmitted();
  dev.startScan({channels, 3000.0, 0, 4}, sink);
  EXPECT_GE(board_.urbsSubmitted() - submitted_before, 12);  // 4 per endpoint before AIN_SCAN
  const auto deadline = std::chrono::steady_clock::now() + 400ms;
  while (std::chrono::steady_clock::now() < deadline) dev.pollScan(20ms);
  dev.stopScan();
  EXPECT_FALSE(board_.withModel([](Usb1408fsModel& m) { return m.scanning(); }));
  const ScanStats stats = dev.scanStats();
  EXPECT_GT(stats.packets, 60u);  // 9000 samples/s -> about 290 packets/s
  EXPECT_EQ(stats.lost_packets, 2u);
  EXPECT_THAT(sink.losses, ElementsAre(std::make_pair(2u, std::uint16_t{6})));
  for (std::size_t c = 0; c < channels.size(); ++c) {
    ASSERT_FALSE(sink.values[c].empty());
    for (double v : sink.values[c]) ASSERT_NEAR(v, testVolts(channels[c], 0), lsb(channels[c]));
  }
  // After the stop, the link is idle and usable.
  EXPECT_NEAR(dev.readVolts(se(2)), testVolts(se(2), 0), lsb(se(2)));
}

TEST_F(UmockdevTest, SingleExecutionScanCompletes) {
  Usb1408fs dev(realOpener(), shortTimeouts());
  Collector sink(2);
  dev.startScan({{se(0), se(1)}, 5000.0, 500, 2}, sink);
  const auto deadline = std::chrono::steady_clock::now() + 1s;
  while (!dev.scanComplete() && std::chrono::steady_clock::now() < deadline) dev.pollScan(20ms);
  ASSERT_TRUE(dev.scanComplete());
  dev.stopScan();
  EXPECT_EQ(sink.values[0].size(), 500u);
  EXPECT_EQ(sink.values[1].size(), 500u);
}

// A scan per PSD reading, as ChainPsdReader runs them: after the first, LibusbTransport reuses
// its transfers and the driver its buffers.
TEST_F(UmockdevTest, RepeatedReadingsAllocateNothingOfOursAfterTheFirst) {
  Usb1408fs dev(realOpener(), shortTimeouts());
  const ScanConfig scan = usb1408fs::averagedScan(usb1408fs::PsdChannels{}, 64, 16000.0);
  usb1408fs::readAveraged(dev, scan);
  long allocations = 0;
  {
    // Counts this thread only: umockdev's handler thread plays the board. libusb and umockdev
    // allocate with malloc, which is not counted; this measures the driver and the transport.
    const test::CountAllocations count;
    for (int i = 0; i < 5; ++i) usb1408fs::readAveraged(dev, scan);
    allocations = count.count();
  }
  EXPECT_EQ(allocations, 0);
}

TEST_F(UmockdevTest, UnpluggedMidScanThenReopenedWhenBack) {
  Usb1408fs dev(realOpener(), shortTimeouts());
  Collector sink(1);
  dev.startScan({{se(3)}, 2000.0, 0, 3}, sink);
  for (int i = 0; i < 5; ++i) dev.pollScan(20ms);
  board_.withModel([](Usb1408fsModel& m) {
    m.unplug();
    return 0;
  });
  try {
    for (int i = 0; i < 50; ++i) dev.pollScan(20ms);
    FAIL() << "no DisconnectedError";
  } catch (const DisconnectedError& e) {
    EXPECT_THAT(e.what(), HasSubstr("unplugged during the scan"));
  }
  EXPECT_FALSE(dev.connected());
  EXPECT_THROW(dev.reopen(), DisconnectedError);  // enumerated, but it does not answer
  board_.withModel([](Usb1408fsModel& m) {
    m.replug();
    return 0;
  });
  dev.reopen();
  EXPECT_NEAR(dev.readVolts(se(3)), testVolts(se(3), 0), lsb(se(3)));
}

// The helper runs as nobody in the parent's testbed: it must read sysfs, create umockdev's
// netlink stand-in and reach the ioctl socket, and still be refused the device node.
int makeReadable(const char* path, const struct stat* st, int type, FTW*) {
  chmod(path, (st->st_mode & 07777) | (type == FTW_D || S_ISSOCK(st->st_mode) ? 0777 : 0444));
  return 0;
}

// libusb reports EACCES on the device node as LIBUSB_ERROR_ACCESS. Root ignores file modes, so
// when the suite runs as root the open is made by a child that has dropped to nobody.
TEST_F(UmockdevTest, PermissionDeniedNamesTheUdevRule) {
  const std::string root = board_.rootDir();
  ASSERT_EQ(nftw(root.c_str(), makeReadable, 16, FTW_PHYS), 0);
  const std::string node = root + board_.devnode();
  ASSERT_EQ(chmod(node.c_str(), 0), 0);

  std::vector<std::string> env_storage;
  for (char** e = environ; *e != nullptr; ++e) env_storage.emplace_back(*e);
  env_storage.push_back(std::string(kPermissionChildEnv) + "=1");
  std::vector<char*> envp;
  for (auto& e : env_storage) envp.push_back(e.data());
  envp.push_back(nullptr);
  char exe[] = "/proc/self/exe";
  char* argv[] = {exe, nullptr};
  const bool drop = geteuid() == 0;

  const pid_t pid = fork();
  ASSERT_GE(pid, 0);
  if (pid == 0) {
    if (drop && (setgroups(0, nullptr) != 0 || setgid(65534) != 0 || setuid(65534) != 0)) {
      _exit(5);
    }
    execve(exe, argv, envp.data());
    _exit(6);
  }
  int status = 0;
  ASSERT_EQ(waitpid(pid, &status, 0), pid);
  chmod(node.c_str(), 0644);
  ASSERT_TRUE(WIFEXITED(status));
  // 0: PermissionError naming VID:PID and the rule; 1 opened; 2 wrong text; 3/4 other error.
  EXPECT_EQ(WEXITSTATUS(status), 0);
}

}  // namespace
}  // namespace zerocal::usb1408fs
