#include "zerocal/daemon/config.h"

#include <gtest/gtest.h>
#include <unistd.h>

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <sstream>

#include "zerocal/error.h"
#include "zerocal/usb1408fs/usb1408fs_kind.h"

namespace zerocal {
namespace {

namespace fs = std::filesystem;

class ConfigTest : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() /
           ("zerocal-config-" + std::to_string(::getpid()) + "-" +
            ::testing::UnitTest::GetInstance()->current_test_info()->name());
    fs::remove_all(dir_);
    fs::create_directories(dir_ / "conf.d");
  }
  void TearDown() override { fs::remove_all(dir_); }

  std::string write(const std::string& name, const std::string& text) {
    const fs::path path = dir_ / name;
    std::ofstream(path) << text;
    return path.string();
  }
  ConfigSources sources(std::vector<std::string> overrides = {}) {
    ConfigSources s;
    s.config_path = (dir_ / "main.yaml").string();
    s.config_path_explicit = true;
    s.drop_in_dir = (dir_ / "conf.d").string();
    s.overrides = std::move(overrides);
    return s;
  }
  // The problems of a load that must fail.
  std::vector<std::string> problems(const ConfigSources& s) {
    try {
      loadDaemonConfig(s);
    } catch (const ConfigError& e) {
      return e.problems();
    }
    ADD_FAILURE() << "the configuration was accepted";
    return {};
  }

  fs::path dir_;
};

// True when exactly one problem contains every fragment.
bool reported(const std::vector<std::string>& problems, std::vector<std::string> fragments) {
  return std::count_if(problems.begin(), problems.end(), [&](const std::string& p) {
           return std::all_of(fragments.begin(), fragments.end(),
                              [&](const std::string& f) { return p.find(f) != std::string::npos; });
         }) == 1;
}

std::string joined(const std::vector<std::string>& problems) {
  std::string text;
  for (const auto& p : problems) text += p + "\n";
  return text;
}

TEST_F(ConfigTest, DefaultsAreValidAndDocumentedValues) {
  const DaemonConfig c;
  EXPECT_TRUE(validateDaemonConfig(c).empty()) << joined(validateDaemonConfig(c));
  EXPECT_EQ(c.servo.tolerance_um, 2.0);
  EXPECT_EQ(c.control.bind_address, "127.0.0.1");
  EXPECT_EQ(c.control.port, 7450);
  EXPECT_EQ(c.session.plan, PlanKind::kOptimal);
}

TEST_F(ConfigTest, MissingDefaultFilesAreFineMissingNamedOnesAreNot) {
  ConfigSources s;
  s.config_path = (dir_ / "absent.yaml").string();
  s.drop_in_dir = (dir_ / "absent.d").string();
  EXPECT_NO_THROW(loadDaemonConfig(s));
  s.config_path_explicit = true;
  s.drop_in_dir_explicit = true;
  const auto p = problems(s);
  EXPECT_EQ(p.size(), 2u) << joined(p);
  EXPECT_TRUE(reported(p, {"absent.yaml", "no such file"})) << joined(p);
  EXPECT_TRUE(reported(p, {"absent.d", "no such folder"})) << joined(p);
}

TEST_F(ConfigTest, LayersApplyInOrderDefaultsFileDropInsCommandLine) {
  write("main.yaml",
        "servo:\n  tolerance_um: 3\n  max_iterations: 20\ncontrol:\n  port: 7000\n"
        "session:\n  poses: 10\n");
  write("conf.d/10-site.yaml", "servo:\n  tolerance_um: 4\ncontrol:\n  port: 7001\n");
  const DaemonConfig c = loadDaemonConfig(sources({"control.port=7002"}));
  EXPECT_EQ(c.servo.max_iterations, 20);  // file over default
  EXPECT_EQ(c.session.poses, 10);
  EXPECT_EQ(c.servo.tolerance_um, 4.0);  // drop-in over file
  EXPECT_EQ(c.control.port, 7002);       // command line over drop-in
  EXPECT_EQ(c.servo.search_radius_mm, DaemonConfig{}.servo.search_radius_mm);  // untouched
}

TEST_F(ConfigTest, DropInsApplyInLexicalOrderAndOnlyYamlFiles) {
  write("main.yaml", "");
  write("conf.d/20-b.yaml", "session:\n  poses: 20\n");
  write("conf.d/10-a.yaml", "session:\n  poses: 10\n  noise_mm: 0.5\n");
  write("conf.d/30-c.yaml", "session:\n  noise_mm: 0.25\n");
  write("conf.d/99-z.yaml.disabled", "session:\n  poses: 99\n");
  write("conf.d/50-notes.txt", "not: yaml at all: [");
  const DaemonConfig c = loadDaemonConfig(sources());
  EXPECT_EQ(c.session.poses, 20);
  EXPECT_EQ(c.session.noise_mm, 0.25);
}

