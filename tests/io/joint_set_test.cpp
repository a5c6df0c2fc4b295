#include "zerocal/io/joint_set.h"

#include <gtest/gtest.h>
#include <sys/stat.h>
#include <unistd.h>

#include <fstream>

#include "zerocal/error.h"

namespace zerocal {
namespace {

std::string errorOf(const std::string& text) {
  try {
    parseJointSet(text, "poses.csv");
  } catch (const InputError& e) {
    return e.what();
  }
  return "no error";
}

TEST(JointSetCsv, ReadsColumnsInAnyOrderWithCommentsAndExtras) {
  const auto poses = parseJointSet(
      "# recorded 2026-11-22\n"
      "time,q6,q5,q4,q3,q2,q1,v,u\n"
      "\n"
      "12.5,6,5,4,3,2,1,-0.2,0.1\n"
      "# a comment between rows\n"
      "13.0, 6.5 ,5,4,3,2,1.25,0,0\n",
      "p.csv");
  ASSERT_EQ(poses.size(), 2u);
  EXPECT_EQ(poses[0].q_deg, (Joints{1, 2, 3, 4, 5, 6}));
  ASSERT_TRUE(poses[0].spot.has_value());
  EXPECT_DOUBLE_EQ(poses[0].spot->u_mm, 0.1);
  EXPECT_DOUBLE_EQ(poses[0].spot->v_mm, -0.2);
  EXPECT_EQ(poses[0].source_line, 4);
  EXPECT_DOUBLE_EQ(poses[1].q_deg[0], 1.25);
  EXPECT_DOUBLE_EQ(poses[1].q_deg[5], 6.5);
}

TEST(JointSetCsv, BadInputNamesTheLine) {
  EXPECT_NE(errorOf("").find("empty file"), std::string::npos);
  EXPECT_NE(errorOf("a,b,c\n1,2,3\n").find("poses.csv:1: the header must name the columns q1..q6"),
            std::string::npos);
  EXPECT_NE(errorOf("q1,q2,q3,q4,q5\n").find("missing: q6"), std::string::npos);
  EXPECT_NE(errorOf("q1,q2,q3,q4,q5,q6,u\n").find("only one of u and v"), std::string::npos);
  EXPECT_NE(errorOf("q1,q2,q3,q4,q5,q6\n1,2,3,4,5,x\n")
                .find("poses.csv:2: column 6 is not a decimal number"),
            std::string::npos);
  EXPECT_NE(errorOf("q1,q2,q3,q4,q5,q6\n1,2,3,4,5,0x1p3\n").find("column 6 is not a decimal"),
            std::string::npos);
  EXPECT_NE(errorOf("q1,q2,q3,q4,q5,q6\n1,2,3,4,5,inf\n").find("column 6 is not a decimal"),
            std::string::npos);
  EXPECT_NE(errorOf("q1,q2,q3,q4,q5,q6\n1,2,3,4,5,1e999\n").find("column 6 is not finite"),
            std::string::npos);
  EXPECT_NE(
      errorOf("q1,q2,q3,q4,q5,q6\n1,2,3,4,5,nan\n").find("poses.csv:2: column 6 is not a decimal"),
      std::string::npos);
  EXPECT_NE(errorOf("q1,q2,q3,q4,q5,q6\n1,2,3\n").find("poses.csv:2: expected 6 fields"),
            std::string::npos);
  EXPECT_NE(errorOf("q1,q2,q3,q4,q5,q6\n1,2,3,4,5,\n").find("is not a decimal number"),
            std::string::npos);
  EXPECT_NE(errorOf("q1,q1,q2,q3,q4,q5,q6\n").find("appears twice"), std::string::npos);
  EXPECT_THROW(readJointSet("/nonexistent/poses.csv"), InputError);
}

TEST(JointSetCsv, ErrorsNeverQuoteTheFileAndAByteOrderMarkIsSkipped) {
  const std::string secret = "s3cr3t-token-value";
  EXPECT_EQ(errorOf(secret + "\n").find(secret), std::string::npos) << errorOf(secret + "\n");
  EXPECT_EQ(errorOf("q1,q2,q3,q4,q5,q6\n1,2,3,4,5," + secret + "\n").find(secret),
            std::string::npos);
  const auto poses = parseJointSet("\xEF\xBB\xBFq1,q2,q3,q4,q5,q6\n1,2,3,4,5,6\n", "bom.csv");
  ASSERT_EQ(poses.size(), 1u);
  EXPECT_EQ(poses[0].q_deg[5], 6);
}

TEST(JointSetCsv, OnlyABoundedRegularFileIsRead) {
  // A device that never ends, a directory and a FIFO with no writer are refused at once.
  for (const char* path : {"/dev/zero", "/tmp"}) {
    try {
      readJointSet(path);
      FAIL() << path << " was read";
    } catch (const InputError& e) {
      EXPECT_NE(std::string(e.what()).find("not a regular file"), std::string::npos) << e.what();
    }
  }
  const std::string fifo = "/tmp/zerocal-joint-set-fifo-" + std::to_string(::getpid());
  ASSERT_EQ(::mkfifo(fifo.c_str(), 0600), 0);
  EXPECT_THROW(readJointSet(fifo), InputError);
  ::unlink(fifo.c_str());
  const std::string big = "/tmp/zerocal-joint-set-big-" + std::to_string(::getpid());
  {
    std::ofstream out(big);
    out << "q1,q2,q3,q4,q5,q6\n";
    for (std::size_t n = 0; n < kMaxJointSetBytes / 12 + 1; ++n) out << "1,2,3,4,5,6\n";
  }
  try {
    readJointSet(big);
    FAIL() << "a file over the limit was read";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("larger than 1 MiB"), std::string::npos) << e.what();
  }
  ::unlink(big.c_str());
}

TEST(JointSetCsv, FormatRoundTripsWithFiveDecimals) {
  std::vector<Pose> poses{{Joints{1.123456, -2, 3, 4, 5, 6}, PsdSpot{0.1, 0.2}, 0},
                          {Joints{7, 8, 9, 10, 11, 12}, PsdSpot{-0.1, 0}, 0}};
  const std::string text = formatJointSet(poses, "two poses");
  EXPECT_EQ(text.rfind("# two poses\nq1,q2,q3,q4,q5,q6,u,v\n1.12346,", 0), 0u) << text;
  const auto back = parseJointSet(text, "x");
  ASSERT_EQ(back.size(), 2u);
  EXPECT_NEAR(back[0].q_deg[0], 1.12346, 1e-12);
  EXPECT_NEAR(back[1].spot->u_mm, -0.1, 1e-12);
}

TEST(JointSetCsv, FormatWritesLargeValuesWholeSoTheyReadBack) {
  // What the reader accepts, the writer must write out in full: 1e80 in fixed notation is 87
  // characters, more than a line's field was once given room for.
  std::vector<Pose> poses{{Joints{1e80, -2, 3, 4, 5, 6}, PsdSpot{1e100, -1e100}, 0}};
  const auto back = parseJointSet(formatJointSet(poses), "x");
  ASSERT_EQ(back.size(), 1u);
  EXPECT_DOUBLE_EQ(back[0].q_deg[0], 1e80);
  EXPECT_DOUBLE_EQ(back[0].spot->u_mm, 1e100);
  EXPECT_DOUBLE_EQ(back[0].spot->v_mm, -1e100);
}

TEST(JointSetCsv, PlacementColumnIsOptionalAndOneBased) {
  const auto without = parseJointSet("q1,q2,q3,q4,q5,q6\n1,2,3,4,5,6\n", "p.csv");
  ASSERT_EQ(without.size(), 1u);
  EXPECT_EQ(without[0].placement, 1);
  const auto with = parseJointSet(
      "placement,q1,q2,q3,q4,q5,q6\n"
      "2,1,2,3,4,5,6\n"
      " 3 ,1,2,3,4,5,7\n",
      "p.csv");
  ASSERT_EQ(with.size(), 2u);
  EXPECT_EQ(with[0].placement, 2);
  EXPECT_EQ(with[1].placement, 3);
  EXPECT_DOUBLE_EQ(with[1].q_deg[5], 7);
}

TEST(JointSetCsv, BadPlacementsNameTheLineAndColumn) {
  const std::string header = "q1,q2,q3,q4,q5,q6,placement\n1,2,3,4,5,6,1\n";
  for (const char* bad : {"0", "-1", "1.5", "x", "", "2e0", "101", "9999999999"})
    EXPECT_NE(errorOf(header + "1,2,3,4,5,6," + bad + "\n")
                  .find("poses.csv:3: column 7 (placement) is not a whole number from 1 to 100"),
              std::string::npos)
        << bad;
  EXPECT_NE(errorOf("q1,q2,q3,q4,q5,q6,placement,placement\n").find("appears twice"),
            std::string::npos);
}

TEST(JointSetCsv, FormatWritesPlacementOnlyWhenThereIsMoreThanOne) {
  std::vector<Pose> poses(2);
  poses[1].q_deg[0] = 1;
  EXPECT_EQ(formatJointSet(poses).find("placement"), std::string::npos);
  poses[1].placement = 3;
  const std::string text = formatJointSet(poses);
  EXPECT_NE(text.find("q1,q2,q3,q4,q5,q6,placement\n"), std::string::npos);
  const auto back = parseJointSet(text, "p.csv");
  ASSERT_EQ(back.size(), 2u);
  EXPECT_EQ(back[0].placement, 1);
  EXPECT_EQ(back[1].placement, 3);
}

}  // namespace
}  // namespace zerocal
