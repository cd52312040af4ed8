// SPDX-License-Identifier: MIT
// The Beast/Asio implementation of btf::stream::Server (docs/protocol.md). All Beast code of the
// library lives in this file so that only it pays Beast's compile time.
//
// Structure: one acceptor on its own strand; each connection is a session object on its own
// strand (so its handlers never run concurrently) kept alive by the shared_ptrs its pending
// operations hold. An HttpSession reads one request header at a time and answers it; an Upgrade
// on stream/<id> hands the socket to a WebSocketSession. Every session registers itself in
// Shared, which is how the connection cap counts them and how stop() reaches them.

#include "btf/stream/server.h"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <array>
#include <atomic>
#include <boost/asio/dispatch.hpp>
#include <boost/asio/executor_work_guard.hpp>
#include <boost/asio/io_context.hpp>
#include <boost/asio/ip/tcp.hpp>
#include <boost/asio/post.hpp>
#include <boost/asio/steady_timer.hpp>
#include <boost/asio/strand.hpp>
#include <boost/beast/core.hpp>
#include <boost/beast/http.hpp>
#include <boost/beast/websocket.hpp>
#include <cerrno>
#include <condition_variable>
#include <functional>
#include <mutex>
#include <optional>
#include <thread>
#include <unordered_map>

#include <fmt/format.h>

#include "btf/stream/request.h"
#include "btf/util/error.h"

namespace btf::stream {

namespace fs = std::filesystem;
namespace beast = boost::beast;
namespace http = beast::http;
namespace websocket = beast::websocket;
namespace net = boost::asio;
using tcp = net::ip::tcp;

namespace {

constexpr const char* kServerName = "btfkit";
using Request = http::request<http::empty_body>;

// Boost 1.74's Beast uses boost::string_view.
std::string_view std_view(beast::string_view s) {
    return {s.data(), s.size()};
}
beast::string_view beast_view(std::string_view s) {
    return {s.data(), s.size()};
}

// ---- files -------------------------------------------------------------------------------------

// An open file descriptor, read with pread so that no file position is shared.
class File {
  public:
    File() = default;
    explicit File(int fd) : m_fd(fd) {}
    ~File() {
        if (m_fd >= 0) ::close(m_fd);
    }
    File(File&& other) noexcept : m_fd(std::exchange(other.m_fd, -1)), m_size(other.m_size) {}
    File& operator=(File&& other) noexcept {
        if (this != &other) {
            if (m_fd >= 0) ::close(m_fd);
            m_fd = std::exchange(other.m_fd, -1);
            m_size = other.m_size;
        }
        return *this;
    }

    bool is_open() const { return m_fd >= 0; }
    uint64_t size() const { return m_size; }

    // Opens a regular file; a symbolic link as the last component is refused (callers pass
    // canonical paths, so one appearing there was swapped in after the check).
    static File open_regular(const fs::path& path) {
        File file(::open(path.c_str(), O_RDONLY | O_CLOEXEC | O_NOFOLLOW));
        struct stat st;
        if (!file.is_open() || ::fstat(file.m_fd, &st) != 0 || !S_ISREG(st.st_mode)) return {};
        file.m_size = uint64_t(st.st_size);
        return file;
    }

    // Reads exactly `size` bytes at `offset`; false on an error or a short file.
    bool read_at(char* data, size_t size, uint64_t offset) const {
        while (size > 0) {
            const ssize_t n = ::pread(m_fd, data, size, off_t(offset));
            if (n < 0 && errno == EINTR) continue;
            if (n <= 0) return false;
            data += n, size -= size_t(n), offset += uint64_t(n);
        }
        return true;
    }

  private:
    int m_fd = -1;
    uint64_t m_size = 0;
};

std::string_view content_type(const fs::path& path) {
    const std::string ext = ascii_lower(path.extension().string());
    if (ext == ".html" || ext == ".htm") return "text/html; charset=utf-8";
    if (ext == ".js" || ext == ".mjs") return "text/javascript; charset=utf-8";
    if (ext == ".css") return "text/css; charset=utf-8";
    if (ext == ".json" || ext == ".map") return "application/json";
    if (ext == ".png") return "image/png";
    if (ext == ".svg") return "image/svg+xml";
    if (ext == ".wasm") return "application/wasm";
    if (ext == ".txt") return "text/plain; charset=utf-8";
    return "application/octet-stream";
}

// ---- shared state and sessions -----------------------------------------------------------------

class Session;

struct Shared {
    Catalog catalog;
    ServerOptions options;
    fs::path web_root;           // canonical; empty: no static files
    std::string materials_json;  // GET api/materials
    std::string builtin_page;    // `/` when the web root has no index.html

    std::mutex mutex;
    std::condition_variable changed;
    std::unordered_map<Session*, std::weak_ptr<Session>> sessions;
    std::atomic<int> served{0}, rejecting{0};
    std::atomic<bool> stopping{false};