TEST_F(ConfigTest, CommandLineTakesYamlValuesAndNestedKeys) {
  write("main.yaml", "");
  const DaemonConfig c = loadDaemonConfig(
      sources({"session.target_mm=[1, 2.5, -3]", "daq.usb-1408fs.channels.x.number=1",
               "daq.usb-1408fs.channels.y.number=2", "daq.usb-1408fs.channels.sum.number=3",
               "daq.usb-1408fs.channels.sum.mode=differential", "backend.kind=sim",
               "backend.sim_seed=42", "logging.level=debug"}));
  EXPECT_EQ(c.session.target_mm, (std::array<double, 3>{1, 2.5, -3}));
  EXPECT_EQ(usb1408fs::boardSettingsOf(c.daq.boards).channels.sum.number, 3);
  EXPECT_EQ(c.backend.kind, BackendKind::kSim);
  EXPECT_EQ(c.backend.sim_seed, 42u);
  EXPECT_EQ(c.logging.level, LogLevel::kDebug);
}

TEST_F(ConfigTest, PsdChannelsMustBeConsecutiveInputsInScanOrder) {
  write("main.yaml", "");
  const auto p = problems(
      sources({"daq.usb-1408fs.channels.x.number=1", "daq.usb-1408fs.channels.y.number=0"}));
  EXPECT_TRUE(reported(p, {"daq.usb-1408fs.channels", "consecutive inputs"})) << joined(p);
  EXPECT_EQ(p.size(), 1u) << joined(p);
  EXPECT_NO_THROW(loadDaemonConfig(
      sources({"daq.usb-1408fs.channels.x.number=1", "daq.usb-1408fs.channels.y.number=2",
               "daq.usb-1408fs.channels.sum.number=3"})));
}

TEST_F(ConfigTest, EmptySectionsAndFilesChangeNothing) {
  write("main.yaml", "# all commented out\n");
  write("conf.d/10.yaml", "servo:\n  # tolerance_um: 1\nsession:\n");
  EXPECT_EQ(configToJson(loadDaemonConfig(sources())), configToJson(DaemonConfig{}));
}

TEST_F(ConfigTest, LaterLayerCanClearTheSeed) {
  write("main.yaml", "backend:\n  kind: sim\n  sim_seed: 7\n");
  write("conf.d/10.yaml", "backend:\n  sim_seed: null\n");
  EXPECT_FALSE(loadDaemonConfig(sources()).backend.sim_seed.has_value());
}

TEST_F(ConfigTest, RelativePathsResolveAgainstTheWritingFile) {
  write("world.yaml", "robot: builtin\n");
  write("conf.d/10.yaml", "backend:\n  kind: sim\n  sim_world: ../world.yaml\n");
  write("main.yaml", "session:\n  data_dir: data\ncontroller:\n  robot: builtin\n");
  const DaemonConfig c = loadDaemonConfig(sources());
  EXPECT_EQ(fs::path(c.backend.sim_world), (dir_ / "world.yaml").lexically_normal());
  EXPECT_EQ(fs::path(c.session.data_dir), dir_ / "data");
  EXPECT_EQ(c.controller.robot, "builtin");
}

TEST_F(ConfigTest, UnknownKeysNameFileLineAndPath) {
  write("main.yaml", "servo:\n  tolerance_um: 3\n  tolerence_um: 5\nsesion:\n  poses: 8\n");
  write("conf.d/10.yaml", "daq:\n  usb-1408fs:\n    channels:\n      z:\n        number: 1\n");
  const auto p = problems(sources({"control.prot=1"}));
  EXPECT_EQ(p.size(), 4u) << joined(p);
  EXPECT_TRUE(reported(p, {"main.yaml:3", "unknown key 'servo.tolerence_um'"})) << joined(p);
  EXPECT_TRUE(reported(p, {"main.yaml:4", "unknown key 'sesion'"})) << joined(p);
  EXPECT_TRUE(reported(p, {"10.yaml:4", "unknown key 'daq.usb-1408fs.channels.z'"})) << joined(p);
  EXPECT_TRUE(reported(p, {"command line", "unknown key 'control.prot'"})) << joined(p);
}

