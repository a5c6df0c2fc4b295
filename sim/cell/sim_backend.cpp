#include "zerocal/sim/sim_backend.h"

#include "zerocal/sim/simulated_rig.h"

namespace zerocal::sim {
namespace {

class ConnectedSimCell final : public service::ConnectedCell {
 public:
  ConnectedSimCell(SimulatedCell& cell, Irc5Options options)
      : cell_(cell),
        client_(std::move(options)),
        daq_(cell.boardOpener()),
        psd_(daq_, cell.psdMap(), cell) {
    client_.connect();
  }
  ~ConnectedSimCell() override { client_.close(); }

  ControllerLink& robot() override { return client_; }
  servo::PsdReader& psd() override { return psd_; }
  servo::CellClock& clock() override { return cell_; }
  void reconnectRobot() override { client_.reconnect(); }
  void reopenPsd() override { daq_.reopen(); }
  void stopRobot() noexcept override {
    try {
      if (client_.connected()) client_.stop();
    } catch (const std::exception&) {
      // Best effort: the controller is unreachable, so it is not moving on our behalf either.
    }
  }
  std::optional<std::array<double, 4>> truthDeg() const override {
    const auto& t = cell_.world().true_offsets_deg;
    return std::array<double, 4>{t[1], t[2], t[3], t[4]};
  }

 private:
  SimulatedCell& cell_;
  Irc5Client client_;
  usb1408fs::Usb1408fs daq_;
  servo::ChainPsdReader psd_;
};

}  // namespace

SimBackend::SimBackend(SimulatedCellOptions options, std::function<void(Irc5Options&)> adjust)
    : cell_(std::move(options)), adjust_(std::move(adjust)) {}

service::CellKnowledge SimBackend::knowledge() const {
  const SessionKnowledge k = knowledgeOf(cell_.world());
  return {k.cell, k.taught_centre};
}

std::unique_ptr<service::ConnectedCell> SimBackend::connect() {
  Irc5Options o = cell_.clientOptions();
  if (adjust_) adjust_(o);
  return std::make_unique<ConnectedSimCell>(cell_, std::move(o));
}

}  // namespace zerocal::sim
