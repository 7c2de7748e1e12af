// SPDX-License-Identifier: Apache-2.0
// The viewer's server on Boost.Beast (HTTP and WebSocket) over Boost.Asio, one thread.
//
// Why Beast (Boost 1.74 in Debian 12, package libboost-dev): of the three well-kept servers
// Debian packages (libwebsockets 4.1, CivetWeb 1.15, Boost.Beast), Beast leaves every decision
// that matters here to us and hides none behind a callback: which requests get an answer (only
// the embedded files; there is no document root to traverse), the Origin and Host checks before
// the upgrade, and the write side of each page, where one write is in flight at a time and
// newer batches replace older queued ones, so a slow page costs drops, never memory or a
// blocked producer. CivetWeb's websocket writes block the calling thread on a slow reader and
// its file serving is path based; libwebsockets would do, through a C callback state machine
// with its own logging and event loop to configure. Beast is header-only
// (toonforce/viewer/beast.hpp includes it, for this file and its tests) and Boost is on every
// Debian machine that builds C++.
#include "toonforce/viewer/viewer_server.hpp"

#include <ifaddrs.h>
#include <netinet/in.h>

#include <algorithm>
#include <chrono>
#include <cstring>
#include <deque>
#include <limits>
#include <set>
#include <thread>

#if defined(__GLIBC__)
#include <malloc.h>
#endif

#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include "toonforce/viewer/assets.hpp"
#include "toonforce/viewer/beast.hpp"

namespace toonforce::viewer {

namespace asio = boost::asio;
namespace beast = boost::beast;
namespace http = beast::http;
namespace websocket = beast::websocket;
using tcp = asio::ip::tcp;

namespace {

/// Hand-over from the producer thread: 8192 frames is 0.8 s at 10 kHz, 40 times the batch
/// interval, so the server thread would have to stall for that long before a frame drops here.
using FrameRing = SpscRing<ViewFrame, 8192>;

/// A batch on the wire: a Float64Array whose first kBatchHeader values are
///   kind (1 live, 2 history), stride (values per frame), sequence number of the first frame,
///   frame count; then the frames, kViewColumns each. Frames are numbered from 0 in the order
///   they were published, so the page sees a dropped batch as a gap.
constexpr std::size_t kBatchHeader = 4;
constexpr double kLiveBatch = 1.0;
constexpr double kHistoryBatch = 2.0;

std::string lower(std::string_view text) {
  std::string out(text);
  for (char& c : out) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  return out;
}

/// A batch of frames given in up to two runs (the history ring wraps).
std::shared_ptr<const std::string> make_batch(double kind, std::uint64_t first_seq, std::span<const ViewFrame> frames,
                                              std::span<const ViewFrame> more = {}) {
  auto out = std::make_shared<std::string>();
  const std::size_t count = frames.size() + more.size();
  out->resize((kBatchHeader + count * kViewStride) * sizeof(double));
  const std::array<double, kBatchHeader> header{kind, static_cast<double>(kViewStride), static_cast<double>(first_seq),
                                                static_cast<double>(count)};
  std::memcpy(out->data(), header.data(), sizeof header);
  if (!frames.empty()) std::memcpy(out->data() + sizeof header, frames.data(), frames.size() * sizeof(ViewFrame));
  if (!more.empty()) {
    std::memcpy(out->data() + sizeof header + frames.size() * sizeof(ViewFrame), more.data(),
                more.size() * sizeof(ViewFrame));
  }
  return out;
}

struct Message {
  std::shared_ptr<const std::string> data;
  bool text = false;
  bool droppable = false;  ///< live batches: a slow page may lose them
  std::size_t frames = 0;
  bool status = false;  ///< a newer status replaces a queued one (and drops no batch)
  std::size_t bytes() const noexcept { return data ? data->size() : 0; }
};

class PageSession;
class HttpSession;

}  // namespace

struct ViewerServer::Impl {
  ViewerOptions options;
  // Any thread. Before the io_context: sessions it destroys last still count themselves out.
  std::atomic<std::uint64_t> frames_dropped_pages{0}, pages_connected{0}, pages_refused{0}, messages_refused{0},
      http_refused{0}, connections_refused{0}, accept_failures{0};
  std::atomic<std::size_t> max_queued{0}, pages_open{0}, queued_bytes{0}, max_queued_bytes{0};
  /// Pages that hold a slot: taken when the upgrade request is read, given back when the page
  /// session ends. pages_open counts finished handshakes only, too late to be the cap.
  std::atomic<std::size_t> page_slots{0};
  std::atomic<std::size_t> connections{0};      ///< HTTP sessions alive (not yet, or never, pages)
  std::atomic<std::size_t> control_slots{0};    ///< /control connections whose hello passed, alive
  std::atomic<std::size_t> control_pending{0};  ///< /control connections not yet past their hello
  std::atomic<std::uint64_t> control_hello_late{0};
  std::atomic<std::size_t> control_bytes{0}, max_control_bytes{0};  ///< control replies held (being written)
  std::atomic<std::uint64_t> requests_late{0};     ///< HTTP connections closed: no whole request in time
  std::atomic<std::uint64_t> requests_evicted{0};  ///< HTTP connections closed to make room for a new one
  std::atomic<std::uint64_t> control_messages{0}, control_refused{0};
  std::atomic<std::uint64_t> controls_authenticated{0};  ///< control connections whose hello passed
  bool stopping = false;                                 ///< set on the server thread before the io_context stops

