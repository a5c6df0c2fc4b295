// Writes that survive a crash or a power cut once they return: what the session files need.
// Each throws zerocal::FileError naming the path and the system's reason.
#pragma once

#include <string>

namespace zerocal {

// mkdir -p that fsync()s the parent of every folder it creates.
void makeDirsDurably(const std::string& dir);
// Replaces `path` by `text` atomically: a temporary file (`path`.tmp, removed when the write
// fails), fsync, rename, fsync of the folder. A reader sees the old content or the new, never
// part of it.
void writeFileDurably(const std::string& path, const std::string& text);
// fsync()s a folder, so that an entry made in it (a file, a folder) is durable.
void syncFolder(const std::string& dir);
// Writes all of `data` to the open file `fd` (named `path` in messages), then fsync()s it.
void writeAllDurably(int fd, const std::string& data, const std::string& path);

}  // namespace zerocal
