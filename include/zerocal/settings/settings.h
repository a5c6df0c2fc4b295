// The parts a configuration section is made of, for zerocald's configuration (zerocal/daemon/
// config.h) and for the sections that the controller and DAQ kinds own (zerocal/cell/
// controller_kind.h, zerocal/cell/daq_kind.h): a key bound to a member, parsed from YAML and
// written to JSON; the checks of a whole configuration, each problem pointing at where its key was
// set; and the sections of every kind of one family (controllers, acquisition boards), each
// owning its options.
#pragma once

#include <array>
#include <chrono>
#include <cstdint>
#include <functional>
#include <limits>
#include <map>
#include <memory>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>
#include <utility>
#include <vector>

namespace YAML {
class Node;
}

namespace zerocal::settings {

// One key of a schema. The setter parses completely before it assigns, so a wrong value never
// leaves a half-changed member behind; it returns the reason for refusing, or "". Relative paths
// are resolved against `base_dir`, the folder of the file that set them.
struct Field {
  std::string path;
  std::function<std::string(const YAML::Node&, const std::string& base_dir)> set;
  std::function<nlohmann::json()> get;
};
using Fields = std::vector<Field>;

// What a YAML value is, for messages: "'abc'", "a list", "a mapping", "no value".
std::string describe(const YAML::Node& node);

// Keys bound to members; the member types name the units (docs/configuration.md).
// An integer member of any width; a value that does not fit it is refused.
template <class T>
Field integerField(std::string path, T& target);
Field millisField(std::string path, std::chrono::milliseconds& target);
// A key in seconds (a number) for a member in milliseconds; fractions of a millisecond are cut
// off, as the timers that use the member count whole milliseconds.
Field secondsField(std::string path, std::chrono::milliseconds& target);
// A key in KiB for a member in bytes.
Field kibField(std::string path, std::size_t& target_bytes);
Field realField(std::string path, double& target);
Field textField(std::string path, std::string& target);
// A file or folder name; relative names are resolved against the folder of the file that wrote
// them, so a drop-in can name a neighbour. `keep` is a word that is not a path ("builtin").
Field pathField(std::string path, std::string& target, std::string keep = {});
Field seedField(std::string path, std::optional<std::uint64_t>& target);
Field vec3Field(std::string path, std::array<double, 3>& target);

// One of a few words for an enumeration.
template <class E>
using Choices = std::vector<std::pair<std::string, E>>;
template <class E>
Field choiceField(std::string path, E& target, Choices<E> choices);

// The parsing the templates share: a whole decimal integer; the node is the plain word `word`.
bool parseInteger(const YAML::Node& node, long long& value);
bool isWord(const YAML::Node& node, const std::string& word);
std::string integerRefusal(const YAML::Node& node, long long lo, long long hi, bool parsed);

// Where each key was last set ("file:line", "command line '...'"), so that a check can point at it.
using Origins = std::map<std::string, std::string>;

// The range and consistency checks of a configuration: each failure is one problem, prefixed
// with where the key was set ("default" when no layer set it).
class Checker {
 public:
  Checker(const Origins& origins, std::vector<std::string>& problems)
      : origins_(origins), problems_(problems) {}

  void fail(const std::string& path, const std::string& message);
  // lo <= value <= hi, or lo < value when open_low.
  void range(const std::string& path, double value, double lo, double hi, bool open_low = false);
  void positive(const std::string& path, double value, double hi) {
    range(path, value, 0.0, hi, true);
  }
  void fileExists(const std::string& path, const std::string& file);

