#include "zerocal/service/cell_factory.h"

#include "zerocal/model/builtin.h"

namespace zerocal::service {

Robot robotOf(const ControllerConfig& c) {
  return c.robot == "builtin" ? builtinIrb1600() : loadRobot(c.robot);
}

std::unique_ptr<ControllerConnection> makeControllerConnection(const ControllerConfig& config,
                                                               const LinkEndpoint* endpoint) {
  return config.section().link(robotOf(config), endpoint);
}

std::unique_ptr<PsdReadout> makePsdReadout(const DaqConfig& config, const psd::PsdMap& map,
                                           CellClock& clock) {
  return config.board().readout(map, config.psd, clock);
}

}  // namespace zerocal::service
