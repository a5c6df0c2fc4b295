#include "zerocal/model/robot.h"

#include <gtest/gtest.h>

#include <cmath>

#include "zerocal/error.h"
#include "zerocal/model/builtin.h"

namespace zerocal {
namespace {

TEST(RobotFile, ShippedIrb1600Parses) {
  const Robot r = builtinIrb1600();
  EXPECT_EQ(r.name, "ABB IRB 1600-10/1.45");
  EXPECT_DOUBLE_EQ(r.limits[2].lower_deg, -245);
  EXPECT_DOUBLE_EQ(r.max_speed_deg_s[5], 460);
}

TEST(RobotFile, ReportsEveryProblemAtOnce) {
  const std::string yaml = R"(
joints:
  - {a_mm: 150, alpha_deg: -90, d_mm: x, theta_offset_deg: 0, lower_deg: 10, upper_deg: -10, max_speed_deg_s: 180}
  - {a_mm: 700, alpha_deg: 0, d_mm: 0, theta_offset_deg: -90, lower_deg: -90, upper_deg: 120, max_speed_deg_s: 0}
  - {a_mm: 0, alpha_deg: -90, d_mm: 0, theta_offset_deg: 0, lower_deg: -245, upper_deg: 65, max_speed_deg_s: 185}
  - {a_mm: 0, alpha_deg: 90, d_mm: 600, theta_offset_deg: 0, lower_deg: -200, upper_deg: 200, max_speed_deg_s: 385}
  - {a_mm: 0, alpha_deg: -90, d_mm: 0, theta_offset_deg: 0, lower_deg: -115, upper_deg: 115}
  - {a_mm: 0, alpha_deg: 0, d_mm: 65, theta_offset_deg: 180, lower_deg: -400, upper_deg: 400, max_speed_deg_s: 460, colour: red}
)";
  try {
    parseRobot(yaml, "bad.yaml");
    FAIL() << "expected ConfigError";
  } catch (const ConfigError& e) {
    const auto& p = e.problems();
    auto has = [&](const std::string& s) {
      for (const auto& x : p)
        if (x.find(s) != std::string::npos) return true;
      return false;
    };
    EXPECT_TRUE(has("missing 'name'"));
    EXPECT_TRUE(has("joint 1: 'd_mm' is not a number"));
    EXPECT_TRUE(has("joint 1: lower_deg must be below upper_deg"));
    EXPECT_TRUE(has("joint 2: max_speed_deg_s must lie within 0.1..2000"));
    EXPECT_TRUE(has("joint 5: missing 'max_speed_deg_s'"));
    EXPECT_TRUE(has("joint 6: unknown key 'colour'"));
    EXPECT_EQ(p.size(), 6u);
  }
}

TEST(RobotFile, AbsurdLimitsSpeedsAndLinksAreRefused) {
  std::string yaml = "name: wide\njoints:\n";
  for (int i = 0; i < kJointCount; ++i)
    yaml += i == 0 ? "  - {a_mm: 0, alpha_deg: 0, d_mm: 1e9, theta_offset_deg: 0, lower_deg: "
                     "-1e308, upper_deg: 1e308, max_speed_deg_s: 1e-300}\n"
                   : "  - {a_mm: 0, alpha_deg: 0, d_mm: 0, theta_offset_deg: 0, lower_deg: -10, "
                     "upper_deg: 10, max_speed_deg_s: 100}\n";
  try {
    parseRobot(yaml, "wide.yaml");
    FAIL() << "expected ConfigError";
  } catch (const ConfigError& e) {
    const std::string all = e.what();
    EXPECT_NE(all.find("joint 1: lower_deg must lie within +-720"), std::string::npos) << all;
    EXPECT_NE(all.find("joint 1: upper_deg must lie within +-720"), std::string::npos) << all;
    EXPECT_NE(all.find("joint 1: d_mm must lie within +-10000"), std::string::npos) << all;
    EXPECT_NE(all.find("joint 1: max_speed_deg_s must lie within"), std::string::npos) << all;
    EXPECT_EQ(e.problems().size(), 4u);
  }
}

TEST(RobotFile, TransmissionsAreSignedAndUnconfirmedInTheShippedFile) {
  const Robot r = builtinIrb1600();
  for (double k : r.transmission) EXPECT_GE(std::abs(k), 1.0);
  EXPECT_FALSE(r.transmission_confirmed);  // placeholders: docs/apply.md
  std::string yaml = builtinIrb1600Yaml();
  yaml.replace(yaml.find("transmission: +120"), 18, "transmission: -117.5");
  yaml.replace(yaml.find("transmission_confirmed: false"), 29, "transmission_confirmed: true");
  const Robot m = parseRobot(yaml, "m.yaml");
  EXPECT_EQ(m.transmission[0], -117.5);
  EXPECT_TRUE(m.transmission_confirmed);
  // A magnitude without its sign, a ratio below 1, a flag that is not a boolean.
  std::string bad = builtinIrb1600Yaml();
  bad.replace(bad.find("transmission: +120"), 18, "transmission: 120");
  bad.replace(bad.find("transmission: +80"), 17, "transmission: +0.5");
  bad.replace(bad.find("transmission_confirmed: false"), 29, "transmission_confirmed: maybe");
  try {
    parseRobot(bad, "bad.yaml");
    FAIL() << "expected ConfigError";
  } catch (const ConfigError& e) {
    const std::string what = e.what();
    EXPECT_NE(what.find("joint 1: 'transmission' must be written with its sign"), std::string::npos)
        << what;
    EXPECT_NE(what.find("joint 4: 'transmission' must be at least 1 in magnitude"),
              std::string::npos)
        << what;
    EXPECT_NE(what.find("'transmission_confirmed' must be true or false"), std::string::npos);
    EXPECT_EQ(e.problems().size(), 3u);
  }
}

TEST(RobotFile, WrongJointCountAndBadYaml) {
  EXPECT_THROW(parseRobot("name: x\njoints: []\n", "a"), ConfigError);
  EXPECT_THROW(parseRobot("name: [unclosed\n", "b"), ConfigError);
  EXPECT_THROW(loadRobot("/nonexistent/robot.yaml"), ConfigError);
}

TEST(RobotFile, LimitViolationNamesTheJoint) {
  const Robot r = builtinIrb1600();
  EXPECT_TRUE(r.withinLimits(Joints{}));
  EXPECT_EQ(r.limitViolation(Joints{0, 0, 70, 0, 0, 0}).rfind("joint 3 = 70", 0), 0u);
  EXPECT_FALSE(r.withinLimits(Joints{0, 0, 63, 0, 0, 0}, 5.0));
}

}  // namespace
}  // namespace zerocal