 private:
  const Origins& origins_;
  std::vector<std::string>& problems_;
};

// A number as a message shows it (the shortest form that reads back: 0.5, 1e+06).
std::string numberText(double value);

// A section owned by one kind of a family (controller.irc5, daq.usb-1408fs): its keys and checks.
class KindSection {
 public:
  virtual ~KindSection() = default;
  // The section's keys, each `prefix` + its own name ("controller.irc5." + "host"), bound to
  // this object's members.
  virtual void declare(const std::string& prefix, Fields& fields) = 0;
  // The section's range and consistency checks, with its keys under `prefix`. `real_cell`: the
  // configuration drives a real cell (the hardware backend), so addresses and devices must be
  // named.
  virtual void check(const std::string& prefix, bool real_cell, Checker& check) const = 0;
};

// The sections of every kind of one family, by kind name, each with its own options: a
// configuration holds them all (a drop-in may set a kind's keys before another layer picks it),
// and uses the one its `kind` names. Copies are deep: a configuration is a value.
template <class Section>
class KindSections {
 public:
  KindSections() = default;
  KindSections(const KindSections& other) {
    for (const auto& [name, section] : other.sections_)
      sections_.emplace_back(name, section->clone());
  }
  KindSections& operator=(const KindSections& other) {
    if (this != &other) {
      KindSections copy(other);
      sections_.swap(copy.sections_);
    }
    return *this;
  }
  KindSections(KindSections&&) noexcept = default;
  KindSections& operator=(KindSections&&) noexcept = default;

  void add(std::string name, std::unique_ptr<Section> section) {
    sections_.emplace_back(std::move(name), std::move(section));
  }
  Section* find(const std::string& name) noexcept {
    for (auto& [n, s] : sections_)
      if (n == name) return s.get();
    return nullptr;
  }
  const Section* find(const std::string& name) const noexcept {
    for (const auto& [n, s] : sections_)
      if (n == name) return s.get();
    return nullptr;
  }
  // The section of kind `name` as its own type; nullptr when there is none of that type.
  template <class T>
  T* get(const std::string& name) noexcept {
    return dynamic_cast<T*>(find(name));
  }
  template <class T>
  const T* get(const std::string& name) const noexcept {
    return dynamic_cast<const T*>(find(name));
  }
  std::vector<std::string> names() const {
    std::vector<std::string> out;
    for (const auto& entry : sections_) out.push_back(entry.first);
    return out;
  }
  // Every kind's keys under `family` ("controller" -> "controller.irc5.host", ...).
  void declare(const std::string& family, Fields& fields) {
    for (auto& [name, section] : sections_) section->declare(family + "." + name + ".", fields);
  }

 private:
  std::vector<std::pair<std::string, std::unique_ptr<Section>>> sections_;
};

template <class T>
Field integerField(std::string path, T& target) {
  return {std::move(path),
          [&target](const YAML::Node& node, const std::string&) -> std::string {
            long long value = 0;
            const bool parsed = parseInteger(node, value);
            // Compared as long long: the widest member types (std::size_t) are capped there.
            constexpr long long lo = static_cast<long long>(std::numeric_limits<T>::min());
            constexpr long long hi =
                std::numeric_limits<T>::max() >
                        static_cast<unsigned long long>(std::numeric_limits<long long>::max())
                    ? std::numeric_limits<long long>::max()
                    : static_cast<long long>(std::numeric_limits<T>::max());
            if (!parsed || value < lo || value > hi) return integerRefusal(node, lo, hi, parsed);
            target = static_cast<T>(value);
            return {};
          },
          [&target] { return nlohmann::json(target); }};
}

template <class E>
Field choiceField(std::string path, E& target, Choices<E> choices) {
  return {std::move(path),
          [&target, choices](const YAML::Node& node, const std::string&) -> std::string {
            std::string list;
            for (const auto& [name, value] : choices) {
              if (isWord(node, name)) {
                target = value;
                return {};
              }
              list += (list.empty() ? "" : ", ") + name;
            }
            return "expected one of " + list + ", got " + describe(node);
          },
          [&target, choices] {
            for (const auto& [name, value] : choices)
              if (value == target) return nlohmann::json(name);
            return nlohmann::json("?");
          }};
}

}  // namespace zerocal::settings