TEST_F(ConfigTest, WrongTypesAreErrorsNotDefaults) {
  write("main.yaml",
        "servo:\n"
        "  max_iterations: 2.5\n"  // 2
        "  tolerance_um: two\n"    // 3
        "  timeout_s:\n"           // 4: no value
        "session:\n"
        "  target_mm: [1, 2]\n"  // 6
        "  plan: best\n"         // 7
        "control:\n"
        "  port: 70000\n"       // 9
        "logging: verbose\n");  // 10
  const auto p = problems(sources());
  EXPECT_EQ(p.size(), 7u) << joined(p);
  EXPECT_TRUE(reported(p, {"main.yaml:2", "servo.max_iterations", "integer", "'2.5'"}));
  EXPECT_TRUE(reported(p, {"main.yaml:3", "servo.tolerance_um", "number", "'two'"}));
  EXPECT_TRUE(reported(p, {"main.yaml:4", "servo.timeout_s", "no value"})) << joined(p);
  EXPECT_TRUE(reported(p, {"main.yaml:6", "session.target_mm", "list of 2"}));
  EXPECT_TRUE(reported(p, {"main.yaml:7", "session.plan", "optimal, I, II, mixed, file"}));
  EXPECT_TRUE(reported(p, {"main.yaml:9", "control.port", "does not fit"}));
  EXPECT_TRUE(reported(p, {"main.yaml:10", "logging", "expected a mapping"}));
}

// A cell's devices are named by kind; a kind zerocal has no link for is an error, not the IRC5.
TEST_F(ConfigTest, DeviceKindsAreTheOnesZerocalCanDrive) {
  write("main.yaml",
        "controller:\n"
        "  kind: fanuc\n"  // 2
        "daq:\n"
        "  kind: usb-1608\n");  // 4
  const auto p = problems(sources());
  EXPECT_EQ(p.size(), 2u) << joined(p);
  EXPECT_TRUE(reported(p, {"main.yaml:2", "controller.kind", "irc5", "'fanuc'"})) << joined(p);
  EXPECT_TRUE(reported(p, {"main.yaml:4", "daq.kind", "usb-1408fs", "'usb-1608'"})) << joined(p);
  write("main.yaml", "controller: {kind: irc5}\ndaq: {kind: usb-1408fs}\n");
  const DaemonConfig accepted = loadDaemonConfig(sources());
  EXPECT_EQ(accepted.controller.kind, "irc5");
  EXPECT_EQ(accepted.daq.kind, "usb-1408fs");
}

TEST_F(ConfigTest, OutOfRangeValuesNameWhereTheyWereSet) {
  write("main.yaml", "servo:\n  tolerance_um: -1\n");
  write("conf.d/10.yaml", "session:\n  poses: 3\n");
  const auto p = problems(
      sources({"controller.irc5.speed_tcp_mm_s=1e6", "daq.usb-1408fs.channels.x.number=4"}));
  EXPECT_EQ(p.size(), 4u) << joined(p);
  EXPECT_TRUE(reported(p, {"main.yaml:2", "servo.tolerance_um", "greater than 0"})) << joined(p);
  EXPECT_TRUE(reported(p, {"10.yaml:2", "session.poses", "at least 6"})) << joined(p);
  EXPECT_TRUE(reported(p, {"command line", "controller.irc5.speed_tcp_mm_s", "at most 7000"}));
  EXPECT_TRUE(reported(p, {"command line", "daq.usb-1408fs.channels.x.number", "at most 3"}))
      << joined(p);
}

TEST_F(ConfigTest, AZeroChangeIsAJointOf2To5AndAFewDegrees) {
  write("main.yaml", "backend:\n  kind: sim\n");
  const DaemonConfig ok = loadDaemonConfig(
      sources({"backend.sim_zero_change_joint=3", "backend.sim_zero_change_deg=-0.25"}));
  EXPECT_EQ(ok.backend.sim_zero_change_joint, 3);
  EXPECT_DOUBLE_EQ(ok.backend.sim_zero_change_deg, -0.25);

  auto p =
      problems(sources({"backend.sim_zero_change_joint=1", "backend.sim_zero_change_deg=0.1"}));
  EXPECT_TRUE(reported(p, {"backend.sim_zero_change_joint", "joints 2..5"})) << joined(p);
  p = problems(sources({"backend.sim_zero_change_joint=4", "backend.sim_zero_change_deg=2.5"}));
  EXPECT_TRUE(reported(p, {"backend.sim_zero_change_deg", "within +-2 deg", "2.5 given"}))
      << joined(p);
  p = problems(sources({"backend.sim_zero_change_joint=4"}));
  EXPECT_TRUE(reported(p, {"backend.sim_zero_change_deg", "non-zero"})) << joined(p);
  p = problems(sources({"backend.sim_zero_change_deg=0.1"}));
  EXPECT_TRUE(reported(p, {"backend.sim_zero_change_deg", "needs its joint"})) << joined(p);
  p = problems(sources({"backend.sim_zero_change_joint=three"}));
  EXPECT_TRUE(reported(p, {"backend.sim_zero_change_joint"})) << joined(p);
  p = problems(sources({"backend.sim_zero_change_joint=2", "backend.sim_zero_change_deg=0.1",
                        "backend.sim_host=127.0.0.1", "backend.sim_port=5010"}));
  EXPECT_TRUE(reported(p, {"backend.sim_zero_change_joint", "external zerocal-sim"})) << joined(p);
}

