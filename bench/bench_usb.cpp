// USB-1408FS driver throughput and latency against the simulated board.
//
//   BM_SustainedScan48k     30 s of a 48 kS/s aggregate hardware-paced scan (3 channels at
//                           16 kHz) through FakeTransport and the board model: lost packets and
//                           CPU per second of data (model included, so an upper bound).
//   BM_DriverDecode48k      the same data rate, packets replayed from memory: the protocol
//                           layer's own CPU per second of data.
//   BM_AveragedReading64    one PSD reading of 64 samples per channel at 16 kHz: simulated time
//                           from request to result, and the CPU it costs.
//   BM_StreamReading64      the same readings from a continuous scan (PsdStream): interval
//                           between readings, no command round trips.
//   BM_ChainPsdReading      one servo reading through ChainPsdReader (scan, average, spot
//                           detector, degree-7 map) at the reader's defaults (64 at 16 kHz) and
//                           the daemon's (100 at 1 kHz): CPU per reading and simulated latency.
#include <benchmark/benchmark.h>

#include <chrono>
#include <ctime>

#include "zerocal/psd/psd.h"
#include "zerocal/sim/fake_transport.h"
#include "zerocal/sim/psd_model.h"
#include "zerocal/sim/psd_rig.h"
#include "zerocal/usb1408fs/psd_readout.h"
#include "zerocal/usb1408fs/usb1408fs.h"

namespace {

using namespace zerocal;
using namespace std::chrono_literals;

double cpuSeconds() {
  timespec ts{};
  clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &ts);
  return ts.tv_sec + ts.tv_nsec * 1e-9;
}

const std::vector<usb1408fs::Channel> kPsdChannels = {
    {0, usb1408fs::InputMode::kDifferential, usb1408fs::Range::kBip5V},
    {1, usb1408fs::InputMode::kDifferential, usb1408fs::Range::kBip5V},
    {2, usb1408fs::InputMode::kDifferential, usb1408fs::Range::kBip5V}};

class Sink : public usb1408fs::ScanConsumer {
 public:
  void onScanData(const usb1408fs::ScanBlock& block) noexcept override {
    for (std::size_t i = 0; i < block.count; ++i) acc += block.volts[i];
  }
  double acc = 0;
};

void BM_SustainedScan48k(benchmark::State& state) {
  const double seconds = static_cast<double>(state.range(0));
  std::uint64_t lost = 0, packets = 0;
  double cpu = 0;
  for (auto _ : state) {
    sim::Usb1408fsModel board;
    board.setAnalogSource(
        [](const usb1408fs::Channel& ch, double t) { return 0.5 * ch.number + 0.1 * std::sin(t); });
    usb1408fs::Usb1408fs daq(sim::FakeTransport::opener(board));
    Sink sink;
    const double cpu0 = cpuSeconds();
    daq.startScan({kPsdChannels, 16000.0, 0, 4}, sink);
    const auto start = board.now();
    while (board.now() - start < std::chrono::duration<double>(seconds)) daq.pollScan(10ms);
    daq.stopScan();
    cpu += cpuSeconds() - cpu0;
    lost += daq.scanStats().lost_packets + board.scanPacketsDropped();
    packets += daq.scanStats().packets;
    benchmark::DoNotOptimize(sink.acc);
  }
  const double runs = static_cast<double>(state.iterations());
  state.counters["data_s"] = seconds;
  state.counters["packets"] = static_cast<double>(packets) / runs;
  state.counters["lost_packets"] = static_cast<double>(lost) / runs;
  state.counters["cpu_ms_per_data_s"] = 1e3 * cpu / runs / seconds;
}
BENCHMARK(BM_SustainedScan48k)->Arg(30)->Unit(benchmark::kMillisecond)->Iterations(1);

// Replays ready-made scan packets as fast as the driver takes them.
class ReplayTransport final : public usb1408fs::UsbTransport {
 public:
  explicit ReplayTransport(sim::Usb1408fsModel& board) : board_(board) {
    for (std::size_t i = 0; i < 31; ++i) usb1408fs::putU16(&packet_[2 * i], 0x1234);
  }
  void controlOut(std::uint8_t rt, std::uint8_t r, std::uint16_t v, std::uint16_t i,
                  const std::uint8_t* d, std::size_t n, std::chrono::milliseconds) override {
    board_.controlOut(rt, r, v, i, d, n);
  }
  std::size_t interruptIn(std::uint8_t, std::uint8_t* data, std::size_t capacity,
                          std::chrono::milliseconds) override {
    auto reply = board_.takeReply();
    if (!reply) throw usb1408fs::TimeoutError("no reply");
    std::copy_n(reply->bytes.begin(), std::min(capacity, reply->length), data);
    return reply->length;
  }
  void startStream(const std::uint8_t*, std::size_t, std::size_t, std::size_t,
                   usb1408fs::StreamSink& sink) override {
    sink_ = &sink;
    index_ = 0;
  }
  void pollStream(std::chrono::milliseconds timeout) override {
    // One poll hands over `timeout` worth of packets at 48 kS/s.
    const int n = static_cast<int>(48000.0 / 31.0 * timeout.count() / 1000.0);
    for (int k = 0; k < n; ++k) {
      usb1408fs::putU16(&packet_[62], index_++);
      sink_->onPacket(0x83, packet_, 64, usb1408fs::TransferStatus::kCompleted);
    }
  }
  void stopStream() noexcept override {}

