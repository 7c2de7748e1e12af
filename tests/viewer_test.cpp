// SPDX-License-Identifier: Apache-2.0
// The live viewer's server side, over real sockets on 127.0.0.1 with a Beast client:
// only the embedded files are served (path traversal spellings are 404), the Host and Origin
// checks, the socket is read-only (a message closes it with 1008 and changes nothing), a page
// that does not read loses queued batches (counted, bounded queue) while publish() never waits
// or allocates, and frames arrive in order with their sequence numbers. As a server:
// the page cap under hundreds of concurrent upgrades, the bytes and resident memory they cost,
// the accept loop out of descriptors, the Host check on other addresses and the names given.
// Also the hello message, trace reading for `toonforce view`, and the run and sim hooks; for a
// world (several devices), the hello naming each device, the frames by device and the world
// simulation's rows through a server to a page. Counts and bounds only, never times.
#include <gtest/gtest.h>

#include <dirent.h>
#include <ifaddrs.h>
#include <netinet/in.h>
#include <netinet/tcp.h>
#include <poll.h>
#include <signal.h>
#include <spawn.h>
#include <sys/resource.h>
#include <sys/socket.h>
#include <sys/time.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <array>
#include <atomic>
#include <cerrno>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <functional>
#include <map>
#include <string>
#include <thread>
#include <vector>

#include "toonforce/viewer/beast.hpp"

#include "alloc_counter.hpp"
#include "toonforce/config/scene_file.hpp"
#include "toonforce/run/run.hpp"
#include "toonforce/run/world_run.hpp"
#include "toonforce/sim/sim_run.hpp"
#include "toonforce/viewer/assets.hpp"
#include "toonforce/viewer/hello.hpp"
#include "toonforce/viewer/scene_json.hpp"
#include "toonforce/viewer/trace_file.hpp"
#include "toonforce/viewer/viewer_server.hpp"
#include "toonforce/viewer/world_sink.hpp"
#include "toonforce/viewer/world_view.hpp"

namespace {

namespace asio = boost::asio;
namespace beast = boost::beast;
namespace http = beast::http;
namespace websocket = beast::websocket;
using tcp = asio::ip::tcp;
using namespace toonforce;
using namespace toonforce::viewer;

constexpr const char* kSource = TOONFORCE_SOURCE_DIR;

std::unique_ptr<ViewerServer> start_server(ViewerOptions options = {}) {
  options.port = 0;
  auto server = ViewerServer::start(options, R"({"type":"hello","test":true})");
  EXPECT_TRUE(server) << server.error();
  return std::move(server.value());
}

std::string host_of(const ViewerServer& server) { return "127.0.0.1:" + std::to_string(server.port()); }

/// One raw HTTP request to a port (on 127.0.0.1 unless another address is given); the response.
http::response<http::string_body> request_to(std::uint16_t port, http::verb verb, const std::string& target,
                                             const std::string& host, const std::string& to = "127.0.0.1") {
  asio::io_context io;
  tcp::socket socket(io);
  socket.connect(tcp::endpoint(asio::ip::make_address(to), port));
  http::request<http::empty_body> req{verb, target, 11};
  req.set(http::field::host, host);
  http::write(socket, req);
  beast::flat_buffer buffer;
  http::response<http::string_body> res;
  http::response_parser<http::string_body> parser;
  parser.skip(verb == http::verb::head);
  http::read(socket, buffer, parser);
  return parser.release();
}

http::response<http::string_body> request(const ViewerServer& server, http::verb verb, const std::string& target,
                                          const std::string& host, const std::string& to = "127.0.0.1") {
  return request_to(server.port(), verb, target, host, to);
}

TEST(ViewerAssets, OnlyExactPathsOfEmbeddedFilesAreFound) {
  ASSERT_FALSE(assets().empty());
  const Asset* index = find_asset("/");
  ASSERT_NE(index, nullptr);
  EXPECT_EQ(index->path, "/index.html");
  EXPECT_NE(index->body.find("<title>toonforce viewer</title>"), std::string_view::npos);
  EXPECT_EQ(find_asset("/index.html?x=1"), index);
  for (const Asset& a : assets()) {
    EXPECT_EQ(find_asset(a.path), &a);
    EXPECT_FALSE(a.content_type.empty());
  }
  for (const char* bad : {"/../CMakeLists.txt", "/%2e%2e/CMakeLists.txt", "//etc/passwd", "/assets/../index.html",
                          "/assets/", "/index.html/", "index.html", "/INDEX.HTML", "/./index.html", ""}) {
    EXPECT_EQ(find_asset(bad), nullptr) << bad;
  }
}

TEST(ViewerServer, ServesThePageAndNothingElse) {
  auto server = start_server();
  const std::string host = host_of(*server);
  auto page = request(*server, http::verb::get, "/", host);
  EXPECT_EQ(page.result(), http::status::ok);
  EXPECT_NE(page.body().find("toonforce viewer"), std::string::npos);
  EXPECT_NE(std::string(page[http::field::content_type]).find("text/html"), std::string::npos);
  EXPECT_NE(std::string(page["Content-Security-Policy"]).find("default-src 'self'"), std::string::npos);
  EXPECT_EQ(page["X-Content-Type-Options"], "nosniff");
  for (const Asset& a : assets()) {
    auto res = request(*server, http::verb::get, std::string(a.path), host);
    EXPECT_EQ(res.result(), http::status::ok) << a.path;
    EXPECT_EQ(res.body(), a.body) << a.path;
  }
  auto head = request(*server, http::verb::head, "/index.html", host);
  EXPECT_EQ(head.result(), http::status::ok);
  EXPECT_EQ(head[http::field::content_length], std::to_string(find_asset("/")->body.size()));

  // Path traversal, in the spellings that get past naive checks: none reaches a file.
  for (const char* target : {"/../../../../etc/passwd", "/%2e%2e/%2e%2e/etc/passwd", "/..%2f..%2fetc%2fpasswd",
                             "//etc/passwd", "/assets/../../CMakeLists.txt", "/index.html/../../README.md", "/assets/",
                             "/%00", "/.git/config", "/ws", "/tools/viewer/web/index.html"}) {
    auto res = request(*server, http::verb::get, target, host);
    EXPECT_EQ(res.result(), http::status::not_found) << target;
    EXPECT_EQ(res.body().find("root:"), std::string::npos) << target;
  }
  // Read-only: nothing but GET and HEAD.
  for (const http::verb verb : {http::verb::post, http::verb::put, http::verb::delete_, http::verb::patch}) {
    auto res = request(*server, verb, "/index.html", host);
    EXPECT_EQ(res.result(), http::status::method_not_allowed);
    EXPECT_EQ(res[http::field::allow], "GET, HEAD");
  }
  EXPECT_GE(server->stats().http_refused, 15U);
}

TEST(ViewerServer, RequestsNamingAnotherHostAreRefused) {
  auto server = start_server();
  const std::string port = std::to_string(server->port());
  EXPECT_EQ(request(*server, http::verb::get, "/", "localhost:" + port).result(), http::status::ok);
  EXPECT_EQ(request(*server, http::verb::get, "/", "[::1]:" + port).result(), http::status::ok);
  // DNS rebinding: a page of evil.example resolved to 127.0.0.1 asks with its own name.
  for (const std::string& host : std::vector<std::string>{"evil.example:" + port, "127.0.0.1:1", "127.0.0.1", "",
                                                          "127.0.0.1:" + port + "@evil"}) {
    EXPECT_EQ(request(*server, http::verb::get, "/", host).result(), http::status::misdirected_request) << host;
  }
}

/// A WebSocket client of the viewer (optionally with a small receive buffer, to be slow).
struct Client {
  asio::io_context io;
  websocket::stream<tcp::socket> ws{io};
  beast::error_code ec;

  Client(const ViewerServer& server, const std::string& origin, int receive_buffer = 0, const std::string& host = {}) {
    tcp::socket& s = ws.next_layer();
    s.open(tcp::v4());
    if (receive_buffer > 0) s.set_option(asio::socket_base::receive_buffer_size(receive_buffer));
    s.connect(tcp::endpoint(asio::ip::make_address("127.0.0.1"), server.port()));
    ws.set_option(websocket::stream_base::decorator([origin](websocket::request_type& req) {
      if (!origin.empty()) req.set(http::field::origin, origin);
    }));
    ws.handshake(host.empty() ? host_of(server) : host, "/ws", ec);
  }