TEST_F(ConfigTest, APsdOrLaserReMountIsAFewMillimetresAndDegreesOnTheInProcessCell) {
  write("main.yaml", "backend:\n  kind: sim\n");
  const DaemonConfig none = loadDaemonConfig(sources());
  EXPECT_EQ(none.backend.sim_psd_moved_mm, (std::array<double, 3>{0, 0, 0}));  // not moved
  const DaemonConfig ok = loadDaemonConfig(sources(
      {"backend.sim_psd_moved_mm=[0.05, -0.02, 0]", "backend.sim_laser_turned_deg=[0, 0.01, 0]"}));
  EXPECT_EQ(ok.backend.sim_psd_moved_mm, (std::array<double, 3>{0.05, -0.02, 0}));
  EXPECT_EQ(ok.backend.sim_laser_turned_deg, (std::array<double, 3>{0, 0.01, 0}));

  auto p = problems(sources({"backend.sim_psd_moved_mm=[6, 0, 0]"}));
  EXPECT_TRUE(reported(p, {"backend.sim_psd_moved_mm", "within +-5 mm", "6 given"})) << joined(p);
  p = problems(sources({"backend.sim_laser_turned_deg=[0, 0, -3]"}));
  EXPECT_TRUE(reported(p, {"backend.sim_laser_turned_deg", "within +-2 deg", "-3 given"}))
      << joined(p);
  p = problems(sources({"backend.sim_psd_turned_deg=[1, 2]"}));
  EXPECT_TRUE(reported(p, {"backend.sim_psd_turned_deg"})) << joined(p);
  p = problems(sources({"backend.sim_laser_moved_mm=[0.1, 0, 0]", "backend.sim_host=127.0.0.1",
                        "backend.sim_port=5010"}));
  EXPECT_TRUE(reported(p, {"backend.sim_laser_moved_mm", "external zerocal-sim"})) << joined(p);
}

TEST_F(ConfigTest, ThePsdsBaseRepeatsWithinAMillimetre) {
  write("main.yaml", "backend:\n  kind: sim\n");
  EXPECT_EQ(loadDaemonConfig(sources()).session.psd_base_repeatability_mm, 0.005);
  EXPECT_EQ(loadDaemonConfig(sources({"session.psd_base_repeatability_mm=0"}))
                .session.psd_base_repeatability_mm,
            0.0);
  for (const char* bad : {"-0.01", "1.5", "tight"}) {
    const auto p = problems(sources({std::string("session.psd_base_repeatability_mm=") + bad}));
    EXPECT_TRUE(reported(p, {"session.psd_base_repeatability_mm"})) << bad << ": " << joined(p);
  }
}

TEST_F(ConfigTest, TheArmsWarmUpIsSecondsFromZeroToAWeekOnTheInProcessCell) {
  write("main.yaml", "backend:\n  kind: sim\n");
  EXPECT_EQ(loadDaemonConfig(sources()).backend.sim_warm_s, 0.0);  // cold, as before
  EXPECT_EQ(loadDaemonConfig(sources({"backend.sim_warm_s=3600"})).backend.sim_warm_s, 3600.0);
  auto p = problems(sources({"backend.sim_warm_s=-1"}));
  EXPECT_TRUE(reported(p, {"command line", "backend.sim_warm_s"})) << joined(p);
  p = problems(sources({"backend.sim_warm_s=1e6"}));
  EXPECT_TRUE(reported(p, {"backend.sim_warm_s", "604800"})) << joined(p);
  p = problems(sources({"backend.sim_warm_s=warm"}));
  EXPECT_TRUE(reported(p, {"backend.sim_warm_s"})) << joined(p);
  p = problems(
      sources({"backend.sim_warm_s=60", "backend.sim_host=127.0.0.1", "backend.sim_port=5010"}));
  EXPECT_TRUE(reported(p, {"backend.sim_warm_s", "external zerocal-sim keeps its own clock"}))
      << joined(p);
}

