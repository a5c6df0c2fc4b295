// zerocal-lab apply on a session folder made as zerocald makes one and a MOC.cfg fixture: the
// values written are the formula's, nothing else changes, and every refusal writes nothing.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <sstream>

#include "apply_file_command.h"
#include "session_fixture.h"
#include "zerocal/apply/moc_file.h"
#include "zerocal/apply/motor_calibration.h"
#include "zerocal/model/builtin.h"
#include "zerocal/report/session_report.h"

namespace zerocal {
namespace {

namespace fs = std::filesystem;

std::string readText(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  std::stringstream s;
  s << in.rdbuf();
  return s.str();
}

class ApplyCommand : public ::testing::Test {
 protected:
  void SetUp() override {
    session_ = test::makeSession(::testing::UnitTest::GetInstance()->current_test_info()->name());
    args_.session_dir = session_;
    args_.moc_file = std::string(ZEROCAL_APPLY_DATA) + "/irb1600_rw6.cfg";
    args_.out_file = session_ + "/MOC.new.cfg";
    args_.robot = "builtin";
    args_.unconfirmed_transmission = true;
  }
  int run() {
    out_.str("");
    err_.str("");
    return lab::runApplyFile(args_, out_, err_);
  }
  std::string session_;
  lab::ApplyFileArgs args_;
  std::ostringstream out_, err_;
};

TEST_F(ApplyCommand, WritesTheFormulasValuesAndNothingElse) {
  ASSERT_EQ(run(), 0) << err_.str();
  const report::SessionReport s = report::parseSession(report::readSessionFiles(session_));
  const apply::MocFile before = apply::readMocFile(args_.moc_file);
  const apply::MocFile after = apply::readMocFile(args_.out_file);
  const Robot robot = builtinIrb1600();
  std::string expected = before.text;
  for (int j = 2; j <= 5; ++j) {
    const std::string inst = "rob1_" + std::to_string(j);
    double delta_deg = 0;
    for (const auto& p : s.parameters)
      if (p.name == "delta" + std::to_string(j) + "_deg") delta_deg = p.value;
    const apply::CalOffsetChange c =
        apply::calOffsetChange(j, delta_deg / 57.29577951308232, robot.transmission[j - 1],
                               apply::presentCalOffset(before, inst));
    EXPECT_NEAR(apply::presentCalOffset(after, inst), c.new_rad, 5e-6) << inst;
    EXPECT_NE(out_.str().find(apply::formulaText(c)), std::string::npos) << out_.str();
    // The expected file: the backup with this one value replaced.
    const apply::MocAttribute* a = before.find("MOTOR_CALIB", inst)->find("cal_offset");
    const std::string old_text = "-cal_offset " + *a->value;
    const auto at = expected.find(old_text);
    ASSERT_NE(at, std::string::npos);
    expected.replace(at, old_text.size(), "-cal_offset " + apply::mocNumber(c.new_rad));
  }
  EXPECT_EQ(after.text, expected);
  EXPECT_NE(out_.str().find("NOT CONFIRMED"), std::string::npos);
  EXPECT_NE(out_.str().find("Taught positions"), std::string::npos);
  EXPECT_NE(out_.str().find("MOTOR_CALIB \"rob1_5\""), std::string::npos);
  // Recorded beside the session's result.
  const std::string record = readText(session_ + "/apply.jsonl");
  EXPECT_NE(record.find("\"format\":\"zerocal-apply-file/1\""), std::string::npos) << record;
  EXPECT_NE(record.find("\"joint\":5"), std::string::npos);
}

TEST_F(ApplyCommand, RefusesUnconfirmedTransmissionsUnlessAccepted) {
  args_.unconfirmed_transmission = false;
  EXPECT_EQ(run(), 2);
  EXPECT_NE(err_.str().find("placeholders to be confirmed"), std::string::npos) << err_.str();
  EXPECT_FALSE(fs::exists(args_.out_file));
}

TEST_F(ApplyCommand, RefusesAnotherRobotsBackupAnExistingOutputAndABadFile) {
  std::string other = readText(args_.moc_file);
  other.replace(other.find("ROB1_1600_1.45_10"), 17, "ROB1_120_0.58_3");
  const std::string other_file = session_ + "/other.cfg";
  std::ofstream(other_file, std::ios::binary) << other;
  args_.moc_file = other_file;
  EXPECT_EQ(run(), 2);
  EXPECT_NE(err_.str().find("backup of a ROB1_120_0.58_3"), std::string::npos) << err_.str();
  EXPECT_FALSE(fs::exists(args_.out_file));

  std::string bad = readText(std::string(ZEROCAL_APPLY_DATA) + "/irb1600_rw6.cfg");
  bad.replace(bad.find("MOTOR_CALIB:"), 12, "MOTOR CALIB");
  std::ofstream(other_file, std::ios::binary | std::ios::trunc) << bad;
  EXPECT_EQ(run(), 2);
  EXPECT_NE(err_.str().find("not understood: 'MOTOR CALIB'"), std::string::npos) << err_.str();
  EXPECT_NE(err_.str().find("Nothing was written"), std::string::npos);
  EXPECT_FALSE(fs::exists(args_.out_file));

  args_.moc_file = std::string(ZEROCAL_APPLY_DATA) + "/irb1600_rw6.cfg";
  std::ofstream(args_.out_file) << "keep me";
  EXPECT_EQ(run(), 2);
  EXPECT_NE(err_.str().find("exists"), std::string::npos);
  EXPECT_EQ(readText(args_.out_file), "keep me");
}

// zerocald's session.json holds its configuration as it loaded it: the robot file is
// config.controller.robot, which is where the command looks without --robot.
TEST_F(ApplyCommand, TakesTheRobotOfTheDaemonsConfigurationSnapshot) {
  const std::string path = session_ + "/session.json";
  nlohmann::json session = nlohmann::json::parse(readText(path));
  session["config"] = {{"controller", {{"robot", "builtin"}}}};
  std::ofstream(path, std::ios::binary | std::ios::trunc) << session.dump();
  args_.robot.clear();
  EXPECT_EQ(run(), 0) << err_.str();
  EXPECT_TRUE(fs::exists(args_.out_file));
  EXPECT_NE(out_.str().find("built-in IRB 1600-10/1.45"), std::string::npos) << out_.str();

  session["config"] = nlohmann::json::object();
  std::ofstream(path, std::ios::binary | std::ios::trunc) << session.dump();
  fs::remove(args_.out_file);
  EXPECT_EQ(run(), 2);
  EXPECT_NE(err_.str().find("no config.controller.robot; give the robot file with --robot"),
            std::string::npos)
      << err_.str();
  EXPECT_FALSE(fs::exists(args_.out_file));
}

TEST_F(ApplyCommand, ARobotFileWithoutTransmissionIsRefused) {
  std::string yaml = builtinIrb1600Yaml();
  std::size_t at;
  while ((at = yaml.find(", transmission: +")) != std::string::npos)
    yaml.erase(at, yaml.find('}', at) - at);
  args_.robot = session_ + "/robot.yaml";
  std::ofstream(args_.robot) << yaml;
  EXPECT_EQ(run(), 2);
  EXPECT_NE(err_.str().find("joint 2: the robot file"), std::string::npos) << err_.str();
  EXPECT_NE(err_.str().find("gives no transmission"), std::string::npos);
}

}  // namespace
}  // namespace zerocal