  asio::io_context io{1};
  tcp::acceptor acceptor{io};
  asio::steady_timer timer{io};
  asio::steady_timer accept_timer{io};  ///< the wait after a failed accept
  std::chrono::duration<double> accept_delay{kAcceptRetryMinS};
  std::shared_ptr<const std::string> hello;  ///< one copy, shared by every page
  std::uint16_t port = 0;
  std::set<std::string> hosts;  ///< lower-case Host values a request may give ("name:port")
  std::string url;
  std::unique_ptr<FrameRing> ring = std::make_unique<FrameRing>();
  std::atomic<bool> finish_requested{false};
  std::atomic<std::uint64_t> drained{0};

  // Server thread only.
  std::vector<ViewFrame> history;  ///< circular, capacity history_frames; seq s at s % size
  std::uint64_t next_seq = 0;
  bool ended = false;
  std::vector<ViewFrame> batch;
  std::vector<std::weak_ptr<PageSession>> pages;
  /// HTTP connections reading a request, oldest first (some may have finished or ended).
  std::deque<std::weak_ptr<HttpSession>> readers;
  std::chrono::steady_clock::time_point next_status{};

  std::thread thread;

  bool host_allowed(std::string_view host) const { return hosts.count(lower(host)) != 0; }
  /// A browser's WebSocket from our own page carries Origin http://<the Host it asked>.
  bool origin_allowed(std::string_view origin, std::string_view host) const {
    return host_allowed(host) && lower(origin) == "http://" + lower(host);
  }

  /// Takes a page slot if one is free: check and take are one atomic step.
  bool reserve_page() noexcept {
    std::size_t taken = page_slots.load();
    do {
      if (taken >= options.max_pages) return false;
    } while (!page_slots.compare_exchange_weak(taken, taken + 1));
    return true;
  }
  void release_page() noexcept {
    if (page_slots.fetch_sub(1) == 1 && !stopping) trim_memory();
  }
  /// Bytes a page holds (queued, or being written): the count behind the memory bound.
  void hold_bytes(std::size_t bytes) noexcept {
    const std::size_t now = queued_bytes.fetch_add(bytes) + bytes;
    std::size_t seen = max_queued_bytes.load();
    while (now > seen && !max_queued_bytes.compare_exchange_weak(seen, now)) {
    }
  }
  void free_bytes(std::size_t bytes) noexcept { queued_bytes.fetch_sub(bytes); }
  void hold_control_bytes(std::size_t bytes) noexcept {
    const std::size_t now = control_bytes.fetch_add(bytes) + bytes;
    std::size_t seen = max_control_bytes.load();
    while (now > seen && !max_control_bytes.compare_exchange_weak(seen, now)) {
    }
  }
  void free_control_bytes(std::size_t bytes) noexcept { control_bytes.fetch_sub(bytes); }
  /// A control connection changed the scene: pages that connect from now on get it in their hello.
  void scene_changed();
  /// The last page has gone: give the memory its batches used back to the system. glibc keeps
  /// freed blocks of a thread's arena for reuse; under `run --view` memory is locked, so what it
  /// keeps stays resident and locked in the real-time process.
  static void trim_memory() noexcept {
#if defined(__GLIBC__)
    malloc_trim(0);
#endif
  }

  void start_accept();
  /// Ends the HTTP connection that has been reading its request longest; false if none is.
  bool evict_oldest_reader();
  /// A connection starts reading a request (kept in `readers`, which stays bounded).
  void reading(const std::weak_ptr<HttpSession>& session);
  void on_timer();
  void add_page(const std::shared_ptr<PageSession>& page);
  void broadcast(const Message& message);
  /// The next history message of a page that wants frames [next, end): at most
  /// kHistoryChunkFrames from the history ring. Frames the ring lost since the page came
  /// (overwritten by newer ones) are skipped and added to `lost`.
  Message history_chunk(std::uint64_t& next, std::uint64_t end, std::uint64_t& lost) const;
  std::shared_ptr<const std::string> status_json(std::uint64_t page_dropped) const;
};

namespace {

/// One WebSocket page: hello, history, then live batches; never reads anything but a close.
/// It holds at most: the message being written, one status, max_queued_batches live batches
/// (shared with the other pages), and the history as a range, made into one chunk at a time
/// when the one before has been written.
class PageSession : public std::enable_shared_from_this<PageSession> {
 public:
  /// The caller took a page slot for this session (reserve_page); the session gives it back.
  PageSession(tcp::socket socket, ViewerServer::Impl& server) : ws_(std::move(socket)), server_(server) {}
  ~PageSession() {
    drop_queue();
    server_.free_bytes(current_.bytes());
    if (counted_) server_.pages_open.fetch_sub(1);
    server_.release_page();
  }
  PageSession(const PageSession&) = delete;
  PageSession& operator=(const PageSession&) = delete;

  void accept(http::request<http::string_body> request) {
    ws_.set_option(websocket::stream_base::timeout::suggested(beast::role_type::server));
    ws_.set_option(websocket::stream_base::decorator(
        [](websocket::response_type& response) { response.set(http::field::server, "toonforce-viewer"); }));
    ws_.read_message_max(1024);  // the page sends nothing; anything it sends is refused anyway
    ws_.async_accept(request, [self = shared_from_this()](beast::error_code ec) {
      if (ec) return;
      self->counted_ = true;
      self->server_.pages_open.fetch_add(1);
      self->server_.pages_connected.fetch_add(1);
      self->server_.add_page(self);
      self->read();
    });
  }

  /// The first messages: the hello, then history frames [first, end) as they can be written.
  void join(Message hello, std::uint64_t first, std::uint64_t end) {
    send(std::move(hello));  // nothing is in flight yet: the hello goes out first
    history_next_ = first;
    history_end_ = end;  // from here on, history goes before anything queued
  }

