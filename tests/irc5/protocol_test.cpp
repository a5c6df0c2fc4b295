#include "zerocal/irc5/protocol.h"

#include <gtest/gtest.h>

#include "zerocal/irc5/errors.h"
#include "zerocal/irc5/motion_time.h"
#include "zerocal/model/builtin.h"
#include "zerocal/model/kinematics.h"

namespace zerocal {
namespace irc5 {
namespace {

TEST(Protocol, FormatsZeroPaddedCodesAndSignedFixedDecimals) {
  EXPECT_EQ(formatRequest(kReadJoints), "04 #");
  EXPECT_EQ(formatRequest(kRobotInfo), "98 #");
  EXPECT_EQ(formatRequest(kMoveJoints, {{10, 5}, {-5.25, 5}, {0, 5}, {-1e-9, 5}, {90, 5}, {0, 5}}),
            "02 +10.00000 -5.25000 +0.00000 +0.00000 +90.00000 +0.00000 #");
}

TEST(Protocol, LongestRequestsFitEightyCharacters) {
  const std::string joints =
      formatRequest(kMoveJoints, {{-180, 5}, {-90, 5}, {-245, 5}, {-200, 5}, {-115, 5}, {-400, 5}});
  const std::string linear = formatRequest(
      kMoveLinear, {{-1450, 3}, {-1450, 3}, {-1450, 3}, {-0.7, 6}, {-0.7, 6}, {-0.7, 6}, {-1, 6}});
  EXPECT_LE(joints.size(), kMaxMessageLength);
  EXPECT_LE(linear.size(), kMaxMessageLength);
  EXPECT_NO_THROW(checkRequest(joints));
  EXPECT_NO_THROW(checkRequest(linear));
}

TEST(Protocol, CheckRefusesOverlongMissingHashAndTrailingBytes) {
  EXPECT_THROW(checkRequest("02 " + std::string(76, '1') + " #"), RequestRefusedError);
  EXPECT_THROW(checkRequest("04 "), RequestRefusedError);
  EXPECT_THROW(checkRequest("04 #\n"), RequestRefusedError);
  EXPECT_THROW(checkRequest("123 #"), RequestRefusedError);
  EXPECT_THROW(checkRequest("#"), RequestRefusedError);
  EXPECT_NO_THROW(checkRequest("4 #"));
}

TEST(Protocol, ParsesUpstreamClientFormatting) {
  // open_abb's abb.py: "%02d " code, "%+08.2f " numbers.
  const ParsedRequest r =
      parseRequest("02 +0010.00 -0005.25 +0000.00 +0000.00 +0090.00 +0000.00 #");
  ASSERT_TRUE(r.valid);
  EXPECT_EQ(r.code, 2);
  ASSERT_EQ(r.params.size(), 6u);
  EXPECT_DOUBLE_EQ(r.params[1], -5.25);
  EXPECT_EQ(parseRequest("4 #").code, 4);
}

TEST(Protocol, ParameterAgainstHashIsNotCountedLikeUpstream) {
  EXPECT_EQ(parseRequest("02 1 2 3 4 5 6#").params.size(), 5u);
  EXPECT_FALSE(parseRequest("xx #").valid);
  EXPECT_FALSE(parseRequest("02 1 abc #").valid);
}

TEST(Protocol, ParsesReplies) {
  Reply r = parseReply("2 1 ");
  EXPECT_EQ(r.code, 2);
  EXPECT_TRUE(r.ok);
  EXPECT_TRUE(r.fields.empty());
  r = parseReply("98 1 SN*6.15*IRB 1600-10/1.45\n");
  EXPECT_EQ(r.data, "SN*6.15*IRB 1600-10/1.45");
  r = parseReply("4 0 ");
  EXPECT_FALSE(r.ok);
  EXPECT_THROW(parseReply("garbage"), ProtocolError);
  EXPECT_THROW(parseReply("4"), ProtocolError);
  EXPECT_THROW(parseReply("4 7 1 2"), ProtocolError);
}

TEST(Protocol, InPlaceFormsAgreeWithTheAllocatingOnes) {
  std::string out = "left over";
  const Param joints[] = {{10, 5}, {-5.25, 5}, {0, 5}, {-1e-9, 5}, {90, 5}, {0, 5}};
  formatRequest(out, kMoveJoints, joints, 6);
  EXPECT_EQ(out, formatRequest(kMoveJoints,
                               {joints[0], joints[1], joints[2], joints[3], joints[4], joints[5]}));
  formatRequest(out, kReadJoints, nullptr, 0);
  EXPECT_EQ(out, "04 #");

  for (const char* text : {"2 1 ", "4 1 1.5 -2 3 4 5 6.25\n", "98 1 SN*6.15*IRB 1600-10/1.45\n",
                           "4 0 ", "  30 0 not supported  "}) {
    const Reply r = parseReply(text);
    const ReplyView v = parseReplyView(text);
    EXPECT_EQ(v.code, r.code) << text;
    EXPECT_EQ(v.ok, r.ok) << text;
    EXPECT_EQ(v.data, r.data) << text;
    ASSERT_EQ(v.field_count, r.fields.size()) << text;
    for (std::size_t i = 0; i < v.field_count; ++i) EXPECT_EQ(v.fields[i], r.fields[i]) << text;
  }
  EXPECT_THROW(parseReplyView("4 7 1 2"), ProtocolError);
  // More fields than a reply can hold are counted, so the count check still refuses them.
  std::string many = "4 1";
  for (std::size_t i = 0; i < kMaxReplyFields + 5; ++i) many += " 1";
  EXPECT_EQ(parseReplyView(many).field_count, kMaxReplyFields + 5);
}

TEST(Protocol, CompletenessWithoutLf) {
  EXPECT_EQ(replyCompleteness("2 1", 0), Completeness::kNeedMore);
  EXPECT_EQ(replyCompleteness("2 1 ", 0), Completeness::kComplete);
  EXPECT_EQ(replyCompleteness("4 1 1.0 2.0 3.0", 6), Completeness::kNeedMore);
  EXPECT_EQ(replyCompleteness("4 1 1 2 3 4 5 6.0", 6), Completeness::kMaybe);
  EXPECT_EQ(replyCompleteness("4 1 1 2 3 4 5 6.0 ", 6), Completeness::kComplete);
  EXPECT_EQ(replyCompleteness("4 0 ", 6), Completeness::kMaybe);
  EXPECT_EQ(replyCompleteness("98 1 a*b", -1), Completeness::kNeedMore);
  EXPECT_EQ(replyCompleteness("98 1 a*b*c", -1), Completeness::kMaybe);
  EXPECT_EQ(replyCompleteness("#?! garbage", 6), Completeness::kComplete);
}

TEST(MotionTime, JointMoveIsLimitedByJointTcpAndOrientationSpeeds) {
  const Robot robot = builtinIrb1600();
  // J1 by 90 deg at q = 0 swings the flange (815 mm from the axis) along a quarter circle.
  EXPECT_NEAR(jointMoveSeconds(robot, Joints{}, Joints{90, 0, 0, 0, 0, 0}, 100, 50),
              815 * kPi / 2 / 100, 0.05);
  // J6 alone: no TCP path, the tool turns 90 deg at 50 deg/s.
  EXPECT_NEAR(jointMoveSeconds(robot, Joints{}, Joints{0, 0, 0, 0, 0, 90}, 100, 50), 1.8, 1e-9);
  // Fast settings: J1's own 180 deg/s maximum limits.
  EXPECT_NEAR(jointMoveSeconds(robot, Joints{}, Joints{90, 0, 0, 0, 0, 0}, 1e6, 1e6), 0.5, 1e-9);
}

}  // namespace
}  // namespace irc5
}  // namespace zerocal
