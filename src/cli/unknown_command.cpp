#include "unknown_command.h"

#include <algorithm>
#include <vector>

namespace zerocal::cli {
namespace {

// Edits (insert, delete, substitute, swap two neighbours) from one word to the other.
std::size_t editDistance(const std::string& a, const std::string& b) {
  std::vector<std::vector<std::size_t>> d(a.size() + 1, std::vector<std::size_t>(b.size() + 1));
  for (std::size_t i = 0; i <= a.size(); ++i) d[i][0] = i;
  for (std::size_t j = 0; j <= b.size(); ++j) d[0][j] = j;
  for (std::size_t i = 1; i <= a.size(); ++i)
    for (std::size_t j = 1; j <= b.size(); ++j) {
      d[i][j] = std::min(
          {d[i - 1][j] + 1, d[i][j - 1] + 1, d[i - 1][j - 1] + (a[i - 1] == b[j - 1] ? 0 : 1)});
      if (i > 1 && j > 1 && a[i - 1] == b[j - 2] && a[i - 2] == b[j - 1])
        d[i][j] = std::min(d[i][j], d[i - 2][j - 2] + 1);
    }
  return d[a.size()][b.size()];
}

}  // namespace

bool refuseUnknownCommand(const CLI::App& app, const std::string& word, std::ostream& err) {
  if (word.empty() || word[0] == '-') return false;
  std::string nearest;
  std::size_t best = 3;  // more edits than two: no suggestion
  for (const CLI::App* c : app.get_subcommands([](const CLI::App*) { return true; })) {
    if (c->get_name() == word) return false;
    const std::size_t d = editDistance(word, c->get_name());
    if (d < best) best = d, nearest = c->get_name();
  }
  const std::string program = app.get_name();
  err << program << ": unknown command '" << word << "'";
  if (!nearest.empty()) err << "; did you mean '" << nearest << "'?";
  err << " (" << program << " --help lists the commands)\n";
  return true;
}

}  // namespace zerocal::cli