  void send(Message message) {
    if (closing_) return;
    if (message.status) {
      for (auto it = queue_.begin(); it != queue_.end(); ++it) {
        if (it->status) {
          server_.free_bytes(it->bytes());
          queue_.erase(it);
          break;
        }
      }
    } else if (message.droppable) {
      std::size_t queued = 0;
      for (const Message& m : queue_) queued += m.droppable ? 1U : 0U;
      while (queued >= server_.options.max_queued_batches && queued > 0) {
        for (auto it = queue_.begin(); it != queue_.end(); ++it) {
          if (!it->droppable) continue;
          lose(it->frames);
          server_.free_bytes(it->bytes());
          queue_.erase(it);
          break;
        }
        --queued;
      }
      if (server_.options.max_queued_batches == 0) {
        lose(message.frames);
        return;
      }
      std::size_t seen = server_.max_queued.load();
      while (queued + 1 > seen && !server_.max_queued.compare_exchange_weak(seen, queued + 1)) {
      }
    }
    server_.hold_bytes(message.bytes());
    queue_.push_back(std::move(message));
    write_next();
  }

  std::uint64_t dropped() const noexcept { return dropped_; }

 private:
  void lose(std::uint64_t frames) {
    dropped_ += frames;
    server_.frames_dropped_pages.fetch_add(frames);
  }

  void drop_queue() {
    for (const Message& m : queue_) server_.free_bytes(m.bytes());
    queue_.clear();
    history_next_ = history_end_;
  }

  void write_next() {
    if (writing_ || closing_) return;
    if (history_next_ < history_end_) {
      std::uint64_t lost = 0;
      current_ = server_.history_chunk(history_next_, history_end_, lost);
      lose(lost);
      if (current_.data) server_.hold_bytes(current_.bytes());
    }
    if (!current_.data) {
      if (queue_.empty()) return;
      current_ = std::move(queue_.front());  // its bytes stay held while it is written
      queue_.pop_front();
    }
    writing_ = true;
    ws_.text(current_.text);
    ws_.binary(!current_.text);
    ws_.async_write(asio::buffer(*current_.data), [self = shared_from_this()](beast::error_code ec, std::size_t) {
      self->writing_ = false;
      self->server_.free_bytes(self->current_.bytes());
      self->current_ = Message{};
      if (ec) {
        self->closing_ = true;
        self->drop_queue();
        return;
      }
      self->write_next();
    });
  }

  void read() {
    ws_.async_read(in_, [self = shared_from_this()](beast::error_code ec, std::size_t) {
      if (ec) {  // closed by the page, or the connection failed: nothing more will be written
        self->closing_ = true;
        self->drop_queue();
        return;
      }
      // Read-only: there is no message a page may send. Close with 1008 (policy violation).
      self->server_.messages_refused.fetch_add(1);
      self->closing_ = true;
      self->in_.consume(self->in_.size());
      self->drop_queue();
      self->ws_.async_close(websocket::close_reason(websocket::close_code::policy_error, "read-only: send nothing"),
                            [self](beast::error_code) {});
    });
  }

  websocket::stream<beast::tcp_stream> ws_;
  ViewerServer::Impl& server_;
  beast::flat_buffer in_;
  Message current_;                 ///< being written (no data: nothing is)
  std::deque<Message> queue_;       ///< waiting, after the history
  std::uint64_t history_next_ = 0;  ///< history still to send: [history_next_, history_end_)
  std::uint64_t history_end_ = 0;
  bool writing_ = false;
  bool closing_ = false;
  bool counted_ = false;
  std::uint64_t dropped_ = 0;
};

/// One /control connection (live scenes): each text message goes to a ControlSession on this,
/// the server's only thread, and its reply comes back in order. A failed hello closes it.
///
/// Bounded by construction: the next message is read only once the reply to the
/// last has been written, so a connection holds at most one message (max_message_bytes) and
/// one reply, whatever its client reads. A connection that has not said hello holds one of
/// max_control_pending slots, for control_hello_deadline_s at most; its hello moves it to one
/// of max_controls, so connections that never say hello cannot keep a client out.
class ControlSocket : public std::enable_shared_from_this<ControlSocket> {
 public:
  /// The caller took a pending control slot; the socket gives back whichever it holds.
  ControlSocket(tcp::socket socket, ViewerServer::Impl& server)
      : ws_(std::move(socket)),
        server_(server),
        session_(*server.options.control, server.options.control_options),
        deadline_(ws_.get_executor()) {}
  ~ControlSocket() {
    server_.free_control_bytes(reply_.size());
    if (authenticated_slot_) {
      server_.control_slots.fetch_sub(1);
    } else {
      server_.control_pending.fetch_sub(1);
    }
    if (server_.control_slots.load() == 0 && server_.control_pending.load() == 0 && !server_.stopping) {
      server_.trim_memory();
    }
  }
  ControlSocket(const ControlSocket&) = delete;
  ControlSocket& operator=(const ControlSocket&) = delete;

  void accept(http::request<http::string_body> request) {
    ws_.set_option(websocket::stream_base::timeout::suggested(beast::role_type::server));
    ws_.set_option(websocket::stream_base::decorator(
        [](websocket::response_type& response) { response.set(http::field::server, "toonforce-viewer"); }));
    // Larger messages fail the read (1009, message too big) before any is buffered.
    ws_.read_message_max(server_.options.control_options.max_message_bytes);
    // No hello in time: the connection ends (1008), its pending slot freed.
    deadline_.expires_after(std::chrono::duration_cast<std::chrono::steady_clock::duration>(
        std::chrono::duration<double>(server_.options.control_hello_deadline_s)));
    deadline_.async_wait([weak = weak_from_this()](beast::error_code ec) {
      auto self = weak.lock();
      if (ec || !self || self->session_.authenticated()) return;
      self->server_.control_hello_late.fetch_add(1);
      self->finish(websocket::close_code::policy_error, "no hello in time");
    });
    ws_.async_accept(request, [self = shared_from_this()](beast::error_code ec) {
      if (!ec) self->read();
    });
  }

