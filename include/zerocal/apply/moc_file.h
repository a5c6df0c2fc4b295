// A MOC.cfg from an ABB IRC5 backup (SYSPAR/MOC.cfg), read so that it can be written back with a
// few attribute values changed and every other byte as it was.
//
// The format, as the controller writes it (public backups; docs/apply.md cites them):
//
//   MOC:CFG_1.0:6:0::          header: domain, format version, RobotWare major
//   #                          separates types
//   MOTOR_CALIB:               a type, then instances with blank lines between them:
//         -name "rob1_2" -valid_com_offset  -cal_offset 2.26943 -valid_cal_offset (backslash)
//         -fine_cal_position -6.34389
//
// An instance is one logical line, continued onto the next physical line by a trailing backslash.
//
// An attribute is "-name value" (a number, a bare word or a "quoted string") or "-name" alone, a
// flag (present = TRUE). The controller omits attributes at their default value.
#pragma once

#include <cstddef>
#include <optional>
#include <string>
#include <vector>

#include "zerocal/error.h"

namespace zerocal::apply {

// A MOC.cfg that zerocal does not fully understand, or that does not hold what an edit needs.
// Carries every problem found.
class MocFormatError : public ConfigError {
 public:
  using ConfigError::ConfigError;
};

struct MocAttribute {
  std::string name;                            // without the leading '-'
  std::optional<std::string> value;            // nullopt: a flag; quoted strings keep their quotes
  std::size_t begin = 0;                       // byte offset of the '-'
  std::size_t value_begin = 0, value_end = 0;  // byte range of the value (flags: end of name)
};

struct MocInstance {
  std::string type;                      // "MOTOR_CALIB"
  std::string name;                      // "rob1_2", without quotes
  std::vector<MocAttribute> attributes;  // in file order, "name" first
  std::size_t begin = 0, end = 0;        // byte range of the logical line, line ending excluded
  int line = 0;                          // 1-based physical line where it starts

  const MocAttribute* find(const std::string& attribute) const;
};

struct MocFile {
  std::string origin;  // file name, for messages
  std::string text;    // the bytes as read
  std::vector<MocInstance> instances;

  // nullptr when absent. Throws MocFormatError when the instance appears more than once.
  const MocInstance* find(const std::string& type, const std::string& name) const;
};

// Parses the whole text and refuses (MocFormatError, every problem with its line) anything that
// is not the format above: a missing or foreign header, a line that is neither separator, type,
// blank nor instance, an instance outside a type or not starting with -name, a continuation at
// the end of the file, an unterminated quote, an attribute given twice in one instance.
MocFile parseMocFile(std::string text, const std::string& origin);
MocFile readMocFile(const std::string& path);

// One new MOTOR_CALIB cal_offset.
struct CalOffsetEdit {
  std::string instance;  // "rob1_3"
  double new_rad = 0;    // in [0, 2 pi)
};

// The physical lines of one changed instance, before and after.
struct MocChange {
  std::string instance;
  int line = 0;  // 1-based, in the file as read
  std::string before, after;
  std::optional<double> old_rad;  // nullopt: the instance had no -cal_offset (default 0)
  bool had_valid_flag = false;
};

// The present cal_offset of a MOTOR_CALIB instance: its value, or 0 when the attribute is absent
// (the controller omits defaults). Throws MocFormatError when the instance is missing, repeated,
// carries an attribute zerocal does not know in that type, or a cal_offset that is not a number
// in [0, 2 pi).
double presentCalOffset(const MocFile& file, const std::string& instance);

// The file's text with, for each edit, the instance's cal_offset set (written as the controller
// writes numbers, inserted before -valid_cal_offset when absent) and its -valid_cal_offset flag
// present; every other byte unchanged. Throws MocFormatError as presentCalOffset.
std::string withCalOffsets(const MocFile& file, const std::vector<CalOffsetEdit>& edits,
                           std::vector<MocChange>* changes = nullptr);

// "-"/"+" lines per changed instance, for the terminal.
std::string diffText(const std::vector<MocChange>& changes);

// The ROBOT instance's -use_robot_type (e.g. "ROB1_1600_1.45_10"), or nullopt.
std::optional<std::string> robotType(const MocFile& file);

// -transm_joint of TRANSMISSION instance `instance`, when the file carries it.
std::optional<double> transmissionOf(const MocFile& file, const std::string& instance);

}  // namespace zerocal::apply
