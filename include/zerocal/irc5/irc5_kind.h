// ABB's IRC5 as a controller kind (zerocal/cell/controller_kind.h): the controller.irc5 section
// of the configuration (the link's Irc5Options: address, timeouts, speeds, limit margin,
// reconnection, restart), its checks, its motion model (zerocal/irc5/motion_time.h) and the
// Irc5Client it makes.
#pragma once

#include <memory>

#include "zerocal/cell/controller_kind.h"
#include "zerocal/irc5/irc5_client.h"

namespace zerocal::irc5 {

// The link's own defaults (Irc5Options) suit a bench that talks to a controller by hand; the
// daemon's cell is closed and its calibration moves are short, so it moves faster and keeps a
// degree clear of the joint limits. Named once here: these are the section's defaults.
Irc5Options configuredDefaults();

class Irc5Settings final : public ControllerSettings {
 public:
  // Members of the options without a key keep the link's own defaults; `robot` is the one
  // controller.robot names, loaded when the link is made.
  Irc5Options options = configuredDefaults();

  std::unique_ptr<ControllerSettings> clone() const override {
    return std::make_unique<Irc5Settings>(*this);
  }
  void declare(const std::string& prefix, settings::Fields& fields) override;
  void check(const std::string& prefix, bool real_cell, settings::Checker& check) const override;
  ControllerMotion motion() const override;
  std::unique_ptr<ControllerConnection> link(const Robot& robot,
                                             const LinkEndpoint* endpoint) const override;
  // The options link() gives its client.
  Irc5Options linkOptions(const Robot& robot, const LinkEndpoint* endpoint) const;
};

// The kind "irc5".
ControllerKind controllerKind();

}  // namespace zerocal::irc5