 private:
  void read() {
    ws_.async_read(in_, [self = shared_from_this()](beast::error_code ec, std::size_t) {
      if (ec) {  // closed, failed, or too big: the socket ends
        self->deadline_.cancel();
        return;
      }
      self->on_read();
    });
  }

  void on_read() {
    if (!ws_.got_text()) {  // the protocol is text; a binary message ends the connection (1003)
      in_.consume(in_.size());
      server_.control_messages.fetch_add(1);
      server_.control_refused.fetch_add(1);
      reply(R"({"type":"error","message":"binary messages are not spoken here: send JSON text"})",
            websocket::close_code::unknown_data, "binary message");
      return;
    }
    const std::string_view text(static_cast<const char*>(in_.data().data()), in_.size());
    const double now_s = std::chrono::duration<double>(std::chrono::steady_clock::now().time_since_epoch()).count();
    const std::uint64_t refused_before = session_.refused();
    const std::uint64_t changes_before = session_.changes();
    const bool was_authenticated = session_.authenticated();
    ControlSession::Reply answer = session_.on_message(text, now_s);
    in_.consume(in_.size());
    server_.control_messages.fetch_add(1);
    if (session_.refused() != refused_before) server_.control_refused.fetch_add(1);
    if (session_.changes() != changes_before) server_.scene_changed();
    if (!was_authenticated && session_.authenticated()) {
      deadline_.cancel();
      // From a pending slot to an authenticated one, if one is free.
      if (server_.control_slots.fetch_add(1) >= server_.options.max_controls) {
        server_.control_slots.fetch_sub(1);
        server_.control_refused.fetch_add(1);
        reply(R"({"type":"error","message":"too many control connections open"})",
              websocket::close_code::try_again_later, "too many control connections");
        return;
      }
      server_.control_pending.fetch_sub(1);
      authenticated_slot_ = true;
      server_.controls_authenticated.fetch_add(1);
    }
    if (answer.close) {
      reply(std::move(answer.text), websocket::close_code::policy_error, "hello refused");
    } else {
      reply(std::move(answer.text));
    }
  }

  /// Writes one reply, then reads the next message (or closes with `code`, when given).
  void reply(std::string text, websocket::close_code code = websocket::close_code::none, const char* why = "") {
    close_code_ = code;
    close_why_ = why;
    reply_ = std::move(text);
    server_.hold_control_bytes(reply_.size());
    ws_.text(true);
    ws_.async_write(asio::buffer(reply_), [self = shared_from_this()](beast::error_code ec, std::size_t) {
      self->server_.free_control_bytes(self->reply_.size());
      self->reply_.clear();
      self->reply_.shrink_to_fit();
      if (ec) return;
      if (self->close_code_ != websocket::close_code::none) {
        self->finish(self->close_code_, self->close_why_);
        return;
      }
      self->read();
    });
  }

  void finish(websocket::close_code code, const char* why) {
    deadline_.cancel();
    if (closing_) return;
    closing_ = true;
    ws_.async_close(websocket::close_reason(code, why), [self = shared_from_this()](beast::error_code) {});
  }

  websocket::stream<beast::tcp_stream> ws_;
  ViewerServer::Impl& server_;
  ControlSession session_;
  asio::steady_timer deadline_;
  beast::flat_buffer in_;
  std::string reply_;  ///< being written (one at a time)
  websocket::close_code close_code_ = websocket::close_code::none;
  const char* close_why_ = "";
  bool authenticated_slot_ = false;
  bool closing_ = false;
};

/// One HTTP connection: the page's files, or the upgrade to a PageSession.
class HttpSession : public std::enable_shared_from_this<HttpSession> {
 public:
  HttpSession(tcp::socket socket, ViewerServer::Impl& server) : stream_(std::move(socket)), server_(server) {
    server_.connections.fetch_add(1);
  }
  ~HttpSession() { server_.connections.fetch_sub(1); }
  HttpSession(const HttpSession&) = delete;
  HttpSession& operator=(const HttpSession&) = delete;

  void read() {
    reading_ = true;
    reading_since_ = std::chrono::steady_clock::now();
    server_.reading(weak_from_this());
    parser_.emplace();
    parser_->header_limit(8 * 1024);
    parser_->body_limit(1024);  // GET and HEAD have no body
    // The whole request in time, or the connection ends: a client sending a header line now
    // and then holds a connection slot no longer than this.
    stream_.expires_after(std::chrono::duration_cast<std::chrono::steady_clock::duration>(
        std::chrono::duration<double>(server_.options.request_deadline_s)));
    http::async_read(stream_, buffer_, *parser_,
                     [self = shared_from_this()](beast::error_code ec, std::size_t) { self->on_read(ec); });
  }