 private:
  sim::Usb1408fsModel& board_;
  usb1408fs::StreamSink* sink_ = nullptr;
  std::uint8_t packet_[64] = {};
  std::uint16_t index_ = 0;
};

void BM_DriverDecode48k(benchmark::State& state) {
  sim::Usb1408fsModel board;
  usb1408fs::Usb1408fs daq([&board]() -> std::unique_ptr<usb1408fs::UsbTransport> {
    return std::make_unique<ReplayTransport>(board);
  });
  Sink sink;
  daq.startScan({kPsdChannels, 16000.0, 0, 4}, sink);
  for (auto _ : state) daq.pollScan(1000ms);  // one second of data per iteration
  state.counters["lost_packets"] = static_cast<double>(daq.scanStats().lost_packets);
  state.counters["samples_per_iter"] =
      static_cast<double>(daq.scanStats().samples) / static_cast<double>(state.iterations());
  daq.stopScan();
  benchmark::DoNotOptimize(sink.acc);
}
BENCHMARK(BM_DriverDecode48k)->Unit(benchmark::kMicrosecond);

void BM_AveragedReading64(benchmark::State& state) {
  sim::PsdModel psd;
  sim::Usb1408fsModel board;
  board.setAnalogSource(sim::psdAnalogSource(psd, [](double) { return PsdSpot{0.1, -0.2}; }));
  usb1408fs::Usb1408fs daq(sim::FakeTransport::opener(board));
  double simulated = 0;
  for (auto _ : state) {
    const auto t0 = board.now();
    const psd::VoltageReading r =
        usb1408fs::readAveraged(daq, usb1408fs::PsdChannels{}, 64, 16000.0);
    simulated += std::chrono::duration<double>(board.now() - t0).count();
    benchmark::DoNotOptimize(r.x);
  }
  state.counters["simulated_latency_ms"] =
      1e3 * simulated / static_cast<double>(state.iterations());
}
BENCHMARK(BM_AveragedReading64)->Unit(benchmark::kMicrosecond);

void BM_StreamReading64(benchmark::State& state) {
  sim::PsdModel psd;
  sim::Usb1408fsModel board;
  board.setAnalogSource(sim::psdAnalogSource(psd, [](double) { return PsdSpot{0.1, -0.2}; }));
  usb1408fs::Usb1408fs daq(sim::FakeTransport::opener(board));
  usb1408fs::PsdStream stream(daq, usb1408fs::PsdChannels{}, 64, 16000.0);
  psd::VoltageReading r;
  stream.next(r, 10ms);
  const auto t0 = board.now();
  for (auto _ : state) {
    if (!stream.next(r, 10ms)) state.SkipWithError("no reading");
    benchmark::DoNotOptimize(r.x);
  }
  state.counters["simulated_interval_ms"] =
      std::chrono::duration<double, std::milli>(board.now() - t0).count() /
      static_cast<double>(state.iterations());
}
BENCHMARK(BM_StreamReading64)->Unit(benchmark::kMicrosecond);

// The board's clock, as the simulated cell's would be without a robot.
class BoardClock final : public CellClock {
 public:
  explicit BoardClock(sim::Usb1408fsModel& board) : board_(board) {}
  double nowS() noexcept override { return std::chrono::duration<double>(board_.now()).count(); }

 private:
  sim::Usb1408fsModel& board_;
};

void BM_ChainPsdReading(benchmark::State& state) {
  sim::SimulatedPsdRig rig;
  sim::SweepOptions sweep;
  sweep.step_mm = 0.1;
  const psd::PsdMap map = psd::PsdMap::fit(sim::simulateSweep(rig, sweep), psd::MapFitOptions{});
  rig.setSpot(PsdSpot{0.1, -0.2});
  BoardClock clock(rig.board());
  usb1408fs::BoardSettings o;
  o.samples_per_reading = static_cast<int>(state.range(0));
  o.scan_rate_hz = static_cast<double>(state.range(1));
  usb1408fs::ChainPsdReader reader(rig.daq(), map, clock, o, psd::PsdConfig{});
  double simulated = 0;
  for (auto _ : state) {
    const auto t0 = rig.board().now();
    const PsdReading r = reader.read();
    simulated += std::chrono::duration<double>(rig.board().now() - t0).count();
    benchmark::DoNotOptimize(r.spot.u_mm);
  }
  state.counters["simulated_latency_ms"] =
      1e3 * simulated / static_cast<double>(state.iterations());
}
BENCHMARK(BM_ChainPsdReading)->Args({64, 16000})->Args({100, 1000})->Unit(benchmark::kMicrosecond);

}  // namespace

BENCHMARK_MAIN();
