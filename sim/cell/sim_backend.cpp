#include "zerocal/sim/sim_backend.h"

#include <stdexcept>

#include "zerocal/error.h"
#include "zerocal/model/builtin.h"
#include "zerocal/service/linked_cell.h"
#include "zerocal/sim/simulated_rig.h"
#include "zerocal/sim/world.h"
#include "zerocal/usb1408fs/psd_readout.h"

namespace zerocal::sim {
namespace {

// zerocal-sim's protocol has no request that moves its PSD (its world is fixed at start, and
// compared with the daemon's at connect), so a session cannot move it between placements.
constexpr const char* kExternalPlacements =
    "the external zerocal-sim cannot move its PSD between placements: run sessions at several "
    "PSD placements on the in-process simulated cell (leave backend.sim_host unset)";

// The world as a world file, when its robot is the built-in one (a world file's own robot file is
// not known here; that world is on disk already), naming the seed of the session's noise when
// there is one: the file then replays the session.
std::optional<std::string> truthFile(World world, std::optional<std::uint64_t> noise_seed = {}) {
  if (world.robot.name != builtinIrb1600().name) return std::nullopt;
  if (noise_seed) world.noise.seed = noise_seed;
  return worldYaml(world);
}

// The simulated controller's calibration: the client's requests, and the revolution counter
// updated by the simulator itself when the cell allows it (on a real IRC5 a technician at the
// FlexPendant does it: remote_counter_update false).
class SimCalibration final : public ControllerCalibration {
 public:
  SimCalibration(ControllerCalibration& link, SimController& controller, bool remote_update)
      : link_(link), controller_(controller), remote_update_(remote_update) {}
  std::array<double, 6> readCalOffsets() override { return link_.readCalOffsets(); }
  void writeCalOffset(int joint, double rad) override { link_.writeCalOffset(joint, rad); }
  std::array<double, 6> readMotorAngles() override { return link_.readMotorAngles(); }
  void restart() override { link_.restart(); }
  bool updateRevolutionCounter(int joint) override {
    if (!remote_update_) return false;
    controller_.updateRevolutionCounter(joint);
    return true;
  }

 private:
  ControllerCalibration& link_;
  SimController& controller_;
  bool remote_update_;
};

// The simulated controllers speak the IRC5 protocol (sim::SimController): a link of another
// kind could not talk to them.
std::unique_ptr<Irc5Client> irc5Link(std::unique_ptr<ControllerConnection> link) {
  if (dynamic_cast<Irc5Client*>(link.get()) == nullptr)
    throw ConfigError("controller.kind",
                      {"the simulated cell's controller speaks the IRC5 protocol: "
                       "backend.kind: sim needs controller.kind: irc5"});
  return std::unique_ptr<Irc5Client>(static_cast<Irc5Client*>(link.release()));
}

class SimulatedLinkedCell final : public service::LinkedCell {
 public:
  SimulatedLinkedCell(SimBackend& backend, SimulatedCell& cell,
                      std::unique_ptr<ControllerConnection> link)
      : LinkedCell(std::move(link),
                   std::make_unique<usb1408fs::Usb1408fsReadout>(cell.boardOpener(), cell.psdMap(),
                                                                 cell, simulatedReadout().board,
                                                                 simulatedReadout().psd),
                   cell),
        backend_(backend),
        cell_(cell),
        calibration_(*LinkedCell::calibration(), cell.controller(),
                     cell.options().remote_counter_update) {}
  ControllerCalibration* calibration() override { return &calibration_; }
  std::optional<std::array<double, 4>> truthDeg() const override {
    // The world's offsets and what calibration values applied since moved the zeros by.
    const auto& t = cell_.world().true_offsets_deg;
    const Joints shift = cell_.controller().zeroShiftDeg();
    return std::array<double, 4>{t[1] + shift[1], t[2] + shift[2], t[3] + shift[3],
                                 t[4] + shift[4]};
  }
  std::optional<std::string> truthWorldYaml() const override {
    return truthFile(cell_.world(), backend_.sessionNoiseSeed());
  }
  void beginSession() override { backend_.beginSession(); }
  std::optional<std::uint64_t> truthNoiseSeed() const override {
    return backend_.sessionNoiseSeed();
  }
  void placePsd(int placement, const std::vector<Eigen::Vector3d>& planned_centres_mm) override {
    cell_.controller().placePsd(placement, planned_centres_mm);
  }

