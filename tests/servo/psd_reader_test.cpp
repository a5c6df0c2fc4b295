// ChainPsdReader over the real USB-1408FS protocol code and the simulated board and detector.
#include <gtest/gtest.h>

#include <optional>

#include "zerocal/sim/fake_transport.h"
#include "zerocal/sim/psd_model.h"
#include "zerocal/sim/simulated_cell.h"
#include "zerocal/usb1408fs/psd_readout.h"

namespace zerocal::servo {
namespace {

class FixedClock final : public CellClock {
 public:
  double nowS() noexcept override { return now += 1; }
  double now = 0;
};

class ChainReader : public ::testing::Test {
 protected:
  ChainReader() {
    board_.setAnalogSource(sim::psdAnalogSource(psd_, [this](double) { return spot_; }));
  }
  // The map a simulated cell fits from its stage sweep.
  static const psd::PsdMap& map() {
    static const psd::PsdMap fitted = [] {
      sim::SimulatedCellOptions o;
      o.world = randomWorld(1);
      return sim::SimulatedCell(o).psdMap();
    }();
    return fitted;
  }
  sim::PsdModel psd_;
  sim::Usb1408fsModel board_;
  std::optional<PsdSpot> spot_;
  FixedClock clock_;
};

TEST_F(ChainReader, InsideTheZoneGivesMappedMillimetres) {
  usb1408fs::Usb1408fs daq(sim::FakeTransport::opener(board_));
  usb1408fs::ChainPsdReader reader(daq, map(), clock_, sim::simulatedReadout().board,
                                   sim::simulatedReadout().psd);
  spot_ = PsdSpot{0.2, -0.3};
  const PsdReading r = reader.read();
  EXPECT_TRUE(r.spot_present);
  EXPECT_TRUE(r.in_valid_zone);
  EXPECT_NEAR(r.spot.u_mm, 0.2, 0.002);
  EXPECT_NEAR(r.spot.v_mm, -0.3, 0.002);
  EXPECT_GT(r.se.u_mm, 0);
  EXPECT_EQ(r.time_s, 1);
}

TEST_F(ChainReader, OutsideTheZoneGivesACoarseEstimateOfTheRightSign) {
  usb1408fs::Usb1408fs daq(sim::FakeTransport::opener(board_));
  usb1408fs::ChainPsdReader reader(daq, map(), clock_, sim::simulatedReadout().board,
                                   sim::simulatedReadout().psd);
  spot_ = PsdSpot{2.5, -3.0};
  const PsdReading r = reader.read();
  EXPECT_TRUE(r.spot_present);
  EXPECT_FALSE(r.in_valid_zone);
  EXPECT_GT(r.spot.u_mm, 0.1);
  EXPECT_LT(r.spot.v_mm, -0.1);
  EXPECT_LT(r.spot.u_mm, 2.5);  // saturated: an underestimate, so the servo cannot overshoot on it
}

TEST_F(ChainReader, NoLightIsNoSpot) {
  usb1408fs::Usb1408fs daq(sim::FakeTransport::opener(board_));
  usb1408fs::ChainPsdReader reader(daq, map(), clock_, sim::simulatedReadout().board,
                                   sim::simulatedReadout().psd);
  spot_ = PsdSpot{20, 0};
  EXPECT_FALSE(reader.read().spot_present);
  spot_.reset();
  EXPECT_FALSE(reader.read().spot_present);
}

}  // namespace
}  // namespace zerocal::servo
