#include "zerocal/web/web_server.h"

#include <spdlog/spdlog.h>
#include <unistd.h>

#include <algorithm>
#include <array>
#include <boost/asio/ip/tcp.hpp>
#include <boost/asio/ssl.hpp>
#include <boost/asio/steady_timer.hpp>
#include <boost/beast/core.hpp>
#include <boost/beast/http.hpp>
#include <boost/beast/ssl.hpp>
#include <boost/beast/websocket.hpp>
#include <filesystem>
#include <fstream>
#include <map>
#include <optional>
#include <random>
#include <set>
#include <sstream>
#include <string_view>

#include "zerocal/control/line_connection.h"
#include "zerocal/control/listener.h"
#include "zerocal/control/messages.h"
#include "zerocal/control/token.h"
#include "zerocal/error.h"

namespace zerocal::web {

namespace asio = boost::asio;
namespace beast = boost::beast;
namespace http = beast::http;
namespace websocket = beast::websocket;
namespace fs = std::filesystem;
using asio::ip::tcp;
using nlohmann::json;
using Clock = std::chrono::steady_clock;
using Request = http::request<http::string_body>;
using Response = http::response<http::string_body>;
using PlainStream = beast::tcp_stream;
using TlsStream = beast::ssl_stream<beast::tcp_stream>;

namespace {

constexpr const char* kCookieName = "zerocal_login";
constexpr std::uintmax_t kMaxFileBytes = 4 << 20;
// A session's reports: /sessions/ID/report.html and /sessions/ID/summary.txt, nothing else.
constexpr std::string_view kSessionsPath = "/sessions/";
constexpr std::array<std::string_view, 2> kReportFiles{"report.html", "summary.txt"};
// report.html carries its plots inline: larger than a page file, but bounded all the same.
constexpr std::uintmax_t kMaxReportBytes = 16 << 20;
// The pages load nothing from elsewhere and may not be framed by another site.
constexpr const char* kPagePolicy =
    "default-src 'self'; frame-ancestors 'none'; base-uri 'none'; form-action 'self'";
// A report is self-contained (inline CSS and SVG, no script): it may use its own styles and
// nothing else, and runs sandboxed, as a document from elsewhere would.
constexpr const char* kReportPolicy =
    "default-src 'none'; style-src 'unsafe-inline'; img-src data:; frame-ancestors 'none'; "
    "sandbox";

std::string contentType(const fs::path& file) {
  const std::string ext = file.extension().string();
  if (ext == ".html") return "text/html; charset=utf-8";
  if (ext == ".css") return "text/css; charset=utf-8";
  if (ext == ".js" || ext == ".mjs") return "text/javascript; charset=utf-8";
  if (ext == ".svg") return "image/svg+xml";
  if (ext == ".json") return "application/json";
  if (ext == ".png") return "image/png";
  if (ext == ".ico") return "image/x-icon";
  return "text/plain; charset=utf-8";
}

// A path a page file may have: segments of letters, digits, '-', '_' and '.', none starting with
// a dot (so neither `..` nor hidden files) and none empty. Anything else, a percent-escape
// included, is refused before the file system is asked: no escape to decode, no way out.
bool plainPath(const std::string& path) {
  if (path.empty() || path.front() != '/' || path.size() > 256) return false;
  std::size_t segment_start = 1;
  for (std::size_t i = 1; i <= path.size(); ++i) {
    if (i == path.size() || path[i] == '/') {
      if (i == segment_start || path[segment_start] == '.') return false;
      segment_start = i + 1;
      continue;
    }
    const char c = path[i];
    const bool ok = (c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') || (c >= '0' && c <= '9') ||
                    c == '-' || c == '_' || c == '.';
    if (!ok) return false;
  }
  return true;
}

// A session id as the session store makes them (20261122T073447Z; -002 and on for a second
// session within the same second), checked character by character: nothing else names a folder.
bool sessionIdLike(std::string_view id) {
  if (id.size() != 16 && id.size() != 20) return false;
  const auto digits = [&](std::size_t from, std::size_t to) {
    for (std::size_t i = from; i < to; ++i)
      if (id[i] < '0' || id[i] > '9') return false;
    return true;
  };
  if (!digits(0, 8) || id[8] != 'T' || !digits(9, 15) || id[15] != 'Z') return false;
  return id.size() == 16 || (id[16] == '-' && digits(17, 20));
}

std::string randomHex(std::size_t bytes) {
  std::random_device device;  // getrandom(2) on Linux: unpredictable
  static const char* kDigits = "0123456789abcdef";
  std::string out;
  for (std::size_t i = 0; i < bytes; i += 4) {
    std::uint32_t word = device();
    for (int k = 0; k < 8; ++k, word >>= 4) out.push_back(kDigits[word & 0xf]);
  }
  return out;
}

std::string cookieOf(const Request& request) {
  const auto header = request.find(http::field::cookie);
  if (header == request.end()) return {};
  const std::string text(header->value());
  const std::string key = std::string(kCookieName) + "=";
  std::size_t at = 0;
  while (at < text.size()) {
    while (at < text.size() && (text[at] == ' ' || text[at] == ';')) ++at;
    const auto end = text.find(';', at);
    const std::string pair = text.substr(at, end == std::string::npos ? end : end - at);
    if (pair.compare(0, key.size(), key) == 0) return pair.substr(key.size());
    if (end == std::string::npos) break;
    at = end + 1;
  }
  return {};
}

// A page's script or a WebSocket opened by another site's page carries that site's Origin; the
// browser never lets a page forge it. Only the terminal's own pages may use a login.
bool sameOrigin(const Request& request, bool required, bool tls) {
  const auto origin = request.find(http::field::origin);
  if (origin == request.end()) return !required;
  const auto host = request.find(http::field::host);
  if (host == request.end()) return false;
  return origin->value() == (tls ? "https://" : "http://") + std::string(host->value());
}

}  // namespace

// An HTTP connection, plain or TLS, as the core closes it.
class HttpLink {
 public:
  virtual ~HttpLink() = default;
  virtual void close() = 0;
};

class WebCore : public std::enable_shared_from_this<WebCore> {
 public:
  WebCore(asio::io_context& io, std::shared_ptr<control::ProtocolHub> hub, WebOptions options)
      : io_(io),
        hub_(std::move(hub)),
        options_(std::move(options)),
        listener_(std::make_shared<control::Listener>(io, hub_->logger(), "web")) {}

