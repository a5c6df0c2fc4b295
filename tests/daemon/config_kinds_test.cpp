// A controller kind registered beside the built-in ones owns its section of the configuration:
// its keys are accepted under controller.<kind>, checked only when it is the kind in use, and
// stored in the snapshot only then. Its own binary: the registration is process-wide.
#include <gtest/gtest.h>

#include <algorithm>

#include "zerocal/cell/kinds.h"
#include "zerocal/daemon/config.h"
#include "zerocal/error.h"

namespace zerocal {
namespace {

// A kind with one key, refused when empty; it makes no link (nothing here connects).
class BenchSettings final : public ControllerSettings {
 public:
  std::string address = "bench-1";
  std::unique_ptr<ControllerSettings> clone() const override {
    return std::make_unique<BenchSettings>(*this);
  }
  void declare(const std::string& prefix, settings::Fields& fields) override {
    fields.push_back(settings::textField(prefix + "address", address));
  }
  void check(const std::string& prefix, bool, settings::Checker& check) const override {
    if (address.empty()) check.fail(prefix + "address", "must not be empty");
  }
  ControllerMotion motion() const override {
    ControllerMotion m;
    m.linear_speed_mm_s = 500;
    m.limit_margin_deg = 2;
    return m;
  }
  std::unique_ptr<ControllerConnection> link(const Robot&, const LinkEndpoint*) const override {
    return nullptr;
  }
};

class ConfigKinds : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    kinds::registerControllerKind(
        {"bench", "a test bench", [] { return std::make_unique<BenchSettings>(); }});
  }
  static std::vector<std::string> problemsOf(const std::vector<std::string>& overrides) {
    DaemonConfig config;
    ConfigOrigins origins;
    std::vector<std::string> problems;
    for (const auto& o : overrides) applyConfigOverride(config, o, origins, problems);
    const auto invalid = validateDaemonConfig(config, origins);
    problems.insert(problems.end(), invalid.begin(), invalid.end());
    return problems;
  }
  static bool mentions(const std::vector<std::string>& problems, const std::string& text) {
    return std::any_of(problems.begin(), problems.end(),
                       [&](const std::string& p) { return p.find(text) != std::string::npos; });
  }
};

TEST_F(ConfigKinds, ARegisteredKindsKeysAreItsSection) {
  const auto keys = configKeys();
  EXPECT_NE(std::find(keys.begin(), keys.end(), "controller.bench.address"), keys.end());
  EXPECT_NE(std::find(keys.begin(), keys.end(), "controller.irc5.host"), keys.end());
  EXPECT_THROW(kinds::registerControllerKind(
                   {"bench", "again", [] { return std::make_unique<BenchSettings>(); }}),
               std::invalid_argument);
}

TEST_F(ConfigKinds, OnlyTheKindInUseIsCheckedAndStored) {
  // The IRC5's section is wrong, the bench's empty: only the kind in use is held to its checks.
  const std::vector<std::string> bad = {"controller.irc5.port=0", "controller.bench.address=''"};
  auto p = problemsOf(bad);
  EXPECT_TRUE(mentions(p, "controller.irc5.port")) << p.size();
  EXPECT_FALSE(mentions(p, "controller.bench.address"));
  auto with_bench = bad;
  with_bench.push_back("controller.kind=bench");
  p = problemsOf(with_bench);
  EXPECT_TRUE(mentions(p, "controller.bench.address: must not be empty"));
  EXPECT_FALSE(mentions(p, "controller.irc5.port"));
  EXPECT_EQ(p.size(), 1u);

  DaemonConfig config;
  ConfigOrigins origins;
  std::vector<std::string> problems;
  applyConfigOverride(config, "controller.kind=bench", origins, problems);
  applyConfigOverride(config, "controller.bench.address=cell-7", origins, problems);
  ASSERT_TRUE(problems.empty());
  const nlohmann::json snapshot = configToJson(config);
  EXPECT_EQ(snapshot["controller"]["bench"]["address"], "cell-7");
  EXPECT_FALSE(snapshot["controller"].contains("irc5"));
  // The servo's limit margin and sweep ceiling are the kind's.
  EXPECT_EQ(config.controller.section().motion().limit_margin_deg, 2);
  EXPECT_TRUE(mentions(problemsOf({"controller.kind=bench", "servo.sweep_speed_mm_s=600"}),
                       "linear speed of the controller.bench section (500 mm/s)"));
}

}  // namespace
}  // namespace zerocal
