#include "zerocal/cell/kinds.h"

#include <stdexcept>

#include "zerocal/irc5/irc5_kind.h"
#include "zerocal/usb1408fs/usb1408fs_kind.h"

namespace zerocal::kinds {
namespace {

// The built-in kinds: a new controller or board is one line here.
std::vector<ControllerKind>& controllers() {
  static std::vector<ControllerKind> kinds = {irc5::controllerKind()};
  return kinds;
}

std::vector<DaqKind>& daqs() {
  static std::vector<DaqKind> kinds = {usb1408fs::daqKind()};
  return kinds;
}

template <class Kind>
void add(std::vector<Kind>& kinds, Kind kind) {
  for (const Kind& k : kinds)
    if (k.name == kind.name) throw std::invalid_argument("a kind named " + kind.name + " exists");
  kinds.push_back(std::move(kind));
}

template <class Kind>
std::string namesOf(const std::vector<Kind>& kinds) {
  std::string names;
  for (const Kind& k : kinds) names += (names.empty() ? "" : ", ") + k.name;
  return names;
}

template <class Section, class Kind>
settings::KindSections<Section> sectionsOf(const std::vector<Kind>& kinds) {
  settings::KindSections<Section> sections;
  for (const Kind& k : kinds) sections.add(k.name, k.defaults());
  return sections;
}

}  // namespace

const std::vector<ControllerKind>& controllerKinds() { return controllers(); }
const std::vector<DaqKind>& daqKinds() { return daqs(); }
void registerControllerKind(ControllerKind kind) { add(controllers(), std::move(kind)); }
void registerDaqKind(DaqKind kind) { add(daqs(), std::move(kind)); }
std::string controllerKindNames() { return namesOf(controllers()); }
std::string daqKindNames() { return namesOf(daqs()); }

settings::KindSections<ControllerSettings> controllerSections() {
  return sectionsOf<ControllerSettings>(controllers());
}
settings::KindSections<DaqSettings> daqSections() { return sectionsOf<DaqSettings>(daqs()); }

}  // namespace zerocal::kinds
