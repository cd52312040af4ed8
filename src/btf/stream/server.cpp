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

std::string lower(std::string_view text) {
    std::string out(text);
    std::transform(out.begin(), out.end(), out.begin(),
                   [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
    return out;
}

std::string_view content_type(const fs::path& path) {
    const std::string ext = lower(path.extension().string());
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

// True if canonical `path` lies inside canonical folder `root`.
bool inside(const fs::path& path, const fs::path& root) {
    auto p = path.begin();
    for (auto r = root.begin(); r != root.end(); ++r, ++p)
        if (p == path.end() || *p != *r) return false;
    return p != path.end();
}

// ---- request targets ---------------------------------------------------------------------------

struct DecodedTarget {
    http::status error = http::status::ok;
    std::string path;                   // decoded, starts with '/'
    std::vector<std::string> segments;  // its non-empty segments
};

int hex_digit(char c) {
    if (c >= '0' && c <= '9') return c - '0';
    if (c >= 'a' && c <= 'f') return c - 'a' + 10;
    if (c >= 'A' && c <= 'F') return c - 'A' + 10;
    return -1;
}

// Decodes the path of an origin-form target. Percent-escapes are decoded before the checks, so
// %2e%2e is a dot segment and %2f a separator like '/'. Dot segments, names starting with '.'
// (hidden files, temporary folders), backslashes and NUL are refused as not found: nothing
// outside the roots, and nothing hidden inside them, exists as far as a client can tell.
DecodedTarget decode_target(std::string_view target) {
    DecodedTarget out;
    if (target.empty() || target[0] != '/') {
        out.error = http::status::bad_request;
        return out;
    }
    target = target.substr(0, target.find_first_of("?#"));
    for (size_t i = 0; i < target.size(); ++i) {
        if (target[i] != '%') {
            out.path += target[i];
            continue;
        }
        const int hi = i + 2 < target.size() ? hex_digit(target[i + 1]) : -1;
        const int lo = i + 2 < target.size() ? hex_digit(target[i + 2]) : -1;
        if (hi < 0 || lo < 0) {
            out.error = http::status::bad_request;
            return out;
        }
        out.path += static_cast<char>(hi * 16 + lo);
        i += 2;
    }
    if (out.path.find('\0') != std::string::npos || out.path.find('\\') != std::string::npos) {
        out.error = http::status::not_found;
        return out;
    }
    size_t start = 1;
    while (start <= out.path.size()) {
        size_t end = out.path.find('/', start);
        if (end == std::string::npos) end = out.path.size();
        std::string segment = out.path.substr(start, end - start);
        if (!segment.empty()) {
            if (segment[0] == '.') {
                out.error = http::status::not_found;
                return out;
            }
            out.segments.push_back(std::move(segment));
        }
        start = end + 1;
    }
    return out;
}

// Parses a Range header of one range: "bytes=a-b", "bytes=a-" or "bytes=-n". Returns the
// inclusive [first, last] clamped to the file, or nothing when the header is malformed, asks for
// several ranges or cannot be satisfied (all answered 416 by the protocol).
std::optional<std::pair<uint64_t, uint64_t>> parse_range(std::string_view value, uint64_t size) {
    const auto trim = [](std::string_view s) {
        while (!s.empty() && (s.front() == ' ' || s.front() == '\t')) s.remove_prefix(1);
        while (!s.empty() && (s.back() == ' ' || s.back() == '\t')) s.remove_suffix(1);
        return s;
    };
    const auto number = [](std::string_view s) -> std::optional<uint64_t> {
        if (s.empty() || s.size() > 18) return std::nullopt;
        uint64_t n = 0;
        for (const char c : s) {
            if (c < '0' || c > '9') return std::nullopt;
            n = n * 10 + uint64_t(c - '0');
        }
        return n;
    };
    value = trim(value);
    if (value.substr(0, 6) != "bytes=") return std::nullopt;
    value = trim(value.substr(6));
    const size_t dash = value.find('-');
    if (dash == std::string_view::npos || value.find(',') != std::string_view::npos)
        return std::nullopt;
    const std::string_view a = trim(value.substr(0, dash)), b = trim(value.substr(dash + 1));
    if (size == 0) return std::nullopt;
    if (a.empty()) {
        const auto n = number(b);
        if (!n || *n == 0) return std::nullopt;
        return std::pair{size - std::min(*n, size), size - 1};
    }
    const auto first = number(a);
    if (!first || *first >= size) return std::nullopt;
    if (b.empty()) return std::pair{*first, size - 1};
    const auto last = number(b);
    if (!last || *last < *first) return std::nullopt;
    return std::pair{*first, std::min(*last, size - 1)};
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

// Streams one package over an upgraded connection: begin message, the file in binary messages
// that end at every section boundary, end message, close 1000. One write at a time; the next
// chunk is read from disk only when the socket has taken the previous one.
class WebSocketSession : public Session, public std::enable_shared_from_this<WebSocketSession> {
  public:
    WebSocketSession(beast::tcp_stream&& stream, Shared& shared, const CatalogEntry& entry,
                     File file)
        : Session(shared, true), m_ws(std::move(stream)), m_entry(entry), m_file(std::move(file)) {
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
    // and pings are answered. A message above the limit fails the read, and Beast closes the
    // connection with 1009.
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
        // layer has closed it, after a failed read Beast is sending its close frame (1009) and
        // draining the client, and a dead peer fails the pending read too.
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

    websocket::stream<beast::tcp_stream> m_ws;
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
        if (target.error == http::status::bad_request)
            return send_error(target.error, "malformed request target", true);
        if (target.error != http::status::ok) return send_error(target.error, "not found");
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
            if (!websocket::is_upgrade(m_request))
                return send_error(http::status::bad_request,
                                  "a WebSocket endpoint: send a GET with Upgrade: websocket");
            File file = open_package(*entry);
            if (!file.is_open()) return;
            auto session = std::make_shared<WebSocketSession>(std::move(m_stream), m_shared, *entry,
                                                              std::move(file));
            m_handed_off = true;
            m_shared.remember(session);
            session->run(std::move(m_request));
            return;
        }
        send_static(target.segments);
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

    // A file in chunks of chunk_bytes, each read when the socket has taken the one before; a
    // Range header selects one range (206) or is refused (416).
    void send_file(File file, std::string_view type) {
        const uint64_t size = file.size();
        uint64_t first = 0, end = size;
        http::status status = http::status::ok;
        const auto range_field = m_request.find(http::field::range);
        if (range_field != m_request.end()) {
            const auto range = parse_range(std_view(range_field->value()), size);
            if (!range)
                return send_error(
                    http::status::range_not_satisfiable,
                    fmt::format("range '{}' is not one satisfiable byte range of the {} bytes",
                                std_view(range_field->value()), size),
                    false, [size](http::fields& f) {
                        f.set(http::field::content_range, fmt::format("bytes */{}", size));
                    });
            first = range->first;
            end = range->second + 1;
            status = http::status::partial_content;
        }
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