  void start();
  void stop();
  spdlog::logger& log() { return hub_->log(); }

  // Logins: a cookie value, when it expires and whose it is (control/roles.h).
  struct Login {
    Clock::time_point expires;
    control::Role role = control::Role::kNone;
  };
  std::string login(control::Role role);
  void logout(const std::string& cookie) { logins_.erase(cookie); }
  // The time left of a login; nullopt when it is unknown or expired.
  std::optional<Clock::duration> loginLeft(const std::string& cookie);
  // Its role; kNone when it is unknown or expired.
  control::Role loginRole(const std::string& cookie) {
    return loginLeft(cookie) ? logins_.at(cookie).role : control::Role::kNone;
  }

  asio::io_context& io_;
  std::shared_ptr<control::ProtocolHub> hub_;
  const WebOptions options_;
  std::string root_;  // canonical
  std::shared_ptr<control::Listener> listener_;
  std::set<std::shared_ptr<HttpLink>> http_;
  std::set<std::shared_ptr<control::LineConnection>> ws_;
  // Present when web.tls_certificate and web.tls_key are set: every connection is TLS.
  std::optional<asio::ssl::context> tls_;
  std::map<std::string, Login> logins_;
  bool stopped_ = false;
  std::uint16_t port_ = 0;
};

// The control protocol over a WebSocket: one line per text message, without its '\n'. Stream:
// PlainStream or TlsStream.
template <class Stream>
class WsConnection : public control::LineConnection {
 public:
  WsConnection(std::shared_ptr<WebCore> core, Stream stream, std::string peer, std::string address,
               std::string cookie)
      : LineConnection(core->hub_, std::move(peer), std::move(address)),
        core_(std::move(core)),
        ws_(std::move(stream)),
        cookie_(std::move(cookie)) {}

