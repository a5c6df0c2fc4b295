#include "zerocal/io/json_reader.h"

#include <cmath>

#include "zerocal/error.h"

namespace zerocal {

JsonReader::JsonReader(const nlohmann::json& json, std::string where)
    : json_(json), where_(std::move(where)) {
  if (!json_.is_object()) throw InputError(where_ + ": not an object");
}

bool JsonReader::has(const char* key) const { return json_.contains(key); }

bool JsonReader::present(const char* key) const { return has(key) && !json_.at(key).is_null(); }

const nlohmann::json& JsonReader::at(const char* key) const {
  if (!has(key)) throw InputError(where_ + ": '" + key + "' is missing");
  return json_.at(key);
}

double JsonReader::number(const char* key) const {
  const nlohmann::json& v = at(key);
  if (!v.is_number()) throw InputError(where_ + ": '" + key + "' is not a number");
  return v.get<double>();
}

double JsonReader::numberOrNan(const char* key) const {
  return present(key) ? number(key) : std::nan("");
}

std::optional<double> JsonReader::optionalNumber(const char* key) const {
  if (!present(key)) return std::nullopt;
  return number(key);
}

int JsonReader::integer(const char* key) const {
  const nlohmann::json& v = at(key);
  if (!v.is_number_integer()) throw InputError(where_ + ": '" + key + "' is not an integer");
  return v.get<int>();
}

std::int64_t JsonReader::integer64(const char* key) const {
  const nlohmann::json& v = at(key);
  if (!v.is_number_integer()) throw InputError(where_ + ": '" + key + "' is not an integer");
  return v.get<std::int64_t>();
}

bool JsonReader::boolean(const char* key) const {
  const nlohmann::json& v = at(key);
  if (!v.is_boolean()) throw InputError(where_ + ": '" + key + "' is not true or false");
  return v.get<bool>();
}

std::string JsonReader::string(const char* key) const {
  const nlohmann::json& v = at(key);
  if (!v.is_string()) throw InputError(where_ + ": '" + key + "' is not a string");
  return v.get<std::string>();
}

std::string JsonReader::stringOr(const char* key, const std::string& fallback) const {
  return has(key) && json_.at(key).is_string() ? json_.at(key).get<std::string>() : fallback;
}

const nlohmann::json& JsonReader::array(const char* key) const {
  const nlohmann::json& v = at(key);
  if (!v.is_array()) throw InputError(where_ + ": '" + key + "' is not a list");
  return v;
}

std::vector<double> JsonReader::numbers(const char* key, std::size_t count) const {
  return numbersOf(at(key), count, where_ + " " + key);
}

JsonReader JsonReader::object(const char* key) const {
  return JsonReader(at(key), where_ + " " + key);
}

JsonReader JsonReader::element(const char* key, std::size_t i) const {
  return JsonReader(array(key).at(i), where_ + " " + key + "[" + std::to_string(i) + "]");
}

std::vector<double> JsonReader::numbersOf(const nlohmann::json& value, std::size_t count,
                                          const std::string& where) {
  if (!value.is_array() || value.size() != count)
    throw InputError(where + ": expected a list of " + std::to_string(count) + " numbers");
  std::vector<double> out;
  for (const nlohmann::json& v : value) {
    if (v.is_null()) {
      out.push_back(std::nan(""));
      continue;
    }
    if (!v.is_number()) throw InputError(where + ": expected a list of numbers");
    out.push_back(v.get<double>());
  }
  return out;
}

}  // namespace zerocal