    void remember(const std::shared_ptr<Session>& session);
    void forget(Session* session) {
        std::lock_guard lock(mutex);
        sessions.erase(session);
        changed.notify_all();
    }
    std::vector<std::shared_ptr<Session>> snapshot() {
        std::lock_guard lock(mutex);
        std::vector<std::shared_ptr<Session>> list;
        for (auto& [key, weak] : sessions)
            if (auto s = weak.lock()) list.push_back(std::move(s));
        return list;
    }
};

// A connection. `counted` sessions are served and count against the cap; the others only
// answer 503 (they have their own, equal, cap).
class Session {
  public:
    Session(Shared& shared, bool counted) : m_shared(shared), m_counted(counted) {
        (m_counted ? m_shared.served : m_shared.rejecting).fetch_add(1);
    }
    virtual ~Session() {
        (m_counted ? m_shared.served : m_shared.rejecting).fetch_sub(1);
        m_shared.forget(this);
    }
    Session(const Session&) = delete;
    Session& operator=(const Session&) = delete;

    // Shutdown, first step: close if idle, finish what is running.
    virtual void soft_stop() = 0;
    // Shutdown, last step: close now.
    virtual void hard_stop() = 0;

  protected:
    Shared& m_shared;
    const bool m_counted;
};

void Shared::remember(const std::shared_ptr<Session>& session) {
    std::lock_guard lock(mutex);
    sessions.emplace(session.get(), session);
}

// ---- the WebSocket client's byte stream --------------------------------------------------------

// The TCP stream under a WebSocket session. It corrects three things in how Beast 1.74 ends a
// connection that a client breaks (RFC 6455 §7.1.7: send a close frame, then close):
// - Bytes the client sent right after its upgrade request, read with the request, are handed to
//   Beast first instead of being lost with the HTTP session's buffer (a frame sent that early
//   would otherwise never be seen, nor refused).
// - Beast reads a 64-bit payload length with its top bit set (which RFC 6455 §5.2 forbids) as a
//   very long message and closes with 1009. Those length bytes are replaced, as they pass, by
//   zeros: a non-minimal length, which Beast refuses with 1002 like every other malformed header.
// - Beast's teardown after its close frame reads at most one buffer of what the client still
//   sends, then closes the socket. With more unread (the rest of an oversized message) the kernel
//   answers with a reset, and the close frame, queued behind the stream's data, never arrives.
//   async_teardown() below reads on to the client's end of stream (at most kDrainLimit bytes,
//   within the linger time) before it closes.
class ClientStream {
  public:
    using executor_type = beast::tcp_stream::executor_type;
    static constexpr uint64_t kDrainLimit = uint64_t(1) << 20;

    ClientStream(beast::tcp_stream&& stream, std::string early, std::chrono::milliseconds linger)
        : m_next(std::move(stream)), m_early(std::move(early)), m_linger(linger) {}

    executor_type get_executor() noexcept { return m_next.get_executor(); }
    beast::tcp_stream& next_layer() noexcept { return m_next; }
    const beast::tcp_stream& next_layer() const noexcept { return m_next; }
    std::chrono::milliseconds linger() const { return m_linger; }

    template <typename ConstBuffers, typename Handler>
    void async_write_some(const ConstBuffers& buffers, Handler&& handler) {
        m_next.async_write_some(buffers, std::forward<Handler>(handler));
    }

    template <typename MutableBuffers, typename Handler>
    void async_read_some(const MutableBuffers& buffers, Handler&& handler) {
        ReadOp<MutableBuffers, std::decay_t<Handler>>(std::forward<Handler>(handler), *this,
                                                      buffers);
    }

  private:
    template <typename MutableBuffers, typename Handler>
    class ReadOp : public beast::async_base<Handler, executor_type> {
      public:
        template <typename H>
        ReadOp(H&& handler, ClientStream& stream, const MutableBuffers& buffers)
            : beast::async_base<Handler, executor_type>(std::forward<H>(handler),
                                                        stream.get_executor()),
              m_stream(stream),
              m_buffers(buffers) {
            if (!stream.m_early.empty()) {
                const size_t n = net::buffer_copy(buffers, net::buffer(stream.m_early));
                stream.m_early.erase(0, n);
                stream.scan(buffers, n);
                this->complete(false, beast::error_code{}, n);
                return;
            }
            stream.m_next.async_read_some(buffers, std::move(*this));
        }
        void operator()(beast::error_code ec, size_t n) {
            m_stream.scan(m_buffers, n);
            this->complete(true, ec, n);
        }

      private:
        ClientStream& m_stream;
        MutableBuffers m_buffers;
    };