  // Completes the upgrade `request` asked for; then the protocol starts, authenticated by the
  // login cookie the upgrade carried.
  void accept(const Request& request) {
    auto& options = hub().options();
    ws_.read_message_max(options.max_line_bytes);
    ws_.text(true);
    // Pings when quiet, and a close after the suggested idle time: a dead peer is found.
    ws_.set_option(websocket::stream_base::timeout::suggested(beast::role_type::server));
    beast::get_lowest_layer(ws_).expires_never();
    authenticateByTransport(core_->loginRole(cookie_));
    ws_.async_accept(request, [self = self()](beast::error_code ec) {
      if (ec || self->core_->stopped_) {
        self->abandon();
        return;
      }
      self->core_->ws_.insert(self);
      self->start();
    });
  }

 private:
  std::shared_ptr<WsConnection> self() {
    return std::static_pointer_cast<WsConnection>(shared_from_this());
  }

  void readLine() override {
    ws_.async_read(buffer_, [self = self()](beast::error_code ec, std::size_t) {
      if (ec == websocket::error::message_too_big) return self->lineTooLong();
      if (ec) return self->readFailed(ec);
      std::string line = beast::buffers_to_string(self->buffer_.data());
      self->buffer_.consume(self->buffer_.size());
      self->received(std::move(line));
    });
  }

  void writeLine(const control::Line& line) override {
    write_pending_ = true;
    // The message is the line; its '\n' is the TCP port's framing.
    ws_.async_write(asio::buffer(line->data(), line->size() - 1),
                    [self = self(), line](beast::error_code ec, std::size_t) {
                      self->write_pending_ = false;
                      self->written(ec);
                    });
  }

  void shutdown() override {
    beast::error_code ec;
    // A daemon that stops runs no more handlers: the socket goes now.
    if (write_pending_ || !ws_.is_open() || core_->stopped_ || core_->hub_->stopped()) {
      beast::get_lowest_layer(ws_).socket().close(ec);
      return;
    }
    // A close frame, so that the page sees a clean close; the socket goes in any case.
    beast::get_lowest_layer(ws_).expires_after(std::chrono::seconds(2));
    ws_.async_close(websocket::close_code::normal, [self = self()](beast::error_code) {
      beast::error_code e;
      beast::get_lowest_layer(self->ws_).socket().close(e);
    });
  }

  void left() override { core_->ws_.erase(self()); }

  std::string revoked() const override {
    if (core_->loginLeft(cookie_)) return {};
    return "the web login expired or was logged out; log in again";
  }

