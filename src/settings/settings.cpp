#include "zerocal/settings/settings.h"

#include <yaml-cpp/yaml.h>

#include <cerrno>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <sstream>

namespace zerocal::settings {
namespace {

namespace fs = std::filesystem;
using Json = nlohmann::json;

// A text value goes into every session's session.json (the configuration's snapshot): it must be
// what JSON can hold, UTF-8, or that snapshot would fail at every session start. Checked by the
// same serializer.
bool isUtf8(const std::string& text) {
  try {
    Json(text).dump();
    return true;
  } catch (const Json::type_error&) {
    return false;
  }
}

bool parseReal(const YAML::Node& node, double& value) {
  if (!node.IsScalar()) return false;
  const std::string& text = node.Scalar();
  if (text.empty()) return false;
  char* end = nullptr;
  value = std::strtod(text.c_str(), &end);
  return end == text.c_str() + text.size();
}

}  // namespace

std::string describe(const YAML::Node& node) {
  switch (node.Type()) {
    case YAML::NodeType::Null:
      return "no value";
    case YAML::NodeType::Sequence:
      return "a list";
    case YAML::NodeType::Map:
      return "a mapping";
    default:
      return "'" + node.Scalar() + "'";
  }
}

bool parseInteger(const YAML::Node& node, long long& value) {
  if (!node.IsScalar()) return false;
  const std::string& text = node.Scalar();
  if (text.empty()) return false;
  errno = 0;
  char* end = nullptr;
  value = std::strtoll(text.c_str(), &end, 10);
  return errno == 0 && end == text.c_str() + text.size();
}

bool isWord(const YAML::Node& node, const std::string& word) {
  return node.IsScalar() && node.Scalar() == word;
}

std::string integerRefusal(const YAML::Node& node, long long lo, long long hi, bool parsed) {
  if (!parsed) return "expected an integer, got " + describe(node);
  return node.Scalar() + " does not fit (" + std::to_string(lo) + ".." + std::to_string(hi) + ")";
}

Field millisField(std::string path, std::chrono::milliseconds& target) {
  return {std::move(path),
          [&target](const YAML::Node& node, const std::string&) -> std::string {
            long long value = 0;
            if (!parseInteger(node, value))
              return "expected an integer (milliseconds), got " + describe(node);
            target = std::chrono::milliseconds(value);
            return {};
          },
          [&target] { return Json(target.count()); }};
}

Field secondsField(std::string path, std::chrono::milliseconds& target) {
  return {std::move(path),
          [&target](const YAML::Node& node, const std::string&) -> std::string {
            double value = 0;
            if (!parseReal(node, value))
              return "expected a number (seconds), got " + describe(node);
            if (!std::isfinite(value) || std::abs(value) > 1e9)
              return "expected a finite number of seconds, got " + describe(node);
            target = std::chrono::duration_cast<std::chrono::milliseconds>(
                std::chrono::duration<double>(value));
            return {};
          },
          [&target] { return Json(std::chrono::duration<double>(target).count()); }};
}

Field kibField(std::string path, std::size_t& target_bytes) {
  return {std::move(path),
          [&target_bytes](const YAML::Node& node, const std::string&) -> std::string {
            long long value = 0;
            if (!parseInteger(node, value))
              return "expected an integer (KiB), got " + describe(node);
            if (value < 0 || value > (1LL << 40))
              return node.Scalar() + " does not fit (0.." + std::to_string(1LL << 40) + ")";
            target_bytes = static_cast<std::size_t>(value) * 1024;
            return {};
          },
          [&target_bytes] { return Json(static_cast<long long>(target_bytes / 1024)); }};
}

Field realField(std::string path, double& target) {
  return {std::move(path),
          [&target](const YAML::Node& node, const std::string&) -> std::string {
            double value = 0;
            if (!parseReal(node, value)) return "expected a number, got " + describe(node);
            if (!std::isfinite(value)) return "expected a finite number, got " + describe(node);
            target = value;
            return {};
          },
          [&target] { return Json(target); }};
}

Field textField(std::string path, std::string& target) {
  return {std::move(path),
          [&target](const YAML::Node& node, const std::string&) -> std::string {
            if (!node.IsScalar()) return "expected a text, got " + describe(node);
            if (!isUtf8(node.Scalar())) return "expected a text in UTF-8";
            target = node.Scalar();
            return {};
          },
          [&target] { return Json(target); }};
}

Field pathField(std::string path, std::string& target, std::string keep) {
  return {std::move(path),
          [&target, keep](const YAML::Node& node, const std::string& base_dir) -> std::string {
            if (!node.IsScalar()) return "expected a path, got " + describe(node);
            if (!isUtf8(node.Scalar())) return "expected a path in UTF-8";
            std::string value = node.Scalar();
            if (!value.empty() && value != keep && fs::path(value).is_relative())
              value = (fs::path(base_dir.empty() ? fs::current_path() : fs::path(base_dir)) / value)
                          .lexically_normal()
                          .string();
            target = value;
            return {};
          },
          [&target] { return Json(target); }};
}

Field seedField(std::string path, std::optional<std::uint64_t>& target) {
  return {std::move(path),
          [&target](const YAML::Node& node, const std::string&) -> std::string {
            // null is a value here: a later layer can take back an earlier layer's seed.
            if (node.IsNull()) {
              target.reset();
              return {};
            }
            long long value = 0;
            if (!parseInteger(node, value) || value < 0)
              return "expected a non-negative integer or null, got " + describe(node);
            target = static_cast<std::uint64_t>(value);
            return {};
          },
          [&target] { return target ? Json(*target) : Json(nullptr); }};
}

Field vec3Field(std::string path, std::array<double, 3>& target) {
  return {std::move(path),
          [&target](const YAML::Node& node, const std::string&) -> std::string {
            const std::string expected = "expected a list of 3 numbers, got ";
            if (!node.IsSequence() || node.size() != 3) {
              return expected + (node.IsSequence() ? "a list of " + std::to_string(node.size())
                                                   : describe(node));
            }
            std::array<double, 3> value{};
            for (std::size_t i = 0; i < 3; ++i)
              if (!parseReal(node[i], value[i]) || !std::isfinite(value[i]))
                return expected + describe(node[i]) + " at position " + std::to_string(i + 1);
            target = value;
            return {};
          },
          [&target] { return Json(target); }};
}

std::string numberText(double value) {
  std::ostringstream s;
  s << value;
  return s.str();
}

void Checker::fail(const std::string& path, const std::string& message) {
  const auto it = origins_.find(path);
  problems_.push_back((it == origins_.end() ? std::string("default") : it->second) + ": " + path +
                      ": " + message);
}

void Checker::range(const std::string& path, double value, double lo, double hi, bool open_low) {
  if (open_low ? !(value > lo) : !(value >= lo)) {
    fail(path, numberText(value) + " must be " + (open_low ? "greater than " : "at least ") +
                   numberText(lo));
  } else if (!(value <= hi)) {
    fail(path, numberText(value) + " must be at most " + numberText(hi));
  }
}

void Checker::fileExists(const std::string& path, const std::string& file) {
  std::error_code ec;
  if (!fs::is_regular_file(file, ec)) fail(path, "no such file: " + file);
}

}  // namespace zerocal::settings
