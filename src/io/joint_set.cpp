#include "zerocal/io/joint_set.h"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <iomanip>
#include <regex>
#include <sstream>

#include "zerocal/error.h"

namespace zerocal {
namespace {

constexpr const char* kUtf8Bom = "\xEF\xBB\xBF";

std::string trim(const std::string& s) {
  const auto b = s.find_first_not_of(" \t\r");
  if (b == std::string::npos) return {};
  return s.substr(b, s.find_last_not_of(" \t\r") - b + 1);
}

std::vector<std::string> splitFields(const std::string& line) {
  std::vector<std::string> out;
  std::stringstream s(line);
  std::string field;
  while (std::getline(s, field, ',')) out.push_back(trim(field));
  if (!line.empty() && line.back() == ',') out.emplace_back();
  return out;
}

}  // namespace

std::vector<Pose> parseJointSet(const std::string& text, const std::string& origin) {
  std::istringstream in(text);
  std::string line;
  int line_no = 0;
  std::vector<int> column(9, -1);  // q1..q6, u, v, placement
  bool have_header = false;
  std::size_t header_fields = 0;
  std::vector<Pose> poses;
  auto fail = [&](const std::string& what) {
    throw InputError(origin + ":" + std::to_string(line_no) + ": " + what);
  };
  while (std::getline(in, line)) {
    ++line_no;
    std::string t = trim(line);
    // A spreadsheet's byte-order mark would make "q1" a different, invisible name.
    if (line_no == 1 && t.rfind(kUtf8Bom, 0) == 0) t = trim(t.substr(3));
    if (t.empty() || t[0] == '#') continue;
    const auto fields = splitFields(t);
    if (!have_header) {
      static const char* names[9] = {"q1", "q2", "q3", "q4", "q5", "q6", "u", "v", "placement"};
      for (std::size_t i = 0; i < fields.size(); ++i)
        for (int k = 0; k < 9; ++k)
          if (fields[i] == names[k]) {
            if (column[k] >= 0) fail("column '" + fields[i] + "' appears twice in the header");
            column[k] = static_cast<int>(i);
          }
      std::string missing;
      for (int k = 0; k < 6; ++k)
        if (column[k] < 0) missing += std::string(missing.empty() ? "" : ", ") + names[k];
      if (!missing.empty())
        fail("the header must name the columns q1..q6 (missing: " + missing + "); it has " +
             std::to_string(fields.size()) + " columns");
      if ((column[6] < 0) != (column[7] < 0)) fail("the header has only one of u and v");
      have_header = true;
      header_fields = fields.size();
      continue;
    }
    if (fields.size() != header_fields)
      fail("expected " + std::to_string(header_fields) + " fields as in the header, found " +
           std::to_string(fields.size()));
    auto value = [&](int k) {
      const std::string& f = fields[column[k]];
      // Decimal notation only: strtod would also take hex ("0x1p3"), "inf" and "nan". The field
      // itself is not echoed: an error message never shows a file's content.
      static const std::regex kDecimal(R"([+-]?([0-9]+\.?[0-9]*|\.[0-9]+)([eE][+-]?[0-9]+)?)");
      if (!std::regex_match(f, kDecimal))
        fail("column " + std::to_string(column[k] + 1) + " is not a decimal number");
      const double v = std::strtod(f.c_str(), nullptr);
      if (!std::isfinite(v)) fail("column " + std::to_string(column[k] + 1) + " is not finite");
      return v;
    };
    Pose pose;
    pose.source_line = line_no;
    for (int k = 0; k < 6; ++k) pose.q_deg[k] = value(k);
    if (column[6] >= 0) pose.spot = PsdSpot{value(6), value(7)};
    if (column[8] >= 0) {
      const std::string& f = fields[column[8]];
      static const std::regex kWhole(R"([0-9]{1,9})");
      const int placement = std::regex_match(f, kWhole) ? std::atoi(f.c_str()) : 0;
      if (placement < 1 || placement > kMaxPlacements)
        fail("column " + std::to_string(column[8] + 1) +
             " (placement) is not a whole number from 1 to " + std::to_string(kMaxPlacements));
      pose.placement = placement;
    }
    if (poses.size() >= kMaxJointSetPoses)
      fail("more than " + std::to_string(kMaxJointSetPoses) + " poses: not a joint set");
    poses.push_back(pose);
  }
  if (!have_header) throw InputError(origin + ": empty file: expected a header naming q1..q6");
  return poses;
}

std::vector<Pose> readJointSet(const std::string& path) {
  // O_NONBLOCK: opening a FIFO must not wait for a writer; only a regular file is read at all.
  const int fd = ::open(path.c_str(), O_RDONLY | O_NONBLOCK | O_CLOEXEC);
  if (fd < 0) throw InputError(path + ": cannot open the joint-set file: " + std::strerror(errno));
  struct stat st {};
  std::string text;
  std::string problem;
  if (::fstat(fd, &st) != 0)
    problem = std::strerror(errno);
  else if (!S_ISREG(st.st_mode))
    problem = "not a regular file";
  else if (st.st_size > static_cast<off_t>(kMaxJointSetBytes))
    problem = "larger than " + std::to_string(kMaxJointSetBytes >> 20) + " MiB: not a joint set";
  for (char buffer[65536]; problem.empty() && text.size() <= kMaxJointSetBytes;) {
    const ssize_t n = ::read(fd, buffer, sizeof buffer);
    if (n < 0 && errno == EINTR) continue;
    if (n < 0) problem = std::strerror(errno);
    if (n <= 0) break;
    text.append(buffer, static_cast<std::size_t>(n));
  }
  ::close(fd);
  if (problem.empty() && text.size() > kMaxJointSetBytes) problem = "grew while it was read";
  if (!problem.empty()) throw InputError(path + ": cannot use it as a joint-set file: " + problem);
  return parseJointSet(text, path);
}

std::string formatJointSet(const std::vector<Pose>& poses, const std::string& comment) {
  std::ostringstream out;
  if (!comment.empty()) {
    std::istringstream lines(comment);
    std::string l;
    while (std::getline(lines, l)) out << "# " << l << "\n";
  }
  bool with_uv = !poses.empty();
  for (const auto& p : poses) with_uv = with_uv && p.spot.has_value();
  bool with_placement = false;
  for (const auto& p : poses) with_placement = with_placement || p.placement != 1;
  out << "q1,q2,q3,q4,q5,q6" << (with_uv ? ",u,v" : "") << (with_placement ? ",placement" : "")
      << "\n";
  // Fixed notation with 5 decimals at any magnitude: a bounded buffer would cut a large value
  // short, and what was read would not read back.
  out << std::fixed << std::setprecision(5);
  for (const auto& p : poses) {
    for (int k = 0; k < kJointCount; ++k) out << (k ? "," : "") << p.q_deg[k];
    if (with_uv) out << "," << p.spot->u_mm << "," << p.spot->v_mm;
    if (with_placement) out << "," << p.placement;
    out << "\n";
  }
  return out.str();
}

}  // namespace zerocal
