#include "zerocal/apply/motor_calibration.h"

#include <gtest/gtest.h>

#include <cmath>

#include "zerocal/error.h"

namespace zerocal::apply {
namespace {

TEST(WrapCalOffset, IntoZeroToTwoPi) {
  EXPECT_DOUBLE_EQ(wrapCalOffset(1.0), 1.0);
  EXPECT_NEAR(wrapCalOffset(-0.5), kTwoPi - 0.5, 1e-15);
  EXPECT_NEAR(wrapCalOffset(kTwoPi + 0.25), 0.25, 1e-15);
  EXPECT_NEAR(wrapCalOffset(-3 * kTwoPi - 0.25), kTwoPi - 0.25, 1e-13);
  EXPECT_EQ(wrapCalOffset(kTwoPi), 0.0);
  const double tiny = wrapCalOffset(-1e-18);  // must not land on 2 pi itself
  EXPECT_GE(tiny, 0.0);
  EXPECT_LT(tiny, kTwoPi);
}

// The controller's joint angle q = (phi - cal) / k; the true one theta = q + delta. After the
// change, the joint must read the true angle at every motor angle.
TEST(CalOffsetChange, RemovesTheOffsetForEitherSign) {
  for (double k : {+120.0, -120.0, +80.0, -50.0}) {
    for (double delta : {+0.01, -0.007, 0.0}) {
      const double old_cal = 2.5;
      const CalOffsetChange c = calOffsetChange(3, delta, k, old_cal);
      EXPECT_EQ(c.turns, 0) << k << " " << delta;
      for (double phi : {-300.0, 0.0, 17.0}) {
        const double theta = (phi - old_cal) / k + delta;
        const double q_new = (phi - c.new_rad) / k;
        EXPECT_NEAR(q_new, theta, 1e-12) << "k " << k << " delta " << delta;
      }
    }
  }
}

TEST(CalOffsetChange, SignOfTheChangeIsMinusKTimesDelta) {
  const CalOffsetChange c = calOffsetChange(2, 0.001, 120.0, 3.0);
  EXPECT_NEAR(c.new_rad, 3.0 - 0.12, 1e-12);
  const CalOffsetChange d = calOffsetChange(2, 0.001, -120.0, 3.0);
  EXPECT_NEAR(d.new_rad, 3.0 + 0.12, 1e-12);
}

TEST(CalOffsetChange, CrossingTheSeamCountsTheTurnAndItsArmSideError) {
  // 0.067 - 120 x 0.001 = -0.053: wraps to 2 pi - 0.053, one turn up.
  const CalOffsetChange c = calOffsetChange(4, 0.001, 120.0, 0.067);
  EXPECT_TRUE(c.crossesSeam());
  EXPECT_EQ(c.turns, 1);
  EXPECT_NEAR(c.new_rad, kTwoPi - 0.053, 1e-12);
  // With the revolution counter on the old turn the joint reads 2 pi / k too little... which
  // is the whole motor turn on the arm side: 3 deg for k = 120.
  EXPECT_NEAR(c.turnErrorRad() * 180 / M_PI, 3.0, 1e-9);
  const CalOffsetChange d = calOffsetChange(4, -0.001, 120.0, 6.2);
  EXPECT_EQ(d.turns, -1);
  EXPECT_NEAR(d.new_rad, 6.32 - kTwoPi, 1e-12);
}

TEST(CalOffsetChange, RefusesWhatIsNotATransmissionOrACalOffset) {
  EXPECT_THROW(calOffsetChange(3, 0.01, 0.0, 1.0), InputError);
  EXPECT_THROW(calOffsetChange(3, 0.01, 0.5, 1.0), InputError);
  EXPECT_THROW(calOffsetChange(3, 0.01, 120.0, -0.1), InputError);
  EXPECT_THROW(calOffsetChange(3, 0.01, 120.0, 7.0), InputError);
  EXPECT_THROW(calOffsetChange(7, 0.01, 120.0, 1.0), InputError);
  EXPECT_THROW(calOffsetChange(3, NAN, 120.0, 1.0), InputError);
}

TEST(FormulaText, WritesEverySign) {
  const CalOffsetChange c = calOffsetChange(3, 0.00872665, 120.0, 5.54649);
  const std::string f = formulaText(c);
  EXPECT_NE(f.find("cal_offset_3 = wrap(5.546490 - (+120) x (+0.00872665 rad))"), std::string::npos)
      << f;
  EXPECT_NE(f.find("= wrap(+4.499292) = 4.499292 rad"), std::string::npos) << f;
  const std::string g = formulaText(calOffsetChange(5, -0.001, -80.0, 0.05));
  EXPECT_NE(g.find("(-80) x (-0.00100000 rad)"), std::string::npos) << g;
  EXPECT_NE(g.find("wrap(-0.030000)"), std::string::npos) << g;
  EXPECT_NE(g.find("+1 motor turn: crosses the 0 / 2 pi seam"), std::string::npos) << g;
}

TEST(MocNumber, SixSignificantDigitsAsTheController) {
  EXPECT_EQ(mocNumber(0.7282571), "0.728257");
  EXPECT_EQ(mocNumber(6.072449), "6.07245");
  EXPECT_EQ(mocNumber(0.067), "0.067");
  EXPECT_EQ(mocNumber(4.3e-6), "4.3E-06");
}

}  // namespace
}  // namespace zerocal::apply
