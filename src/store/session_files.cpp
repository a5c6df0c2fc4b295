#include "zerocal/store/session_files.h"

#include <filesystem>
#include <fstream>

#include "zerocal/error.h"

namespace zerocal {
namespace {

namespace fs = std::filesystem;
using Json = nlohmann::json;

}  // namespace

Json readJsonFile(const std::string& path, const std::string& what) {
  std::ifstream in(path);
  if (!in)
    throw FileError(path + ": cannot open " + what + (fs::exists(path) ? "" : " (no such file)"));
  try {
    return Json::parse(in);
  } catch (const Json::exception& e) {
    throw FileError(path + ": " + what + " is not valid JSON: " + e.what());
  }
}

SessionFolder readSessionFolder(const std::string& session_dir) {
  const fs::path dir(session_dir);
  if (!fs::is_directory(dir)) throw FileError(session_dir + ": not a session folder");
  SessionFolder folder;
  folder.dir = session_dir;
  folder.session =
      sessionFileFromJson(readJsonFile((dir / kSessionFileName).string(), "the session file"));
  const fs::path result = dir / kResultFileName;
  if (!fs::exists(result))
    throw FileError(result.string() +
                    ": no result: the session is unfinished or its solve failed, so there is "
                    "nothing to report yet");
  folder.result = resultFileFromJson(readJsonFile(result.string(), "the result"));
  const fs::path journal = dir / kJournalFileName;
  if (!fs::exists(journal))
    throw FileError(journal.string() + ": no journal: the recorded poses are missing");
  folder.journal = readJournal(journal.string()).records;
  return folder;
}

}  // namespace zerocal