 private:
  void on_read(beast::error_code ec) {
    reading_ = false;
    if (ec == beast::error::timeout) server_.requests_late.fetch_add(1);
    if (ec) {
      beast::error_code ignored;
      stream_.socket().shutdown(tcp::socket::shutdown_send, ignored);
      return;
    }
    http::request<http::string_body> request = parser_->release();
    // Two Host or Origin headers: which one a check reads and which one a proxy or browser
    // meant are not the same question. Refused, whatever they say.
    if (request.count(http::field::host) > 1 || request.count(http::field::origin) > 1) {
      refuse(request, http::status::bad_request, "one Host header and at most one Origin header\n");
      return;
    }
    const std::string_view host(request[http::field::host].data(), request[http::field::host].size());
    if (!server_.host_allowed(host)) {
      refuse(request, http::status::misdirected_request,
             "this viewer answers only to its own names: 127.0.0.1, localhost, [::1], the address it listens on, "
             "and names it was given (--view-host)\n");
      return;
    }
    if (websocket::is_upgrade(request)) {
      const std::string_view origin(request[http::field::origin].data(), request[http::field::origin].size());
      if (request.target() == "/control" && server_.options.control != nullptr) {
        // A program (no Origin) or a page of this server; a page of another site never. The
        // token in the hello is the rest.
        if (!origin.empty() && !server_.origin_allowed(origin, host)) {
          refuse(request, http::status::forbidden, "WebSocket origin refused: only this server's pages and programs\n");
        } else if (server_.control_pending.fetch_add(1) >= server_.options.max_control_pending) {
          // Slots for connections yet to say hello, apart from the authenticated ones'.
          server_.control_pending.fetch_sub(1);
          refuse(request, http::status::service_unavailable, "too many control connections waiting for their hello\n");
        } else {
          stream_.expires_never();
          std::make_shared<ControlSocket>(stream_.release_socket(), server_)->accept(std::move(request));
        }
        return;
      }
      if (request.target() != "/ws") {
        refuse(request, http::status::not_found, "no such socket\n");
      } else if (!server_.origin_allowed(origin, host)) {
        server_.pages_refused.fetch_add(1);
        refuse(request, http::status::forbidden, "WebSocket origin refused: only the viewer's own page may connect\n");
      } else if (!server_.reserve_page()) {
        server_.pages_refused.fetch_add(1);
        refuse(request, http::status::service_unavailable, "too many pages open\n");
      } else {
        stream_.expires_never();
        std::make_shared<PageSession>(stream_.release_socket(), server_)->accept(std::move(request));
      }
      return;
    }
    if (request.method() != http::verb::get && request.method() != http::verb::head) {
      refuse(request, http::status::method_not_allowed, "the viewer is read-only: GET and HEAD only\n");
      return;
    }
    const std::string_view target(request.target().data(), request.target().size());
    const Asset* asset = find_asset(target);
    if (asset == nullptr) {
      refuse(request, http::status::not_found, "not found\n");
      return;
    }
    auto response = std::make_shared<http::response<http::string_body>>(http::status::ok, request.version());
    headers(*response, asset->content_type);
    if (request.method() == http::verb::head) {
      response->content_length(asset->body.size());
    } else {
      response->body().assign(asset->body.data(), asset->body.size());
      response->prepare_payload();
    }
    response->keep_alive(request.keep_alive());
    write(response);
  }

  static void headers(http::response<http::string_body>& response, std::string_view type) {
    response.set(http::field::server, "toonforce-viewer");
    response.set(http::field::content_type, beast::string_view(type.data(), type.size()));
    response.set(http::field::cache_control, "no-cache");
    response.set("X-Content-Type-Options", "nosniff");
    response.set("Referrer-Policy", "no-referrer");
    response.set("Content-Security-Policy",
                 "default-src 'self'; connect-src 'self'; img-src 'self' data:; object-src 'none'; base-uri 'none'; "
                 "form-action 'none'; frame-ancestors 'none'");
  }

  void refuse(const http::request<http::string_body>& request, http::status status, std::string_view why) {
    server_.http_refused.fetch_add(1);
    auto response = std::make_shared<http::response<http::string_body>>(status, request.version());
    headers(*response, "text/plain; charset=utf-8");
    if (status == http::status::method_not_allowed) response->set(http::field::allow, "GET, HEAD");
    response->body().assign(why);
    response->prepare_payload();
    response->keep_alive(false);
    write(response);
  }

  void write(const std::shared_ptr<http::response<http::string_body>>& response) {
    http::async_write(stream_, *response, [self = shared_from_this(), response](beast::error_code ec, std::size_t) {
      if (!ec && response->keep_alive()) {
        self->read();
        return;
      }
      beast::error_code ignored;
      self->stream_.socket().shutdown(tcp::socket::shutdown_send, ignored);
    });
  }

  beast::tcp_stream stream_;
  ViewerServer::Impl& server_;
  beast::flat_buffer buffer_;
  std::optional<http::request_parser<http::string_body>> parser_;
  bool reading_ = false;
  std::chrono::steady_clock::time_point reading_since_{};

