// The wire form of the service's events (docs/protocol.md, "Events"): the control layer is the
// only place that serialises them, so these keys are the protocol.
#include "zerocal/control/protocol.h"

#include <gtest/gtest.h>

#include <cmath>

namespace zerocal::control {
namespace {

using nlohmann::json;

TEST(EventJson, PlanNamesEachOffsetsSigmaAndNullWhereNotIdentifiable) {
  const json e = toJson(service::SessionEvent(
      service::PlanEvent{"20261122T073447Z", 8, "optimal plan", {0.002, std::nan(""), 0.003}}));
  EXPECT_EQ(e, json::parse(R"({"event":"plan","session":"20261122T073447Z","pose_count":8,
      "description":"optimal plan",
      "predicted_sigma_deg":{"delta2_deg":0.002,"delta3_deg":null,"delta4_deg":0.003}})"));
}

TEST(EventJson, StateCarriesItsMessageOnlyWhenThereIsOne) {
  service::StateEvent state{service::SessionState::kServoing, "S", 3, 8, 2, ""};
  EXPECT_EQ(toJson(service::SessionEvent(state)),
            json::parse(R"({"event":"state","state":"servoing","session":"S","pose":3,
                            "pose_count":8,"recorded":2})"));
  state.state = service::SessionState::kFaulted;
  state.message = "servo spot not found";
  EXPECT_EQ(toJson(service::SessionEvent(state))["message"], "servo spot not found");
}

TEST(EventJson, PoseNamesThePlanPoseAndItsServoFiguresOrWhyItWasSkipped) {
  service::PoseEvent pose;
  pose.session = "S";
  pose.pose_count = 8;
  pose.record.index = 9;
  pose.record.remeasure_of = 2;  // plan pose 3, measured again
  pose.record.servo.final_error_um = 1.5;
  pose.record.servo.moves = 4;
  EXPECT_EQ(toJson(service::SessionEvent(pose)),
            json::parse(R"({"event":"pose","session":"S","pose":3,"servo_error_um":1.5,
                            "servo_moves":4,"again":true,"pose_count":8})"));
  service::PoseEvent skipped;
  skipped.session = "S";
  skipped.pose_count = 8;
  skipped.record.index = 1;
  skipped.record.skipped = "spot never found";
  EXPECT_EQ(toJson(service::SessionEvent(skipped)),
            json::parse(R"({"event":"pose","session":"S","pose":2,
                            "skipped":"spot never found","pose_count":8})"));
}

TEST(EventJson, RemeasureAndResult) {
  EXPECT_EQ(toJson(service::SessionEvent(service::RemeasureEvent{"S", {2, 5}})),
            json::parse(R"({"event":"remeasure","session":"S","poses":[2,5]})"));
  service::ResultEvent result;
  result.session = "S";
  result.report.converged = true;
  ParameterEstimate delta2;
  delta2.name = "delta2_deg";
  delta2.identifiable = true;
  delta2.value = 0.1;
  delta2.sigma = 0.002;
  result.report.parameters.push_back(delta2);
  result.achieved_sigma_deg = {0.002};
  const json e = toJson(service::SessionEvent(result));
  EXPECT_EQ(e["event"], "result");
  EXPECT_EQ(e["converged"], true);
  EXPECT_EQ(e["achieved_sigma_deg"], json::parse(R"({"delta2_deg":0.002})"));
  EXPECT_EQ(e["parameters"]["delta2_deg"]["value"], 0.1);
  EXPECT_EQ(e["parameters"]["delta2_deg"]["sigma"], 0.002);
}

}  // namespace
}  // namespace zerocal::control
