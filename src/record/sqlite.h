// A thin C++ hold on SQLite's C API for the record: a connection, a statement, a transaction,
// each closed by its destructor, and every failure a FileError naming the database and what was
// being done (DamagedRecordError when SQLite says the file is no database or is corrupt).
#pragma once

#include <sqlite3.h>

#include <cstdint>
#include <optional>
#include <string>

#include "zerocal/record/sqlite_record.h"

namespace zerocal::record::sqlite {

// Throws DamagedRecordError for SQLITE_NOTADB and SQLITE_CORRUPT, FileError otherwise.
[[noreturn]] void fail(sqlite3* db, int code, const std::string& path, const std::string& doing);

class Connection {
 public:
  // Opens (creating) the database file. Throws FileError.
  explicit Connection(const std::string& path);
  ~Connection();
  Connection(const Connection&) = delete;
  Connection& operator=(const Connection&) = delete;

  // Runs statements that return no rows of interest. Throws as fail().
  void exec(const std::string& sql, const std::string& doing);
  // The first column of the first row of a one-value query (a PRAGMA), as text.
  std::string value(const std::string& sql, const std::string& doing);
  sqlite3* get() const { return db_; }
  const std::string& path() const { return path_; }

 private:
  std::string path_;
  sqlite3* db_ = nullptr;
};

class Statement {
 public:
  Statement(Connection& db, const char* sql, std::string doing);
  ~Statement();
  Statement(const Statement&) = delete;
  Statement& operator=(const Statement&) = delete;

  // Parameters count from 1, as SQLite's.
  Statement& bind(int i, const std::string& text);
  Statement& bind(int i, double value);
  Statement& bind(int i, std::int64_t value);
  Statement& bind(int i, int value) { return bind(i, static_cast<std::int64_t>(value)); }
  Statement& bind(int i, bool value) { return bind(i, static_cast<std::int64_t>(value)); }
  Statement& bindNull(int i);
  template <typename T>
  Statement& bind(int i, const std::optional<T>& value) {
    return value ? bind(i, *value) : bindNull(i);
  }
  // True with a row to read, false when done. Throws as fail().
  bool step();
  // step() for a statement that returns no row.
  void run();
  // Ready to bind and step again.
  void reset();

  // Columns count from 0.
  bool isNull(int i) const;
  std::string text(int i) const;
  double real(int i) const;
  std::int64_t integer(int i) const;
  std::optional<double> optionalReal(int i) const;

 private:
  Connection& db_;
  std::string doing_;
  sqlite3_stmt* stmt_ = nullptr;
};

// BEGIN IMMEDIATE (the write lock now, not at the first write); rolled back unless committed.
class Transaction {
 public:
  explicit Transaction(Connection& db);
  ~Transaction();
  void commit();

 private:
  Connection& db_;
  bool open_ = true;
};

}  // namespace zerocal::record::sqlite