TEST_F(ConfigTest, InconsistentCombinations) {
  write("main.yaml",
        "backend:\n  kind: sim\n  sim_world: /nonexistent/world.yaml\n  sim_seed: 3\n"
        "  sim_host: localhost\n"
        "servo:\n  max_step_deg: 4\n  search_step_mm: 70\n  search_radius_mm: 60\n"
        "controller:\n  max_step_deg: 3\n"
        "session:\n  plan: file\n"
        "control:\n  bind_address: 0.0.0.0\n"
        "daq:\n  usb-1408fs:\n    channels:\n      y:\n        number: 0\n"
        "logging:\n  directory: /var/lib/zerocal/sessions\n");
  const auto p = problems(sources());
  EXPECT_TRUE(reported(p, {"backend.sim_seed", "not both"})) << joined(p);
  EXPECT_TRUE(reported(p, {"backend.sim_world", "no such file"})) << joined(p);
  EXPECT_TRUE(reported(p, {"backend.sim_host", "both"})) << joined(p);
  EXPECT_TRUE(reported(p, {"servo.max_step_deg", "exceeds controller.max_step_deg"}));
  EXPECT_TRUE(reported(p, {"servo.search_step_mm", "exceeds servo.search_radius_mm"}));
  EXPECT_TRUE(reported(p, {"session.plan_file", "required"})) << joined(p);
  EXPECT_TRUE(reported(p, {"control.token_file", "required"})) << joined(p);
  EXPECT_TRUE(reported(p, {"daq.usb-1408fs.channels.y", "same input as daq.usb-1408fs.channels.x"}))
      << joined(p);
  EXPECT_TRUE(reported(p, {"logging.directory", "differ from session.data_dir"})) << joined(p);
  EXPECT_EQ(p.size(), 9u) << joined(p);
}

TEST_F(ConfigTest, AnOperatorsTokenNeedsTheEngineersAndAFileOfItsOwn) {
  write("engineer.token", "engineer-token-0123456789");
  write("main.yaml", "control:\n  operator_token_file: engineer.token\n");
  auto p = problems(sources());
  EXPECT_TRUE(reported(p, {"control.operator_token_file", "needs control.token_file"}))
      << joined(p);
  write("main.yaml",
        "control:\n  token_file: engineer.token\n  operator_token_file: engineer.token\n");
  p = problems(sources());
  EXPECT_TRUE(reported(p, {"control.operator_token_file", "a token of its own"})) << joined(p);
  write("operator.token", "operator-token-0123456789");
  write("main.yaml",
        "control:\n  token_file: engineer.token\n  operator_token_file: operator.token\n");
  EXPECT_NO_THROW(loadDaemonConfig(sources()));
}

TEST_F(ConfigTest, PlanFileOnlyWithPlanFile) {
  write("plan.txt", "");
  write("main.yaml", "session:\n  plan_file: plan.txt\n");
  EXPECT_TRUE(reported(problems(sources()), {"session.plan_file", "only used with"}));
  write("main.yaml", "session:\n  plan: file\n  plan_file: plan.txt\n");
  EXPECT_EQ(fs::path(loadDaemonConfig(sources()).session.plan_file), dir_ / "plan.txt");
}

TEST_F(ConfigTest, SeveralErrorsInSeveralSourcesAllReportedAtOnce) {
  write("main.yaml", "servo:\n  tolerance_um: [1]\n  bogus: 1\n");
  write("conf.d/10-broken.yaml", "session: {poses: 8\n");  // not YAML
  write("conf.d/20.yaml", "control:\n  bind_address: not-an-ip\n");
  const auto p = problems(sources({"nonsense", "session.poses=2"}));
  EXPECT_EQ(p.size(), 6u) << joined(p);
  EXPECT_TRUE(reported(p, {"main.yaml:2", "servo.tolerance_um"}));
  EXPECT_TRUE(reported(p, {"main.yaml:3", "servo.bogus"}));
  EXPECT_TRUE(reported(p, {"10-broken.yaml", "not valid YAML"})) << joined(p);
  EXPECT_TRUE(reported(p, {"20.yaml:2", "control.bind_address", "not an IP address"}));
  EXPECT_TRUE(reported(p, {"command line 'nonsense'", "section.key=value"}));
  EXPECT_TRUE(reported(p, {"command line 'session.poses=2'", "at least 6"}));
}

TEST_F(ConfigTest, PlacementsAreOneToFiveAndNotWithAPlanFile) {
  write("main.yaml", "session:\n  poses: 8\n");
  EXPECT_EQ(loadDaemonConfig(sources()).session.placements, 1);
  EXPECT_EQ(loadDaemonConfig(sources({"session.placements=3"})).session.placements, 3);
  EXPECT_TRUE(
      reported(problems(sources({"session.placements=0"})), {"session.placements", "at least 1"}));
  EXPECT_TRUE(
      reported(problems(sources({"session.placements=6"})), {"session.placements", "at most 5"}));
  write("plan.txt", "q1,q2,q3,q4,q5,q6\n");
  write("main.yaml", "session:\n  plan: file\n  plan_file: plan.txt\n  placements: 2\n");
  EXPECT_TRUE(reported(problems(sources()), {"main.yaml:4", "session.placements", "plan file"}))
      << joined(problems(sources()));
}

