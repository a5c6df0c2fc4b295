#include "zerocal/sim/sim_backend.h"

#include "zerocal/service/linked_cell.h"
#include "zerocal/sim/simulated_rig.h"

namespace zerocal::sim {
namespace {

class SimulatedLinkedCell final : public service::LinkedCell {
 public:
  SimulatedLinkedCell(SimulatedCell& cell, Irc5Options options)
      : LinkedCell(std::move(options), cell.boardOpener(), cell.psdMap(), cell), cell_(cell) {}
  std::optional<std::array<double, 4>> truthDeg() const override {
    const auto& t = cell_.world().true_offsets_deg;
    return std::array<double, 4>{t[1], t[2], t[3], t[4]};
  }

 private:
  const SimulatedCell& cell_;
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
  return std::make_unique<SimulatedLinkedCell>(cell_, std::move(o));
}

}  // namespace zerocal::sim
