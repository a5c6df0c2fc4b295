// A ControlServer on an ephemeral loopback port with FakeSession behind it, its io_context run on
// a thread of its own as in the daemon.
#pragma once

#include <gtest/gtest.h>

#include <boost/asio/executor_work_guard.hpp>
#include <boost/asio/post.hpp>
#include <future>
#include <memory>
#include <thread>

#include "fake_session.h"
#include "zerocal/control/client.h"
#include "zerocal/control/server.h"

namespace zerocal::control {

using namespace std::chrono_literals;

inline constexpr const char* kToken = "c0ffee-7450-secret";

class ControlServerTest : public ::testing::Test {
 protected:
  void SetUp() override { startServer(ServerOptions{}); }

  void startServer(ServerOptions options) {
    stopServer();
    options.port = 0;
    options.token = kToken;
    options.daemon_version = "9.9.9";
    options.auth_failure_delay = 10ms;
    if (options.status_period == ServerOptions{}.status_period) options.status_period = 50ms;
    // Every test client comes from 127.0.0.1: the per-peer limit is tested on its own.
    if (options.max_clients_per_peer == ServerOptions{}.max_clients_per_peer)
      options.max_clients_per_peer = options.max_clients;
    server_ = std::make_unique<ControlServer>(io_, session_, options);
    server_->start();
    io_.restart();
    thread_ = std::thread([this] {
      auto guard = boost::asio::make_work_guard(io_);
      io_.run();
    });
  }

  void stopServer() {
    if (!server_) return;
    std::promise<void> stopped;
    boost::asio::post(io_, [&] {
      server_->stop();
      stopped.set_value();
    });
    stopped.get_future().wait();
    io_.stop();
    thread_.join();
    server_.reset();
  }

  void TearDown() override { stopServer(); }

  std::size_t connections() {
    std::promise<std::size_t> n;
    boost::asio::post(io_, [&] { n.set_value(server_->connectionCount()); });
    return n.get_future().get();
  }

  std::unique_ptr<ControlClient> connect(bool authenticate = true) {
    auto c = std::make_unique<ControlClient>();
    c->connect("127.0.0.1", server_->port());
    if (authenticate) c->authenticate(kToken);
    return c;
  }

  // Another client gets its status answer quickly: the daemon was not hurt.
  void expectOthersServedFast() {
    auto other = connect();
    const auto t0 = std::chrono::steady_clock::now();
    const auto r = other->call("status");
    const auto dt = std::chrono::steady_clock::now() - t0;
    EXPECT_TRUE(r["status"].is_object());
    EXPECT_LT(dt, 100ms);
  }

  // The connection is closed by the daemon within `within` (after any lines still to read).
  static void expectClosed(ControlClient& c, std::chrono::milliseconds within = 2000ms) {
    const auto deadline = std::chrono::steady_clock::now() + within;
    try {
      while (std::chrono::steady_clock::now() < deadline) c.readLine(50ms);
    } catch (const ConnectionError&) {
      return;
    }
    ADD_FAILURE() << "the connection is still open";
  }

  boost::asio::io_context io_;
  testing::FakeSession session_;
  std::unique_ptr<ControlServer> server_;
  std::thread thread_;
};

}  // namespace zerocal::control