 private:
  SimBackend& backend_;
  SimulatedCell& cell_;
  SimCalibration calibration_;
};

}  // namespace

SimBackend::SimBackend(SimulatedCellOptions options, SimLinkFactory link, SessionNoise noise)
    : cell_(std::move(options)), link_(std::move(link)), noise_(noise) {
  // Refused when the daemon starts, not at every session: a link, not connected, shows its kind.
  if (link_) irc5Link(link_({"127.0.0.1", cell_.clientOptions().port, {}}));
}

CellKnowledge SimBackend::knowledge() const {
  const SessionKnowledge k = knowledgeOf(cell_.world());
  return {k.cell, k.taught_centre,
          "simulated bench sweep, fingerprint " + cell_.psdMap().fingerprint()};
}

std::unique_ptr<ConnectedCell> SimBackend::connect() {
  const Irc5Options own = cell_.clientOptions();
  if (!link_)
    return std::make_unique<SimulatedLinkedCell>(*this, cell_, std::make_unique<Irc5Client>(own));
  return std::make_unique<SimulatedLinkedCell>(
      *this, cell_, irc5Link(link_({own.host, own.port, own.backoff_initial})));
}

std::optional<std::uint64_t> SimBackend::beginSession() {
  if (!noise_.first) return std::nullopt;
  session_seed_ =
      zerocal::sessionNoiseSeed(*noise_.first, noise_.sessions_before + sessions_begun_);
  ++sessions_begun_;
  cell_.reseedNoise(*session_seed_);
  return session_seed_;
}

class ExternalSimBackend::Cell final : public service::LinkedCell {
  // A restart of zerocal-sim drops every connection, the beam-spot link's too: it reconnects
  // with the controller link, or the PSD would read no light from then on.
  class Calibration final : public ControllerCalibration {
   public:
    Calibration(ControllerCalibration& link, Cell& cell) : link_(link), cell_(cell) {}
    std::array<double, 6> readCalOffsets() override { return link_.readCalOffsets(); }
    void writeCalOffset(int joint, double rad) override { link_.writeCalOffset(joint, rad); }
    std::array<double, 6> readMotorAngles() override { return link_.readMotorAngles(); }
    void restart() override {
      link_.restart();
      cell_.spot_link_->reconnect();
    }

   private:
    ControllerCalibration& link_;
    Cell& cell_;
  };

 public:
  Cell(ExternalSimBackend& backend, std::unique_ptr<Irc5Client> spot_link)
      : LinkedCell(irc5Link(backend.options_.link(backend.options_.at)),
                   std::make_unique<usb1408fs::Usb1408fsReadout>(
                       FakeTransport::opener(backend.board_), backend.map_, backend.clock_,
                       simulatedReadout().board, simulatedReadout().psd),
                   backend.clock_),
        backend_(backend),
        spot_link_(std::move(spot_link)),
        calibration_(*LinkedCell::calibration(), *this),
        reader_(LinkedCell::psd(), backend.spot_failure_) {
    backend_.spot_link_ = spot_link_.get();
  }
  ControllerCalibration* calibration() override { return &calibration_; }
  ~Cell() override { backend_.spot_link_ = nullptr; }

