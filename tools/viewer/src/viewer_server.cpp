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

#include <algorithm>
#include <chrono>
#include <cstring>
#include <deque>
#include <limits>
#include <set>
#include <thread>

#include <fmt/format.h>

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
constexpr std::size_t kHistoryChunkFrames = 4096;
constexpr std::size_t kMaxPages = 16;

std::string lower(std::string_view text) {
  std::string out(text);
  for (char& c : out) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  return out;
}

std::shared_ptr<const std::string> make_batch(double kind, std::uint64_t first_seq, std::span<const ViewFrame> frames) {
  auto out = std::make_shared<std::string>();
  out->resize((kBatchHeader + frames.size() * kViewStride) * sizeof(double));
  const std::array<double, kBatchHeader> header{kind, static_cast<double>(kViewStride), static_cast<double>(first_seq),
                                                static_cast<double>(frames.size())};
  std::memcpy(out->data(), header.data(), sizeof header);
  if (!frames.empty()) std::memcpy(out->data() + sizeof header, frames.data(), frames.size() * sizeof(ViewFrame));
  return out;
}

struct Message {
  std::shared_ptr<const std::string> data;
  bool text = false;
  bool droppable = false;  ///< live batches: a slow page may lose them
  std::size_t frames = 0;
  bool status = false;     ///< a newer status replaces a queued one (and drops no batch)
};

class PageSession;

}  // namespace

struct ViewerServer::Impl {
  ViewerOptions options;
  // Any thread. Before the io_context: sessions it destroys last still count themselves out.
  std::atomic<std::uint64_t> frames_dropped_pages{0}, pages_connected{0}, pages_refused{0}, messages_refused{0},
      http_refused{0};
  std::atomic<std::size_t> max_queued{0}, pages_open{0};

  asio::io_context io{1};
  tcp::acceptor acceptor{io};
  asio::steady_timer timer{io};
  std::string hello;
  std::uint16_t port = 0;
  bool wildcard = false;            ///< bound to every address: any Host with our port
  std::set<std::string> hosts;      ///< lower-case "name:port" a request may name
  std::string url;
  std::unique_ptr<FrameRing> ring = std::make_unique<FrameRing>();
  std::atomic<bool> finish_requested{false};
  std::atomic<std::uint64_t> drained{0};

  // Server thread only.
  std::vector<ViewFrame> history;   ///< circular, capacity history_frames; seq s at s % size
  std::uint64_t next_seq = 0;
  bool ended = false;
  std::vector<ViewFrame> batch;
  std::vector<std::weak_ptr<PageSession>> pages;
  std::chrono::steady_clock::time_point next_status{};

  std::thread thread;

  bool host_allowed(std::string_view host) const {
    const std::string h = lower(host);
    if (hosts.count(h) != 0) return true;
    if (!wildcard) return false;
    const std::size_t colon = h.rfind(':');
    return colon != std::string::npos && colon + 1 < h.size() && h.substr(colon + 1) == std::to_string(port) &&
           h.find_first_of("/@ ") == std::string::npos;
  }
  /// A browser's WebSocket from our own page carries Origin http://<the Host it asked>.
  bool origin_allowed(std::string_view origin, std::string_view host) const {
    return host_allowed(host) && lower(origin) == "http://" + lower(host);
  }

  void start_accept();
  void on_timer();
  void add_page(const std::shared_ptr<PageSession>& page);
  void broadcast(const Message& message);
  std::shared_ptr<const std::string> status_json(std::uint64_t page_dropped) const;
};

namespace {

/// One WebSocket page: hello, history, then live batches; never reads anything but a close.
class PageSession : public std::enable_shared_from_this<PageSession> {
 public:
  PageSession(tcp::socket socket, ViewerServer::Impl& server) : ws_(std::move(socket)), server_(server) {}
  ~PageSession() {
    if (counted_) server_.pages_open.fetch_sub(1);
  }

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

  void send(Message message) {
    if (closing_) return;
    const std::size_t first = writing_ ? 1 : 0;  // the front is being written: keep it
    if (message.status) {
      for (std::size_t i = first; i < queue_.size(); ++i) {
        if (queue_[i].status) {
          queue_.erase(queue_.begin() + static_cast<std::ptrdiff_t>(i));
          break;
        }
      }
    } else if (message.droppable) {
      std::size_t queued = 0;
      for (std::size_t i = first; i < queue_.size(); ++i) queued += queue_[i].droppable ? 1U : 0U;
      while (queued >= server_.options.max_queued_batches && queued > 0) {
        for (std::size_t i = first; i < queue_.size(); ++i) {
          if (!queue_[i].droppable) continue;
          dropped_ += queue_[i].frames;
          server_.frames_dropped_pages.fetch_add(queue_[i].frames);
          queue_.erase(queue_.begin() + static_cast<std::ptrdiff_t>(i));
          break;
        }
        --queued;
      }
      if (server_.options.max_queued_batches == 0) {
        dropped_ += message.frames;
        server_.frames_dropped_pages.fetch_add(message.frames);
        return;
      }
      std::size_t seen = server_.max_queued.load();
      while (queued + 1 > seen && !server_.max_queued.compare_exchange_weak(seen, queued + 1)) {
      }
    }
    queue_.push_back(std::move(message));
    if (!writing_) write_next();
  }