  std::shared_ptr<WebCore> core_;
  websocket::stream<Stream> ws_;
  beast::flat_buffer buffer_;
  std::string cookie_;
  bool write_pending_ = false;
};

// One HTTP connection: requests one at a time (keep-alive), each within Beast's header and body
// limits and the request deadline; an upgrade to /ws hands the connection to a WsConnection.
// Stream: PlainStream, or TlsStream, whose handshake comes first, within the request deadline.
template <class Stream>
class HttpConnection : public HttpLink,
                       public std::enable_shared_from_this<HttpConnection<Stream>> {
  static constexpr bool kTls = std::is_same_v<Stream, TlsStream>;

 public:
  HttpConnection(std::shared_ptr<WebCore> core, Stream stream)
      : core_(std::move(core)), stream_(std::move(stream)), delay_(core_->io_) {
    beast::error_code ec;
    const auto endpoint = tcpLayer().socket().remote_endpoint(ec);
    address_ = ec ? std::string("?") : endpoint.address().to_string();
    peer_ = ec ? address_ : address_ + ":" + std::to_string(endpoint.port());
  }

  void start() {
    if constexpr (kTls) {
      tcpLayer().expires_after(core_->options_.request_timeout);
      stream_.async_handshake(
          asio::ssl::stream_base::server, [self = this->shared_from_this()](beast::error_code ec) {
            if (self->closed_) return;
            if (ec) {
              self->core_->log().info("{} (web): no TLS handshake: {}", self->peer_, ec.message());
              return self->close();
            }
            self->read();
          });
    } else {
      read();
    }
  }

  void close() override {
    if (closed_) return;
    closed_ = true;
    delay_.cancel();
    beast::error_code ec;
    tcpLayer().socket().shutdown(tcp::socket::shutdown_both, ec);
    tcpLayer().close();
    core_->http_.erase(this->shared_from_this());
  }

 private:
  beast::tcp_stream& tcpLayer() { return beast::get_lowest_layer(stream_); }

  void read() {
    if (closed_) return;
    parser_.emplace();
    parser_->header_limit(static_cast<std::uint32_t>(core_->options_.max_header_bytes));
    parser_->body_limit(core_->options_.max_body_bytes);
    buffer_.clear();
    tcpLayer().expires_after(core_->options_.request_timeout);
    http::async_read(
        stream_, buffer_, *parser_,
        [self = this->shared_from_this()](beast::error_code ec, std::size_t) { self->onRead(ec); });
  }

  void onRead(beast::error_code ec) {
    if (closed_) return;
    if (ec == http::error::header_limit)
      return fail(http::status::request_header_fields_too_large,
                  "the request's header is over " +
                      std::to_string(core_->options_.max_header_bytes) + " bytes");
    if (ec == http::error::body_limit)
      return fail(http::status::payload_too_large,
                  "the request's body is over " + std::to_string(core_->options_.max_body_bytes) +
                      " bytes");
    if (ec == http::error::end_of_stream || ec == beast::error::timeout ||
        ec == asio::error::operation_aborted || ec == asio::error::connection_reset ||
        ec == asio::error::eof)
      return close();
    if (ec) return fail(http::status::bad_request, "not an HTTP request: " + ec.message());
    handle(parser_->release());
  }

  // Answers and closes: what the client sends next cannot be trusted to be a request.
  void fail(http::status status, const std::string& why) {
    core_->log().info("{} (web): {} {}", peer_, static_cast<int>(status), why);
    auto shared = std::make_shared<Response>(text(status, why + "\n", 11, false));
    tcpLayer().expires_after(core_->options_.request_timeout);
    http::async_write(stream_, *shared,
                      [self = this->shared_from_this(), shared](beast::error_code ec, std::size_t) {
                        if (ec) return self->close();
                        self->drain();
                      });
  }

  // After an answer to a request that was not read to its end: the rest is read and dropped
  // for a moment before closing, since closing with unread bytes resets the connection and the
  // client could lose the answer.
  void drain() {
    if (closed_) return;
    beast::error_code ec;
    tcpLayer().socket().shutdown(tcp::socket::shutdown_send, ec);
    tcpLayer().expires_after(std::chrono::seconds(1));  // the whole drain, not each read
    drainMore(std::make_shared<std::array<char, 4096>>());
  }

  void drainMore(std::shared_ptr<std::array<char, 4096>> scratch) {
    if (closed_) return;
    stream_.async_read_some(asio::buffer(*scratch), [self = this->shared_from_this(), scratch](
                                                        beast::error_code e, std::size_t) {
      if (e) return self->close();
      self->drainMore(scratch);
    });
  }

  Response text(http::status status, std::string body, unsigned version, bool keep_alive,
                const char* type = "text/plain; charset=utf-8") {
    Response r{status, version};
    r.set(http::field::server, "zerocald");
    r.set(http::field::content_type, type);
    r.set(http::field::cache_control, "no-store");
    r.set("X-Content-Type-Options", "nosniff");
    r.keep_alive(keep_alive);
    r.body() = std::move(body);
    r.prepare_payload();
    return r;
  }

  Response jsonResponse(const Request& request, http::status status, const json& body) {
    return text(status, body.dump() + "\n", request.version(), request.keep_alive(),
                "application/json");
  }

  void send(Response response) {
    auto shared = std::make_shared<Response>(std::move(response));
    tcpLayer().expires_after(core_->options_.request_timeout);
    http::async_write(stream_, *shared,
                      [self = this->shared_from_this(), shared](beast::error_code ec, std::size_t) {
                        if (ec || shared->need_eof()) return self->close();
                        self->read();
                      });
  }

  void handle(Request request) {
    const std::string target(request.target());
    const std::string path = target.substr(0, target.find('?'));
    if (websocket::is_upgrade(request)) return upgrade(std::move(request), path);
    const auto method = request.method();
    if (path == "/api/login") {
      if (method == http::verb::post) return login(request);
      if (method == http::verb::get) return loginState(request);
      return send(text(http::status::method_not_allowed, "GET or POST\n", request.version(),
                       request.keep_alive()));
    }
    if (path == "/api/logout") {
      if (method != http::verb::post)
        return send(text(http::status::method_not_allowed, "POST\n", request.version(),
                         request.keep_alive()));
      return logout(request);
    }
    if (method != http::verb::get && method != http::verb::head)
      return send(text(http::status::method_not_allowed, "GET or HEAD\n", request.version(),
                       request.keep_alive()));
    if (path.compare(0, kSessionsPath.size(), kSessionsPath) == 0)
      return serveReport(request, path);
    serveFile(request, path);
  }

  // /sessions/ID/report.html or /sessions/ID/summary.txt of the configured sessions folder, to a
  // logged-in browser only. The id is checked character by character and the file name is one
  // of the two, so no path reaches the file system that the daemon did not make; a link in the
  // folder that leads out of it is refused as well.
  void serveReport(const Request& request, const std::string& path) {
    if (!core_->loginLeft(cookieOf(request))) {
      core_->log().warn("{} (web): refused a report without a valid login", peer_);
      return send(text(http::status::unauthorized, "log in first (POST /api/login)\n",
                       request.version(), request.keep_alive()));
    }
    const std::string rest = path.substr(kSessionsPath.size());
    const auto slash = rest.find('/');
    const std::string id = rest.substr(0, slash);
    const std::string name = slash == std::string::npos ? "" : rest.substr(slash + 1);
    if (!sessionIdLike(id) || name.find('/') != std::string::npos || !plainPath("/" + name)) {
      core_->log().warn("{} (web): refused the path '{}'", peer_, target(request));
      return send(text(http::status::bad_request,
                       "not a session's report (/sessions/20261122T073447Z/report.html): " +
                           target(request) + "\n",
                       request.version(), request.keep_alive()));
    }
    if (std::find(kReportFiles.begin(), kReportFiles.end(), name) == kReportFiles.end())
      return send(text(http::status::not_found,
                       "a session has report.html and summary.txt here, nothing else\n",
                       request.version(), request.keep_alive()));
    std::error_code ec;
    const fs::path folder = core_->options_.sessions_dir.empty()
                                ? fs::path()
                                : fs::canonical(core_->options_.sessions_dir, ec);
    const auto real = folder.empty() ? std::nullopt : fileInside(folder, folder / id / name);
    if (!real || fs::file_size(*real, ec) > kMaxReportBytes)
      return send(text(http::status::not_found, "session " + id + " has no " + name + "\n",
                       request.version(), request.keep_alive()));
    sendFile(request, *real, kReportPolicy);
  }

  // `file` resolved, when it is a regular file inside `folder` (canonical) after every link.
  static std::optional<fs::path> fileInside(const fs::path& folder, const fs::path& file) {
    std::error_code ec;
    const fs::path real = fs::canonical(file, ec);
    if (ec) return std::nullopt;
    const std::string prefix = folder.string() + "/";
    if (real.string().compare(0, prefix.size(), prefix) != 0) return std::nullopt;
    if (!fs::is_regular_file(real, ec)) return std::nullopt;
    return real;
  }

  void serveFile(const Request& request, const std::string& path) {
    const std::string name = path == "/" ? "/index.html" : path;
    if (!plainPath(name)) {
      core_->log().warn("{} (web): refused the path '{}'", peer_, target(request));
      return send(text(http::status::bad_request, "not a path of the terminal's files\n",
                       request.version(), request.keep_alive()));
    }
    std::error_code ec;
    // A symbolic link inside the folder must not lead out of it either.
    const auto real = fileInside(core_->root_, fs::path(core_->root_) / name.substr(1));
    if (!real || fs::file_size(*real, ec) > kMaxFileBytes)
      return send(text(http::status::not_found, "no such page: " + name + "\n", request.version(),
                       request.keep_alive()));
    sendFile(request, *real, kPagePolicy);
  }

  void sendFile(const Request& request, const fs::path& real, const char* policy) {
    std::ifstream in(real, std::ios::binary);
    std::ostringstream body;
    body << in.rdbuf();
    auto response = text(http::status::ok, body.str(), request.version(), request.keep_alive(),
                         contentType(real).c_str());
    response.set(http::field::cache_control, "no-cache");
    response.set("Content-Security-Policy", policy);
    response.set("Referrer-Policy", "no-referrer");
    if (request.method() == http::verb::head) {
      response.body().clear();
      response.content_length(body.str().size());
    }
    send(std::move(response));
  }

  static std::string target(const Request& request) {
    std::string t(request.target());
    if (t.size() > 120) t = t.substr(0, 120) + "...";
    return t;
  }

  void loginState(const Request& request) {
    const std::string cookie = cookieOf(request);
    const auto left = core_->loginLeft(cookie);
    json body{{"authenticated", left.has_value()}};
    if (left) {
      body["expires_in_s"] = std::chrono::duration_cast<std::chrono::seconds>(*left).count();
      body["role"] = control::roleName(core_->loginRole(cookie));
    }
    send(jsonResponse(request, left ? http::status::ok : http::status::unauthorized, body));
  }

  void login(const Request& request) {
    if (!sameOrigin(request, false, kTls))
      return forbidden(request, "a login from another site's page");
    std::string token;
    try {
      // The control port's reader: its nesting limit holds here too.
      const json body = control::parseRequestLine(request.body());
      if (body.is_object() && body.contains("token") && body["token"].is_string())
        token = body["token"].get<std::string>();
    } catch (const std::exception&) {
      // Not JSON: no token, a failed login like any other.
    }
    const auto& options = core_->hub_->options();
    const control::Role role = control::roleOfToken(options, token);
    if (role == control::Role::kNone) {
      ++failures_;
      const bool last = failures_ >= options.max_auth_failures;
      core_->log().warn("{} (web): login failed ({} of {}){}", peer_, failures_,
                        options.max_auth_failures, last ? "; closing" : "");
      auto response = jsonResponse(
          request, http::status::unauthorized,
          {{"ok", false},
           {"error", {{"code", control::code::kAuthFailed}, {"message", "wrong token"}}}});
      if (last) response.keep_alive(false);
      // The answer waits, as on the TCP port, so that guessing costs time; nothing is read
      // meanwhile.
      delay_.expires_after(options.auth_failure_delay);
      delay_.async_wait([self = this->shared_from_this(),
                         response = std::move(response)](boost::system::error_code ec) mutable {
        if (ec || self->closed_) return;
        self->send(std::move(response));
      });
      return;
    }
    failures_ = 0;
    const std::string cookie = core_->login(role);
    const auto lifetime_s =
        std::chrono::duration_cast<std::chrono::seconds>(core_->options_.session_lifetime).count();
    core_->log().info("{} (web): logged in as the {}", peer_, control::roleName(role));
    auto response = jsonResponse(
        request, http::status::ok,
        {{"ok", true}, {"expires_in_s", lifetime_s}, {"role", control::roleName(role)}});
    response.set(http::field::set_cookie,
                 std::string(kCookieName) + "=" + cookie +
                     "; Path=/; HttpOnly; SameSite=Strict; Max-Age=" + std::to_string(lifetime_s) +
                     (kTls ? "; Secure" : ""));
    send(std::move(response));
  }

  void logout(const Request& request) {
    if (!sameOrigin(request, false, kTls))
      return forbidden(request, "a logout from another site's page");
    core_->logout(cookieOf(request));
    auto response = jsonResponse(request, http::status::ok, {{"ok", true}});
    response.set(http::field::set_cookie,
                 std::string(kCookieName) + "=; Path=/; HttpOnly; SameSite=Strict; Max-Age=0");
    send(std::move(response));
  }

  void forbidden(const Request& request, const std::string& why) {
    core_->log().warn("{} (web): refused {} (Origin {})", peer_, why,
                      std::string(request[http::field::origin]));
    send(text(http::status::forbidden, "refused: " + why + "\n", request.version(), false));
  }

  void upgrade(Request request, const std::string& path) {
    if (path != "/ws")
      return send(text(http::status::not_found, "no WebSocket at " + path + "\n", request.version(),
                       false));
    if (!sameOrigin(request, true, kTls))
      return forbidden(request, "a WebSocket from another origin");
    const std::string cookie = cookieOf(request);
    if (!core_->loginLeft(cookie)) {
      core_->log().warn("{} (web): refused a WebSocket without a valid login", peer_);
      return send(text(http::status::unauthorized, "log in first (POST /api/login)\n",
                       request.version(), false));
    }
    if (core_->hub_->stopped()) return close();
    closed_ = true;  // the socket is the WebSocket's now
    delay_.cancel();
    auto self = this->shared_from_this();
    core_->http_.erase(self);
    auto ws = std::make_shared<WsConnection<Stream>>(core_, std::move(stream_), peer_ + " (web)",
                                                     address_, cookie);
    ws->accept(request);
  }

  std::shared_ptr<WebCore> core_;
  Stream stream_;
  beast::flat_buffer buffer_;
  std::optional<http::request_parser<http::string_body>> parser_;
  asio::steady_timer delay_;
  std::string peer_;
  std::string address_;
  int failures_ = 0;
  bool closed_ = false;
};

std::string WebCore::login(control::Role role) {
  const auto now = Clock::now();
  for (auto it = logins_.begin(); it != logins_.end();)
    it = it->second.expires <= now ? logins_.erase(it) : std::next(it);
  // Every login lasts as long: the one that expires first is the oldest.
  while (logins_.size() >= options_.max_logins) {
    auto oldest = logins_.begin();
    for (auto it = logins_.begin(); it != logins_.end(); ++it)
      if (it->second.expires < oldest->second.expires) oldest = it;
    logins_.erase(oldest);
  }
  std::string cookie = randomHex(32);
  logins_[cookie] = Login{now + options_.session_lifetime, role};
  return cookie;
}

std::optional<Clock::duration> WebCore::loginLeft(const std::string& cookie) {
  if (cookie.empty()) return std::nullopt;
  const auto it = logins_.find(cookie);
  if (it == logins_.end()) return std::nullopt;
  const auto now = Clock::now();
  if (it->second.expires <= now) {
    logins_.erase(it);
    return std::nullopt;
  }
  return it->second.expires - now;
}

void WebCore::start() {
  port_ = listener_->listen(options_.bind_address, options_.port);
  log().info("web terminal listening on {}://{}:{}/", tls_ ? "https" : "http",
             options_.bind_address, port_);
  listener_->accept([self = shared_from_this()](tcp::socket socket) {
    if (self->stopped_) return;
    if (self->http_.size() + self->ws_.size() >= self->options_.max_connections) {
      // No room: the TCP port (and the connections open here) are not starved by more.
      self->log().warn("web: refused a connection, {} are open", self->options_.max_connections);
      boost::system::error_code e;
      socket.close(e);
      return;
    }
    if (self->tls_) {
      auto connection = std::make_shared<HttpConnection<TlsStream>>(
          self, TlsStream(PlainStream(std::move(socket)), *self->tls_));
      self->http_.insert(connection);
      connection->start();
    } else {
      auto connection =
          std::make_shared<HttpConnection<PlainStream>>(self, PlainStream(std::move(socket)));
      self->http_.insert(connection);
      connection->start();
    }
  });
}

void WebCore::stop() {
  if (stopped_) return;
  stopped_ = true;
  listener_->close();
  auto http = http_;
  for (const auto& c : http) c->close();
  http_.clear();
  auto ws = ws_;
  for (const auto& c : ws) c->close();
  ws_.clear();
}

std::string defaultWebRoot() {
  std::error_code ec;
  const fs::path program = fs::read_symlink("/proc/self/exe", ec);
  if (ec) return "share/zerocal/web";
  return (program.parent_path() / ".." / "share" / "zerocal" / "web").lexically_normal().string();
}

WebServer::WebServer(asio::io_context& io, std::shared_ptr<control::ProtocolHub> hub,
                     WebOptions options) {
  boost::system::error_code ec;
  const auto address = asio::ip::make_address(options.bind_address, ec);
  if (ec) throw Error("web.bind_address '" + options.bind_address + "' is not an IP address");
  const bool tls = !options.tls_certificate.empty() || !options.tls_key.empty();
  if (!address.is_loopback() && !tls && !options.trusted_network)
    throw Error("web.bind_address " + options.bind_address +
                " is reachable from other machines and the web terminal has no TLS: set "
                "web.tls_certificate and web.tls_key, or web.trusted_network: true for a trusted "
                "network, or keep 127.0.0.1");
  std::optional<asio::ssl::context> context;
  if (tls) {
    if (options.tls_certificate.empty() || options.tls_key.empty())
      throw Error("web.tls_certificate and web.tls_key go together: TLS needs both");
    context.emplace(asio::ssl::context::tls_server);
    context->set_options(asio::ssl::context::default_workarounds | asio::ssl::context::no_sslv2 |
                         asio::ssl::context::no_sslv3 | asio::ssl::context::no_tlsv1 |
                         asio::ssl::context::no_tlsv1_1 | asio::ssl::context::single_dh_use);
    try {
      context->use_certificate_chain_file(options.tls_certificate);
    } catch (const boost::system::system_error& e) {
      throw Error("web.tls_certificate " + options.tls_certificate + ": " + e.what());
    }
    try {
      context->use_private_key_file(options.tls_key, asio::ssl::context::pem);
    } catch (const boost::system::system_error& e) {
      throw Error("web.tls_key " + options.tls_key + ": " + e.what());
    }
  }
  const std::string root = options.root.empty() ? defaultWebRoot() : options.root;
  std::error_code fec;
  const fs::path canonical = fs::canonical(root, fec);
  if (fec || !fs::is_regular_file(canonical / "index.html", fec))
    throw Error("web.root: no index.html in " + root);
  impl_ = std::make_shared<WebCore>(io, std::move(hub), std::move(options));
  impl_->root_ = canonical.string();
  impl_->tls_ = std::move(context);
}

WebServer::~WebServer() { stop(); }
void WebServer::start() { impl_->start(); }
void WebServer::stop() { impl_->stop(); }
std::uint16_t WebServer::port() const { return impl_->port_; }
const std::string& WebServer::root() const { return impl_->root_; }
std::size_t WebServer::connectionCount() const { return impl_->http_.size() + impl_->ws_.size(); }

}  // namespace zerocal::web