    // Follows the frames in the first `n` bytes of `buffers` (just read, not yet parsed by
    // Beast), zeroing 64-bit lengths that have their top bit set.
    template <typename MutableBuffers>
    void scan(const MutableBuffers& buffers, size_t n) {
        for (auto it = net::buffer_sequence_begin(buffers);
             n > 0 && it != net::buffer_sequence_end(buffers); ++it) {
            const net::mutable_buffer b = *it;
            const size_t size = std::min(n, b.size());
            scan(static_cast<uint8_t*>(b.data()), size);
            n -= size;
        }
    }
    void scan(uint8_t* p, size_t size) {
        while (size > 0) {
            if (m_payload > 0) {
                const size_t skip = size_t(std::min<uint64_t>(m_payload, size));
                m_payload -= skip, p += skip, size -= skip;
                continue;
            }
            // A header byte: FIN, RSV and opcode; mask bit and 7-bit length; extended length;
            // masking key.
            if (m_header == 1) {
                const int length7 = *p & 0x7f;
                m_length_bytes = length7 == 127 ? 8 : length7 == 126 ? 2 : 0;
                m_length = length7 < 126 ? uint64_t(length7) : 0;
                m_header_size = 2 + m_length_bytes + (*p & 0x80 ? 4 : 0);
            } else if (m_header >= 2 && m_header < 2 + m_length_bytes) {
                if (m_header == 2 && m_length_bytes == 8 && (*p & 0x80)) m_top_bit = true;
                if (m_top_bit) *p = 0;
                m_length = m_length << 8 | *p;
            }
            ++p, --size;
            if (++m_header == m_header_size) {
                m_payload = m_length;
                m_header = 0, m_header_size = 2, m_length_bytes = 0, m_length = 0;
                m_top_bit = false;
            }
        }
    }

    beast::tcp_stream m_next;
    std::string m_early;  // bytes that came with the upgrade request, not read by Beast yet
    std::chrono::milliseconds m_linger;
    // Where the client's bytes are: in a payload (m_payload bytes of it left) or in a header
    // (m_header bytes of its m_header_size seen).
    uint64_t m_payload = 0;
    int m_header = 0, m_header_size = 2, m_length_bytes = 0;
    uint64_t m_length = 0;
    bool m_top_bit = false;
};

// Beast's websocket::stream ends a connection with async_teardown(), found by argument-dependent
// lookup: stop sending, read what the client still sends to its end of stream (up to kDrainLimit
// bytes, for at most the linger time), then close.
template <typename Handler>
class TeardownOp : public beast::async_base<Handler, ClientStream::executor_type> {
  public:
    template <typename H>
    TeardownOp(H&& handler, ClientStream& stream)
        : beast::async_base<Handler, ClientStream::executor_type>(std::forward<H>(handler),
                                                                  stream.get_executor()),
          m_stream(stream.next_layer()),
          m_buffer(std::make_unique<std::array<char, 16384>>()) {
        beast::error_code ec;
        m_stream.socket().shutdown(tcp::socket::shutdown_send, ec);
        if (ec) {
            m_stream.close();
            this->complete(false, ec);
            return;
        }
        m_stream.expires_after(stream.linger());
        m_stream.async_read_some(net::buffer(*m_buffer), std::move(*this));
    }
    void operator()(beast::error_code ec, size_t n) {
        m_drained += n;
        if (!ec && m_drained <= ClientStream::kDrainLimit) {
            m_stream.async_read_some(net::buffer(*m_buffer), std::move(*this));
            return;
        }
        m_stream.close();
        this->complete(true, ec == net::error::eof ? beast::error_code{} : ec);
    }

  private:
    beast::tcp_stream& m_stream;
    std::unique_ptr<std::array<char, 16384>> m_buffer;
    uint64_t m_drained = 0;
};

template <typename Handler>
void async_teardown(beast::role_type, ClientStream& stream, Handler&& handler) {
    TeardownOp<std::decay_t<Handler>>(std::forward<Handler>(handler), stream);
}

// Streams one package over an upgraded connection: begin message, the file in binary messages
// that end at every section boundary, end message, close 1000. One write at a time; the next
// chunk is read from disk only when the socket has taken the previous one.
class WebSocketSession : public Session, public std::enable_shared_from_this<WebSocketSession> {
  public:
    // `early`: what the client sent after its upgrade request, read with it.
    WebSocketSession(beast::tcp_stream&& stream, std::string early, Shared& shared,
                     const CatalogEntry& entry, File file)
        : Session(shared, true),
          m_ws(
              std::move(stream), std::move(early),
              std::min<std::chrono::milliseconds>(shared.options.timeout, std::chrono::seconds(2))),
          m_entry(entry),
          m_file(std::move(file)) {
        m_boundaries.push_back(entry.header_bytes);
        for (const CatalogSection& s : entry.sections) m_boundaries.push_back(s.offset + s.size);
        m_boundaries.push_back(entry.bytes);
    }

    void run(Request request) {
        m_upgrade = std::move(request);
        const ServerOptions& o = m_shared.options;
        // The WebSocket stream times its handshakes itself; the TCP layer only times writes
        // (set before each one), so a stalled reader cannot hold a connection forever.
        beast::get_lowest_layer(m_ws).expires_never();
        websocket::stream_base::timeout timeout{};
        timeout.handshake_timeout = o.timeout;
        timeout.idle_timeout = websocket::stream_base::none();
        timeout.keep_alive_pings = false;
        m_ws.set_option(timeout);
        m_ws.set_option(websocket::stream_base::decorator(
            [](websocket::response_type& res) { res.set(http::field::server, kServerName); }));
        m_ws.read_message_max(o.websocket_message_limit);
        // One frame per message: the protocol's message boundaries are the section boundaries.
        m_ws.auto_fragment(false);
        m_chunk.resize(o.chunk_bytes);
        m_ws.async_accept(
            m_upgrade, beast::bind_front_handler(&WebSocketSession::on_accept, shared_from_this()));
    }