  /// The next message: text, or binary as doubles.
  bool next(std::string& text, std::vector<double>& values) {
    beast::flat_buffer buffer;
    ws.read(buffer, ec);
    if (ec) return false;
    const std::string data = beast::buffers_to_string(buffer.data());
    text.clear();
    values.clear();
    if (ws.got_text()) {
      text = data;
    } else {
      values.resize(data.size() / sizeof(double));
      std::memcpy(values.data(), data.data(), values.size() * sizeof(double));
    }
    return true;
  }
};

TEST(ViewerServer, TheWebSocketOnlyOpensForTheViewersOwnOrigin) {
  auto server = start_server();
  const std::string own = "http://" + host_of(*server);
  for (const std::string& origin :
       std::vector<std::string>{"http://evil.example", "", "null", "https://" + host_of(*server), own + ".evil.example",
                                "http://localhost:" + std::to_string(server->port())}) {
    // (localhost is one of our names, but the Host asked was 127.0.0.1: not the same origin.)
    Client client(*server, origin);
    EXPECT_EQ(client.ec, websocket::error::upgrade_declined) << origin;
  }
  EXPECT_EQ(server->stats().pages_refused, 6U);
  EXPECT_EQ(server->stats().pages_connected, 0U);
  Client client(*server, own);
  ASSERT_FALSE(client.ec) << client.ec.message();
  std::string text;
  std::vector<double> values;
  ASSERT_TRUE(client.next(text, values));
  EXPECT_EQ(text, R"({"type":"hello","test":true})");
}

TEST(ViewerServer, TheSocketIsReadOnlyAMessageClosesIt) {
  auto server = start_server();
  ViewFrame frame{};
  frame[kT] = 0.5;
  server->publish(frame);
  std::atomic<int> stop{0};
  server->wait_drained(stop);
  Client client(*server, "http://" + host_of(*server));
  ASSERT_FALSE(client.ec);
  std::string text;
  std::vector<double> values;
  ASSERT_TRUE(client.next(text, values));  // hello
  client.ws.write(asio::buffer(std::string(R"({"type":"force","force":[0,0,8]})")));
  while (client.next(text, values)) {
  }
  EXPECT_EQ(client.ec, websocket::error::closed);
  EXPECT_EQ(client.ws.reason().code, websocket::close_code::policy_error);
  EXPECT_EQ(server->stats().messages_refused, 1U);
  EXPECT_EQ(server->stats().frames_in, 1U);  // what was published is all there is
}

TEST(ViewerServer, APageGetsTheHistoryThenLiveFramesInOrder) {
  auto server = start_server();
  std::atomic<int> stop{0};
  for (int i = 0; i < 5000; ++i) {
    ViewFrame f{};
    f[kT] = i * 1e-3;
    f[kTick] = i;
    server->publish(f);
    if (i % 1000 == 999) server->wait_drained(stop);
  }
  server->wait_drained(stop);
  Client client(*server, "http://" + host_of(*server));
  ASSERT_FALSE(client.ec);
  for (int i = 5000; i < 6000; ++i) {
    ViewFrame f{};
    f[kTick] = i;
    server->publish(f);
  }
  server->finish();
  std::string text;
  std::vector<double> values;
  double expected_seq = 0;
  bool ended = false;
  while (!ended && client.next(text, values)) {
    if (!text.empty()) {
      ended = text.find(R"("ended":true)") != std::string::npos;
      continue;
    }
    ASSERT_GE(values.size(), 4U);
    EXPECT_EQ(values[1], static_cast<double>(kViewStride));
    EXPECT_EQ(values[2], expected_seq);
    const auto n = static_cast<std::size_t>(values[3]);
    ASSERT_EQ(values.size(), 4 + n * kViewStride);
    for (std::size_t k = 0; k < n; ++k)
      EXPECT_EQ(values[4 + k * kViewStride + kTick], expected_seq + static_cast<double>(k));
    expected_seq += static_cast<double>(n);
  }
  EXPECT_TRUE(ended);
  EXPECT_EQ(expected_seq, 6000.0);
}

TEST(ViewerServer, ASlowPageLosesBatchesNotTheProducer) {
  ViewerOptions options;
  options.send_buffer_bytes = 4096;
  options.max_queued_batches = 4;
  options.batch_interval_s = 0.005;
  auto server = start_server(options);
  Client client(*server, "http://" + host_of(*server), 4096);
  ASSERT_FALSE(client.ec);
  // The page reads nothing while 300 batches of 100 frames (6.5 MB) are published.
  std::atomic<int> stop{0};
  std::uint64_t published = 0;
  for (int b = 0; b < 300; ++b) {
    for (int i = 0; i < 100; ++i) {
      ViewFrame f{};
      f[kTick] = static_cast<double>(published++);
      server->publish(f);
    }
    server->wait_drained(stop);  // the server took them: batch b is queued for the page
  }
  server->finish();
  const ViewerStats during = server->stats();
  EXPECT_EQ(during.frames_in, published);
  EXPECT_EQ(during.frames_dropped_ring, 0U);
  EXPECT_GT(during.frames_dropped_pages, 0U) << "the page read nothing: batches must have been dropped";
  EXPECT_LE(during.max_queued, options.max_queued_batches) << "the queue stays bounded";

  // Now the page reads: what it gets plus the gaps it sees is everything published.
  std::string text;
  std::vector<double> values;
  double next_seq = 0;
  double received = 0;
  double gaps = 0;
  std::string last_status;
  while (client.next(text, values)) {
    if (!text.empty()) {
      last_status = text;
      if (text.find(R"("ended":true)") != std::string::npos) break;
      continue;
    }
    if (values[2] > next_seq) gaps += values[2] - next_seq;
    next_seq = values[2] + values[3];
    received += values[3];
  }
  EXPECT_EQ(received + gaps + (static_cast<double>(published) - next_seq), static_cast<double>(published));
  EXPECT_GT(gaps, 0.0);
  EXPECT_EQ(static_cast<std::uint64_t>(gaps), server->stats().frames_dropped_pages)
      << "every dropped frame shows as a gap to the page";
  EXPECT_NE(last_status.find(R"("dropped_page":)" + std::to_string(server->stats().frames_dropped_pages)),
            std::string::npos)
      << last_status;
}

TEST(ViewerServer, PublishNeitherAllocatesNorWaits) {
  ViewerOptions options;
  options.batch_interval_s = 1.0;
  auto server = start_server(options);
  TelemetryFrame frame;
  frame.position_m = {0.01, 0.0, -0.002};
  std::size_t allocations = 0;
  {
    test::AllocationScope scope;
    for (int i = 0; i < 20000; ++i) {  // more than the ring holds: the rest are dropped, counted
      frame.tick = i;
      server->publish(frame);
    }
    allocations = scope.count();
  }
  EXPECT_EQ(allocations, 0U);
  const ViewerStats s = server->stats();
  EXPECT_EQ(s.frames_in, 20000U);
  EXPECT_GT(s.frames_dropped_ring, 0U);
}

/// This process's resident memory [kB] (VmRSS in /proc/self/status), or -1.
long resident_kb() {
  std::ifstream status("/proc/self/status");
  std::string line;
  while (std::getline(status, line)) {
    if (line.rfind("VmRSS:", 0) == 0) return std::stol(line.substr(6));
  }
  return -1;
}

/// Waits (generously: a loaded machine is slow, never wrong) until `done` holds; its last value.
bool eventually(const std::function<bool()>& done, std::chrono::seconds limit = std::chrono::seconds(60)) {
  const auto end = std::chrono::steady_clock::now() + limit;
  while (!done()) {
    if (std::chrono::steady_clock::now() > end) return done();
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
  }
  return true;
}

/// A plain blocking TCP socket to the server on 127.0.0.1 (POSIX, so that a receive timeout
/// guards every read: a test that waits for an answer that never comes fails, it does not hang).
int connect_raw(std::uint16_t port, int receive_buffer = 0) {
  const int fd = ::socket(AF_INET, SOCK_STREAM, 0);
  if (fd < 0) return -1;
  if (receive_buffer > 0) ::setsockopt(fd, SOL_SOCKET, SO_RCVBUF, &receive_buffer, sizeof receive_buffer);
  const timeval timeout{60, 0};
  ::setsockopt(fd, SOL_SOCKET, SO_RCVTIMEO, &timeout, sizeof timeout);
  sockaddr_in to{};
  to.sin_family = AF_INET;
  to.sin_port = htons(port);
  to.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  if (::connect(fd, reinterpret_cast<const sockaddr*>(&to), sizeof to) != 0) {
    ::close(fd);
    return -1;
  }
  return fd;
}

/// The status code of the answer on `fd` ("101", "503", ...), "closed" or "timeout".
std::string read_status(int fd) {
  std::string head;
  char c = 0;
  while (head.size() < 12) {
    const ssize_t n = ::recv(fd, &c, 1, 0);
    if (n == 1) {
      head.push_back(c);
    } else {
      return n < 0 && (errno == EAGAIN || errno == EWOULDBLOCK) ? "timeout" : "closed";
    }
  }
  return head.rfind("HTTP/1.1 ", 0) == 0 ? head.substr(9, 3) : "garbage";
}

// 300 valid upgrades at once from a local process got 133 pages past the cap
// of 16 (the count went up only once each handshake was written, so every request read before
// then passed the check), and each page queued a copy of the whole history: 3.4 GB, kept after
// the pages closed. Counts are exact; resident memory gets a generous bound (a page's copy of
// this history is 7 MB, so 16 copies alone exceed it).
TEST(ViewerServer, HundredsOfConcurrentUpgradesGetTheCapAndBoundedMemory) {
  ViewerOptions options;
  options.history_frames = 1U << 15;     // 7 MB of history, all of it published
  options.send_buffer_bytes = 4096;      // what is queued stays in this process, not in the kernel
  options.evict_reading_after_s = 60.0;  // none evicted, however slowly a loaded host connects 300
  auto server = start_server(options);
  std::atomic<int> stop{0};
  for (std::size_t i = 0; i < options.history_frames; ++i) {
    ViewFrame f{};
    f[kTick] = static_cast<double>(i);
    server->publish(f);
    if (i % 4096 == 4095) server->wait_drained(stop);
  }
  server->wait_drained(stop);
  const long before_kb = resident_kb();
  ASSERT_GT(before_kb, 0);

  constexpr int kClients = 300;
  const std::string port = std::to_string(server->port());
  const std::string upgrade = "GET /ws HTTP/1.1\r\nHost: 127.0.0.1:" + port + "\r\nOrigin: http://127.0.0.1:" + port +
                              "\r\nUpgrade: websocket\r\nConnection: Upgrade\r\n"
                              "Sec-WebSocket-Key: dGhlIHNhbXBsZSBub25jZQ==\r\nSec-WebSocket-Version: 13\r\n\r\n";
  std::vector<int> clients;
  for (int i = 0; i < kClients; ++i) {
    const int fd = connect_raw(server->port(), 4096);  // pages that read nothing
    ASSERT_GE(fd, 0) << std::strerror(errno);
    clients.push_back(fd);
  }
  for (const int fd : clients) {  // every request on the wire before the server answers one
    static_cast<void>(::send(fd, upgrade.data(), upgrade.size(), MSG_NOSIGNAL));
  }
  std::map<std::string, int> answers;
  for (const int fd : clients) ++answers[read_status(fd)];
  EXPECT_EQ(answers["101"], 16) << "the cap of 16 pages";
  EXPECT_EQ(answers["timeout"], 0);
  EXPECT_EQ(answers["101"] + answers["503"] + answers["closed"], kClients);
  EXPECT_TRUE(eventually([&] { return server->stats().pages_connected >= 16; }));
  const ViewerStats held = server->stats();
  EXPECT_EQ(held.pages_connected, 16U);
  EXPECT_EQ(held.pages_open, 16U);
  EXPECT_EQ(held.pages_refused, static_cast<std::uint64_t>(answers["503"]));
  // Over max_connections: closed at once (none had been reading long enough to make room).
  EXPECT_EQ(held.connections_refused, static_cast<std::uint64_t>(answers["closed"]));
  EXPECT_EQ(held.requests_evicted, 0U);
  // Each page holds one history chunk (and the small hello and status), not the 7 MB history.
  const std::size_t chunk_bytes = (4 + kHistoryChunkFrames * kViewStride) * sizeof(double);
  EXPECT_GT(held.max_queued_bytes, 0U);
  EXPECT_LE(held.max_queued_bytes, 16 * (chunk_bytes + 4096)) << "bytes queued for pages at most";
  const long held_kb = resident_kb();
  EXPECT_LT(held_kb - before_kb, 64 * 1024)
      << "resident memory with 16 pages open, kB: " << before_kb << " -> " << held_kb;

  for (const int fd : clients) ::close(fd);
  EXPECT_TRUE(eventually([&] { return server->stats().pages_open == 0; }));
  EXPECT_EQ(server->stats().queued_bytes, 0U) << "what the pages held is released when they close";
  const long after_kb = resident_kb();
  EXPECT_LT(after_kb - before_kb, 64 * 1024)
      << "resident memory after the pages closed, kB: " << before_kb << " -> " << after_kb;
  std::printf("resident memory: %ld kB before, %ld kB with 16 pages of %d upgrades, %ld kB after they closed\n",
              before_kb, held_kb, kClients, after_kb);
}

// The history goes out a chunk at a time, made when the page has taken the one before: a slow
// page holds one chunk, and frames the ring overwrites meanwhile are lost for it, counted, and
// seen by the page as a gap, like the live batches it could not take.
TEST(ViewerServer, HistoryGoesOutAChunkAtATimeAndWhatTheRingLostIsCounted) {
  ViewerOptions options;
  options.history_frames = 3000;
  options.send_buffer_bytes = 4096;
  options.max_queued_batches = 4;
  options.batch_interval_s = 0.005;
  auto server = start_server(options);
  std::atomic<int> stop{0};
  std::uint64_t published = 0;
  const auto publish = [&](int frames) {
    for (int i = 0; i < frames; ++i) {
      ViewFrame f{};
      f[kTick] = static_cast<double>(published++);
      server->publish(f);
    }
    server->wait_drained(stop);
  };
  for (int b = 0; b < 50; ++b) publish(100);  // 5000: the ring keeps 2000..4999
  Client client(*server, "http://" + host_of(*server), 4096);
  ASSERT_FALSE(client.ec);
  ASSERT_TRUE(eventually([&] { return server->stats().pages_open == 1; }));
  for (int b = 0; b < 200; ++b) publish(100);  // the page reads nothing meanwhile
  server->finish();
  EXPECT_LE(server->stats().max_queued_bytes,
            (4 + kHistoryChunkFrames * kViewStride) * sizeof(double) + 4096 +
                options.max_queued_batches * (4 + 100 * kViewStride) * sizeof(double));

  // The page came when frames 0..4999 had been taken from the ring (publish waits for that),
  // of which the history ring kept 2000..4999: that is what it asks for.
  std::string text;
  std::vector<double> values;
  double first_seq = -1;
  double next_seq = 2000;
  double history_frames = 0;
  double received = 0;
  double gaps = 0;
  while (client.next(text, values)) {
    if (!text.empty()) {
      if (text.find(R"("ended":true)") != std::string::npos) break;
      continue;
    }
    ASSERT_EQ(values.size(), 4 + static_cast<std::size_t>(values[3]) * kViewStride);
    if (first_seq < 0) first_seq = values[2];
    ASSERT_GE(values[2], next_seq) << "in order";
    gaps += values[2] - next_seq;
    for (std::size_t k = 0; k < static_cast<std::size_t>(values[3]); ++k) {
      EXPECT_EQ(values[4 + k * kViewStride + kTick], values[2] + static_cast<double>(k));
    }
    next_seq = values[2] + values[3];
    received += values[3];
    if (values[0] == 2.0) history_frames += values[3];
  }
  EXPECT_GE(first_seq, 2000.0) << "nothing older than the ring kept";
  EXPECT_GT(history_frames, 0.0);
  EXPECT_LT(history_frames, 3000.0) << "the history was overwritten before the page took all of it";
  EXPECT_EQ(static_cast<std::uint64_t>(gaps), server->stats().frames_dropped_pages);
  EXPECT_EQ(received + gaps + (static_cast<double>(published) - next_seq), static_cast<double>(published) - 2000.0);
}

/// The highest descriptor this process has open.
int highest_fd() {
  int highest = 2;
  if (DIR* dir = ::opendir("/proc/self/fd")) {
    while (const dirent* entry = ::readdir(dir)) highest = std::max(highest, std::atoi(entry->d_name));
    ::closedir(dir);
  }
  return highest;
}

// Out of file descriptors, accept() fails with EMFILE while the connection
// stays in the backlog, so the listener is readable again at once and the accept loop spun at
// 100 % CPU. The test runs the process out of descriptors (a lower RLIMIT_NOFILE, the rest
// taken by dup), connects, and counts the accepts that fail over a wall interval: the server
// waits at least kAcceptRetryMinS between them, so a slow machine only makes the count smaller.
// Then it gives the descriptors back and the waiting connection is served.
TEST(ViewerServer, OutOfDescriptorsTheAcceptLoopWaitsInsteadOfSpinning) {
  auto server = start_server();
  // UBSan checks a polymorphic object's type the first time it meets it with a pipe(), which
  // fails without descriptors ("invalid vptr"): meet it now, while there are some.
  EXPECT_EQ(server->stats().accept_failures, 0U);
  rlimit old{};
  ASSERT_EQ(::getrlimit(RLIMIT_NOFILE, &old), 0);
  rlimit low = old;
  low.rlim_cur = static_cast<rlim_t>(highest_fd() + 32);
  ASSERT_LE(low.rlim_cur, old.rlim_cur);
  ASSERT_EQ(::setrlimit(RLIMIT_NOFILE, &low), 0);
  std::vector<int> fillers;
  for (int fd = ::dup(STDERR_FILENO); fd >= 0; fd = ::dup(STDERR_FILENO)) fillers.push_back(fd);
  const int dup_errno = errno;
  ASSERT_FALSE(fillers.empty());
  ::close(fillers.back());  // one for the client; none is left for the server's accept
  fillers.pop_back();
  const int client = connect_raw(server->port());
  const int connect_errno = errno;
  const auto give_back = [&] {
    for (const int fd : fillers) ::close(fd);
    fillers.clear();
    ::setrlimit(RLIMIT_NOFILE, &old);
  };
  if (dup_errno != EMFILE || client < 0) give_back();
  ASSERT_EQ(dup_errno, EMFILE);
  ASSERT_GE(client, 0) << std::strerror(connect_errno);

  const bool failing = eventually([&] { return server->stats().accept_failures > 0; });
  const auto start = std::chrono::steady_clock::now();
  const std::uint64_t failures_before = server->stats().accept_failures;
  std::this_thread::sleep_for(std::chrono::seconds(1));
  const std::uint64_t failures = server->stats().accept_failures - failures_before;
  const double wall_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  give_back();
  EXPECT_TRUE(failing) << "the server's accept must have failed for want of a descriptor";
  EXPECT_LE(static_cast<double>(failures), 2.0 + wall_s / kAcceptRetryMinS)
      << failures << " failed accepts in " << wall_s << " s: the accept loop spins";
  std::printf("out of descriptors: %llu failed accepts in %.2f s\n", static_cast<unsigned long long>(failures), wall_s);

  const std::string get = "GET / HTTP/1.1\r\nHost: " + host_of(*server) + "\r\nConnection: close\r\n\r\n";
  ASSERT_EQ(::send(client, get.data(), get.size(), MSG_NOSIGNAL), static_cast<ssize_t>(get.size()));
  EXPECT_EQ(read_status(client), "200") << "served once descriptors are back";
  ::close(client);
}

/// This host's IPv4 addresses other than loopback (a sandbox may have none).
std::vector<std::string> other_ipv4_addresses() {
  std::vector<std::string> out;
  ifaddrs* list = nullptr;
  if (::getifaddrs(&list) != 0) return out;
  for (const ifaddrs* i = list; i != nullptr; i = i->ifa_next) {
    if (i->ifa_addr == nullptr || i->ifa_addr->sa_family != AF_INET) continue;
    sockaddr_in in{};
    std::memcpy(&in, i->ifa_addr, sizeof in);
    const asio::ip::address_v4 address(ntohl(in.sin_addr.s_addr));
    if (!address.is_loopback()) out.push_back(address.to_string());
  }
  ::freeifaddrs(list);
  return out;
}

// With --view-address 0.0.0.0 any Host with the right port was accepted, so a
// page of evil.example, its name rebound to this host, could read the viewer (DNS rebinding).
// On every address the Host must name this server: the loopback names, this host's addresses,
// or a name it was given.
TEST(ViewerServer, OnEveryAddressTheHostMustStillNameThisServer) {
  ViewerOptions options;
  options.address = "0.0.0.0";
  auto server = start_server(options);
  const std::string port = std::to_string(server->port());
  for (const std::string& host :
       std::vector<std::string>{"evil.example:" + port, "viewer.lan:" + port, "localhost.evil.example:" + port,
                                "127.0.0.1:" + port + "@evil", "0.0.0.0:" + port, "127.0.0.1"}) {
    EXPECT_EQ(request(*server, http::verb::get, "/", host).result(), http::status::misdirected_request) << host;
  }
  EXPECT_EQ(request(*server, http::verb::get, "/", "LOCALHOST:" + port).result(), http::status::ok);
  const std::vector<std::string> names = server->host_names();
  EXPECT_NE(std::find(names.begin(), names.end(), "127.0.0.1:" + port), names.end());
  for (const std::string& host : names) {  // this host's addresses among them
    EXPECT_EQ(request(*server, http::verb::get, "/", host).result(), http::status::ok) << host;
  }
  for (const std::string& address : other_ipv4_addresses()) {
    EXPECT_NE(std::find(names.begin(), names.end(), address + ":" + port), names.end()) << address;
  }
  // The rebinding page's socket: its Host and its Origin are its own name.
  Client rebound(*server, "http://evil.example:" + port, 0, "evil.example:" + port);
  EXPECT_EQ(rebound.ec, websocket::error::upgrade_declined);
  EXPECT_EQ(server->stats().pages_connected, 0U);
}

// Serving to other hosts by a name is an explicit choice: ViewerOptions::hosts (--view-host).
TEST(ViewerServer, NamesGivenForTheHostAreAcceptedAndNoOthers) {
  ViewerOptions options;
  options.address = "0.0.0.0";
  options.hosts = {"Viewer.LAN", "192.0.2.7", "2001:DB8::1", "[2001:db8::2]"};
  auto server = start_server(options);
  const std::string port = std::to_string(server->port());
  for (const std::string& host :
       std::vector<std::string>{"viewer.lan:" + port, "VIEWER.lan:" + port, "192.0.2.7:" + port,
                                "[2001:db8::1]:" + port, "[2001:db8::2]:" + port}) {
    EXPECT_EQ(request(*server, http::verb::get, "/", host).result(), http::status::ok) << host;
  }
  for (const std::string& host :
       std::vector<std::string>{"viewer.lan", "viewer.lan:1", "other.lan:" + port, "www.viewer.lan:" + port}) {
    EXPECT_EQ(request(*server, http::verb::get, "/", host).result(), http::status::misdirected_request) << host;
  }
  Client page(*server, "http://viewer.lan:" + port, 0, "viewer.lan:" + port);
  ASSERT_FALSE(page.ec) << page.ec.message();
  std::string text;
  std::vector<double> values;
  ASSERT_TRUE(page.next(text, values));
  EXPECT_EQ(text, R"({"type":"hello","test":true})");

  // A name that is not one is refused before anything listens.
  for (const std::string& bad : std::vector<std::string>{"evil example", "viewer.lan:8765", "", "a/b", "-x", "*"}) {
    ViewerOptions o;
    o.port = 0;
    o.hosts = {bad};
    auto refused = ViewerServer::start(o, "{}");
    ASSERT_FALSE(refused) << bad;
    EXPECT_NE(refused.error().find("host name"), std::string::npos) << refused.error();
  }
}

// On one address other than loopback, the Host names that address (or a name given).
TEST(ViewerServer, OnAnotherAddressTheHostMustNameThatAddress) {
  const std::vector<std::string> addresses = other_ipv4_addresses();
  if (addresses.empty()) GTEST_SKIP() << "this host has no IPv4 address but loopback";
  ViewerOptions options;
  options.address = addresses.front();
  auto server = start_server(options);
  const std::string port = std::to_string(server->port());
  EXPECT_EQ(server->url(), "http://" + addresses.front() + ":" + port + "/");
  EXPECT_EQ(request(*server, http::verb::get, "/", addresses.front() + ":" + port, addresses.front()).result(),
            http::status::ok);
  for (const std::string& host : std::vector<std::string>{"evil.example:" + port, "0.0.0.0:" + port}) {
    EXPECT_EQ(request(*server, http::verb::get, "/", host, addresses.front()).result(),
              http::status::misdirected_request)
        << host;
  }
}

// The option reaches the server: `toonforce view --host NAME` (and run/sim's --view-host, the
// same plumbing) accepts NAME and still refuses other names.
TEST(ViewerCommand, HostNamesGivenOnTheCommandLineAreAccepted) {
  const std::string trace = ::testing::TempDir() + "/viewer_host_option.csv";
  {
    std::FILE* f = std::fopen(trace.c_str(), "w");
    ASSERT_NE(f, nullptr);
    std::fputs("t,x,y,z,vx,vy,vz,fx,fy,fz\n0,0,0,0,0,0,0,0,0,0\n0.001,0,0,0,0,0,0,0,0,0\n", f);
    std::fclose(f);
  }
  int err[2];
  ASSERT_EQ(::pipe(err), 0);
  posix_spawn_file_actions_t actions;
  posix_spawn_file_actions_init(&actions);
  posix_spawn_file_actions_adddup2(&actions, err[1], STDERR_FILENO);
  posix_spawn_file_actions_addclose(&actions, err[0]);
  std::vector<std::string> args{"toonforce", "view",       trace,    "--port",   "0",
                                "--host",    "Viewer.LAN", "--host", "192.0.2.9"};
  std::vector<char*> argv;
  for (std::string& a : args) argv.push_back(a.data());
  argv.push_back(nullptr);
  pid_t pid = 0;
  const int spawned = ::posix_spawn(&pid, TOONFORCE_BINARY, &actions, nullptr, argv.data(), environ);
  posix_spawn_file_actions_destroy(&actions);
  ::close(err[1]);
  ASSERT_EQ(spawned, 0);
  // "viewer: http://127.0.0.1:PORT/ ..." on standard error, then "... until Ctrl-C" once SIGTERM
  // is handled (before that line it would kill the command, and the test would see that).
  std::string out;
  std::size_t at = std::string::npos;
  while ((at = out.find("http://127.0.0.1:")) == std::string::npos || out.find("until Ctrl-C") == std::string::npos) {
    pollfd p{err[0], POLLIN, 0};
    char buffer[512];
    const ssize_t n = ::poll(&p, 1, 60000) == 1 ? ::read(err[0], buffer, sizeof buffer) : 0;
    if (n <= 0) break;
    out.append(buffer, static_cast<std::size_t>(n));
  }
  const auto port = static_cast<std::uint16_t>(at == std::string::npos ? 0 : std::atoi(out.c_str() + at + 17));
  if (port != 0) {
    EXPECT_EQ(request_to(port, http::verb::get, "/", "viewer.lan:" + std::to_string(port)).result(), http::status::ok);
    EXPECT_EQ(request_to(port, http::verb::get, "/", "192.0.2.9:" + std::to_string(port)).result(), http::status::ok);
    EXPECT_EQ(request_to(port, http::verb::get, "/", "evil.example:" + std::to_string(port)).result(),
              http::status::misdirected_request);
  }
  ::kill(pid, SIGTERM);
  int status = 0;
  ::waitpid(pid, &status, 0);
  ::close(err[0]);
  ASSERT_NE(port, 0) << out;
  EXPECT_TRUE(WIFEXITED(status) && WEXITSTATUS(status) == 0) << status;
}

TEST(ViewerServer, RefusesAnAddressItCannotUse) {
  ViewerOptions options;
  options.address = "not-an-address";
  auto bad = ViewerServer::start(options, "{}");
  ASSERT_FALSE(bad);
  EXPECT_NE(bad.error().find("--view-address not-an-address: not an IP address"), std::string::npos) << bad.error();
  // `toonforce view` calls it --address (its errors named --view-address).
  options.address_option = "--address";
  auto bad_view = ViewerServer::start(options, "{}");
  ASSERT_FALSE(bad_view);
  EXPECT_NE(bad_view.error().find("--address not-an-address: not an IP address"), std::string::npos)
      << bad_view.error();
  auto first = start_server();
  options.address = "127.0.0.1";
  options.port = first->port();
  auto taken = ViewerServer::start(options, "{}");
  ASSERT_FALSE(taken);
  EXPECT_NE(taken.error().find("another program uses the port"), std::string::npos) << taken.error();
}

TEST(ViewerHello, CarriesTheSceneGeometryAndTheColumns) {
  auto scene = load_scene_file(std::string(kSource) + "/scenes/cliff.toml");
  ASSERT_TRUE(scene) << scene.error();
  HelloInfo info;
  info.source = "sim";
  info.title = "a \"cliff\" </script>";
  info.rate_hz = 1000.0;
  info.scene_json = scene_json(scene.value());
  info.effect_values = {"cliff1.state", "cliff1.speed"};
  const std::string hello = make_hello(info);
  EXPECT_NE(hello.find(R"("type":"hello")"), std::string::npos);
  // Every key of the effect, from its schema, defaults included.
  EXPECT_NE(hello.find(R"({"key":"cliff","number":1,"line":)"), std::string::npos) << hello;
  EXPECT_NE(hello.find(R"("gap_min":0,"gap_max":0.02)"), std::string::npos) << hello;
  EXPECT_NE(hello.find(R"("speed_threshold":0.08)"), std::string::npos);
  EXPECT_NE(hello.find(R"("axis":[1,0,0])"), std::string::npos);
  EXPECT_NE(hello.find(R"("tau":0.02)"), std::string::npos);
  EXPECT_NE(hello.find(R"("values":["cliff1.state","cliff1.speed"])"), std::string::npos) << hello;
  EXPECT_NE(hello.find(R"(a \"cliff\" \u003c/script>)"), std::string::npos) << hello;
  EXPECT_NE(hello.find(R"("columns":["t","tick","x")"), std::string::npos);
  EXPECT_NE(hello.find(R"("missed","cliff1.state","cliff1.speed","")"), std::string::npos) << hello;
  EXPECT_NE(hello.find(R"~([16,"missed ticks (the loop's own watchdog)"])~"), std::string::npos);
}

TEST(ViewerTrace, ReadsRunAndSimTracesByColumnName) {
  auto run = parse_trace("t,x,y,z,vx,vy,vz,fx,fy,fz,faults,contact,cliff_state,tick,wake_latency_us,missed\n"
                         "0,0.001,0,-0.002,0,0,0,0,0,3,0,1,-1,0,12.5,0\n"
                         "0.001,0.001,0,-0.002,0,0,0,0,0,3,16,1,-1,1,40,2\n",
                         "run.csv");
  ASSERT_TRUE(run) << run.error();
  EXPECT_EQ(run->source, "run");
  EXPECT_TRUE(run->has_loop);
  ASSERT_EQ(run->frames.size(), 2U);
  EXPECT_DOUBLE_EQ(run->rate_hz, 1000.0);
  EXPECT_EQ(run->frames[1][kFaults], 16.0);
  EXPECT_EQ(run->frames[1][kWakeLatencyUs], 40.0);
  EXPECT_TRUE(std::isnan(run->frames[1][kLatched]));

  auto sim = parse_trace("t,x,y,z,vx,vy,vz,fx,fy,fz,faults,limits,contact,surface1.impact_t,cliff1.state,true_x\n"
                         "0,0,0,0,0,0,0,0,0,0,0,0,0,nan,0,0\n"
                         "0.002,0,0,0,0,0,0,0,0,0,1,0,,,1,0\n",
                         "sim.csv");
  ASSERT_TRUE(sim) << sim.error();
  EXPECT_EQ(sim->source, "sim");
  EXPECT_FALSE(sim->has_loop);
  EXPECT_EQ(sim->frames[1][kTick], 1.0);  // no tick column: the row number
  EXPECT_TRUE(std::isnan(sim->frames[1][kContact]));
  EXPECT_DOUBLE_EQ(sim->rate_hz, 500.0);
  // The effects' values, in the frame's effect columns, in the trace's order.
  EXPECT_EQ(sim->effect_values, (std::vector<std::string>{"surface1.impact_t", "cliff1.state"}));
  EXPECT_TRUE(std::isnan(sim->frames[0][kFirstEffectValue]));
  EXPECT_EQ(sim->frames[1][kFirstEffectValue + 1], 1.0);

  const auto error = [](std::string_view text) {
    auto r = parse_trace(text, "bad.csv", 2);
    return r ? std::string() : r.error();
  };
  EXPECT_NE(error("t,x,y\n").find("bad.csv:1: not a toonforce trace"), std::string::npos);
  EXPECT_NE(error("t,x,y,z,vx,vy,vz,fx,fy,fz\n0,0,0,0,0,0,0,0,0,zero\n").find("bad.csv:2: column 'fz': 'zero'"),
            std::string::npos);
  EXPECT_NE(
      error("t,x,y,z,vx,vy,vz,fx,fy,fz\n1,0,0,0,0,0,0,0,0,0\n1,0,0,0,0,0,0,0,0,0\n").find("bad.csv:3: column 't'"),
      std::string::npos);
  EXPECT_NE(error("t,x,y,z,vx,vy,vz,fx,fy,fz\n0,0,0,0,0,0,0,0,0,0,9\n").find("more fields"), std::string::npos);
  EXPECT_NE(error("t,x,y,z,vx,vy,vz,fx,fy,fz\n0,0,0\n").find("3 fields"), std::string::npos);
  EXPECT_NE(error("t,x,y,z,vx,vy,vz,fx,fy,fz\n0,0,0,0,0,0,0,0,0,0\n1,0,0,0,0,0,0,0,0,0\n2,0,0,0,0,0,0,0,0,0\n")
                .find("more than 2 rows"),
            std::string::npos);
  EXPECT_NE(error("").find("empty"), std::string::npos);
}

// A SIGKILLed run or a full disk leaves a trace whose last row has no end of line;
// the viewer shows the rows before it and says so (it refused the whole trace).
TEST(TraceFile, ACutLastRowIsLeftOutAndNamedNotRefused) {
  auto cut = parse_trace("t,x,y,z,vx,vy,vz,fx,fy,fz\n0,0,0,0,0,0,0,0,0,0\n0.001,0,0,0,0,0,0,0,0,0\n0.002,0,0,0,0,0,0.",
                         "cut.csv");
  ASSERT_TRUE(cut) << cut.error();
  EXPECT_EQ(cut->frames.size(), 2U);
  EXPECT_NE(cut->note.find("cut.csv:4: the last row is cut"), std::string::npos) << cut->note;
  auto whole = parse_trace("t,x,y,z,vx,vy,vz,fx,fy,fz\n0,0,0,0,0,0,0,0,0,0\n", "whole.csv");
  ASSERT_TRUE(whole) << whole.error();
  EXPECT_EQ(whole->frames.size(), 1U);
  EXPECT_TRUE(whole->note.empty()) << whole->note;
}

/// Counts what it is given (a stand-in for the viewer, to check the hooks).
class CountingSink final : public TelemetrySink {
 public:
  void publish(const TelemetryFrame& frame) noexcept override {
    ticks.push_back(frame.tick);
    if (frame.value_count > 0 && frame.values[0] == 1.0) ++fallen;  // a cliff scene: cliff1.state
  }
  void finish() noexcept override { ++finished; }
  std::vector<std::int64_t> ticks;
  int fallen = 0;
  int finished = 0;
};

TEST(ViewerHooks, RunFansOutEveryFrameFromTheWriterThread) {
  RunOptions options;
  options.device = "sim";
  options.scene_path = std::string(kSource) + "/scenes/wall.toml";
  options.duration_s = 0.2;
  options.allow_non_realtime = true;
  options.lock_memory = false;
  options.handle_signals = false;
  options.interactive = false;
  CountingSink sink;
  sink.ticks.reserve(1000);
  options.sink = &sink;
  auto summary = run_servo(options);
  ASSERT_TRUE(summary) << summary.error();
  EXPECT_EQ(sink.finished, 1);
  EXPECT_EQ(sink.ticks.size(), summary->frames_written);
  for (std::size_t i = 1; i < sink.ticks.size(); ++i) EXPECT_LT(sink.ticks[i - 1], sink.ticks[i]);
}

TEST(ViewerHooks, SimWithAViewerWritesTheSameTrace) {
  const std::string dir = ::testing::TempDir();
  SimOptions options;
  options.scene_path = std::string(kSource) + "/scenes/cliff.toml";
  options.script_path = std::string(kSource) + "/scenes/hands/cross_slow.toml";
  options.duration_s = 1.4;
  options.trace_path = dir + "/viewer_plain.csv";
  ASSERT_TRUE(run_sim(options));
  CountingSink sink;
  options.sink = &sink;
  options.pace = 0.0;  // as fast as it goes: this test asserts counts, not times
  options.trace_path = dir + "/viewer_sink.csv";
  auto with_sink = run_sim(options);
  ASSERT_TRUE(with_sink) << with_sink.error();
  EXPECT_EQ(sink.ticks.size(), 1400U);
  EXPECT_EQ(sink.finished, 1);
  EXPECT_GT(sink.fallen, 0) << "the slow crossing falls, and the viewer is told";
  const auto slurp = [](const std::string& path) {
    std::FILE* f = std::fopen(path.c_str(), "rb");
    std::string text;
    char buffer[4096];
    std::size_t n = 0;
    while (f != nullptr && (n = std::fread(buffer, 1, sizeof buffer, f)) > 0) text.append(buffer, n);
    if (f != nullptr) std::fclose(f);
    return text;
  };
  const std::string plain = slurp(dir + "/viewer_plain.csv");
  EXPECT_FALSE(plain.empty());
  EXPECT_EQ(plain, slurp(dir + "/viewer_sink.csv"));
}

std::string slurp_file(const std::string& path) {
  std::FILE* f = std::fopen(path.c_str(), "rb");
  std::string text;
  char buffer[4096];
  std::size_t n = 0;
  while (f != nullptr && (n = std::fread(buffer, 1, sizeof buffer, f)) > 0) text.append(buffer, n);
  if (f != nullptr) std::fclose(f);
  return text;
}

std::size_t column_of(const std::vector<std::string>& columns, const std::string& name) {
  return static_cast<std::size_t>(std::find(columns.begin(), columns.end(), name) - columns.begin());
}

WorldSimOptions two_players(const std::string& trace) {
  WorldSimOptions w;
  w.scene_path = std::string(kSource) + "/scenes/two_players.toml";
  w.scripts = {{"left", std::string(kSource) + "/scenes/hands/left_push.toml"},
               {"right", std::string(kSource) + "/scenes/hands/right_push.toml"}};
  w.duration_s = 0.5;
  w.trace_path = trace;
  return w;
}

TEST(ViewerWorld, TheHelloNamesEveryDeviceTheCouplingsAndTheBall) {
  auto world = load_world_file(std::string(kSource) + "/scenes/two_players.toml");
  ASSERT_TRUE(world) << world.error();
  auto map = WorldViewMap::make(world_columns(world.value()));
  ASSERT_TRUE(map) << map.error();
  EXPECT_EQ(map->devices(), (std::vector<std::string>{"left", "right"}));
  ASSERT_EQ(map->columns().size(), kViewStride);
  for (const char* c : {"t", "tick", "left.x", "left.fz", "left.state", "right.y", "right.faults", "ball.x", "held",
                        "coupling1.fx", "right.ball_fz"}) {
    EXPECT_LT(column_of(map->columns(), c), kViewStride) << c;
  }
  HelloInfo info;
  info.source = "sim";
  info.scene_json = scene_json(world->scene);
  info.world_columns = map->columns();
  info.world_json = world_json(map->devices(), &world.value());
  const std::string hello = make_hello(info);
  EXPECT_NE(hello.find(R"("columns":["t","tick","left.x","left.y","left.z","left.fx")"), std::string::npos) << hello;
  // right faces left: half a turn about z, exactly.
  EXPECT_NE(hello.find(R"("world":{"devices":["left","right"],"couplings":[[0,1]],"ball_radius":0.015,)"
                       R"("rotations":[[[1,0,0],[0,1,0],[0,0,1]],[[-1,0,0],[0,-1,0],[0,0,1]]]})"),
            std::string::npos)
      << hello;
  // One device: no world.
  EXPECT_NE(make_hello(HelloInfo{}).find(R"("world":null)"), std::string::npos);
}

TEST(ViewerWorld, EachValueGoesToItsDevicesColumn) {
  const std::vector<std::string> trace{"t",       "a.x",      "a.y",       "a.z",     "a.fx",     "a.fy",
                                       "a.fz",    "a.faults", "a.latched", "a.state", "b.x",      "b.y",
                                       "b.z",     "b.fx",     "b.fy",      "b.fz",    "b.faults", "b.latched",
                                       "b.state", "ball.x",   "ball.y",    "ball.z",  "held"};
  auto map = WorldViewMap::make(trace);
  ASSERT_TRUE(map) << map.error();
  EXPECT_EQ(map->devices(), (std::vector<std::string>{"a", "b"})) << "the ball is not a device";
  std::vector<double> row;
  for (std::size_t i = 0; i < trace.size(); ++i) row.push_back(100.0 + static_cast<double>(i));
  const ViewFrame f = map->frame(row, 7.0);
  for (std::size_t i = 0; i < trace.size(); ++i) {
    const std::size_t c = column_of(map->columns(), trace[i]);
    ASSERT_LT(c, kViewStride) << trace[i];
    EXPECT_EQ(f[c], row[i]) << trace[i];
  }
  EXPECT_EQ(f[column_of(map->columns(), "tick")], 7.0);
  EXPECT_TRUE(std::isnan(f[kViewStride - 1])) << "unused columns are NaN";
  EXPECT_FALSE(WorldViewMap::make({"t", "x", "y", "z"})) << "a one-device trace is not a world's";
}

TEST(ViewerWorld, FourDevicesFitTheirHipsForcesAndStates) {
  WorldDescription world;
  for (const char* name : {"a", "b", "c", "d"}) {
    WorldDeviceEntry d;
    d.name = name;
    world.devices.push_back(d);
  }
  world.couplings.resize(8);
  world.ball = between::BallParams{};
  auto map = WorldViewMap::make(world_columns(world));
  ASSERT_TRUE(map) << map.error();
  for (const char* name : {"a", "b", "c", "d"}) {
    for (const char* v : {".x", ".y", ".z", ".fx", ".fy", ".fz", ".faults", ".state"}) {
      EXPECT_LT(column_of(map->columns(), std::string(name) + v), kViewStride) << name << v;
    }
  }
  EXPECT_LT(column_of(map->columns(), "held"), kViewStride);
  EXPECT_LT(column_of(map->columns(), "ball.z"), kViewStride);
}

TEST(ViewerWorld, AWorldTraceReadsBackFrameForFrame) {
  const std::string path = ::testing::TempDir() + "/viewer_world.csv";
  auto summary = run_world_sim(two_players(path));
  ASSERT_TRUE(summary) << summary.error();
  const std::string text = slurp_file(path);
  EXPECT_TRUE(is_world_trace_header(read_trace_header(path)));
  auto rec = parse_world_trace(text, path);
  ASSERT_TRUE(rec) << rec.error();
  ASSERT_EQ(rec->frames.size(), static_cast<std::size_t>(summary->ticks) + 0U);
  EXPECT_NEAR(rec->rate_hz, 1000.0, 1e-6);
  // The last row's right.x, as the file has it.
  const std::string header = text.substr(0, text.find('\n'));
  std::vector<std::string> names;
  for (std::size_t start = 0;;) {
    const std::size_t comma = header.find(',', start);
    names.push_back(header.substr(start, comma - start));
    if (comma == std::string::npos) break;
    start = comma + 1;
  }
  const std::string last = text.substr(text.rfind('\n', text.size() - 2) + 1);
  std::vector<double> values;
  for (std::size_t start = 0;;) {
    const std::size_t comma = last.find(',', start);
    values.push_back(std::strtod(last.substr(start, comma - start).c_str(), nullptr));
    if (comma == std::string::npos) break;
    start = comma + 1;
  }
  for (const char* c : {"right.x", "left.fz", "ball.y", "held"}) {
    EXPECT_EQ(rec->frames.back()[column_of(rec->columns, c)], values[column_of(names, c)]) << c;
  }
  EXPECT_FALSE(parse_world_trace("t,x,y,z\n0,1,2,3\n", "one.csv"));
}

/// A page of a world simulation's server: the hello names the devices, and every row reaches it
/// with each device's HIP where the trace has it; the trace is the same with the viewer.
TEST(ViewerWorld, TheWorldSimulationsRowsReachAPageByDevice) {
  const std::string dir = ::testing::TempDir();
  ASSERT_TRUE(run_world_sim(two_players(dir + "/world_plain.csv")));
  auto world = load_world_file(std::string(kSource) + "/scenes/two_players.toml");
  ASSERT_TRUE(world);
  auto map = WorldViewMap::make(world_columns(world.value()));
  ASSERT_TRUE(map);
  HelloInfo info;
  info.world_columns = map->columns();
  info.world_json = world_json(map->devices(), &world.value());
  ViewerOptions options;
  options.port = 0;
  options.has_loop = false;
  auto server = ViewerServer::start(options, make_hello(info));
  ASSERT_TRUE(server) << server.error();
  Client client(*server.value(), "http://" + host_of(*server.value()));
  ASSERT_FALSE(client.ec);
  std::atomic<int> stop{0};
  WorldViewSink sink(*server.value(), std::move(map.value()), 0.0, &stop);
  WorldSimOptions w = two_players(dir + "/world_view.csv");
  w.rows = &sink;
  auto summary = run_world_sim(w);
  ASSERT_TRUE(summary) << summary.error();
  server.value()->finish();
  EXPECT_EQ(slurp_file(dir + "/world_plain.csv"), slurp_file(dir + "/world_view.csv"));
  std::string text;
  std::vector<double> values;
  std::vector<std::vector<double>> frames;
  std::vector<std::string> columns;
  bool ended = false;
  while (!ended && client.next(text, values)) {
    if (!text.empty()) {
      if (text.find(R"("type":"hello")") != std::string::npos) {
        EXPECT_NE(text.find(R"("world":{"devices":["left","right"])"), std::string::npos) << text;
        columns = info.world_columns;
      }
      ended = text.find(R"("ended":true)") != std::string::npos;
      continue;
    }
    const auto n = static_cast<std::size_t>(values[3]);
    for (std::size_t k = 0; k < n; ++k) {
      frames.emplace_back(values.begin() + static_cast<std::ptrdiff_t>(4 + k * kViewStride),
                          values.begin() + static_cast<std::ptrdiff_t>(4 + (k + 1) * kViewStride));
    }
  }
  EXPECT_TRUE(ended);
  ASSERT_EQ(frames.size(), static_cast<std::size_t>(summary->ticks)) << "every row reaches the page";
  auto rec = parse_world_trace(slurp_file(dir + "/world_view.csv"), "world_view.csv");
  ASSERT_TRUE(rec) << rec.error();
  ASSERT_EQ(rec->frames.size(), frames.size());
  for (const char* c : {"left.x", "right.x", "right.fx", "ball.x", "held"}) {
    const std::size_t col = column_of(columns, c);
    ASSERT_LT(col, kViewStride) << c;
    for (std::size_t i = 0; i < frames.size(); i += 97) {
      EXPECT_EQ(frames[i][col], rec->frames[i][col]) << c << " at frame " << i;
    }
  }
  EXPECT_EQ(sink.rows(), summary->ticks);
}

/// Keeps every row it is handed (the run's writer thread), and the columns begin() named.
class KeepingRows final : public WorldRowSink {
 public:
  void begin(const std::vector<std::string>& c, std::int64_t) override { columns = c; }
  void row(const std::vector<double>& values) override { rows.push_back(values); }
  std::vector<std::string> columns;
  std::vector<std::vector<double>> rows;
};

/// `run --view` of a world: the run's writer thread hands every trace row to the viewer's rows,
/// the same numbers the trace has, in its columns.
TEST(ViewerWorld, ARunHandsEveryRowOfTheTraceToTheViewer) {
  RunOptions o;
  o.device = "sim";
  o.scene_path = std::string(kSource) + "/scenes/two_players.toml";
  o.world_scripts = {{"left", std::string(kSource) + "/scenes/hands/left_push.toml"},
                     {"right", std::string(kSource) + "/scenes/hands/right_push.toml"}};
  o.allow_non_realtime = true;
  o.lock_memory = false;
  o.handle_signals = false;
  o.interactive = false;
  o.duration_s = 0.3;
  static std::FILE* const messages = std::tmpfile();
  o.messages = messages;
  o.trace_path = ::testing::TempDir() + "/viewer_world_run.csv";
  KeepingRows rows;
  rows.rows.reserve(1000);
  o.world_rows = &rows;
  const auto summary = run_world_servo(o);
  ASSERT_TRUE(summary) << summary.error();
  EXPECT_EQ(rows.rows.size(), summary->frames_written);
  ASSERT_FALSE(rows.rows.empty());
  auto world = load_world_file(o.scene_path);
  ASSERT_TRUE(world);
  EXPECT_EQ(rows.columns, world_columns(world.value()));
  auto rec = parse_world_trace(slurp_file(o.trace_path), o.trace_path);
  ASSERT_TRUE(rec) << rec.error();
  ASSERT_EQ(rec->frames.size(), rows.rows.size()) << "one row a frame, the trace's";
  auto map = WorldViewMap::make(rows.columns);
  ASSERT_TRUE(map);
  for (std::size_t i = 0; i < rows.rows.size(); i += 37) {
    const ViewFrame f = map->frame(rows.rows[i], static_cast<double>(i));
    for (const char* c : {"t", "left.x", "right.z", "left.fx", "ball.x", "held"}) {
      const std::size_t col = column_of(rec->columns, c);
      EXPECT_EQ(f[col], rec->frames[i][col]) << c << " at row " << i;
    }
  }
}

}  // namespace

// ---- /control as a server: bounded by construction whatever a connection sends ----

namespace {

/// Answers every change ok; its scene is `scene` (big when a test wants big replies).
class FakeControl final : public SceneControl {
 public:
  Result<std::uint64_t> set(std::string_view, std::string_view) override { return ++sequence; }
  Result<std::uint64_t> add(std::string_view, std::string_view) override { return ++sequence; }
  Result<std::uint64_t> remove(std::string_view) override { return ++sequence; }
  Result<std::uint64_t> load(std::string_view, std::string) override { return ++sequence; }
  Result<std::uint64_t> fire(std::string_view, std::string_view, double) override { return ++sequence; }
  std::uint64_t applied() const override { return sequence; }
  std::string scene_json() const override { return scene; }
  std::atomic<std::uint64_t> sequence{0};
  std::string scene = R"({"effects":[]})";
};

constexpr const char* kToken = "tok-27";

ViewerOptions control_options(FakeControl& control) {
  ViewerOptions options;
  options.control = &control;
  options.control_options.token = kToken;
  options.control_options.burst_messages = 1e6;
  options.control_options.max_messages_per_s = 1e6;
  return options;
}

/// A WebSocket client of /control, with a generous deadline on every operation (a server that
/// never answers fails the test instead of hanging it): asynchronous operations, which the
/// tcp_stream's deadline applies to, run to completion one at a time.
struct ControlClient {
  asio::io_context io;
  websocket::stream<beast::tcp_stream> ws{io};
  beast::error_code ec;
  explicit ControlClient(const ViewerServer& server, int receive_buffer = 0) {
    beast::tcp_stream& stream = ws.next_layer();
    stream.socket().open(tcp::v4());
    if (receive_buffer > 0) stream.socket().set_option(asio::socket_base::receive_buffer_size(receive_buffer));
    stream.expires_after(std::chrono::seconds(10));
    stream.async_connect(tcp::endpoint(asio::ip::make_address("127.0.0.1"), server.port()),
                         [this](beast::error_code e) { ec = e; });
    finish();
    if (ec) return;
    stream.expires_after(std::chrono::seconds(10));
    ws.async_handshake(host_of(server), "/control", [this](beast::error_code e) { ec = e; });
    finish();
  }
  void finish() {
    io.restart();
    io.run();
  }
  bool send(const std::string& text) {
    ws.next_layer().expires_after(std::chrono::seconds(10));
    ws.text(true);
    ws.async_write(asio::buffer(text), [this](beast::error_code e, std::size_t) { ec = e; });
    finish();
    return !ec;
  }
  /// The next message; empty with ec set when the connection ended (or the deadline passed).
  std::string receive() {
    ws.next_layer().expires_after(std::chrono::seconds(10));
    beast::flat_buffer buffer;
    ws.async_read(buffer, [this](beast::error_code e, std::size_t) { ec = e; });
    finish();
    return ec ? std::string() : beast::buffers_to_string(buffer.data());
  }
  std::string say_hello() {
    send(std::string(R"({"type":"hello","version":1,"token":")") + kToken + R"("})");
    return receive();
  }
};

/// What reading a connection the server should close gives: eof if it does within 10 s,
/// beast::error::timeout if it does not.
beast::error_code read_until_closed(asio::io_context& io, beast::tcp_stream& stream) {
  stream.expires_after(std::chrono::seconds(10));
  std::array<char, 64> buffer{};
  beast::error_code ec;
  stream.async_read_some(asio::buffer(buffer), [&](beast::error_code e, std::size_t) { ec = e; });
  io.restart();
  io.run();
  return ec;
}

/// The server side of a connection the test made: found among this process's descriptors by
/// its two ends. -1 if there is none.
int server_side(std::uint16_t server_port, const tcp::endpoint& client) {
  int found = -1;
  if (DIR* dir = ::opendir("/proc/self/fd")) {
    while (const dirent* entry = ::readdir(dir)) {
      const int fd = std::atoi(entry->d_name);
      sockaddr_in local{}, peer{};
      socklen_t local_size = sizeof local, peer_size = sizeof peer;
      if (::getsockname(fd, reinterpret_cast<sockaddr*>(&local), &local_size) != 0 || local.sin_family != AF_INET)
        continue;
      if (::getpeername(fd, reinterpret_cast<sockaddr*>(&peer), &peer_size) != 0) continue;
      if (ntohs(local.sin_port) == server_port && ntohs(peer.sin_port) == client.port()) found = fd;
    }
    ::closedir(dir);
  }
  return found;
}

}  // namespace

// Replies to pipelined messages waited ~44 ms for the client's delayed ACK (Nagle).
// Every accepted socket (/control, the viewer's /ws, plain HTTP) has TCP_NODELAY.
TEST(ControlServer, EveryAcceptedSocketHasNoDelay) {
  FakeControl control;
  auto server = start_server(control_options(control));
  ControlClient c(*server);
  ASSERT_FALSE(c.ec) << c.ec.message();
  ASSERT_NE(c.say_hello().find("welcome"), std::string::npos);
  Client page(*server, "http://" + host_of(*server));
  ASSERT_FALSE(page.ec) << page.ec.message();
  for (const tcp::endpoint& end :
       {c.ws.next_layer().socket().local_endpoint(), page.ws.next_layer().local_endpoint()}) {
    const int fd = server_side(server->port(), end);
    ASSERT_GE(fd, 0);
    int nodelay = 0;
    socklen_t size = sizeof nodelay;
    ASSERT_EQ(::getsockopt(fd, IPPROTO_TCP, TCP_NODELAY, &nodelay, &size), 0);
    EXPECT_EQ(nodelay, 1) << "port " << end.port();
  }
}

// A binary message was read as text. It gets an error and the connection closes
// with 1003 (unsupported data), as the spec says.
TEST(ControlServer, ABinaryMessageIsRefusedAndTheConnectionClosedWith1003) {
  FakeControl control;
  auto server = start_server(control_options(control));
  ControlClient c(*server);
  ASSERT_NE(c.say_hello().find("welcome"), std::string::npos);
  c.ws.binary(true);
  const std::string message = R"({"type":"remove","effect":"surface1"})";
  c.ws.next_layer().expires_after(std::chrono::seconds(10));
  c.ws.async_write(asio::buffer(message), [&](beast::error_code e, std::size_t) { c.ec = e; });
  c.finish();
  ASSERT_FALSE(c.ec);
  EXPECT_NE(c.receive().find("binary"), std::string::npos);
  EXPECT_TRUE(c.receive().empty());
  EXPECT_EQ(c.ec, websocket::error::closed);
  EXPECT_EQ(c.ws.reason().code, websocket::close_code::unknown_data);
  EXPECT_EQ(control.sequence.load(), 0U) << "nothing changed";
}

// Only the first of two Host (or Origin) headers was checked.
TEST(ControlServer, ARequestWithTwoHostOrOriginHeadersIsRefused) {
  FakeControl control;
  auto server = start_server(control_options(control));
  const std::string host = host_of(*server);
  for (const std::string& extra : {"Host: " + host + "\r\n", std::string("Host: evil.example\r\n"),
                                   "Origin: http://" + host + "\r\nOrigin: http://evil.example\r\n"}) {
    asio::io_context io;
    tcp::socket socket(io);
    socket.connect(tcp::endpoint(asio::ip::make_address("127.0.0.1"), server->port()));
    const std::string text = "GET /control HTTP/1.1\r\nHost: " + host + "\r\n" + extra +
                             "Connection: Upgrade\r\nUpgrade: websocket\r\nSec-WebSocket-Version: 13\r\n"
                             "Sec-WebSocket-Key: dGhlIHNhbXBsZSBub25jZQ==\r\n\r\n";
    asio::write(socket, asio::buffer(text));
    beast::flat_buffer buffer;
    http::response<http::string_body> res;
    http::read(socket, buffer, res);
    EXPECT_EQ(res.result(), http::status::bad_request) << extra;
  }
}

// The server read the next message whatever replies it still had to send, so a client
// that sends and never reads grew the process without bound. Now a connection reads its next
// message only once its reply has been written: a client that does not read stops the reading.
TEST(ControlServer, AClientThatNeverReadsStopsBeingReadAndHoldsOneReply) {
  FakeControl control;
  control.scene = R"({"effects":[],"pad":")" + std::string(200000, 'p') + R"("})";  // 200 kB replies
  ViewerOptions options = control_options(control);
  options.send_buffer_bytes = 4096;
  auto server = start_server(options);
  ControlClient c(*server, 4096);
  ASSERT_NE(c.say_hello().find("welcome"), std::string::npos);
  constexpr int kSent = 100;
  for (int i = 0; i < kSent; ++i) ASSERT_TRUE(c.send(R"({"type":"scene"})")) << i;
  // Unread: at most the replies the two sockets' buffers hold (a few 200 kB replies, not 100).
  std::this_thread::sleep_for(std::chrono::seconds(1));
  const ViewerStats s = server->stats();
  EXPECT_LE(s.control_messages, 1U + 10U) << "messages read while their replies waited";
  EXPECT_LE(s.max_control_bytes, control.scene.size() + 1000U);
  // Read now: every reply comes, in order.
  for (int i = 0; i < kSent; ++i) ASSERT_NE(c.receive().find(R"("type":"scene")"), std::string::npos) << i;
  EXPECT_EQ(server->stats().control_messages, 1U + kSent);
}

// Connections that never said hello held every control slot as long as they liked.
// They have slots of their own now and a deadline for the hello.
TEST(ControlServer, SilentConnectionsGetADeadlineAndSlotsOfTheirOwn) {
  FakeControl control;
  ViewerOptions options = control_options(control);
  options.max_controls = 1;
  options.max_control_pending = 2;
  // Long enough that both silent ones still wait when the third comes, on a loaded host too.
  options.control_hello_deadline_s = 2.0;
  auto server = start_server(options);
  ControlClient client(*server);
  ASSERT_NE(client.say_hello().find("welcome"), std::string::npos);
  ControlClient silent1(*server), silent2(*server);
  ASSERT_FALSE(silent1.ec) << "an authenticated connection does not take a waiting one's slot";
  ASSERT_FALSE(silent2.ec);
  ControlClient third(*server);
  EXPECT_EQ(third.ec, websocket::error::upgrade_declined) << "beyond the waiting slots: 503";
  // Without a hello the deadline closes them (1008) ...
  EXPECT_TRUE(silent1.receive().empty());
  EXPECT_EQ(silent1.ec, websocket::error::closed);
  EXPECT_EQ(silent1.ws.reason().code, websocket::close_code::policy_error);
  EXPECT_TRUE(silent2.receive().empty());
  EXPECT_EQ(silent2.ec, websocket::error::closed);
  EXPECT_EQ(server->stats().control_hello_late, 2U);
  // ... and the client that said hello is still served.
  client.send(R"({"type":"status","id":1})");
  EXPECT_NE(client.receive().find(R"("id":1)"), std::string::npos);
  // A hello beyond max_controls: refused (1013), the connection closed.
  for (int tries = 0; tries < 100 && server->stats().controls_pending != 0; ++tries) {
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
  }
  ControlClient second(*server);
  ASSERT_FALSE(second.ec) << second.ec.message();
  EXPECT_NE(second.say_hello().find("too many control connections"), std::string::npos);
  EXPECT_TRUE(second.receive().empty());
  EXPECT_EQ(second.ws.reason().code, websocket::close_code::try_again_later);
}

// A client that sends its request a header line now and then held a connection for
// 30 s. The whole request must come within request_deadline_s.
TEST(ControlServer, ARequestNotReadInTimeEndsTheConnection) {
  ViewerOptions options;
  options.request_deadline_s = 0.3;
  auto server = start_server(options);
  asio::io_context io;
  beast::tcp_stream stream(io);
  stream.connect(tcp::endpoint(asio::ip::make_address("127.0.0.1"), server->port()));
  asio::write(stream.socket(), asio::buffer(std::string("GET / HTTP/1.1\r\n")));
  const beast::error_code ec = read_until_closed(io, stream);
  EXPECT_EQ(ec, asio::error::eof) << ec.message() << " (a timeout here: the server kept the connection)";
  // The stream closes its socket when the deadline passes, before the server's handler counts it.
  EXPECT_TRUE(eventually([&] { return server->stats().requests_late == 1U; }));
}

// A page that connected after a live change was shown the starting scene.
TEST(ControlServer, APageThatComesAfterAChangeGetsTheSceneAsChanged) {
  FakeControl control;
  auto server = start_server(control_options(control));
  ControlClient c(*server);
  ASSERT_NE(c.say_hello().find("welcome"), std::string::npos);
  control.scene = R"({"effects":[{"key":"surface","number":1,"params":{"stiffness":800}}]})";
  c.send(R"({"type":"set","effect":"surface1","keys":{"stiffness":800}})");
  ASSERT_NE(c.receive().find(R"("type":"ok")"), std::string::npos);
  Client page(*server, "http://" + host_of(*server));
  ASSERT_FALSE(page.ec);
  std::string text;
  std::vector<double> values;
  ASSERT_TRUE(page.next(text, values));
  EXPECT_NE(text.find(R"("stiffness":800)"), std::string::npos) << text;
  EXPECT_NE(text.find(R"("test":true)"), std::string::npos) << "the rest of the hello kept: " << text;
}

// 32 slow clients (a header line every 5 s) held every connection slot, and each new
// connection was closed at once for 20-30 s per wave. With every slot taken, the connection
// that has been reading its request longest makes room for the new one.
TEST(ControlServer, WithEverySlotTakenByReadersTheOldestMakesRoom) {
  ViewerOptions options;
  options.max_connections = 2;
  options.request_deadline_s = 60.0;  // the deadline is not what frees the slots here
  options.evict_reading_after_s = 0.0;
  auto server = start_server(options);
  asio::io_context io;
  std::vector<std::unique_ptr<beast::tcp_stream>> slow;
  for (int i = 0; i < 2; ++i) {
    slow.push_back(std::make_unique<beast::tcp_stream>(io));
    slow.back()->connect(tcp::endpoint(asio::ip::make_address("127.0.0.1"), server->port()));
    asio::write(slow.back()->socket(), asio::buffer(std::string("GET / HTTP/1.1\r\n")));
  }
  // Both are open on the server (reading their requests) before the next connection comes.
  for (int tries = 0; tries < 500 && server->stats().connections_open < 2; ++tries) {
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
  }
  ASSERT_EQ(server->stats().connections_open, 2U);
  const auto response = request(*server, http::verb::get, "/", host_of(*server));
  EXPECT_EQ(response.result(), http::status::ok);
  EXPECT_EQ(server->stats().requests_evicted, 1U);
  EXPECT_EQ(server->stats().connections_refused, 0U);
  // The first slow client is the one that was closed.
  const beast::error_code ec = read_until_closed(io, *slow[0]);
  EXPECT_EQ(ec, asio::error::eof) << ec.message();
}