  PsdReader& psd() override { return reader_; }
  void reconnectRobot() override {
    LinkedCell::reconnectRobot();
    spot_link_->reconnect();
  }
  // A reading that failed on the spot link is mended by that link, not by the board.
  void reopenPsd() override {
    LinkedCell::reopenPsd();
    spot_link_->reconnect();
  }
  std::optional<std::array<double, 4>> truthDeg() const override {
    const auto& t = backend_.options_.world.true_offsets_deg;
    return std::array<double, 4>{t[1], t[2], t[3], t[4]};
  }
  std::optional<std::string> truthWorldYaml() const override {
    return truthFile(backend_.options_.world);
  }
  void placePsd(int placement, const std::vector<Eigen::Vector3d>&) override {
    if (placement != 1) throw Error(kExternalPlacements);
  }

 private:
  // The board is lit where zerocal-sim says the beam is, asked over the spot link: a reading
  // taken while that link failed is no reading, not a dark detector (which the servo would take
  // for a spot not found, and offer to skip a good pose), and it names the link.
  class SpotLinkedReader final : public PsdReader {
   public:
    SpotLinkedReader(PsdReader& inner, std::string& failure) : inner_(inner), failure_(failure) {}
    PsdReading read() override {
      failure_.clear();
      const PsdReading reading = inner_.read();
      if (!failure_.empty())
        throw LinkError(LinkError::Kind::kTransient,
                        "the link to the simulated controller that says where the beam meets the "
                        "PSD failed: " +
                            failure_);
      return reading;
    }

   private:
    PsdReader& inner_;
    std::string& failure_;
  };

  ExternalSimBackend& backend_;
  std::unique_ptr<Irc5Client> spot_link_;
  Calibration calibration_;
  SpotLinkedReader reader_;
};

ExternalSimBackend::ExternalSimBackend(ExternalSimOptions options)
    : options_(std::move(options)),
      psd_(options_.psd),
      board_(options_.board_seed),
      map_(simulatedPsdMap(options_.psd, options_.sweep_half_width_mm, options_.sweep_step_mm)) {
  if (!options_.link) throw std::invalid_argument("ExternalSimOptions: no link to zerocal-sim");
  irc5Link(options_.link(options_.at));  // the kind is refused here, before any session
  board_.setAnalogSource(psdAnalogSource(psd_, [this](double) -> std::optional<PsdSpot> {
    // Called on the session's thread, between the servo's requests on the other link. A lost
    // spot link is no light to the board, and a failed reading to the cell's reader
    // (SpotLinkedReader), which reconnects it.
    if (spot_link_ == nullptr) return std::nullopt;
    try {
      return spot_link_->readSimBeamSpot();
    } catch (const std::exception& e) {
      if (spot_failure_.empty()) spot_failure_ = e.what();
      return std::nullopt;
    }
  }));
}

ExternalSimBackend::~ExternalSimBackend() = default;

std::string ExternalSimBackend::placementsRefusal() const { return kExternalPlacements; }

CellKnowledge ExternalSimBackend::knowledge() const {
  const SessionKnowledge k = knowledgeOf(options_.world);
  return {k.cell, k.taught_centre, "simulated bench sweep, fingerprint " + map_.fingerprint()};
}

std::unique_ptr<ConnectedCell> ExternalSimBackend::connect() {
  auto spot_link = irc5Link(options_.link(options_.at));
  spot_link->connect();
  const SimWorldId theirs = spot_link->readSimWorldId();
  const std::string ours = worldHash(options_.world);
  if (theirs.hash != ours) {
    const std::string where = options_.at.host + ":" + std::to_string(options_.at.port);
    throw ConfigError(
        "backend.sim_host",
        {"the zerocal-sim at " + where + " simulates world " + theirs.hash + " (its --seed " +
         std::to_string(theirs.seed) + "), this daemon's is " + ours + " (" +
         options_.world_source + "): start zerocal-sim with the same --seed or --world"});
  }
  return std::make_unique<Cell>(*this, std::move(spot_link));
}

}  // namespace zerocal::sim
