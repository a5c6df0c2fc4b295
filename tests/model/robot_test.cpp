#include "zerocal/model/robot.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <utility>
#include <vector>

#include "zerocal/error.h"
#include "zerocal/model/builtin.h"
#include "zerocal/model/kinematics.h"

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
    EXPECT_TRUE(has("missing 'model_tolerance'"));
    EXPECT_EQ(p.size(), 7u);
  }
}

TEST(RobotFile, AbsurdLimitsSpeedsAndLinksAreRefused) {
  std::string yaml = "name: wide\nmodel_tolerance: {length_mm: 0, angle_deg: 0}\njoints:\n";
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

// Every number is bounded by what an arm can have, and each refusal names file, line and key.
TEST(RobotFile, AnglesLengthsAndTransmissionsNoArmHasAreRefusedWithTheirLine) {
  std::string yaml = builtinIrb1600Yaml();
  yaml.replace(yaml.find("alpha_deg: -90"), 14, "alpha_deg: 1e20");
  yaml.replace(yaml.find("theta_offset_deg: -90"), 21, "theta_offset_deg: 1e17");
  yaml.replace(yaml.find("transmission: +80"), 17, "transmission: +1e300");
  yaml.replace(yaml.find("transmission: +50"), 17, "transmission: -1000.5");
  const auto lineOf = [&yaml](const std::string& text) {
    const std::string before = yaml.substr(0, yaml.find(text));
    return std::to_string(std::count(before.begin(), before.end(), '\n') + 1);
  };
  try {
    parseRobot(yaml, "big.yaml");
    FAIL() << "expected ConfigError";
  } catch (const ConfigError& e) {
    const std::string what = e.what();
    for (const std::string& expected :
         {"big.yaml:" + lineOf("alpha_deg: 1e20") + ": joint 1: alpha_deg must lie within +-360",
          "big.yaml:" + lineOf("theta_offset_deg: 1e17") +
              ": joint 2: theta_offset_deg must lie within +-360",
          "big.yaml:" + lineOf("+1e300") + ": joint 4: 'transmission' must be at most 1000",
          "big.yaml:" + lineOf("-1000.5") + ": joint 6: 'transmission' must be at most 1000"})
      EXPECT_NE(what.find(expected), std::string::npos) << expected << " in " << what;
    EXPECT_EQ(e.problems().size(), 4u) << what;
  }
  // The shipped file's ratios (50..120) and the bounds themselves are an arm's.
  std::string edge = builtinIrb1600Yaml();
  edge.replace(edge.find("transmission: +50"), 17, "transmission: -1000");
  edge.replace(edge.find("alpha_deg: -90"), 14, "alpha_deg: -360");
  EXPECT_NO_THROW(parseRobot(edge, "edge.yaml"));
}

// Keys that are lists or maps, sections of the wrong kind: problems, never a parser's exception.
TEST(RobotFile, AnyShapeOfFileIsAConfigurationError) {
  std::string without_gravity = builtinIrb1600Yaml();
  without_gravity = without_gravity.substr(0, without_gravity.find("\ngravity:") + 1);
  for (const std::string& text :
       {std::string("name: x\n[a]: 1\njoints: []\n"), std::string("name: x\njoints: 5\n"),
        std::string("name: [x]\njoints: [1, 2, 3, 4, 5, 6]\n"),
        without_gravity + "gravity: {masses: [{link: 1e300, kg: 1, at_mm: [0, 0, 0]}]}\n",
        without_gravity + "gravity: {masses: [{link: 2, kg: 1, at_mm: [0, 0, 0], [k]: 1}]}\n",
        without_gravity + "gravity: {[k]: 1}\n"}) {
    try {
      parseRobot(text, "odd.yaml");
      ADD_FAILURE() << "accepted: " << text;
    } catch (const ConfigError& e) {
      EXPECT_EQ(std::string(e.problems().at(0)).rfind("odd.yaml:", 0), 0u) << e.what();
    }
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

namespace zerocal {
namespace {

// A calibrated model written and read back has the same kinematics, sag included.
TEST(RobotFile, ACalibratedModelRoundTripsWithItsKinematics) {
  Robot calibrated = builtinIrb1600();
  ASSERT_TRUE(calibrated.hasGravityModel());
  EXPECT_TRUE(calibrated.masses_inferred);
  const std::array<std::array<double, 3>, kJointCount> errors = {{{0.1, -0.05, 1e-4},
                                                                  {-0.2, 0.0, -2e-4},
                                                                  {0.07, 0.0, 5e-5},
                                                                  {0, 0.12, 0},
                                                                  {0, 0, 0},
                                                                  {0, 0, 0}}};
  for (int j = 0; j < kJointCount; ++j) {
    calibrated.dh[j].a_mm += errors[j][0];
    calibrated.dh[j].d_mm += errors[j][1];
    calibrated.dh[j].alpha_rad += errors[j][2];
  }
  calibrated.identified_link_error = errors;
  calibrated.compliance_deg_per_knm = {0.012, -0.004};
  // A name YAML would read otherwise (a colon, quotes, a backslash, a second line) stays itself.
  calibrated.name = "IRB 1600: \"cell 3\" \\ #2\nrecalibrated";
  const std::string text = robotYaml(calibrated, "calibrated from a test\nsecond line");
  EXPECT_EQ(text.rfind("# calibrated from a test\n# second line\n", 0), 0u) << text;
  const Robot back = parseRobot(text, "saved.yaml");
  EXPECT_EQ(back.name, calibrated.name);
  EXPECT_EQ(back.masses.size(), calibrated.masses.size());
  EXPECT_EQ(back.compliance_deg_per_knm, calibrated.compliance_deg_per_knm);
  EXPECT_EQ(back.transmission, calibrated.transmission);
  for (int j = 0; j < kJointCount; ++j)
    for (int k = 0; k < 3; ++k)
      EXPECT_NEAR(back.identified_link_error[j][k], errors[j][k], 1e-15) << j << " " << k;
  const Joints qs[] = {{0, 0, 0, 0, 0, 0}, {20, 40, -30, 50, -60, 70}, {-45, 80, -100, 10, 90, 0}};
  for (const Joints& q : qs) {
    const Frame<double> a = flangePoseDeg(calibrated, q), b = flangePoseDeg(back, q);
    EXPECT_LT((a.p - b.p).norm(), 1e-9);
    EXPECT_LT((a.R - b.R).norm(), 1e-12);
    // The compliance is in the kinematics: without it the flange is elsewhere.
    Robot stiff = back;
    stiff.compliance_deg_per_knm = {0, 0};
    if (std::abs(gravityTorqueKnm(back, back.masses, q)[0]) > 0.05)
      EXPECT_GT((flangePoseDeg(stiff, q).p - b.p).norm(), 1e-3);
  }
  // The nominal rows are what they were: the errors sit beside them, not in them.
  EXPECT_NE(text.find("a_mm: 150, alpha_deg: -90"), std::string::npos) << text;
  EXPECT_NE(text.find("da_mm: 0.10000000000000001"), std::string::npos) << text;
}

TEST(RobotFile, IdentifiedKinematicsAndMassesAreValidatedAllAtOnce) {
  std::string yaml = builtinIrb1600Yaml();
  // A link error that is a length, a mass on link 1, a negative mass, a compliance list of 3.
  yaml.replace(yaml.find("transmission: +120}"), 19,
               "transmission: +120, da_mm: 150, dalpha_deg: x}");
  yaml.replace(yaml.find("{link: 2, kg: 24"), 16, "{link: 1, kg: 24");
  yaml.replace(yaml.find("kg: 12"), 6, "kg: -12");
  yaml += "compliance_deg_per_knm: [0.01, 0.02, 0.03]\n";
  try {
    parseRobot(yaml, "bad.yaml");
    FAIL() << "expected ConfigError";
  } catch (const ConfigError& e) {
    const std::string what = e.what();
    for (const char* expected :
         {"joint 1: da_mm must lie within +-10", "joint 1: 'dalpha_deg' is not a number",
          "gravity mass 1: 'link' must be a whole number from 2 to 6",
          "gravity mass 3: 'kg' must lie within", "compliance_deg_per_knm: must be a list of 2"})
      EXPECT_NE(what.find(expected), std::string::npos) << expected << " in " << what;
  }
  std::string without_gravity = builtinIrb1600Yaml();
  without_gravity = without_gravity.substr(0, without_gravity.find("\ngravity:") + 1) +
                    "compliance_deg_per_knm: [0.01, 0.02]\n";
  try {
    parseRobot(without_gravity, "no-gravity.yaml");
    FAIL() << "expected ConfigError";
  } catch (const ConfigError& e) {
    EXPECT_NE(std::string(e.what()).find("needs the 'gravity' section"), std::string::npos)
        << e.what();
  }
}

// Joint 3 carries the forearm only and sags less: each joint's sag tolerance is its own. One
// number states both (a model that knows no split); a calibrated model writes both back. A sag has
// gravity's sign: the shipped model states each one's mean beside its RMS, written back as read;
// a mean beyond its RMS (a negative variance) or of the wrong shape is refused.
TEST(RobotFile, EachOfJoints2And3HasItsOwnSagToleranceAndMean) {
  const Robot shipped = builtinIrb1600();
  EXPECT_EQ(shipped.tolerance.sag_deg[0], 0.007);
  EXPECT_EQ(shipped.tolerance.sag_deg[1], 0.0042);
  EXPECT_EQ(shipped.tolerance.sag_mean_deg[0], 0.0065);
  EXPECT_EQ(shipped.tolerance.sag_mean_deg[1], 0.004);
  const Robot back = parseRobot(robotYaml(shipped, "written"), "written.yaml");
  EXPECT_EQ(back.tolerance.sag_deg, shipped.tolerance.sag_deg);
  EXPECT_EQ(back.tolerance.sag_mean_deg, shipped.tolerance.sag_mean_deg);

  const std::string yaml = builtinIrb1600Yaml();
  const std::string rms = "sag_deg: [0.007, 0.0042]", mean = "sag_mean_deg: [0.0065, 0.004]";
  const auto replaced = [&](const std::string& from, const std::string& to) {
    std::string y = yaml;
    y.replace(y.find(from), from.size(), to);
    return y;
  };
  // The sag's RMS alone, no mean.
  const auto with = [&](const std::string& sag) {
    return replaced(rms + "\n  " + mean, "sag_deg: " + sag);
  };
  const Robot both = parseRobot(with("0.005"), "both.yaml");
  EXPECT_EQ(both.tolerance.sag_deg[0], 0.005);
  EXPECT_EQ(both.tolerance.sag_deg[1], 0.005);
  EXPECT_FALSE(anyCounted(both.tolerance.sag_mean_deg));
  std::vector<std::pair<std::string, std::string>> refused;  // the file, the message
  for (const char* bad :
       {"[0.007]", "[0.007, 0.004, 0.001]", "[0.007, -0.001]", "[0.007, x]", "{j2: 0.007}", "2"})
    refused.push_back({with(bad), "'sag_deg' must be a number or a list of 2 numbers"});
  for (const char* bad : {"[0.0075, 0.004]", "0.005"})  // joint 2's RMS 0.007, joint 3's 0.0042
    refused.push_back(
        {replaced(mean, std::string("sag_mean_deg: ") + bad), "must lie within 0..its 'sag_deg'"});
  for (const char* bad : {"[0.0065]", "[0.0065, -0.001]"})
    refused.push_back({replaced(mean, std::string("sag_mean_deg: ") + bad),
                       "'sag_mean_deg' must be a number or a list of 2 numbers"});
  for (const auto& [file, message] : refused) {
    try {
      parseRobot(file, "bad.yaml");
      ADD_FAILURE() << message << ": accepted";
    } catch (const ConfigError& e) {
      EXPECT_NE(std::string(e.what()).find(message), std::string::npos) << e.what();
    }
  }
}

}  // namespace
}  // namespace zerocal
