// The controller and DAQ kinds zerocal knows: the one list that names the vendors
// (src/kinds/kinds.cpp). A new controller is its folder (a ControllerConnection and a
// ControllerSettings), a line in that list and a line in its CMakeLists.txt.
#pragma once

#include <string>
#include <vector>

#include "zerocal/cell/controller_kind.h"
#include "zerocal/cell/daq_kind.h"

namespace zerocal::kinds {

// The kinds a configuration may name, built-in first, then those registered.
const std::vector<ControllerKind>& controllerKinds();
const std::vector<DaqKind>& daqKinds();

// Adds a kind beside the built-in ones (a test's controller speaking a protocol of its own).
// Call it before any configuration is made: a configuration holds the sections of the kinds
// known when it was made. Throws std::invalid_argument for a name already known.
void registerControllerKind(ControllerKind kind);
void registerDaqKind(DaqKind kind);

// A configuration's sections: every known kind's, with its defaults.
settings::KindSections<ControllerSettings> controllerSections();
settings::KindSections<DaqSettings> daqSections();

// The word of every known kind, for messages ("irc5, ur").
std::string controllerKindNames();
std::string daqKindNames();

}  // namespace zerocal::kinds
