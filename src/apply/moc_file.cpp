#include "zerocal/apply/moc_file.h"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <fstream>
#include <regex>
#include <sstream>

#include "zerocal/apply/motor_calibration.h"

namespace zerocal::apply {

namespace {

constexpr const char* kHeader = "MOC:CFG_1.0:";

// MOTOR_CALIB attributes seen in controller backups (RobotWare 5 and 6). An instance to be
// changed that carries anything else is refused: we would not know whether it bears on the zero.
const char* const kMotorCalibAttributes[] = {"name",
                                             "com_offset",
                                             "valid_com_offset",
                                             "cal_offset",
                                             "valid_cal_offset",
                                             "fine_cal_position",
                                             "factory_calibration_method",
                                             "latest_calibration_method"};

struct PhysicalLine {
  std::size_t begin = 0, end = 0;  // content, line ending excluded
};

std::vector<PhysicalLine> splitLines(const std::string& text) {
  std::vector<PhysicalLine> lines;
  std::size_t begin = 0;
  while (begin < text.size()) {
    std::size_t nl = text.find('\n', begin);
    const std::size_t next = nl == std::string::npos ? text.size() : nl + 1;
    std::size_t end = nl == std::string::npos ? text.size() : nl;
    if (end > begin && text[end - 1] == '\r') --end;
    lines.push_back({begin, end});
    begin = next;
  }
  return lines;
}

bool blank(const std::string& s) {
  return std::all_of(s.begin(), s.end(), [](unsigned char c) { return std::isspace(c); });
}

std::string trimmed(const std::string& s) {
  const auto b = s.find_first_not_of(" \t");
  if (b == std::string::npos) return {};
  const auto e = s.find_last_not_of(" \t");
  return s.substr(b, e - b + 1);
}

bool isAttributeToken(const std::string& text, std::size_t pos) {
  return text[pos] == '-' && pos + 1 < text.size() &&
         (std::isalpha(static_cast<unsigned char>(text[pos + 1])) || text[pos + 1] == '_');
}

struct Token {
  std::size_t begin = 0, end = 0;
};

// Tokens of the physical lines [first, last] of one logical line: whitespace separates them, a
// trailing backslash continues the line, a quoted string may hold spaces.
bool tokenize(const std::string& text, const std::vector<PhysicalLine>& lines, std::size_t first,
              std::size_t last, std::vector<Token>* tokens, std::string* problem) {
  for (std::size_t li = first; li <= last; ++li) {
    std::size_t end = lines[li].end;
    if (li < last) --end;  // the continuation backslash
    std::size_t p = lines[li].begin;
    while (p < end) {
      if (std::isspace(static_cast<unsigned char>(text[p]))) {
        ++p;
        continue;
      }
      Token t{p, p};
      if (text[p] == '"') {
        const std::size_t close = text.find('"', p + 1);
        if (close == std::string::npos || close >= end) {
          *problem = "line " + std::to_string(li + 1) + ": a quoted string is not closed";
          return false;
        }
        p = close + 1;
        if (p < end && !std::isspace(static_cast<unsigned char>(text[p]))) {
          *problem = "line " + std::to_string(li + 1) + ": text glued to a quoted string";
          return false;
        }
      } else {
        while (p < end && !std::isspace(static_cast<unsigned char>(text[p])) && text[p] != '"') ++p;
        if (p < end && text[p] == '"') {
          *problem = "line " + std::to_string(li + 1) + ": a quote inside a word";
          return false;
        }
      }
      t.end = p;
      tokens->push_back(t);
    }
  }
  return true;
}

bool parseNumber(const std::string& s, double* v) {
  if (s.empty()) return false;
  char* end = nullptr;
  *v = std::strtod(s.c_str(), &end);
  return end == s.c_str() + s.size() && std::isfinite(*v);
}

std::string physicalLines(const std::string& text, std::size_t begin, std::size_t end) {
  // From the start of begin's physical line to end.
  const std::size_t line_start = text.rfind('\n', begin == 0 ? 0 : begin - 1);
  const std::size_t from = (line_start == std::string::npos || begin == 0) ? 0 : line_start + 1;
  return text.substr(from, end - from);
}

// The instance to change, checked: present once, only known attributes, a numeric cal_offset in
// range, flags where flags belong.
const MocInstance& motorCalib(const MocFile& file, const std::string& instance) {
  const MocInstance* in = file.find("MOTOR_CALIB", instance);
  if (!in)
    throw MocFormatError(file.origin, {"no MOTOR_CALIB instance \"" + instance +
                                       "\": not a backup of this robot, or not a MOC.cfg"});
  std::vector<std::string> problems;
  const std::string where =
      "line " + std::to_string(in->line) + ": MOTOR_CALIB \"" + instance + "\": ";
  for (const MocAttribute& a : in->attributes) {
    const bool known =
        std::any_of(std::begin(kMotorCalibAttributes), std::end(kMotorCalibAttributes),
                    [&](const char* k) { return a.name == k; });
    if (!known)
      problems.push_back(where + "attribute -" + a.name +
                         " is not one zerocal knows in MOTOR_CALIB; refusing to change this "
                         "instance");
  }
  if (const MocAttribute* c = in->find("cal_offset")) {
    double v = 0;
    if (!c->value || !parseNumber(*c->value, &v))
      problems.push_back(where + "-cal_offset has no numeric value");
    else if (!(v >= 0 && v < kTwoPi))
      problems.push_back(where + "-cal_offset " + *c->value +
                         " is outside [0, 2 pi), unlike every controller backup zerocal knows");
  }
  if (const MocAttribute* f = in->find("valid_cal_offset"); f && f->value)
    problems.push_back(where + "-valid_cal_offset carries a value; it is a flag");
  if (!problems.empty()) throw MocFormatError(file.origin, std::move(problems));
  return *in;
}

}  // namespace

const MocAttribute* MocInstance::find(const std::string& attribute) const {
  for (const auto& a : attributes)
    if (a.name == attribute) return &a;
  return nullptr;
}

const MocInstance* MocFile::find(const std::string& type, const std::string& name) const {
  const MocInstance* found = nullptr;
  for (const auto& in : instances) {
    if (in.type != type || in.name != name) continue;
    if (found)
      throw MocFormatError(origin,
                           {type + " instance \"" + name + "\" appears twice (lines " +
                            std::to_string(found->line) + " and " + std::to_string(in.line) + ")"});
    found = &in;
  }
  return found;
}

MocFile parseMocFile(std::string text, const std::string& origin) {
  MocFile file;
  file.origin = origin;
  file.text = std::move(text);
  const std::string& t = file.text;
  std::vector<std::string> problems;
  if (t.compare(0, std::char_traits<char>::length(kHeader), kHeader) != 0)
    throw MocFormatError(origin, {"line 1: not a MOC.cfg (expected a first line starting with '" +
                                  std::string(kHeader) + "')"});
  const std::vector<PhysicalLine> lines = splitLines(t);
  static const std::regex type_line("[A-Za-z0-9_]+:[ \t]*");
  std::string type;
  for (std::size_t i = 1; i < lines.size(); ++i) {
    const std::string content = t.substr(lines[i].begin, lines[i].end - lines[i].begin);
    const std::string where = "line " + std::to_string(i + 1) + ": ";
    if (blank(content)) continue;
    const std::string trim = trimmed(content);
    if (trim == "#") {
      type.clear();
      continue;
    }
    if (std::regex_match(content, type_line)) {
      type = trim.substr(0, trim.find(':'));
      continue;
    }
    if (trim[0] != '-') {
      problems.push_back(where + "not understood: '" + trim.substr(0, 60) + "'");
      continue;
    }
    // An instance: its logical line runs while physical lines end with a backslash.
    std::size_t last = i;
    while (last < lines.size() && lines[last].end > lines[last].begin &&
           t[lines[last].end - 1] == '\\')
      ++last;
    if (last == lines.size()) {
      problems.push_back(where + "the last line ends with a continuation backslash");
      break;
    }
    MocInstance in;
    in.type = type;
    in.line = static_cast<int>(i + 1);
    in.begin = lines[i].begin + content.find('-');
    in.end = lines[last].end;
    const std::size_t first = i;
    i = last;
    if (type.empty()) {
      problems.push_back(where + "an instance outside any type (no 'TYPE:' line before it)");
      continue;
    }
    std::vector<Token> tokens;
    std::string problem;
    if (!tokenize(t, lines, first, last, &tokens, &problem)) {
      problems.push_back(problem);
      continue;
    }
    bool ok = true;
    for (std::size_t k = 0; k < tokens.size() && ok; ++k) {
      const Token& tk = tokens[k];
      if (!isAttributeToken(t, tk.begin)) {
        problems.push_back(where + "a value without an attribute: '" +
                           t.substr(tk.begin, tk.end - tk.begin) + "'");
        ok = false;
        break;
      }
      MocAttribute a;
      a.name = t.substr(tk.begin + 1, tk.end - tk.begin - 1);
      a.begin = tk.begin;
      a.value_begin = a.value_end = tk.end;
      if (k + 1 < tokens.size() && !isAttributeToken(t, tokens[k + 1].begin)) {
        ++k;
        a.value = t.substr(tokens[k].begin, tokens[k].end - tokens[k].begin);
        a.value_begin = tokens[k].begin;
        a.value_end = tokens[k].end;
      }
      if (in.find(a.name)) {
        problems.push_back(where + "attribute -" + a.name + " given twice");
        ok = false;
      }
      in.attributes.push_back(std::move(a));
    }
    if (!ok) continue;
    const MocAttribute* name = in.attributes.empty() ? nullptr : &in.attributes.front();
    if (!name || name->name != "name" || !name->value || name->value->size() < 2 ||
        name->value->front() != '"') {
      problems.push_back(where + "an instance must start with -name \"...\"");
      continue;
    }
    in.name = name->value->substr(1, name->value->size() - 2);
    file.instances.push_back(std::move(in));
  }
  if (!problems.empty()) throw MocFormatError(origin, std::move(problems));
  return file;
}

MocFile readMocFile(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw MocFormatError(path, {"cannot open the file"});
  std::stringstream text;
  text << in.rdbuf();
  return parseMocFile(text.str(), path);
}

double presentCalOffset(const MocFile& file, const std::string& instance) {
  const MocInstance& in = motorCalib(file, instance);
  double v = 0;
  if (const MocAttribute* c = in.find("cal_offset")) parseNumber(*c->value, &v);
  return v;
}

std::string withCalOffsets(const MocFile& file, const std::vector<CalOffsetEdit>& edits,
                           std::vector<MocChange>* changes) {
  struct Splice {
    std::size_t at, erase;
    std::string insert;
  };
  std::vector<Splice> splices;
  std::vector<MocChange> out;
  for (const CalOffsetEdit& e : edits) {
    const MocInstance& in = motorCalib(file, e.instance);
    if (!(e.new_rad >= 0 && e.new_rad < kTwoPi))
      throw MocFormatError(file.origin, {e.instance + ": the new cal_offset is outside [0, 2 pi)"});
    std::string number = mocNumber(e.new_rad);
    if (std::strtod(number.c_str(), nullptr) >= kTwoPi) number = "0";  // rounded up onto 2 pi
    const MocAttribute* cal = in.find("cal_offset");
    const MocAttribute* valid = in.find("valid_cal_offset");
    // Where text goes in front of the attribute after `a`, or at the end of the logical line.
    const auto after = [&](const MocAttribute& a) -> std::pair<std::size_t, bool> {
      for (std::size_t k = 0; k + 1 < in.attributes.size(); ++k)
        if (&in.attributes[k] == &a) return {in.attributes[k + 1].begin, true};
      return {in.end, false};
    };
    const std::size_t first_splice = splices.size();
    if (cal) {
      splices.push_back({cal->value_begin, cal->value_end - cal->value_begin, number});
      if (!valid) {
        const auto [at, before_token] = after(*cal);
        splices.push_back(
            {at, 0, before_token ? "-valid_cal_offset " : std::string(" -valid_cal_offset ")});
      }
    } else if (valid) {
      // As the controller orders them: ... -cal_offset V -valid_cal_offset ...
      splices.push_back({valid->begin, 0, "-cal_offset " + number + " "});
    } else {
      const MocAttribute* anchor = in.find("valid_com_offset");
      if (!anchor) anchor = in.find("com_offset");
      if (!anchor) anchor = &in.attributes.front();
      const auto [at, before_token] = after(*anchor);
      const std::string text = "-cal_offset " + number + " -valid_cal_offset ";
      splices.push_back({at, 0, before_token ? text : " " + text});
    }
    MocChange change;
    change.instance = e.instance;
    change.line = in.line;
    change.had_valid_flag = valid != nullptr;
    if (cal) change.old_rad = std::strtod(cal->value->c_str(), nullptr);
    // The changed instance on its own, for the diff.
    std::string after_text = file.text.substr(0, in.end);
    std::vector<Splice> mine(splices.begin() + static_cast<long>(first_splice), splices.end());
    std::sort(mine.begin(), mine.end(),
              [](const Splice& a, const Splice& b) { return a.at > b.at; });
    for (const Splice& s : mine) after_text.replace(s.at, s.erase, s.insert);
    change.before = physicalLines(file.text, in.begin, in.end);
    const std::size_t grown = after_text.size() - in.end;
    change.after = physicalLines(after_text, in.begin, in.end + grown);
    out.push_back(std::move(change));
  }
  std::sort(splices.begin(), splices.end(),
            [](const Splice& a, const Splice& b) { return a.at > b.at; });
  std::string text = file.text;
  for (const Splice& s : splices) text.replace(s.at, s.erase, s.insert);
  if (changes) *changes = std::move(out);
  return text;
}

std::string diffText(const std::vector<MocChange>& changes) {
  std::ostringstream s;
  const auto lines = [&](const std::string& block, char mark) {
    std::istringstream in(block);
    std::string line;
    while (std::getline(in, line)) {
      if (!line.empty() && line.back() == '\r') line.pop_back();
      s << mark << ' ' << line << "\n";
    }
  };
  for (const MocChange& c : changes) {
    s << "MOTOR_CALIB \"" << c.instance << "\" (line " << c.line << "):\n";
    lines(c.before, '-');
    lines(c.after, '+');
  }
  return s.str();
}

std::optional<std::string> robotType(const MocFile& file) {
  for (const auto& in : file.instances)
    if (in.type == "ROBOT")
      if (const MocAttribute* a = in.find("use_robot_type"); a && a->value && a->value->size() >= 2)
        return a->value->substr(1, a->value->size() - 2);
  return std::nullopt;
}

std::optional<double> transmissionOf(const MocFile& file, const std::string& instance) {
  const MocInstance* in = file.find("TRANSMISSION", instance);
  if (!in) return std::nullopt;
  const MocAttribute* a = in->find("transm_joint");
  double v = 0;
  if (!a || !a->value || !parseNumber(*a->value, &v)) return std::nullopt;
  return v;
}

}  // namespace zerocal::apply