    void soft_stop() override {}
    void hard_stop() override {
        net::post(m_ws.get_executor(),
                  [self = shared_from_this()] { beast::get_lowest_layer(self->m_ws).close(); });
    }

  private:
    void on_accept(beast::error_code ec) {
        if (ec) return;
        read();
        nlohmann::ordered_json sections = nlohmann::ordered_json::array();
        for (const CatalogSection& s : m_entry.sections)
            sections.push_back({{"name", s.name}, {"offset", s.offset}, {"size", s.size}});
        m_text = dump_json({{"type", "begin"},
                            {"id", m_entry.id},
                            {"bytes", m_entry.bytes},
                            {"sections", std::move(sections)}});
        write(true, net::buffer(m_text));
    }

    // The client sends nothing; whatever it sends is read and dropped so that its close frame
    // and pings are answered. A frame that breaks RFC 6455 fails the read, and Beast closes the
    // connection with 1002 (1009 for a message above the limit) after the message being written,
    // which ends the stream: the next write fails.
    void read() {
        m_ws.async_read(m_input,
                        beast::bind_front_handler(&WebSocketSession::on_read, shared_from_this()));
    }
    void on_read(beast::error_code ec, size_t) {
        if (ec) return;
        m_input.consume(m_input.size());
        read();
    }

    void write(bool text, net::const_buffer data) {
        m_ws.text(text);
        beast::get_lowest_layer(m_ws).expires_after(m_shared.options.timeout);
        m_ws.async_write(
            data, beast::bind_front_handler(&WebSocketSession::on_write, shared_from_this()));
    }

    void on_write(beast::error_code ec, size_t) {
        // The deadline was for this write; later writes Beast makes on its own (close and pong
        // replies) must not inherit it.
        beast::get_lowest_layer(m_ws).expires_never();
        // A failed write ends the stream. The socket is not closed here: after a timeout the TCP
        // layer has closed it, after a failed read Beast is sending its close frame (1002 or
        // 1009) and draining the client, and a dead peer fails the pending read too.
        if (ec) return;
        if (m_done) {
            close(websocket::close_code::normal, "");
            return;
        }
        if (m_position == m_entry.bytes) {
            m_done = true;
            m_text = R"({"type":"end"})";
            write(true, net::buffer(m_text));
            return;
        }
        // The next boundary after the current position ends this message.
        uint64_t boundary = m_entry.bytes;
        for (const uint64_t b : m_boundaries)
            if (b > m_position) boundary = std::min(boundary, b);
        const size_t size = size_t(std::min<uint64_t>(m_chunk.size(), boundary - m_position));
        if (!m_file.read_at(m_chunk.data(), size, m_position)) {
            close(websocket::close_code::internal_error, "cannot read the package");
            return;
        }
        m_position += size;
        write(false, net::buffer(m_chunk.data(), size));
    }

    void close(websocket::close_code code, const char* reason) {
        beast::get_lowest_layer(m_ws).expires_after(m_shared.options.timeout);
        m_ws.async_close(websocket::close_reason(code, reason),
                         [self = shared_from_this()](beast::error_code) {
                             beast::get_lowest_layer(self->m_ws).close();
                         });
    }

    websocket::stream<ClientStream> m_ws;
    const CatalogEntry& m_entry;
    File m_file;
    Request m_upgrade;
    std::vector<uint64_t> m_boundaries;
    std::vector<char> m_chunk;
    std::string m_text;
    beast::flat_buffer m_input;
    uint64_t m_position = 0;
    bool m_done = false;
};

// One HTTP/1.1 connection: reads a request header (never a body), answers it, and with
// keep-alive reads the next one.
class HttpSession : public Session, public std::enable_shared_from_this<HttpSession> {
  public:
    HttpSession(tcp::socket&& socket, Shared& shared, bool counted)
        : Session(shared, counted), m_stream(std::move(socket)) {}

    void run() {
        net::dispatch(m_stream.get_executor(),
                      beast::bind_front_handler(&HttpSession::read_request, shared_from_this()));
    }

    void soft_stop() override {
        net::post(m_stream.get_executor(), [self = shared_from_this()] {
            if (!self->m_handed_off && self->m_state != State::kBusy) self->m_stream.close();
        });
    }
    void hard_stop() override {
        net::post(m_stream.get_executor(), [self = shared_from_this()] {
            if (!self->m_handed_off) self->m_stream.close();
        });
    }

  private:
    enum class State { kReading, kBusy, kLingering };

    const ServerOptions& options() const { return m_shared.options; }