  std::uint64_t dropped() const noexcept { return dropped_; }

 private:
  void write_next() {
    writing_ = true;
    const Message& m = queue_.front();
    ws_.text(m.text);
    ws_.binary(!m.text);
    ws_.async_write(asio::buffer(*m.data), [self = shared_from_this()](beast::error_code ec, std::size_t) {
      self->writing_ = false;
      if (ec) {
        self->closing_ = true;
        self->queue_.clear();
        return;
      }
      self->queue_.pop_front();
      if (!self->queue_.empty() && !self->closing_) self->write_next();
    });
  }

  void read() {
    ws_.async_read(in_, [self = shared_from_this()](beast::error_code ec, std::size_t) {
      if (ec) {  // closed by the page, or the connection failed
        self->closing_ = true;
        return;
      }
      // Read-only: there is no message a page may send. Close with 1008 (policy violation).
      self->server_.messages_refused.fetch_add(1);
      self->closing_ = true;
      self->in_.consume(self->in_.size());
      if (self->queue_.size() > (self->writing_ ? 1U : 0U)) {
        self->queue_.erase(self->queue_.begin() + (self->writing_ ? 1 : 0), self->queue_.end());
      }
      self->ws_.async_close(websocket::close_reason(websocket::close_code::policy_error, "read-only: send nothing"),
                            [self](beast::error_code) {});
    });
  }

  websocket::stream<beast::tcp_stream> ws_;
  ViewerServer::Impl& server_;
  beast::flat_buffer in_;
  std::deque<Message> queue_;
  bool writing_ = false;
  bool closing_ = false;
  bool counted_ = false;
  std::uint64_t dropped_ = 0;
};

/// One HTTP connection: the page's files, or the upgrade to a PageSession.
class HttpSession : public std::enable_shared_from_this<HttpSession> {
 public:
  HttpSession(tcp::socket socket, ViewerServer::Impl& server) : stream_(std::move(socket)), server_(server) {}

  void read() {
    parser_.emplace();
    parser_->header_limit(8 * 1024);
    parser_->body_limit(1024);  // GET and HEAD have no body
    stream_.expires_after(std::chrono::seconds(30));
    http::async_read(stream_, buffer_, *parser_, [self = shared_from_this()](beast::error_code ec, std::size_t) {
      self->on_read(ec);
    });
  }

