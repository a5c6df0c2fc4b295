// Typed reading of the JSON files zerocal writes (session.json, result.json, journal lines): a
// member that is missing or of the wrong type is an InputError naming the file and the member,
// never a crash in nlohmann's operator[]. JSON has no NaN: writers put null for an unknown
// number, and the *OrNan readers give it back.
#pragma once

#include <cmath>
#include <cstdint>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>
#include <vector>

namespace zerocal {

// What a writer puts for a number: null when it is not finite (unknown), which numberOrNan reads
// back as NaN.
inline nlohmann::json numberOrNull(double v) {
  return std::isfinite(v) ? nlohmann::json(v) : nlohmann::json();
}

class JsonReader {
 public:
  // `where` names the object in messages: "result.json", "result.json parameters.delta2_deg".
  JsonReader(const nlohmann::json& json, std::string where);

  bool has(const char* key) const;
  // has(key) and not null.
  bool present(const char* key) const;
  const nlohmann::json& at(const char* key) const;
  double number(const char* key) const;
  double numberOrNan(const char* key) const;
  std::optional<double> optionalNumber(const char* key) const;
  int integer(const char* key) const;
  std::int64_t integer64(const char* key) const;
  bool boolean(const char* key) const;
  std::string string(const char* key) const;
  std::string stringOr(const char* key, const std::string& fallback) const;
  const nlohmann::json& array(const char* key) const;
  // A list of `count` numbers (null: NaN).
  std::vector<double> numbers(const char* key, std::size_t count) const;
  // The member, an object, read with `where` extended by its name.
  JsonReader object(const char* key) const;
  // Element `i` of the list member `key`, an object.
  JsonReader element(const char* key, std::size_t i) const;
  const nlohmann::json& json() const { return json_; }
  const std::string& where() const { return where_; }

  // `value` as a list of `count` numbers (null: NaN); `where` names it.
  static std::vector<double> numbersOf(const nlohmann::json& value, std::size_t count,
                                       const std::string& where);

 private:
  const nlohmann::json& json_;
  std::string where_;
};

}  // namespace zerocal