    void read_request() {
        if (m_shared.stopping.load()) return;  // the session ends and the socket closes
        m_parser.emplace();
        m_parser->header_limit(uint32_t(std::min<size_t>(options().header_limit, UINT32_MAX)));
        // One deadline for the whole header: a client trickling bytes gains nothing.
        m_stream.expires_after(options().timeout);
        m_state = State::kReading;
        http::async_read_header(
            m_stream, m_buffer, *m_parser,
            beast::bind_front_handler(&HttpSession::on_read, shared_from_this()));
    }

    void on_read(beast::error_code ec, size_t) {
        m_state = State::kBusy;
        m_head = false;
        m_method_text.clear();
        if (ec) {
            // Parse errors are answered; a client that went away or timed out is just closed.
            static const auto& http_category =
                http::make_error_code(http::error::bad_target).category();
            if (ec == http::error::header_limit)
                send_error(http::status::payload_too_large,
                           fmt::format("request header exceeds {} bytes", options().header_limit),
                           true);
            else if (ec.category() == http_category && ec != http::error::end_of_stream &&
                     ec != http::error::partial_message)
                send_error(http::status::bad_request, "malformed request: " + ec.message(), true);
            return;
        }
        const bool has_body =
            (m_parser->content_length() && *m_parser->content_length() > 0) || m_parser->chunked();
        m_request = m_parser->release();
        m_method_text =
            fmt::format("{} {}", std_view(m_request.method_string()), std_view(m_request.target()));
        const http::verb method = m_request.method();
        m_head = method == http::verb::head;
        if (!m_counted)
            return send_error(http::status::service_unavailable,
                              fmt::format("server busy: {} connections open, try again later",
                                          options().max_connections),
                              true);
        if (method != http::verb::get && method != http::verb::head)
            return send_error(http::status::method_not_allowed,
                              "method not allowed (GET and HEAD only)", has_body);
        if (has_body)
            return send_error(http::status::payload_too_large, "a request body is not accepted",
                              true);
        handle();
    }

    void handle() {
        const DecodedTarget target = decode_target(std_view(m_request.target()));
        if (target.status == 400)
            return send_error(http::status::bad_request, "malformed request target", true);
        if (target.status != 200) return send_error(http::status::not_found, "not found");
        const std::string& path = target.path;

        if (path == "/") return send_index();
        if (path == "/api/materials")
            return send_text(http::status::ok, "application/json", m_shared.materials_json);
        if (path.starts_with("/materials/") && path.ends_with(".btfpkg") &&
            target.segments.size() == 2) {
            const std::string_view id = std::string_view(path).substr(
                11, path.size() - 11 - std::string_view(".btfpkg").size());
            const CatalogEntry* entry = valid_id(id) ? m_shared.catalog.find(id) : nullptr;
            if (!entry) return send_error(http::status::not_found, "no such material");
            File file = open_package(*entry);
            if (!file.is_open()) return;
            return send_file(std::move(file), "application/octet-stream");
        }
        if (path.starts_with("/stream/") && target.segments.size() == 2) {
            const std::string_view id = std::string_view(path).substr(8);
            const CatalogEntry* entry = valid_id(id) ? m_shared.catalog.find(id) : nullptr;
            if (!entry) return send_error(http::status::not_found, "no such material");
            const HandshakeCheck handshake = check_websocket_handshake(
                {.method = std_view(m_request.method_string()),
                 .version = m_request.version(),
                 .host = field_values(http::field::host),
                 .connection = field_values(http::field::connection),
                 .upgrade = field_values(http::field::upgrade),
                 .key = field_values(http::field::sec_websocket_key),
                 .websocket_version = field_values(http::field::sec_websocket_version)});
            if (handshake.status == 426)
                return send_error(
                    http::status::upgrade_required, handshake.message, false,
                    [](http::fields& f) { f.set(http::field::sec_websocket_version, "13"); });
            if (handshake.status != 101)
                return send_error(http::status::bad_request, handshake.message);
            File file = open_package(*entry);
            if (!file.is_open()) return;
            auto session = std::make_shared<WebSocketSession>(
                std::move(m_stream), beast::buffers_to_string(m_buffer.data()), m_shared, *entry,
                std::move(file));
            m_handed_off = true;
            m_shared.remember(session);
            session->run(std::move(m_request));
            return;
        }
        send_static(target.segments);
    }

    // The values of every field line named `field`, in order.
    std::vector<std::string_view> field_values(http::field field) const {
        std::vector<std::string_view> values;
        for (auto [it, end] = m_request.equal_range(field); it != end; ++it)
            values.push_back(std_view(it->value()));
        return values;
    }

    // Opens a catalog entry's package, or answers 500 when the file is gone or has changed
    // since its header was read (its list entry would describe another file).
    File open_package(const CatalogEntry& entry) {
        File file = File::open_regular(entry.path);
        std::error_code ec;
        if (file.is_open() && file.size() == entry.bytes &&
            fs::last_write_time(entry.path, ec) == entry.modified && !ec)
            return file;
        send_error(http::status::internal_server_error,
                   fmt::format("material '{}': {} is missing or changed since the server started",
                               entry.id, entry.path.filename().string()));
        return {};
    }