TEST_F(ConfigTest, ErrorMessageListsEveryProblem) {
  write("main.yaml", "servo:\n  a: 1\n  b: 2\n");
  try {
    loadDaemonConfig(sources());
    FAIL();
  } catch (const ConfigError& e) {
    const std::string what = e.what();
    EXPECT_NE(what.find("2 problems"), std::string::npos) << what;
    EXPECT_NE(what.find("servo.a"), std::string::npos);
    EXPECT_NE(what.find("servo.b"), std::string::npos);
  }
}

TEST_F(ConfigTest, JsonSnapshotHasEveryKeyAndReadsBack) {
  DaemonConfig c;
  c.backend.sim_seed = 5;
  c.daq.boards.get<usb1408fs::Usb1408fsSettings>("usb-1408fs")->board.channels.y.range =
      usb1408fs::Range::kBip2_5V;
  const nlohmann::json j = configToJson(c);
  for (const auto& key : configKeys()) {
    nlohmann::json::json_pointer pointer("/" + [&] {
      std::string p = key;
      std::replace(p.begin(), p.end(), '.', '/');
      return p;
    }());
    EXPECT_TRUE(j.contains(pointer)) << key;
  }
  EXPECT_EQ(j["daq"]["usb-1408fs"]["channels"]["y"]["range"], "2.5V");
  EXPECT_EQ(j["backend"]["sim_seed"], 5);
  // JSON is YAML: the snapshot is a valid configuration file giving the same values.
  DaemonConfig back;
  back.servo.tolerance_um = 99;
  ConfigOrigins origins;
  std::vector<std::string> p;
  applyConfigYaml(back, j.dump(), "snapshot", dir_.string(), origins, p);
  EXPECT_TRUE(p.empty()) << joined(p);
  EXPECT_EQ(configToJson(back), j);
}

TEST_F(ConfigTest, ShippedExampleIsCompleteAndEqualsTheDefaults) {
  const fs::path example = fs::path(ZEROCAL_SOURCE_DIR) / "config" / "zerocald.yaml";
  std::ifstream in(example);
  ASSERT_TRUE(in) << example;
  std::stringstream text;
  text << in.rdbuf();
  DaemonConfig c;
  ConfigOrigins origins;
  std::vector<std::string> p;
  applyConfigYaml(c, text.str(), example.string(), example.parent_path().string(), origins, p);
  EXPECT_TRUE(p.empty()) << joined(p);
  for (const auto& key : configKeys()) EXPECT_TRUE(origins.count(key)) << key << " not in example";
  EXPECT_EQ(configToJson(c), configToJson(DaemonConfig{}));
}

// `zerocal psd` reads the PSD chain's configuration as zerocald does: the daq section of a file.
TEST_F(ConfigTest, TheDaqSectionAloneIsThePsdChainsConfiguration) {
  const DaqConfig rig = loadDaqSection(ZEROCAL_SOURCE_DIR "/config/psd.yaml");
  const usb1408fs::BoardSettings& rig_board = usb1408fs::boardSettingsOf(rig.boards);
  EXPECT_EQ(rig_board.channels.sum.number, 2);
  EXPECT_EQ(rig_board.channels.sum.range, usb1408fs::Range::kBip5V);
  EXPECT_EQ(rig_board.samples_per_reading, 64);
  EXPECT_DOUBLE_EQ(rig_board.scan_rate_hz, 16000);
  EXPECT_EQ(rig.psd.map_file,
            fs::path(ZEROCAL_SOURCE_DIR "/config/psd-map.yaml").lexically_normal().string());
  // zerocald's own file: its daq section; the other sections are zerocald's to check.
  const std::string daemon = write("zerocald.yaml",
                                   "servo: {bogus: 1}\ndaq:\n  usb-1408fs:\n    "
                                   "samples_per_reading: 32\n  map_file: map.yaml\n");
  write("map.yaml", "psd_map: {}\n");
  const DaqConfig read = loadDaqSection(daemon);
  const usb1408fs::BoardSettings& board = usb1408fs::boardSettingsOf(read.boards);
  EXPECT_EQ(board.samples_per_reading, 32);
  EXPECT_DOUBLE_EQ(board.scan_rate_hz, usb1408fs::BoardSettings{}.scan_rate_hz);  // the one default
  EXPECT_EQ(read.psd.map_file, (dir_ / "map.yaml").string());
  EXPECT_DOUBLE_EQ(read.psd.sumOffThresholdV(), 0.4);
}