 private:
  void on_read(beast::error_code ec) {
    if (ec) {
      beast::error_code ignored;
      stream_.socket().shutdown(tcp::socket::shutdown_send, ignored);
      return;
    }
    http::request<http::string_body> request = parser_->release();
    const std::string_view host(request[http::field::host].data(), request[http::field::host].size());
    if (!server_.host_allowed(host)) {
      refuse(request, http::status::misdirected_request, "this server answers to 127.0.0.1 or localhost only\n");
      return;
    }
    if (websocket::is_upgrade(request)) {
      const std::string_view origin(request[http::field::origin].data(), request[http::field::origin].size());
      if (request.target() != "/ws") {
        refuse(request, http::status::not_found, "no such socket\n");
      } else if (!server_.origin_allowed(origin, host)) {
        server_.pages_refused.fetch_add(1);
        refuse(request, http::status::forbidden, "WebSocket origin refused: only the viewer's own page may connect\n");
      } else if (server_.pages_open.load() >= kMaxPages) {
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
};

}  // namespace

void ViewerServer::Impl::start_accept() {
  acceptor.async_accept([this](beast::error_code ec, tcp::socket socket) {
    if (ec == asio::error::operation_aborted) return;
    if (!ec) {
      if (options.send_buffer_bytes > 0) {
        beast::error_code ignored;
        socket.set_option(asio::socket_base::send_buffer_size(options.send_buffer_bytes), ignored);
      }
      std::make_shared<HttpSession>(std::move(socket), *this)->read();
    }
    start_accept();
  });
}

std::shared_ptr<const std::string> ViewerServer::Impl::status_json(std::uint64_t page_dropped) const {
  return std::make_shared<const std::string>(fmt::format(
      R"({{"type":"status","ended":{},"frames":{},"dropped_ring":{},"dropped_page":{},"pages":{}}})", ended, next_seq,
      ring->dropped(), page_dropped, pages_open.load()));
}

void ViewerServer::Impl::add_page(const std::shared_ptr<PageSession>& page) {
  pages.push_back(page);
  page->send(Message{std::make_shared<const std::string>(hello), true, false, 0});
  // What was published before the page came, oldest first, in chunks; never dropped.
  const std::size_t capacity = history.size();
  const std::uint64_t count = std::min<std::uint64_t>(next_seq, capacity);
  std::vector<ViewFrame> chunk;
  chunk.reserve(kHistoryChunkFrames);
  std::uint64_t first = next_seq - count;
  for (std::uint64_t s = first; s < next_seq; ++s) {
    chunk.push_back(history[static_cast<std::size_t>(s % capacity)]);
    if (chunk.size() == kHistoryChunkFrames || s + 1 == next_seq) {
      page->send(Message{make_batch(kHistoryBatch, first, chunk), false, false, chunk.size()});
      first = s + 1;
      chunk.clear();
    }
  }
  page->send(Message{status_json(0), true, false, 0, true});
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
    beast::error_code ignored;
    impl->acceptor.close(ignored);
    impl->timer.cancel();
    impl->io.stop();
  });
  if (impl_->thread.joinable()) impl_->thread.join();
}

namespace {

Result<std::unique_ptr<ViewerServer::Impl>> bind(const ViewerOptions& options, std::string hello) {
  if (!(options.batch_interval_s > 0.0 && options.batch_interval_s <= 1.0)) {
    return Error{"viewer: the batch interval must be within (0, 1] s"};
  }
  beast::error_code ec;
  const asio::ip::address address = asio::ip::make_address(options.address, ec);
  if (ec) {
    return Error{fmt::format("--view-address {}: not an IP address (use 127.0.0.1, ::1, or an address of this host)",
                             options.address)};
  }
  auto impl = std::make_unique<ViewerServer::Impl>();
  impl->options = options;
  impl->hello = std::move(hello);
  const tcp::endpoint endpoint(address, options.port);
  impl->acceptor.open(endpoint.protocol(), ec);
  if (!ec) impl->acceptor.set_option(asio::socket_base::reuse_address(true), ec);
  if (!ec) impl->acceptor.bind(endpoint, ec);
  if (!ec) impl->acceptor.listen(asio::socket_base::max_listen_connections, ec);
  if (ec) {
    return Error{fmt::format("viewer: cannot listen on {}:{}: {}{}", options.address, options.port, ec.message(),
                             ec == asio::error::address_in_use ? " (another program uses the port: give another, or 0 for any free one)"
                                                               : "")};
  }
  impl->port = impl->acceptor.local_endpoint().port();
  const std::string p = std::to_string(impl->port);
  impl->hosts = {"127.0.0.1:" + p, "localhost:" + p, "[::1]:" + p};
  impl->wildcard = address.is_unspecified();
  std::string url_host = "127.0.0.1";
  if (!address.is_unspecified() && !address.is_loopback()) {
    url_host = address.is_v6() ? "[" + address.to_string() + "]" : address.to_string();
    impl->hosts.insert(lower(url_host) + ":" + p);
  } else if (address.is_v6() && address.is_loopback()) {
    url_host = "[::1]";
  }
  impl->url = fmt::format("http://{}:{}/", url_host, impl->port);
  impl->history.resize(std::max<std::size_t>(options.history_frames, 1));
  impl->batch.reserve(FrameRing::kCapacity);
  return impl;
}

}  // namespace

Result<std::unique_ptr<ViewerServer>> ViewerServer::start(const ViewerOptions& options, std::string hello_json) {
  return start_recording(options, std::move(hello_json), std::nullopt);
}

Result<std::unique_ptr<ViewerServer>> ViewerServer::start_recording(const ViewerOptions& options, std::string hello_json,
                                                                    std::optional<std::vector<ViewFrame>> recording) {
  auto bound = bind(options, std::move(hello_json));
  if (!bound) return Error{bound.error()};
  std::unique_ptr<Impl> impl = std::move(bound.value());
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

void ViewerServer::publish(const TelemetryFrame& frame) noexcept { publish(view_frame(frame, impl_->options.has_loop)); }

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

void ViewerServer::wait_drained(const std::atomic<int>& stop) const {
  while (stop.load() == 0 && impl_->drained.load(std::memory_order_acquire) < impl_->ring->pushed()) {
    std::this_thread::sleep_for(std::chrono::milliseconds(5));
  }
}

std::uint16_t ViewerServer::port() const noexcept { return impl_->port; }
std::string ViewerServer::url() const { return impl_->url; }

ViewerStats ViewerServer::stats() const noexcept {
  ViewerStats s;
  s.frames_dropped_ring = impl_->ring->dropped();
  s.frames_in = impl_->ring->pushed() + s.frames_dropped_ring;
  s.frames_dropped_pages = impl_->frames_dropped_pages.load();
  s.pages_connected = impl_->pages_connected.load();
  s.pages_refused = impl_->pages_refused.load();
  s.messages_refused = impl_->messages_refused.load();
  s.http_refused = impl_->http_refused.load();
  s.max_queued = impl_->max_queued.load();
  s.pages_open = impl_->pages_open.load();
  return s;
}

}  // namespace toonforce::viewer