    void send_index() {
        File file = open_static({"index.html"});
        if (file.is_open()) return send_file(std::move(file), "text/html; charset=utf-8");
        send_text(http::status::ok, "text/html; charset=utf-8", m_shared.builtin_page);
    }

    void send_static(const std::vector<std::string>& segments) {
        File file = open_static(segments);
        if (!file.is_open()) return send_error(http::status::not_found, "not found");
        send_file(std::move(file), content_type(segments.back()));
    }

    // The regular file under the web root that `segments` name, or no file. Symbolic links are
    // followed only while they stay inside the web root.
    File open_static(const std::vector<std::string>& segments) const {
        if (m_shared.web_root.empty() || segments.empty()) return {};
        fs::path path = m_shared.web_root;
        for (const std::string& s : segments) path /= s;
        std::error_code ec;
        const fs::path real = fs::canonical(path, ec);
        if (ec || !inside(real, m_shared.web_root)) return {};
        return File::open_regular(real);
    }

    template <typename Response>
    void common_fields(Response& res, bool close) {
        res.version(m_request.version() == 10 ? 10 : 11);
        res.set(http::field::server, kServerName);
        res.set(http::field::cache_control, "no-cache");
        res.set("X-Content-Type-Options", "nosniff");
        res.keep_alive(!close && m_request.keep_alive() && !m_shared.stopping.load());
    }

    // A response held in memory; HEAD gets its header only.
    void send_text(http::status status, std::string_view type, std::string body, bool close = false,
                   std::function<void(http::fields&)> extra = {}) {
        if (m_head) {
            auto res = std::make_shared<http::response<http::empty_body>>(status, 11);
            common_fields(*res, close);
            res->set(http::field::content_type, beast_view(type));
            res->content_length(body.size());
            if (extra) extra(*res);
            return write(res);
        }
        auto res = std::make_shared<http::response<http::string_body>>(status, 11);
        common_fields(*res, close);
        res->set(http::field::content_type, beast_view(type));
        if (extra) extra(*res);
        res->body() = std::move(body);
        res->prepare_payload();
        write(res);
    }

    // {"error": "GET /x: not found"}: the request, then what was wrong with it.
    void send_error(http::status status, const std::string& message, bool close = false,
                    std::function<void(http::fields&)> extra = {}) {
        if (status == http::status::method_not_allowed)
            extra = [](http::fields& f) { f.set(http::field::allow, "GET, HEAD"); };
        const std::string text = dump_json(
            {{"error", m_method_text.empty() ? message : m_method_text + ": " + message}});
        send_text(status, "application/json", text, close, std::move(extra));
    }

    template <typename Response>
    void write(const std::shared_ptr<Response>& res) {
        m_response = res;
        m_stream.expires_after(options().timeout);
        http::async_write(m_stream, *res,
                          [self = shared_from_this(), close = !res->keep_alive()](
                              beast::error_code ec, size_t) { self->on_written(ec, close); });
    }

    void on_written(beast::error_code ec, bool close) {
        m_response.reset();
        m_file = File();
        if (ec) return;  // the session ends and the socket closes
        if (close || m_shared.stopping.load()) return linger();
        read_request();
    }

    // A file in chunks of chunk_bytes, each read when the socket has taken the one before; the
    // Range policy of parse_range() selects the whole file (200), one range (206) or refuses
    // (416).
    void send_file(File file, std::string_view type) {
        const uint64_t size = file.size();
        // Range is defined for GET alone (RFC 9110 §14.2). If-Range names a validator that this
        // server never sends, so its condition is false and the answer is the whole file
        // (§13.1.5).
        std::vector<std::string_view> ranges;
        if (!m_head && m_request.find(http::field::if_range) == m_request.end())
            ranges = field_values(http::field::range);
        const RangeAnswer range = parse_range(ranges, size);
        if (range.status == 416)
            return send_error(
                http::status::range_not_satisfiable,
                fmt::format("range '{}' selects none of the {} bytes", ranges.front(), size), false,
                [size](http::fields& f) {
                    f.set(http::field::content_range, fmt::format("bytes */{}", size));
                });
        const uint64_t first = range.first, end = range.end;
        const http::status status =
            range.status == 206 ? http::status::partial_content : http::status::ok;
        m_file = std::move(file);
        m_position = first;
        m_end = end;
        m_file_response.emplace(status, 11);
        auto& res = *m_file_response;
        common_fields(res, false);
        res.set(http::field::content_type, beast_view(type));
        res.set(http::field::accept_ranges, "bytes");
        if (status == http::status::partial_content)
            res.set(http::field::content_range,
                    fmt::format("bytes {}-{}/{}", first, end - 1, size));
        res.content_length(end - first);
        res.body().data = nullptr;
        res.body().more = !m_head;
        m_serializer.emplace(res);
        m_stream.expires_after(options().timeout);
        http::async_write_header(m_stream, *m_serializer,
                                 [self = shared_from_this()](beast::error_code ec, size_t) {
                                     if (ec) return;
                                     if (self->m_head) {
                                         self->finish_file(ec);
                                         return;
                                     }
                                     self->write_file_chunk();
                                 });
    }

