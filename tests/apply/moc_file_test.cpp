// The MOC.cfg editor against fixtures in the format of public IRC5 backups (docs/apply.md names
// them): only cal_offset and its valid flag of the instances asked for change, every other byte
// stays; what is not understood is refused.
#include "zerocal/apply/moc_file.h"

#include <gtest/gtest.h>

#include <fstream>
#include <sstream>

namespace zerocal::apply {
namespace {

std::string readText(const std::string& name) {
  std::ifstream in(std::string(ZEROCAL_APPLY_DATA) + "/" + name, std::ios::binary);
  std::stringstream s;
  s << in.rdbuf();
  return s.str();
}

// Replaces the first `from` in `text`, which must be there.
std::string replaced(std::string text, const std::string& from, const std::string& to) {
  const auto at = text.find(from);
  EXPECT_NE(at, std::string::npos) << from;
  if (at != std::string::npos) text.replace(at, from.size(), to);
  return text;
}

std::string problemsOf(const std::string& text) {
  try {
    parseMocFile(text, "test.cfg");
  } catch (const MocFormatError& e) {
    return e.what();
  }
  return "";
}

TEST(MocFile, ParsesInstancesAcrossContinuationLines) {
  const MocFile f = parseMocFile(readText("irb1600_rw6.cfg"), "irb1600_rw6.cfg");
  const MocInstance* r3 = f.find("MOTOR_CALIB", "rob1_3");
  ASSERT_NE(r3, nullptr);
  EXPECT_EQ(r3->line, 57);
  ASSERT_NE(r3->find("cal_offset"), nullptr);
  EXPECT_EQ(*r3->find("cal_offset")->value, "2.00189");  // backslash glued to the value
  ASSERT_NE(r3->find("fine_cal_position"), nullptr);     // on the continuation line
  EXPECT_EQ(*r3->find("fine_cal_position")->value, "-133.623");
  EXPECT_FALSE(r3->find("valid_cal_offset")->value.has_value());  // a flag
  EXPECT_EQ(robotType(f), std::optional<std::string>("ROB1_1600_1.45_10"));
  EXPECT_FALSE(transmissionOf(f, "rob1_3").has_value());
  // A quoted value with a space in it, and a negative number, are values.
  const MocInstance* serial = f.find("ROBOT_SERIAL_NUMBER", "rob_1");
  ASSERT_NE(serial, nullptr);
  EXPECT_EQ(*f.find("ROBOT", "ROB_1")->find("base_mass_centre_x")->value, "-0.041");
  EXPECT_DOUBLE_EQ(presentCalOffset(f, "rob1_2"), 5.3999);
}

TEST(MocFile, OnlyTheChangedValuesDifferByteForByte) {
  const std::string original = readText("irb1600_rw6.cfg");
  const MocFile f = parseMocFile(original, "irb1600_rw6.cfg");
  std::vector<MocChange> changes;
  const std::string out = withCalOffsets(f, {{"rob1_2", 5.27990123}, {"rob1_3", 1.5}}, &changes);
  const std::string expected =
      replaced(replaced(original, "-cal_offset 5.3999 ", "-cal_offset 5.2799 "),
               "-cal_offset 2.00189\\", "-cal_offset 1.5\\");
  EXPECT_EQ(out, expected);
  ASSERT_EQ(changes.size(), 2u);
  EXPECT_EQ(changes[0].instance, "rob1_2");
  EXPECT_EQ(changes[0].old_rad, std::optional<double>(5.3999));
  // The rewritten file parses to the same instances, with the new values.
  const MocFile again = parseMocFile(out, "out.cfg");
  EXPECT_EQ(again.instances.size(), f.instances.size());
  EXPECT_DOUBLE_EQ(presentCalOffset(again, "rob1_3"), 1.5);
  EXPECT_DOUBLE_EQ(presentCalOffset(again, "rob1_4"), 0.067);
}

TEST(MocFile, CrlfLineEndingsAreKept) {
  std::string crlf;
  for (char c : readText("irb1600_rw6.cfg")) {
    if (c == '\n') crlf += '\r';
    crlf += c;
  }
  const MocFile f = parseMocFile(crlf, "crlf.cfg");
  const std::string out = withCalOffsets(f, {{"rob1_3", 1.5}});
  EXPECT_EQ(out, replaced(crlf, "-cal_offset 2.00189\\\r\n", "-cal_offset 1.5\\\r\n"));
}

TEST(MocFile, MissingCalOffsetIsInsertedWhereTheControllerPutsIt) {
  const std::string original = readText("no_cal_offset.cfg");
  const MocFile f = parseMocFile(original, "no_cal_offset.cfg");
  EXPECT_EQ(presentCalOffset(f, "rob1_2"), 0.0);  // absent: the default
  std::vector<MocChange> changes;
  const std::string out = withCalOffsets(
      f, {{"rob1_2", 0.25}, {"rob1_3", 0.5}, {"rob1_4", 0.75}, {"rob1_5", 1.25}}, &changes);
  std::string expected = original;
  // Before the valid flag, as "-valid_com_offset  -cal_offset 0.87718 -valid_cal_offset \".
  expected =
      replaced(expected, "\"rob1_2\" -com_offset 0.950014 -valid_com_offset  -valid_cal_offset \\",
               "\"rob1_2\" -com_offset 0.950014 -valid_com_offset  -cal_offset 0.25 "
               "-valid_cal_offset \\");
  // Neither value nor flag, instance ends after a flag (and its space): both appended, two
  // spaces after the flag as the controller writes them.
  expected = replaced(expected, "\"rob1_3\" -com_offset 0.950014 -valid_com_offset \n",
                      "\"rob1_3\" -com_offset 0.950014 -valid_com_offset  -cal_offset 0.5 "
                      "-valid_cal_offset \n");
  // A value without its flag: the flag added after it.
  expected = replaced(expected, "-cal_offset 4.93632\n", "-cal_offset 0.75 -valid_cal_offset \n");
  // Nothing but the name.
  expected = replaced(expected, "-name \"rob1_5\"\n",
                      "-name \"rob1_5\" -cal_offset 1.25 -valid_cal_offset \n");
  EXPECT_EQ(out, expected);
  ASSERT_EQ(changes.size(), 4u);
  EXPECT_FALSE(changes[0].old_rad.has_value());
  EXPECT_TRUE(changes[0].had_valid_flag);
  EXPECT_FALSE(changes[1].had_valid_flag);
  const MocFile again = parseMocFile(out, "out.cfg");
  for (const char* n : {"rob1_2", "rob1_3", "rob1_4", "rob1_5"}) {
    const MocInstance* in = again.find("MOTOR_CALIB", n);
    ASSERT_NE(in, nullptr);
    EXPECT_NE(in->find("valid_cal_offset"), nullptr) << n;
  }
  EXPECT_DOUBLE_EQ(presentCalOffset(again, "rob1_5"), 1.25);
}

TEST(MocFile, DiffShowsThePhysicalLinesBeforeAndAfter) {
  const MocFile f = parseMocFile(readText("irb1600_rw6.cfg"), "irb1600_rw6.cfg");
  std::vector<MocChange> changes;
  withCalOffsets(f, {{"rob1_3", 1.5}}, &changes);
  const std::string d = diffText(changes);
  EXPECT_NE(d.find("MOTOR_CALIB \"rob1_3\" (line 57):\n"
                   "-       -name \"rob1_3\" -com_offset 0.9425 -valid_com_offset  -cal_offset "
                   "2.00189\\\n"
                   "-       -valid_cal_offset  -fine_cal_position -133.623\n"
                   "+       -name \"rob1_3\" -com_offset 0.9425 -valid_com_offset  -cal_offset "
                   "1.5\\\n"
                   "+       -valid_cal_offset  -fine_cal_position -133.623\n"),
            std::string::npos)
      << d;
}

TEST(MocFile, RefusesWhatItDoesNotUnderstand) {
  const std::string good = readText("irb1600_rw6.cfg");
  ASSERT_EQ(problemsOf(good), "");
  EXPECT_NE(problemsOf("EIO:CFG_1.0:6:0::\n#\n").find("line 1: not a MOC.cfg"), std::string::npos);
  EXPECT_NE(problemsOf(replaced(good, "MOTOR_CALIB:", "MOTOR CALIB here"))
                .find("not understood: 'MOTOR CALIB here'"),
            std::string::npos);
  EXPECT_NE(problemsOf(good + "      -name \"x\" -a 1\\\n").find("continuation backslash"),
            std::string::npos);
  EXPECT_NE(problemsOf(replaced(good, "-name \"rob1_4\"", "-name \"rob1_4"))
                .find("a quoted string is not closed"),
            std::string::npos);
  EXPECT_NE(problemsOf(replaced(good, "-cal_offset 0.067", "-cal_offset 0.067 -cal_offset 1"))
                .find("attribute -cal_offset given twice"),
            std::string::npos);
  EXPECT_NE(problemsOf(replaced(good, "-cal_offset 0.067", "-cal_offset 0.067 0.5"))
                .find("a value without an attribute: '0.5'"),
            std::string::npos);
  EXPECT_NE(problemsOf(replaced(good, "-name \"rob1_6\"", "-nom \"rob1_6\""))
                .find("must start with -name"),
            std::string::npos);
  EXPECT_NE(problemsOf("MOC:CFG_1.0:6:0::\n      -name \"a\"\n").find("outside any type"),
            std::string::npos);
  // Every problem at once, each with its line: two broken type lines, and the instances they
  // leave outside any type.
  const std::string all =
      problemsOf(replaced(replaced(good, "#\nROBOT:", "#\nROBOT"), "ARM_CALIB:", "ARM_CALIB"));
  EXPECT_NE(all.find("5 problems"), std::string::npos) << all;
  EXPECT_NE(all.find("line 17: not understood: 'ROBOT'"), std::string::npos) << all;
  EXPECT_NE(all.find("line 41: not understood: 'ARM_CALIB'"), std::string::npos) << all;
  EXPECT_NE(all.find("line 45: an instance outside any type"), std::string::npos) << all;
}

TEST(MocFile, RefusesToChangeAnInstanceItDoesNotFullyKnow) {
  const std::string good = readText("irb1600_rw6.cfg");
  const auto refusal = [](const std::string& text, const std::string& instance) {
    try {
      withCalOffsets(parseMocFile(text, "t.cfg"), {{instance, 1.0}});
    } catch (const MocFormatError& e) {
      return std::string(e.what());
    }
    return std::string();
  };
  EXPECT_NE(refusal(good, "rob1_7").find("no MOTOR_CALIB instance \"rob1_7\""), std::string::npos);
  EXPECT_NE(refusal(replaced(good, "-cal_offset 0.067", "-cal_offset 0.067 -new_thing 2"), "rob1_4")
                .find("attribute -new_thing is not one zerocal knows"),
            std::string::npos);
  EXPECT_NE(refusal(replaced(good, "-cal_offset 0.067", "-cal_offset -0.067"), "rob1_4")
                .find("outside [0, 2 pi)"),
            std::string::npos);
  EXPECT_NE(refusal(replaced(good, "-cal_offset 0.067", "-cal_offset abc"), "rob1_4")
                .find("-cal_offset has no numeric value"),
            std::string::npos);
  const std::string twice = good + "#\nMOTOR_CALIB:\n\n      -name \"rob1_4\"\n";
  EXPECT_NE(refusal(twice, "rob1_4").find("appears twice"), std::string::npos);
  // An unknown attribute elsewhere is no reason to refuse.
  EXPECT_EQ(
      refusal(replaced(good, "-cal_offset 0.067", "-cal_offset 0.067 -new_thing 2"), "rob1_3"), "");
}

TEST(MocFile, ReadsATransmissionWhenTheBackupHasOne) {
  const std::string text = readText("irb1600_rw6.cfg") +
                           "#\nTRANSMISSION:\n\n      -name \"rob1_3\" -transm_joint -117.5\n";
  EXPECT_EQ(transmissionOf(parseMocFile(text, "t.cfg"), "rob1_3"), std::optional<double>(-117.5));
}

}  // namespace
}  // namespace zerocal::apply
