#include "sqlite.h"

namespace zerocal::record::sqlite {

void fail(sqlite3* db, int code, const std::string& path, const std::string& doing) {
  const int primary = code & 0xff;
  std::string why = db != nullptr ? sqlite3_errmsg(db) : sqlite3_errstr(code);
  const std::string message = path + ": cannot " + doing + ": " + why;
  if (primary == SQLITE_NOTADB || primary == SQLITE_CORRUPT) throw DamagedRecordError(message);
  throw FileError(message);
}

Connection::Connection(const std::string& path) : path_(path) {
  // FULLMUTEX: the record's own lock already serialises its use; this keeps SQLite safe even so.
  const int code =
      sqlite3_open_v2(path.c_str(), &db_,
                      SQLITE_OPEN_READWRITE | SQLITE_OPEN_CREATE | SQLITE_OPEN_FULLMUTEX, nullptr);
  if (code != SQLITE_OK) {
    const std::string why = db_ != nullptr ? sqlite3_errmsg(db_) : sqlite3_errstr(code);
    sqlite3_close(db_);
    db_ = nullptr;
    throw FileError(path + ": cannot open the record: " + why);
  }
  sqlite3_extended_result_codes(db_, 1);
  // Another process reading the record (a backup, sqlite3 by hand) holds it for a moment only.
  sqlite3_busy_timeout(db_, 5000);
}

Connection::~Connection() { sqlite3_close_v2(db_); }

void Connection::exec(const std::string& sql, const std::string& doing) {
  char* error = nullptr;
  const int code = sqlite3_exec(db_, sql.c_str(), nullptr, nullptr, &error);
  if (code != SQLITE_OK) {
    const std::string why = error != nullptr ? error : sqlite3_errstr(code);
    sqlite3_free(error);
    const int primary = code & 0xff;
    const std::string message = path_ + ": cannot " + doing + ": " + why;
    if (primary == SQLITE_NOTADB || primary == SQLITE_CORRUPT) throw DamagedRecordError(message);
    throw FileError(message);
  }
}

std::string Connection::value(const std::string& sql, const std::string& doing) {
  Statement s(*this, sql.c_str(), doing);
  if (!s.step()) return "";
  return s.text(0);
}

Statement::Statement(Connection& db, const char* sql, std::string doing)
    : db_(db), doing_(std::move(doing)) {
  const int code = sqlite3_prepare_v2(db_.get(), sql, -1, &stmt_, nullptr);
  if (code != SQLITE_OK) fail(db_.get(), code, db_.path(), doing_);
}

Statement::~Statement() { sqlite3_finalize(stmt_); }

Statement& Statement::bind(int i, const std::string& text) {
  const int code =
      sqlite3_bind_text(stmt_, i, text.data(), static_cast<int>(text.size()), SQLITE_TRANSIENT);
  if (code != SQLITE_OK) fail(db_.get(), code, db_.path(), doing_);
  return *this;
}

Statement& Statement::bind(int i, double value) {
  const int code = sqlite3_bind_double(stmt_, i, value);
  if (code != SQLITE_OK) fail(db_.get(), code, db_.path(), doing_);
  return *this;
}

Statement& Statement::bind(int i, std::int64_t value) {
  const int code = sqlite3_bind_int64(stmt_, i, value);
  if (code != SQLITE_OK) fail(db_.get(), code, db_.path(), doing_);
  return *this;
}

Statement& Statement::bindNull(int i) {
  const int code = sqlite3_bind_null(stmt_, i);
  if (code != SQLITE_OK) fail(db_.get(), code, db_.path(), doing_);
  return *this;
}

bool Statement::step() {
  const int code = sqlite3_step(stmt_);
  if (code == SQLITE_ROW) return true;
  if (code == SQLITE_DONE) return false;
  fail(db_.get(), code, db_.path(), doing_);
}

void Statement::run() {
  while (step()) {
  }
}

void Statement::reset() {
  sqlite3_reset(stmt_);
  sqlite3_clear_bindings(stmt_);
}

bool Statement::isNull(int i) const { return sqlite3_column_type(stmt_, i) == SQLITE_NULL; }

std::string Statement::text(int i) const {
  const unsigned char* t = sqlite3_column_text(stmt_, i);
  if (t == nullptr) return "";
  return std::string(reinterpret_cast<const char*>(t),
                     static_cast<std::size_t>(sqlite3_column_bytes(stmt_, i)));
}

double Statement::real(int i) const { return sqlite3_column_double(stmt_, i); }

std::int64_t Statement::integer(int i) const { return sqlite3_column_int64(stmt_, i); }

std::optional<double> Statement::optionalReal(int i) const {
  if (isNull(i)) return std::nullopt;
  return real(i);
}

Transaction::Transaction(Connection& db) : db_(db) {
  db_.exec("BEGIN IMMEDIATE", "begin a transaction");
}

Transaction::~Transaction() {
  if (!open_) return;
  try {
    db_.exec("ROLLBACK", "roll back");
  } catch (const std::exception&) {
    // SQLite has rolled back already when the failure that brought us here was a full disk or
    // an I/O error: nothing is left to undo.
  }
}

void Transaction::commit() {
  db_.exec("COMMIT", "commit");
  open_ = false;
}

}  // namespace zerocal::record::sqlite