TEST_F(ConfigTest, TheDaqSectionAloneReportsEveryProblem) {
  const auto problemsOf = [&](const std::string& text) {
    try {
      loadDaqSection(write("psd.yaml", text));
    } catch (const ConfigError& e) {
      return e.problems();
    }
    ADD_FAILURE() << "accepted: " << text;
    return std::vector<std::string>{};
  };
  const auto p = problemsOf(
      "daq:\n"
      "  usb-1408fs:\n"
      "    channels:\n"
      "      x: {number: 7}\n"  // 4
      "    samples_per_reading: 0\n"
      "    scan_rate_hz: 20000\n"
      "  smaples: 64\n"  // 7
      "  map_file: /nonexistent/map.yaml\n");
  EXPECT_EQ(p.size(), 5u) << joined(p);
  EXPECT_TRUE(reported(p, {"psd.yaml:7", "unknown key 'daq.smaples'"})) << joined(p);
  EXPECT_TRUE(reported(p, {"psd.yaml:4", "daq.usb-1408fs.channels.x.number", "at most 3"}))
      << joined(p);
  EXPECT_TRUE(reported(p, {"daq.usb-1408fs.samples_per_reading", "at least 1"})) << joined(p);
  EXPECT_TRUE(reported(p, {"daq.usb-1408fs.scan_rate_hz", "at most 16000"})) << joined(p);
  EXPECT_TRUE(reported(p, {"daq.map_file", "no such file"})) << joined(p);
  EXPECT_TRUE(reported(problemsOf("psd:\n  samples: 64\n"),
                       {"the psd: section of earlier versions", "samples_per_reading"}));
  EXPECT_TRUE(reported(problemsOf("servo: {}\n"), {"'daq:' section"}));
  EXPECT_TRUE(reported(problemsOf("daq: [1\n"), {"not valid YAML"}));
  EXPECT_THROW(loadDaqSection((dir_ / "none.yaml").string()), ConfigError);
}

TEST_F(ConfigTest, ReferenceDocumentNamesEveryKey) {
  std::ifstream in(fs::path(ZEROCAL_SOURCE_DIR) / "docs" / "configuration.md");
  ASSERT_TRUE(in);
  std::stringstream text;
  text << in.rdbuf();
  for (const auto& key : configKeys()) {
    const std::string leaf = key.substr(key.rfind('.') + 1);
    const std::string section = "## " + key.substr(0, key.find('.'));
    EXPECT_NE(text.str().find(leaf + "`"), std::string::npos) << key;
    EXPECT_NE(text.str().find(section), std::string::npos) << key;
  }
}

}  // namespace
}  // namespace zerocal

namespace zerocal {
namespace {

// A text or path that is not UTF-8 cannot go into session.json's snapshot of the configuration:
// refused where it is written, not at every session's start.
TEST_F(ConfigTest, TextsAndPathsMustBeUtf8) {
  write("main.yaml",
        "backend:\n  sim_world: \"\xd6\"\ndaq:\n  usb-1408fs:\n    serial: \"a\xff\"\n");
  const auto p = problems(sources());
  EXPECT_TRUE(reported(p, {"main.yaml:2", "backend.sim_world", "UTF-8"})) << joined(p);
  EXPECT_TRUE(reported(p, {"main.yaml:5", "daq.usb-1408fs.serial", "UTF-8"})) << joined(p);
  write("main.yaml", "daq:\n  usb-1408fs:\n    serial: \"\xc3\xa9t\xc3\xa9\"\n");  // UTF-8: fine
  EXPECT_NO_THROW(configToJson(loadDaemonConfig(sources())).dump());
}

}  // namespace
}  // namespace zerocal