    void write_file_chunk() {
        auto& body = m_file_response->body();
        if (m_position == m_end) {
            body.data = nullptr;
            body.size = 0;
            body.more = false;
        } else {
            m_chunk.resize(options().chunk_bytes);
            const size_t size = size_t(std::min<uint64_t>(m_chunk.size(), m_end - m_position));
            // The header is out already: a read error can only end the connection.
            if (!m_file.read_at(m_chunk.data(), size, m_position)) return;
            m_position += size;
            body.data = m_chunk.data();
            body.size = size;
            body.more = true;
        }
        m_stream.expires_after(options().timeout);
        http::async_write(m_stream, *m_serializer,
                          [self = shared_from_this()](beast::error_code ec, size_t) {
                              // need_buffer: the serializer took the chunk and wants the next.
                              if (ec == http::error::need_buffer) ec = {};
                              if (ec) return;
                              if (self->m_serializer->is_done()) return self->finish_file(ec);
                              self->write_file_chunk();
                          });
    }

    void finish_file(beast::error_code ec) {
        const bool close = !m_file_response->keep_alive();
        m_serializer.reset();
        m_file_response.reset();
        on_written(ec, close);
    }

    // Closing a socket with unread input makes the kernel send a reset, which can destroy the
    // response the client has not read yet (the 413 to an oversized header, say). So: stop
    // sending, drain what the client still sends for a short while, then close.
    void linger() {
        m_state = State::kLingering;
        beast::error_code ec;
        m_stream.socket().shutdown(tcp::socket::shutdown_send, ec);
        if (ec) return;
        m_stream.expires_after(
            std::min<std::chrono::milliseconds>(options().timeout, std::chrono::seconds(2)));
        drain(0);
    }
    void drain(size_t drained) {
        m_buffer.consume(m_buffer.size());
        m_stream.async_read_some(m_buffer.prepare(16384), [self = shared_from_this(), drained](
                                                              beast::error_code ec, size_t n) {
            // Stop at the end of the client's data, an error, or 1 MiB of it.
            if (ec || drained + n > (size_t(1) << 20)) return;
            self->drain(drained + n);
        });
    }

    beast::tcp_stream m_stream;
    beast::flat_buffer m_buffer;
    std::optional<http::request_parser<http::empty_body>> m_parser;
    Request m_request;
    std::string m_method_text;  // "GET /x" for error messages
    State m_state = State::kReading;
    bool m_head = false;
    bool m_handed_off = false;
    std::shared_ptr<void> m_response;  // the in-memory response being written
    // The file response being written.
    File m_file;
    uint64_t m_position = 0, m_end = 0;
    std::vector<char> m_chunk;
    std::optional<http::response<http::buffer_body>> m_file_response;
    std::optional<http::response_serializer<http::buffer_body>> m_serializer;
};

}  // namespace

// ---- the server --------------------------------------------------------------------------------

struct Server::Impl {
    // Declared before the io_context: handlers destroyed with it still reach Shared.
    Shared shared;
    net::io_context ioc;
    tcp::acceptor acceptor;
    net::steady_timer retry;
    std::optional<net::executor_work_guard<net::io_context::executor_type>> work;
    std::vector<std::thread> threads;
    std::mutex control;
    bool started = false, stopped = false;
    uint16_t port = 0;

    Impl(int concurrency)
        : ioc(concurrency), acceptor(net::make_strand(ioc)), retry(acceptor.get_executor()) {}

    void accept() {
        acceptor.async_accept(
            net::make_strand(ioc),
            [this](beast::error_code ec, tcp::socket socket) { on_accept(ec, std::move(socket)); });
    }

    void on_accept(beast::error_code ec, tcp::socket socket) {
        if (!acceptor.is_open() || shared.stopping.load()) return;
        if (ec) {
            // Out of file descriptors and the like: try again a little later instead of
            // spinning on the error.
            retry.expires_after(std::chrono::milliseconds(100));
            retry.async_wait([this](beast::error_code e) {
                if (!e && acceptor.is_open()) accept();
            });
            return;
        }
        const int cap = shared.options.max_connections;
        const bool counted = shared.served.load() < cap;
        // Beyond twice the cap even the 503 costs too much: the connection is just closed.
        if (counted || shared.rejecting.load() < cap) {
            auto session = std::make_shared<HttpSession>(std::move(socket), shared, counted);
            shared.remember(session);
            session->run();
        }
        accept();
    }

