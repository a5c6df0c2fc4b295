// The results' three-vectors (targets, centres, their sigmas) as JSON lists of three numbers.
#pragma once

#include <Eigen/Core>
#include <vector>

#include "zerocal/io/json_reader.h"

namespace zerocal {

inline Eigen::Vector3d vector3(const JsonReader& j, const char* key) {
  const std::vector<double> v = j.numbers(key, 3);
  return {v[0], v[1], v[2]};
}

}  // namespace zerocal