 public:
  bool reading() const noexcept { return reading_; }
  std::chrono::steady_clock::time_point reading_since() const noexcept { return reading_since_; }
  /// Ends a connection still reading its request: all slots are taken and a new one came.
  void evict() {
    reading_ = false;
    stream_.cancel();
  }
};

}  // namespace

bool ViewerServer::Impl::evict_oldest_reader() {
  const auto now = std::chrono::steady_clock::now();
  while (!readers.empty()) {
    const auto oldest = readers.front().lock();
    if (!oldest || !oldest->reading()) {
      readers.pop_front();
      continue;
    }
    // A flood of new connections is refused rather than let it close the ones that came
    // before it a moment ago: only a connection that has been reading for a while makes room.
    if (now - oldest->reading_since() < std::chrono::duration<double>(options.evict_reading_after_s)) return false;
    readers.pop_front();
    oldest->evict();
    requests_evicted.fetch_add(1);
    return true;
  }
  return false;
}

void ViewerServer::Impl::reading(const std::weak_ptr<HttpSession>& session) {
  if (readers.size() >= 2 * options.max_connections) {
    std::erase_if(readers, [](const std::weak_ptr<HttpSession>& r) {
      const auto s = r.lock();
      return !s || !s->reading();
    });
  }
  readers.push_back(session);
}

void ViewerServer::Impl::start_accept() {
  acceptor.async_accept([this](beast::error_code ec, tcp::socket socket) {
    if (ec == asio::error::operation_aborted) return;
    if (ec && ec != asio::error::connection_aborted) {
      // Out of descriptors (EMFILE, ENFILE) or memory: the connection stays in the backlog, the
      // listener stays readable, and accepting again at once fails again at once, a loop at
      // 100 % CPU. Wait instead, longer while it goes on, for descriptors to come back.
      accept_failures.fetch_add(1);
      accept_timer.expires_after(std::chrono::duration_cast<std::chrono::steady_clock::duration>(accept_delay));
      accept_delay = std::min(accept_delay * 2.0, std::chrono::duration<double>(kAcceptRetryMaxS));
      accept_timer.async_wait([this](beast::error_code wait_ec) {
        if (!wait_ec) start_accept();
      });
      return;
    }
    if (!ec) accept_delay = std::chrono::duration<double>(kAcceptRetryMinS);
    // Every slot taken: the connection that has been reading its request longest makes room, if
    // it has been reading for evict_reading_after_s (slow clients sending a header line now and
    // then held every slot until their deadline). Otherwise the new one is refused.
    if (!ec && connections.load() >= options.max_connections && !evict_oldest_reader()) {
      // Bounded: a flood of connections costs one descriptor for a moment each, and the backlog
      // keeps moving (waiting instead would leave later clients stalled behind the flood).
      connections_refused.fetch_add(1);
      beast::error_code ignored;
      socket.close(ignored);
    } else if (!ec) {
      // Replies go out when written, not after the client's delayed ACK (Nagle's algorithm held
      // a reply to pipelined messages ~40 ms).
      beast::error_code ignored_nodelay;
      socket.set_option(tcp::no_delay(true), ignored_nodelay);
      if (options.send_buffer_bytes > 0) {
        beast::error_code ignored;
        socket.set_option(asio::socket_base::send_buffer_size(options.send_buffer_bytes), ignored);
      }
      std::make_shared<HttpSession>(std::move(socket), *this)->read();
    }
    start_accept();
  });
}

void ViewerServer::Impl::scene_changed() {
  // The hello pages get from now on carries the scene as changed (a page that came after a
  // live change was shown the starting scene's geometry). Server thread; never throws out.
  if (options.control == nullptr) return;
  try {
    nlohmann::json message = nlohmann::json::parse(*hello, nullptr, false);
    nlohmann::json scene = nlohmann::json::parse(options.control->scene_json(), nullptr, false);
    if (message.is_discarded() || !message.is_object() || scene.is_discarded()) return;
    message["scene"] = std::move(scene);
    hello = std::make_shared<const std::string>(message.dump(-1, ' ', false, nlohmann::json::error_handler_t::replace));
  } catch (const std::exception&) {
    // Out of memory: pages keep the hello they had.
  }
}

std::shared_ptr<const std::string> ViewerServer::Impl::status_json(std::uint64_t page_dropped) const {
  return std::make_shared<const std::string>(
      fmt::format(R"({{"type":"status","ended":{},"frames":{},"dropped_ring":{},"dropped_page":{},"pages":{}}})", ended,
                  next_seq, ring->dropped(), page_dropped, pages_open.load()));
}

void ViewerServer::Impl::add_page(const std::shared_ptr<PageSession>& page) {
  pages.push_back(page);
  // What was published before the page came, oldest first, a chunk at a time (history_chunk);
  // not dropped unless the ring overwrites it before this page has taken it.
  const std::uint64_t count = std::min<std::uint64_t>(next_seq, history.size());
  page->join(Message{hello, true, false, 0}, next_seq - count, next_seq);
  page->send(Message{status_json(0), true, false, 0, true});
}

Message ViewerServer::Impl::history_chunk(std::uint64_t& next, std::uint64_t end, std::uint64_t& lost) const {
  const std::size_t capacity = history.size();
  const std::uint64_t oldest = next_seq - std::min<std::uint64_t>(next_seq, capacity);
  if (next < oldest) {
    const std::uint64_t resume = std::min(oldest, end);
    lost += resume - next;
    next = resume;
  }
  if (next >= end) return Message{};
  const auto count = static_cast<std::size_t>(std::min<std::uint64_t>(end - next, kHistoryChunkFrames));
  const auto at = static_cast<std::size_t>(next % capacity);
  const std::size_t head = std::min(count, capacity - at);  // up to the end of the ring, then from its start
  const std::span<const ViewFrame> ring_frames(history);
  Message m{make_batch(kHistoryBatch, next, ring_frames.subspan(at, head), ring_frames.subspan(0, count - head)), false,
            false, count};
  next += count;
  return m;
}

void ViewerServer::Impl::broadcast(const Message& message) {
  std::erase_if(pages, [](const std::weak_ptr<PageSession>& p) { return p.expired(); });
  for (const auto& weak : pages) {
    if (auto page = weak.lock()) page->send(message);
  }
}

void ViewerServer::Impl::on_timer() {
  batch.clear();
  ViewFrame frame;
  while (batch.size() < FrameRing::kCapacity && ring->pop(frame)) batch.push_back(frame);
  if (!batch.empty()) {
    const std::uint64_t first = next_seq;
    for (const ViewFrame& f : batch) {
      if (!history.empty()) history[static_cast<std::size_t>(next_seq % history.size())] = f;
      ++next_seq;
    }
    drained.fetch_add(batch.size(), std::memory_order_release);
    broadcast(Message{make_batch(kLiveBatch, first, batch), false, true, batch.size()});
  }
  const auto now = std::chrono::steady_clock::now();
  const bool ending = !ended && finish_requested.load(std::memory_order_acquire) && ring->pushed() == drained.load();
  if (ending) ended = true;
  if (ending || now >= next_status) {
    next_status = now + std::chrono::seconds(1);
    std::erase_if(pages, [](const std::weak_ptr<PageSession>& p) { return p.expired(); });
    for (const auto& weak : pages) {
      if (auto page = weak.lock()) page->send(Message{status_json(page->dropped()), true, false, 0, true});
    }
  }
  timer.expires_after(std::chrono::duration_cast<std::chrono::steady_clock::duration>(
      std::chrono::duration<double>(options.batch_interval_s)));
  timer.async_wait([this](beast::error_code ec) {
    if (!ec) on_timer();
  });
}

ViewerServer::ViewerServer(std::unique_ptr<Impl> impl) noexcept : impl_(std::move(impl)) {}

ViewerServer::~ViewerServer() {
  if (!impl_) return;
  asio::post(impl_->io, [impl = impl_.get()] {
    impl->stopping = true;  // sessions the io_context destroys from here on call back into nothing
    beast::error_code ignored;
    impl->acceptor.close(ignored);
    impl->timer.cancel();
    impl->accept_timer.cancel();
    impl->io.stop();
  });
  if (impl_->thread.joinable()) impl_->thread.join();
  impl_->stopping = true;
}

namespace {

/// An IP address as a Host header names it: IPv6 in brackets.
std::string host_literal(const asio::ip::address& address) {
  return address.is_v6() ? "[" + address.to_string() + "]" : address.to_string();
}

/// A name given for the Host header, lower case (IP addresses in their usual spelling), or why not.
Result<std::string> host_name(const std::string& given) {
  const std::string name = lower(given);
  const auto bad = [&](std::string_view why) { return Error{fmt::format("viewer: host name '{}': {}", given, why)}; };
  std::string_view inner = name;
  if (inner.size() >= 2 && inner.front() == '[' && inner.back() == ']') inner = inner.substr(1, inner.size() - 2);
  beast::error_code ec;
  const asio::ip::address address = asio::ip::make_address(inner, ec);
  if (!ec) return host_literal(address);
  if (name.empty() || name.size() > 253) return bad("a DNS name has 1 to 253 characters");
  if (name.find(':') != std::string::npos) return bad("give the name without a port (the viewer's port is added)");
  if (name.find_first_not_of("abcdefghijklmnopqrstuvwxyz0123456789.-_") != std::string::npos || name.front() == '.' ||
      name.front() == '-') {
    return bad("not a DNS name or an IP address (letters, digits, '.', '-')");
  }
  return name;
}

/// The addresses of this host's interfaces (v4, and v6 too for "::"), as Host headers name
/// them: what another host types to reach a server listening on every address. Link-local v6
/// addresses are left out (a browser cannot give their zone).
std::vector<std::string> interface_hosts(bool v6_too) {
  std::vector<std::string> out;
  ifaddrs* list = nullptr;
  if (::getifaddrs(&list) != 0) return out;
  for (const ifaddrs* i = list; i != nullptr; i = i->ifa_next) {
    if (i->ifa_addr == nullptr) continue;
    if (i->ifa_addr->sa_family == AF_INET) {
      sockaddr_in in{};
      std::memcpy(&in, i->ifa_addr, sizeof in);
      out.push_back(host_literal(asio::ip::address_v4(ntohl(in.sin_addr.s_addr))));
    } else if (v6_too && i->ifa_addr->sa_family == AF_INET6) {
      sockaddr_in6 in6{};
      std::memcpy(&in6, i->ifa_addr, sizeof in6);
      asio::ip::address_v6::bytes_type bytes{};
      std::memcpy(bytes.data(), in6.sin6_addr.s6_addr, bytes.size());
      const asio::ip::address_v6 v6(bytes);
      if (!v6.is_link_local()) out.push_back(host_literal(v6));
    }
  }
  ::freeifaddrs(list);
  return out;
}

Result<std::unique_ptr<ViewerServer::Impl>> bind(const ViewerOptions& options, std::string hello) {
  if (!(options.batch_interval_s > 0.0 && options.batch_interval_s <= 1.0)) {
    return Error{"viewer: the batch interval must be within (0, 1] s"};
  }
  std::vector<std::string> names;  // checked before anything is bound
  for (const std::string& given : options.hosts) {
    auto name = host_name(given);
    if (!name) return Error{name.error()};
    names.push_back(std::move(name.value()));
  }
  beast::error_code ec;
  const asio::ip::address address = asio::ip::make_address(options.address, ec);
  if (ec) {
    return Error{fmt::format("{} {}: not an IP address (use 127.0.0.1, ::1, or an address of this host)",
                             options.address_option, options.address)};
  }
  auto impl = std::make_unique<ViewerServer::Impl>();
  impl->options = options;
  impl->hello = std::make_shared<const std::string>(std::move(hello));
  const tcp::endpoint endpoint(address, options.port);
  impl->acceptor.open(endpoint.protocol(), ec);
  if (!ec) impl->acceptor.set_option(asio::socket_base::reuse_address(true), ec);
  if (!ec) impl->acceptor.bind(endpoint, ec);
  if (!ec) impl->acceptor.listen(asio::socket_base::max_listen_connections, ec);
  if (ec) {
    return Error{fmt::format("viewer: cannot listen on {}:{}: {}{}", options.address, options.port, ec.message(),
                             ec == asio::error::address_in_use
                                 ? " (another program uses the port: give another, or 0 for any free one)"
                                 : "")};
  }
  impl->port = impl->acceptor.local_endpoint().port();
  const std::string p = std::to_string(impl->port);
  const auto allow = [&](const std::string& name) {
    impl->hosts.insert(name + ":" + p);
    if (impl->port == 80) impl->hosts.insert(name);  // a browser leaves the default port out
  };
  for (const char* name : {"127.0.0.1", "localhost", "[::1]"}) allow(name);
  // Any address: the Host must still name this server, never anything with our port (that let
  // a rebinding page's own name through).
  if (address.is_unspecified()) {
    for (const std::string& name : interface_hosts(address.is_v6())) allow(name);
  }
  std::string url_host = "127.0.0.1";
  if (!address.is_unspecified() && !address.is_loopback()) {
    url_host = host_literal(address);
    allow(url_host);
  } else if (address.is_v6() && address.is_loopback()) {
    url_host = "[::1]";
  }
  for (const std::string& name : names) allow(name);
  impl->url = fmt::format("http://{}:{}/", url_host, impl->port);
  impl->history.resize(std::max<std::size_t>(options.history_frames, 1));
  impl->batch.reserve(FrameRing::kCapacity);
  return impl;
}

}  // namespace

Result<std::unique_ptr<ViewerServer>> ViewerServer::start(const ViewerOptions& options, std::string hello_json) {
  return start_recording(options, std::move(hello_json), std::nullopt);
}

Result<std::unique_ptr<ViewerServer>> ViewerServer::start_recording(const ViewerOptions& options,
                                                                    std::string hello_json,
                                                                    std::optional<std::vector<ViewFrame>> recording) {
  auto bound = bind(options, std::move(hello_json));
  if (!bound) return Error{bound.error()};
  std::unique_ptr<Impl> impl = std::move(bound.value());
  if (options.before_serving) {
    if (std::string refused = options.before_serving(); !refused.empty()) return Error{std::move(refused)};
  }
  if (recording) {
    const std::size_t frames = recording->size();
    impl->history = std::move(*recording);
    if (frames == 0) impl->history.resize(1);  // a ring of one, holding nothing
    impl->next_seq = frames;
    impl->ended = true;
    impl->finish_requested.store(true);
  }
  Impl* raw = impl.get();
  raw->start_accept();
  raw->on_timer();
  raw->thread = std::thread([raw] { raw->io.run(); });
  return std::unique_ptr<ViewerServer>(new ViewerServer(std::move(impl)));
}

void ViewerServer::publish(const TelemetryFrame& frame) noexcept {
  publish(view_frame(frame, impl_->options.has_loop));
}

void ViewerServer::publish(const ViewFrame& frame) noexcept {
  static_cast<void>(impl_->ring->push(frame));  // full: dropped and counted, never waits
}

void ViewerServer::finish() noexcept { impl_->finish_requested.store(true, std::memory_order_release); }

bool ViewerServer::wait_for_page(const std::atomic<int>& stop) const {
  while (stop.load() == 0) {
    if (impl_->pages_connected.load() > 0) return true;
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
  }
  return impl_->pages_connected.load() > 0;
}

bool ViewerServer::wait_for_control(const std::atomic<int>& stop) const {
  while (stop.load() == 0) {
    if (impl_->controls_authenticated.load() > 0) return true;
    std::this_thread::sleep_for(std::chrono::milliseconds(5));
  }
  return impl_->controls_authenticated.load() > 0;
}

void ViewerServer::wait_drained(const std::atomic<int>& stop) const {
  while (stop.load() == 0 && impl_->drained.load(std::memory_order_acquire) < impl_->ring->pushed()) {
    std::this_thread::sleep_for(std::chrono::milliseconds(5));
  }
}

std::uint16_t ViewerServer::port() const noexcept { return impl_->port; }
std::string ViewerServer::url() const { return impl_->url; }
std::vector<std::string> ViewerServer::host_names() const { return {impl_->hosts.begin(), impl_->hosts.end()}; }

ViewerStats ViewerServer::stats() const noexcept {
  ViewerStats s;
  s.frames_dropped_ring = impl_->ring->dropped();
  s.frames_in = impl_->ring->pushed() + s.frames_dropped_ring;
  s.frames_dropped_pages = impl_->frames_dropped_pages.load();
  s.pages_connected = impl_->pages_connected.load();
  s.pages_refused = impl_->pages_refused.load();
  s.messages_refused = impl_->messages_refused.load();
  s.http_refused = impl_->http_refused.load();
  s.connections_refused = impl_->connections_refused.load();
  s.accept_failures = impl_->accept_failures.load();
  s.max_queued = impl_->max_queued.load();
  s.pages_open = impl_->pages_open.load();
  s.queued_bytes = impl_->queued_bytes.load();
  s.max_queued_bytes = impl_->max_queued_bytes.load();
  s.control_messages = impl_->control_messages.load();
  s.controls_authenticated = impl_->controls_authenticated.load();
  s.control_refused = impl_->control_refused.load();
  s.controls_pending = impl_->control_pending.load();
  s.controls_open = impl_->control_slots.load();
  s.control_hello_late = impl_->control_hello_late.load();
  s.control_bytes = impl_->control_bytes.load();
  s.max_control_bytes = impl_->max_control_bytes.load();
  s.requests_late = impl_->requests_late.load();
  s.requests_evicted = impl_->requests_evicted.load();
  s.connections_open = impl_->connections.load();
  return s;
}

}  // namespace toonforce::viewer