    void run_worker() {
        for (;;) {
            try {
                ioc.run();
                return;
            } catch (...) {
                // A handler threw (out of memory, say): its connection is gone with it; the
                // server keeps serving the others.
            }
        }
    }
};

Server::Server(Catalog catalog, ServerOptions options) {
    const int threads = options.threads > 0 ? options.threads
                                            : std::max(1, int(std::thread::hardware_concurrency()));
    check(options.max_connections > 0, "server: max_connections must be positive, not {}",
          options.max_connections);
    check(options.chunk_bytes > 0, "server: chunk_bytes must be positive");
    m_impl = std::make_unique<Impl>(threads);
    Shared& shared = m_impl->shared;
    shared.options = std::move(options);
    shared.options.threads = threads;
    shared.catalog = std::move(catalog);
    const ServerOptions& o = shared.options;

    std::string note;
    if (!o.web_root.empty()) {
        std::error_code ec;
        if (fs::exists(o.web_root, ec) && !fs::is_directory(o.web_root, ec))
            fail("{}: web root is not a folder", o.web_root.string());
        // A root that does not exist yet (a viewer not built so far) is served once it does.
        shared.web_root = fs::weakly_canonical(fs::absolute(o.web_root, ec), ec);
        if (ec) fail("{}: cannot resolve the web root: {}", o.web_root.string(), ec.message());
        note = fmt::format(
            "The web viewer is not built: {} has no index.html. Build the viewer, or start btf "
            "serve with --web DIR naming a viewer build. Meanwhile this page lists the materials.",
            shared.web_root.string());
    } else {
        note = "No web viewer folder is configured: this page lists the materials.";
    }
    shared.materials_json = dump_json(shared.catalog.to_json(true), 2);
    shared.builtin_page = index_page(shared.catalog, note, true);

    beast::error_code ec;
    const net::ip::address address = net::ip::make_address(o.bind, ec);
    if (ec) fail("bind address '{}' is not an IP address", o.bind);
    const tcp::endpoint endpoint(address, o.port);
    const std::string where = address.is_v6() ? fmt::format("[{}]:{}", o.bind, o.port)
                                              : fmt::format("{}:{}", o.bind, o.port);
    tcp::acceptor& acceptor = m_impl->acceptor;
    acceptor.open(endpoint.protocol(), ec);
    if (!ec) acceptor.set_option(net::socket_base::reuse_address(true), ec);
    if (!ec) acceptor.bind(endpoint, ec);
    if (!ec) acceptor.listen(net::socket_base::max_listen_connections, ec);
    if (ec) fail("{}: cannot listen: {}", where, ec.message());
    m_impl->port = acceptor.local_endpoint(ec).port();
    if (ec) fail("{}: cannot read the bound port: {}", where, ec.message());
}

Server::~Server() {
    stop();
}

uint16_t Server::port() const {
    return m_impl->port;
}

std::string Server::url() const {
    const std::string& bind = m_impl->shared.options.bind;
    const bool v6 = bind.find(':') != std::string::npos;
    return v6 ? fmt::format("http://[{}]:{}/", bind, port())
              : fmt::format("http://{}:{}/", bind, port());
}

const Catalog& Server::catalog() const {
    return m_impl->shared.catalog;
}
const ServerOptions& Server::options() const {
    return m_impl->shared.options;
}

int Server::connections() const {
    return m_impl->shared.served.load() + m_impl->shared.rejecting.load();
}

void Server::start() {
    std::lock_guard lock(m_impl->control);
    if (m_impl->started || m_impl->stopped) return;
    m_impl->started = true;
    m_impl->work.emplace(net::make_work_guard(m_impl->ioc));
    net::post(m_impl->acceptor.get_executor(), [impl = m_impl.get()] { impl->accept(); });
    for (int i = 0; i < m_impl->shared.options.threads; ++i)
        m_impl->threads.emplace_back([impl = m_impl.get()] { impl->run_worker(); });
}

void Server::stop() {
    std::lock_guard lock(m_impl->control);
    if (!m_impl->started || m_impl->stopped) {
        m_impl->stopped = true;
        return;
    }
    m_impl->stopped = true;
    Shared& shared = m_impl->shared;
    shared.stopping.store(true);
    net::post(m_impl->acceptor.get_executor(), [impl = m_impl.get()] {
        beast::error_code ec;
        impl->acceptor.close(ec);
        impl->retry.cancel();
    });
    for (const auto& session : shared.snapshot()) session->soft_stop();
    m_impl->work.reset();

    const auto wait_until = [&](std::chrono::steady_clock::time_point deadline) {
        std::unique_lock wait(shared.mutex);
        return shared.changed.wait_until(wait, deadline, [&] { return shared.sessions.empty(); });
    };
    const auto now = std::chrono::steady_clock::now();
    if (!wait_until(now + shared.options.shutdown_grace)) {
        for (const auto& session : shared.snapshot()) session->hard_stop();
        // Closed sockets end their operations at once; the io_context is stopped only if
        // something still holds on after that.
        if (!wait_until(std::chrono::steady_clock::now() + std::chrono::seconds(2)))
            m_impl->ioc.stop();
    }
    for (std::thread& t : m_impl->threads) t.join();
    m_impl->threads.clear();
}

}  // namespace btf::stream