namespace zerocal {
namespace {

// The controller's and the board's keys are their kind's own now: a key of the old flat layout
// is refused with the place it moved to, never silently ignored or taken.
TEST_F(ConfigTest, AKeyOfAKindsSectionNamesWhereItIsNow) {
  write("main.yaml", "controller:\n  host: 10.0.0.5\ndaq:\n  serial: ABC\n");
  const auto p = problems(sources({"controller.speed_tcp_mm_s=100"}));
  EXPECT_EQ(p.size(), 3u) << joined(p);
  EXPECT_TRUE(
      reported(p, {"main.yaml:2", "unknown key 'controller.host'", "'controller.irc5.host' now"}))
      << joined(p);
  EXPECT_TRUE(reported(p, {"main.yaml:4", "'daq.usb-1408fs.serial' now"})) << joined(p);
  EXPECT_TRUE(reported(p, {"command line", "'controller.irc5.speed_tcp_mm_s' now"})) << joined(p);
  EXPECT_TRUE(
      reported(problems(sources({"controller.colour=red"})), {"unknown key 'controller.colour'"}));
}

// The kind's section is checked by the kind, with its own prefix, and the servo's sweeps are
// held to the kind's linear speed.
TEST_F(ConfigTest, TheKindsSectionIsCheckedByTheKind) {
  write("main.yaml", "controller:\n  irc5:\n    port: 0\n    speed_tcp_mm_s: 20\n");
  const auto p = problems(sources({"servo.sweep_speed_mm_s=30"}));
  EXPECT_TRUE(reported(p, {"main.yaml:3", "controller.irc5.port", "1..65535"})) << joined(p);
  EXPECT_TRUE(reported(p, {"servo.sweep_speed_mm_s", "linear speed", "controller.irc5", "20"}))
      << joined(p);
  EXPECT_EQ(p.size(), 2u) << joined(p);
}

}  // namespace
}  // namespace zerocal

namespace zerocal {
namespace {

// The web terminal's section: on with the simulated cell unless said otherwise, loopback unless
// the network is said to be trusted or TLS is configured, each bad value with its file:line.
TEST_F(ConfigTest, TheWebSectionIsTheWebTerminalsOptionsCheckedLikeTheOthers) {
  write("main.yaml", "backend:\n  kind: sim\n");
  DaemonConfig sim = loadDaemonConfig(sources());
  EXPECT_TRUE(webEnabled(sim));
  EXPECT_EQ(sim.web.port, 7451);
  EXPECT_EQ(sim.web.bind_address, "127.0.0.1");
  EXPECT_FALSE(webEnabled(DaemonConfig{}));  // a real cell opts in
  EXPECT_FALSE(webEnabled(loadDaemonConfig(sources({"web.enabled=false", "backend.kind=sim"}))));
  const DaemonConfig on =
      loadDaemonConfig(sources({"web.enabled=true", "web.port=0", "web.session_lifetime_s=3600"}));
  EXPECT_TRUE(webEnabled(on));
  EXPECT_EQ(on.web.port, 0);
  EXPECT_EQ(on.web.session_lifetime, std::chrono::hours(1));

  write("main.yaml",
        "web:\n  enabled: yes\n  bind_address: 192.168.125.10\n  port: 70000\n"
        "  session_lifetime_s: 5\n  root: /nonexistent\n");
  auto p = problems(sources());
  EXPECT_TRUE(reported(p, {"main.yaml:2", "web.enabled", "auto, false, true"})) << joined(p);
  EXPECT_TRUE(reported(
      p, {"main.yaml:3", "web.bind_address", "no TLS", "web.tls_certificate", "trusted_network"}))
      << joined(p);
  EXPECT_TRUE(reported(p, {"main.yaml:4", "web.port"})) << joined(p);
  EXPECT_TRUE(reported(p, {"main.yaml:5", "web.session_lifetime_s", "at least 60"})) << joined(p);
  EXPECT_TRUE(reported(p, {"main.yaml:6", "web.root", "no index.html"})) << joined(p);

  write("main.yaml", "web:\n  bind_address: 192.168.125.10\n  trusted_network: true\n");
  EXPECT_EQ(loadDaemonConfig(sources()).web.bind_address, "192.168.125.10");
  // TLS serves any address; its certificate and key go together and must be there.
  write("cert.pem", "certificate");
  write("key.pem", "key");
  write("main.yaml",
        "web:\n  bind_address: 192.168.125.10\n  tls_certificate: " + (dir_ / "cert.pem").string() +
            "\n  tls_key: " + (dir_ / "key.pem").string() + "\n");
  EXPECT_EQ(loadDaemonConfig(sources()).web.tls_key, (dir_ / "key.pem").string());
  write("main.yaml", "web:\n  tls_certificate: " + (dir_ / "cert.pem").string() + "\n");
  EXPECT_TRUE(reported(problems(sources()), {"web.tls_key", "go together"}));
  write("main.yaml", "web:\n  tls_certificate: /nonexistent.pem\n  tls_key: /nonexistent.key\n");
  EXPECT_TRUE(reported(problems(sources()), {"main.yaml:2", "web.tls_certificate"}));
  write("main.yaml", "web:\n  bind_address: cellpc\n");
  EXPECT_TRUE(reported(problems(sources()), {"main.yaml:2", "web.bind_address", "not an IP"}));
  write("main.yaml", "web:\n  enabled: true\n  port: 7450\n");
  EXPECT_TRUE(reported(problems(sources()), {"main.yaml:3", "web.port", "control.port"}));
}

}  // namespace
}  // namespace zerocal
