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

// The one name `word` may have meant, or "" when none is close (more than two edits) or two are
// as close. A word that begins exactly one name means it; an acting name yields to any other
// within two edits.
std::string nearestName(const std::string& word, const std::vector<std::string>& names,
                        const std::set<std::string>& acting) {
  std::vector<std::string> prefixed;
  for (const std::string& n : names)
    if (n.rfind(word, 0) == 0) prefixed.push_back(n);
  if (prefixed.size() == 1) return prefixed.front();
  constexpr std::size_t kFarthest = 2;
  // The nearest name within kFarthest edits among those `among` accepts; tied: none.
  const auto nearestOf = [&](auto among, bool* any_close) {
    std::string nearest;
    std::size_t best = kFarthest + 1;
    bool tie = false;
    for (const std::string& n : names) {
      if (!among(n)) continue;
      const std::size_t d = editDistance(word, n);
      if (d < best) {
        best = d, nearest = n, tie = false;
      } else if (d == best) {
        tie = true;
      }
    }
    *any_close = best <= kFarthest;
    return tie ? std::string() : nearest;
  };
  bool quiet_close = false, any_close = false;
  const std::string quiet =
      nearestOf([&](const std::string& n) { return acting.count(n) == 0; }, &quiet_close);
  if (quiet_close) return quiet;  // "" when two are as near: say neither
  return nearestOf([](const std::string&) { return true; }, &any_close);
}

std::vector<std::string> commandNames(const CLI::App& app) {
  std::vector<std::string> names;
  for (const CLI::App* c : app.get_subcommands([](const CLI::App*) { return true; }))
    names.push_back(c->get_name());
  return names;
}

}  // namespace

bool refuseUnknownCommand(const CLI::App& app, const std::string& word, std::ostream& err,
                          const std::set<std::string>& acting) {
  const std::string program = app.get_name();
  if (word.rfind("--", 0) == 0) {
    const std::string name = word.substr(0, word.find('='));
    std::vector<std::string> options;
    for (const CLI::Option* o : app.get_options())
      for (const std::string& l : o->get_lnames()) options.push_back("--" + l);
    if (name == "--" || std::find(options.begin(), options.end(), name) != options.end())
      return false;
    err << program << ": unknown option '" << name << "'";
    if (const std::string n = nearestName(name, options, {}); !n.empty())
      err << "; did you mean '" << n << "'?";
    err << " (" << program << " --help)\n";
    return true;
  }
  if (word.empty() || word[0] == '-') return false;
  const std::vector<std::string> names = commandNames(app);
  if (std::find(names.begin(), names.end(), word) != names.end()) return false;
  err << program << ": unknown command '" << word << "'";
  if (const std::string n = nearestName(word, names, acting); !n.empty())
    err << "; did you mean '" << n << "'?";
  err << " (" << program << " --help lists the commands)\n";
  return true;
}

int answerHelp(const CLI::App& app, const std::vector<std::string>& words, std::ostream& out,
               std::ostream& err) {
  if (words.empty() || words.front() != "help") return -1;
  if (words.size() == 1) {
    out << app.help();
    return 0;
  }
  if (words.size() > 2) {
    err << app.get_name() << ": help takes one command (" << app.get_name() << " help COMMAND)\n";
    return 2;
  }
  for (const CLI::App* c : app.get_subcommands([](const CLI::App*) { return true; }))
    if (c->get_name() == words[1]) {
      out << c->help();
      return 0;
    }
  refuseUnknownCommand(app, words[1], err);
  return 2;
}

}  // namespace zerocal::cli
