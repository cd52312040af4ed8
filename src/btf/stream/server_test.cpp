// SPDX-License-Identifier: MIT
// The streaming server against a real Beast client on loopback: the protocol's endpoints, byte
// ranges, the WebSocket stream's message boundaries, refusals of unsafe or malformed requests,
// limits, concurrency and shutdown.

#include "btf/stream/server.h"

#include <gtest/gtest.h>
#include <unistd.h>

#include <array>
#include <boost/asio/connect.hpp>
#include <boost/asio/ip/tcp.hpp>
#include <boost/beast/core.hpp>
#include <boost/beast/http.hpp>
#include <boost/beast/websocket.hpp>
#include <chrono>
#include <deque>
#include <filesystem>
#include <fstream>
#include <limits>
#include <nlohmann/json.hpp>
#include <optional>
#include <thread>

#include "btf/codecs/codec.h"
#include "btf/io/package.h"
#include "btf/stream/catalog.h"
#include "btf/synth/synth.h"
#include "btf/testing/support.h"

namespace btf::stream {
namespace {

namespace fs = std::filesystem;
namespace beast = boost::beast;
namespace http = beast::http;
namespace websocket = beast::websocket;
namespace net = boost::asio;
using tcp = net::ip::tcp;
using json = nlohmann::json;
using Clock = std::chrono::steady_clock;

using test::read_file;
using test::write_file;

std::string str(beast::string_view s) {
    return std::string(s.data(), s.size());
}

// woven_fabric at 8² texels under ubo81, fmf with 4 components in float32 stored raw: its
// component sections (about 79 KB) are longer than a WebSocket message, so messages end both
// inside sections and at their ends.
void make_fabric(const fs::path& path) {
    const DirectionSet& set = DirectionSet::ubo81();
    const auto source = synth::make("woven_fabric", 8, Sampling{set, set}, 1);
    Package package =
        find_codec("fmf").encode(*source, Params{{"components", "4"}, {"quantize", "f32"}});
    PackageWriteOptions options;
    options.zstd_level = 0;
    write_package(path, package, options);
}

// A package of one large raw section: streams that outlast socket buffers, for the shutdown and
// message-limit tests.
void make_big(const fs::path& path, size_t bytes) {
    Package package;
    package.header = {{"codec", "test"},
                      {"width", 4},
                      {"height", 4},
                      {"views", {{"theta", {0.0}}, {"phi", {0.0}}}},
                      {"lights", {{"theta", {0.0}}, {"phi", {0.0}}}}};
    PackageSection section;
    section.name = "payload";
    section.data.resize(bytes);
    for (size_t i = 0; i < bytes; ++i) section.data[i] = uint8_t((i * 2654435761u) >> 13);
    package.sections.push_back(std::move(section));
    PackageWriteOptions options;
    options.zstd_level = 0;
    write_package(path, package, options);
}

// ---- a small synchronous client ----------------------------------------------------------------

tcp::endpoint local(uint16_t port) {
    return {net::ip::make_address("127.0.0.1"), port};
}

using Response = http::response<http::string_body>;

Response read_response(tcp::socket& socket, beast::flat_buffer& buffer, bool head = false) {
    http::response_parser<http::string_body> parser;
    // Not boost::none: Beast 1.74's response parser compares a Content-Length with the empty
    // optional and may report body_limit.
    parser.body_limit(std::numeric_limits<uint64_t>::max());
    parser.skip(head);
    http::read(socket, buffer, parser);
    return parser.release();
}

Response request(uint16_t port, http::verb method, const std::string& target,
                 const std::vector<std::pair<http::field, std::string>>& fields = {}) {
    net::io_context ioc;
    tcp::socket socket(ioc);
    socket.connect(local(port));
    http::request<http::empty_body> req(method, target, 11);
    req.set(http::field::host, "127.0.0.1");
    // insert, not set: a field given twice is sent twice.
    for (const auto& [field, value] : fields) req.insert(field, value);
    http::write(socket, req);
    beast::flat_buffer buffer;
    return read_response(socket, buffer, method == http::verb::head);
}

Response get(uint16_t port, const std::string& target,
             const std::vector<std::pair<http::field, std::string>>& fields = {}) {
    return request(port, http::verb::get, target, fields);
}

// Sends raw bytes and reads one response.
Response raw(uint16_t port, const std::string& bytes) {
    net::io_context ioc;
    tcp::socket socket(ioc);
    socket.connect(local(port));
    net::write(socket, net::buffer(bytes));
    beast::flat_buffer buffer;
    return read_response(socket, buffer);
}

std::string error_text(const Response& res) {
    EXPECT_EQ(str(res[http::field::content_type]), "application/json");
    return json::parse(res.body()).at("error").get<std::string>();
}

struct Streamed {
    json begin, end;
    std::vector<std::string> messages;  // binary messages in order
    std::string bytes;                  // their concatenation
    int close_code = -1;
};

Streamed stream(uint16_t port, const std::string& id) {
    net::io_context ioc;
    websocket::stream<tcp::socket> ws(ioc);
    ws.next_layer().connect(local(port));
    ws.handshake("127.0.0.1", "/stream/" + id);
    Streamed out;
    for (;;) {
        beast::flat_buffer buffer;
        beast::error_code ec;
        ws.read(buffer, ec);
        if (ec == websocket::error::closed) {
            out.close_code = ws.reason().code;
            break;
        }
        if (ec) throw beast::system_error(ec);
        std::string message = beast::buffers_to_string(buffer.data());
        if (ws.got_text()) {
            (out.begin.is_null() ? out.begin : out.end) = json::parse(message);
        } else {
            EXPECT_TRUE(out.end.is_null()) << "binary message after the end message";
            out.bytes += message;
            out.messages.push_back(std::move(message));
        }
    }
    return out;
}

// ---- a raw WebSocket client --------------------------------------------------------------------

// How long a client waits for the server before it reports a hang: a guard against a test that
// never ends, never a measure of how fast the server is.
constexpr auto kHangGuard = std::chrono::seconds(60);

// Polls `condition` until it holds; false if it still does not after the hang guard.
template <typename Condition>
bool wait_for(Condition condition) {
    for (const auto deadline = Clock::now() + kHangGuard; !condition();) {
        if (Clock::now() > deadline) return false;
        std::this_thread::sleep_for(std::chrono::milliseconds(5));
    }
    return true;
}

// One WebSocket frame as a client sends it (RFC 6455 §5.2), built byte by byte so that a test
// can send what a client library refuses to: any opcode, RSV bits, no mask, any length field.
struct Frame {
    uint8_t opcode = 0x2;  // binary
    bool fin = true;
    uint8_t rsv = 0;  // RSV1, RSV2, RSV3 as the bits 4, 2, 1
    bool masked = true;
    std::optional<uint64_t> length{};  // the length field; payload.size() when not given
    std::string payload{};             // the bytes after the header (masked when `masked`)
};

std::string encode(const Frame& f) {
    std::string out;
    out += char((f.fin ? 0x80 : 0) | (f.rsv & 7) << 4 | (f.opcode & 0x0f));
    const uint64_t length = f.length.value_or(f.payload.size());
    const int mask_bit = f.masked ? 0x80 : 0;
    int bytes = 0;  // of the extended length
    if (length < 126) {
        out += char(mask_bit | int(length));
    } else if (length < 65536) {
        out += char(mask_bit | 126);
        bytes = 2;
    } else {
        out += char(mask_bit | 127);
        bytes = 8;
    }
    for (int i = bytes - 1; i >= 0; --i) out += char(length >> (8 * i));
    const uint8_t key[4] = {0x37, 0xfa, 0x21, 0x3d};
    if (f.masked) out.append(reinterpret_cast<const char*>(key), 4);
    for (size_t i = 0; i < f.payload.size(); ++i)
        out += char(f.payload[i] ^ (f.masked ? key[i % 4] : 0));
    return out;
}

// The upgrade request's fields, as lines; tests change, drop or repeat some.
std::vector<std::string> upgrade_fields() {
    return {"Host: 127.0.0.1", "Connection: Upgrade", "Upgrade: websocket",
            "Sec-WebSocket-Key: dGhlIHNhbXBsZSBub25jZQ==", "Sec-WebSocket-Version: 13"};
}

// `fields` with the line of field `name` replaced by `name: value`, or dropped when value is
// nothing.
std::vector<std::string> with(std::vector<std::string> fields, const std::string& name,
                              std::optional<std::string> value) {
    const auto it = std::find_if(fields.begin(), fields.end(), [&](const std::string& line) {
        return line.starts_with(name + ":");
    });
    if (it == fields.end()) {
        ADD_FAILURE() << "no field " << name;
        return fields;
    }
    if (value)
        *it = name + ": " + *value;
    else
        fields.erase(it);
    return fields;
}

// What a client saw of the end of a WebSocket stream.
struct Ending {
    int close_code = -1;       // the status code of the server's close frame; -1: none came
    uint64_t data_bytes = 0;   // payload bytes of the binary frames before it
    bool then_closed = false;  // the server then ended the TCP connection (end of stream)
    std::string error;         // why the connection ended otherwise (a reset, say)
};

// A WebSocket client on a plain socket: the upgrade request written by hand, frames built by
// encode(), the server's frames parsed here. What it sends goes out while it reads (the server
// stops reading a client that broke the protocol, and streams on until then: a client that only
// wrote would wait for a server waiting for it to read). Reads have the hang guard.
class RawClient {
  public:
    explicit RawClient(uint16_t port) : m_socket(m_ioc) { m_socket.connect(local(port)); }
    ~RawClient() {
        beast::error_code ec;
        m_socket.close(ec);  // cancels what is still queued; its handlers never run
    }

    // Sends a GET of `target` with these field lines, and `after` in the same write, and reads
    // the response header.
    http::response<http::empty_body> upgrade(const std::string& target,
                                             const std::vector<std::string>& fields,
                                             const std::string& after = "") {
        std::string request = "GET " + target + " HTTP/1.1\r\n";
        for (const std::string& line : fields) request += line + "\r\n";
        send(request + "\r\n" + after);
        size_t end;
        while ((end = m_in.find("\r\n\r\n")) == std::string::npos)
            if (!read_more()) return http::response<http::empty_body>{};
        http::response_parser<http::empty_body> parser;
        beast::error_code ec;
        parser.put(net::buffer(m_in.data(), end + 4), ec);
        EXPECT_FALSE(ec) << ec.message();
        EXPECT_TRUE(parser.is_header_done());
        m_in.erase(0, end + 4);
        return parser.release();
    }

    // Queues bytes to send after those queued before.
    void send(std::string bytes) {
        m_out.push_back(std::move(bytes));
        if (m_out.size() == 1) write_next();
    }

    // Reads the server's frames up to its close frame, answers it with a close frame as RFC 6455
    // §5.5.1 asks, and reads on to the end of the connection.
    Ending read_to_close() {
        Ending out;
        for (;;) {
            const auto frame = read_frame(out.error);
            if (!frame) return out;
            if (frame->first == 0x2) out.data_bytes += frame->second.size();
            if (frame->first != 0x8) continue;
            const std::string& body = frame->second;
            out.close_code = body.size() >= 2 ? uint8_t(body[0]) << 8 | uint8_t(body[1]) : 1005;
            break;
        }
        send(encode(Frame{.opcode = 0x8, .payload = "\x03\xe8"}));
        while (read_more()) m_in.clear();
        out.then_closed = m_error == net::error::eof;
        if (!out.then_closed) out.error = "after the close frame: " + m_error.message();
        beast::error_code ec;
        m_socket.shutdown(tcp::socket::shutdown_send, ec);
        return out;
    }

  private:
    void write_next() {
        net::async_write(m_socket, net::buffer(m_out.front()),
                         [this](beast::error_code ec, size_t) {
                             m_out.pop_front();
                             if (ec) m_out.clear();  // the server closed first
                             if (!m_out.empty()) write_next();
                         });
    }

    // One server frame: opcode and payload; nothing when the connection ended first.
    std::optional<std::pair<int, std::string>> read_frame(std::string& error) {
        for (;;) {
            if (m_in.size() >= 2) {
                const uint8_t b0 = uint8_t(m_in[0]), b1 = uint8_t(m_in[1]);
                EXPECT_EQ(b1 & 0x80, 0) << "a masked frame from the server";
                const size_t header = (b1 & 0x7f) == 127 ? 10 : (b1 & 0x7f) == 126 ? 4 : 2;
                if (m_in.size() >= header) {
                    uint64_t length = b1 & 0x7f;
                    if (header > 2) {
                        length = 0;
                        for (size_t i = 2; i < header; ++i) length = length << 8 | uint8_t(m_in[i]);
                    }
                    if (m_in.size() - header >= length) {
                        std::pair<int, std::string> frame{b0 & 0x0f, m_in.substr(header, length)};
                        m_in.erase(0, header + length);
                        return frame;
                    }
                }
            }
            if (!read_more()) {
                error = "no close frame: " + m_error.message();
                return std::nullopt;
            }
        }
    }

    // Appends what the server sent next, sending meanwhile; false at the end of the connection
    // (m_error says how).
    bool read_more() {
        std::array<char, 65536> buffer;
        bool done = false;
        size_t n = 0;
        m_socket.async_read_some(net::buffer(buffer), [&](beast::error_code ec, size_t k) {
            m_error = ec, n = k, done = true;
        });
        m_ioc.restart();
        const auto deadline = Clock::now() + kHangGuard;
        while (!done && m_ioc.run_one_until(deadline)) {
        }
        if (!done) {
            ADD_FAILURE() << "the server sent nothing for " << kHangGuard.count() << " s";
            m_socket.close();
            while (!done) m_ioc.run_one();
            m_error = net::error::timed_out;
            return false;
        }
        m_in.append(buffer.data(), n);
        return !m_error;
    }

    net::io_context m_ioc;
    tcp::socket m_socket;
    std::string m_in;
    std::deque<std::string> m_out;  // to send, the first being sent
    beast::error_code m_error;
};

// ---- fixture: packages, a web root and a running server
// ------------------------------------------

class ServerTest : public testing::Test {
  protected:
    static void SetUpTestSuite() {
        s_dir = fs::path(testing::TempDir()) / ("btf_server_test_" + std::to_string(::getpid()));
        fs::remove_all(s_dir);
        fs::create_directories(s_dir / "packages");
        make_fabric(s_dir / "packages" / "fabric.btfpkg");
        make_big(s_dir / "packages" / "big.btfpkg", size_t(32) << 20);

        const fs::path web = s_dir / "web";
        fs::create_directories(web / "sub");
        write_file(web / "index.html", "<!doctype html><title>viewer</title>");
        write_file(web / "app.js", "console.log('viewer');");
        write_file(web / "style.css", "body { margin: 0 }");
        write_file(web / "sub" / "data.json", "{\"a\": 1}");
        write_file(web / ".hidden", "hidden");
        write_file(s_dir / "secret.txt", "outside the web root");
        fs::create_symlink(s_dir / "secret.txt", web / "escape.txt");
        fs::create_symlink(web / "app.js", web / "alias.js");

        s_server = new Server(Catalog::build({s_dir / "packages"}), options());
        s_server->start();
    }
    static void TearDownTestSuite() {
        delete s_server;
        s_server = nullptr;
        fs::remove_all(s_dir);
    }

    static ServerOptions options() {
        ServerOptions o;
        o.port = 0;
        o.threads = 2;
        o.web_root = s_dir / "web";
        return o;
    }
    static uint16_t port() { return s_server->port(); }
    static fs::path package(const std::string& name) {
        return s_dir / "packages" / (name + ".btfpkg");
    }

    // Sends `bytes` on a stream of the 32 MiB package and expects what RFC 6455 §7.1.7 asks of a
    // failed connection: the server's close frame with `code` (after the message it is writing),
    // then the end of the TCP connection, the rest of the stream not sent. Three times: the bytes
    // after the 101; sent with the upgrade request, before its answer; and followed by 256 KiB
    // more (a long payload: more than the server reads before it gives up).
    static void expect_failure(const std::string& bytes, int code) {
        for (const int delivery : {0, 1, 2}) {
            SCOPED_TRACE(delivery == 0   ? "sent after the 101"
                         : delivery == 1 ? "sent with the upgrade request"
                                         : "followed by 256 KiB");
            RawClient client(port());
            const auto res = client.upgrade("/stream/big", upgrade_fields(),
                                            delivery == 1 ? bytes : std::string());
            ASSERT_EQ(res.result_int(), 101);
            if (delivery == 0) client.send(bytes);
            if (delivery == 2) client.send(bytes + std::string(256 << 10, 'z'));
            const Ending end = client.read_to_close();
            EXPECT_EQ(end.close_code, code) << end.error;
            EXPECT_TRUE(end.then_closed) << end.error;
            EXPECT_LT(end.data_bytes, fs::file_size(package("big")));
        }
    }

    static fs::path s_dir;
    static Server* s_server;
};
fs::path ServerTest::s_dir;
Server* ServerTest::s_server = nullptr;

TEST_F(ServerTest, ListsMaterials) {
    const Response res = get(port(), "/api/materials");
    ASSERT_EQ(res.result(), http::status::ok);
    EXPECT_EQ(str(res[http::field::content_type]), "application/json");
    const json list = json::parse(res.body());
    EXPECT_EQ(list.at("protocol"), 1);
    ASSERT_EQ(list.at("materials").size(), 2u);
    // Folder contents are listed by file name.
    EXPECT_EQ(list["materials"][0].at("id"), "big");
    const json& m = list["materials"][1];
    EXPECT_EQ(m.at("id"), "fabric");
    EXPECT_EQ(m.at("name"), "fabric");
    EXPECT_EQ(m.at("codec"), "fmf");
    EXPECT_EQ(m.at("width"), 8);
    EXPECT_EQ(m.at("height"), 8);
    EXPECT_EQ(m.at("views"), 81);
    EXPECT_EQ(m.at("lights"), 81);
    EXPECT_EQ(m.at("package"), "materials/fabric.btfpkg");
    EXPECT_EQ(m.at("stream"), "stream/fabric");

    const std::string file = read_file(package("fabric"));
    EXPECT_EQ(m.at("bytes").get<uint64_t>(), file.size());
    uint32_t header_length;
    std::memcpy(&header_length, file.data() + 12, 4);
    EXPECT_EQ(m.at("header_bytes").get<uint64_t>(), 24u + header_length);
    const Package decoded = read_package(package("fabric"));
    const json& sections = m.at("sections");
    ASSERT_EQ(sections.size(), decoded.sections.size());
    uint64_t offset = m["header_bytes"];
    for (size_t i = 0; i < sections.size(); ++i) {
        EXPECT_EQ(sections[i].at("name"), decoded.sections[i].name);
        EXPECT_EQ(sections[i].at("offset").get<uint64_t>(), offset);
        EXPECT_EQ(sections[i].at("size").get<uint64_t>(), decoded.sections[i].stored_size);
        offset += sections[i]["size"].get<uint64_t>();
    }
    EXPECT_EQ(offset, file.size());
}

TEST_F(ServerTest, ServesWholePackage) {
    const Response res = get(port(), "/materials/fabric.btfpkg");
    ASSERT_EQ(res.result(), http::status::ok);
    EXPECT_EQ(str(res[http::field::content_type]), "application/octet-stream");
    EXPECT_EQ(str(res[http::field::accept_ranges]), "bytes");
    EXPECT_TRUE(res.body() == read_file(package("fabric")));
}

TEST_F(ServerTest, ServesByteRanges) {
    const std::string file = read_file(package("fabric"));
    const uint64_t n = file.size();
    const auto range = [&](const std::string& value) {
        return get(port(), "/materials/fabric.btfpkg", {{http::field::range, value}});
    };
    Response res = range("bytes=100-1099");
    ASSERT_EQ(res.result(), http::status::partial_content);
    EXPECT_EQ(str(res[http::field::content_range]), fmt::format("bytes 100-1099/{}", n));
    EXPECT_TRUE(res.body() == file.substr(100, 1000));

    res = range("bytes=-500");  // suffix
    ASSERT_EQ(res.result(), http::status::partial_content);
    EXPECT_EQ(str(res[http::field::content_range]),
              fmt::format("bytes {}-{}/{}", n - 500, n - 1, n));
    EXPECT_TRUE(res.body() == file.substr(n - 500));

    res = range("bytes=70000-");  // open-ended, across chunk boundaries
    ASSERT_EQ(res.result(), http::status::partial_content);
    EXPECT_TRUE(res.body() == file.substr(70000));

    res = range(fmt::format("bytes={}-{}", n - 10, n + 1000));  // end clamped to the file
    ASSERT_EQ(res.result(), http::status::partial_content);
    EXPECT_TRUE(res.body() == file.substr(n - 10));

    res = range("BYTES=5-9,");  // the unit in any case; empty list elements do not count
    ASSERT_EQ(res.result(), http::status::partial_content);
    EXPECT_EQ(str(res[http::field::content_range]), fmt::format("bytes 5-9/{}", n));

    for (const std::string& bad : {fmt::format("bytes={}-", n), std::string("bytes=-0")}) {
        res = range(bad);
        EXPECT_EQ(res.result(), http::status::range_not_satisfiable) << bad;
        EXPECT_EQ(str(res[http::field::content_range]), fmt::format("bytes */{}", n)) << bad;
        EXPECT_NE(error_text(res).find("GET /materials/fabric.btfpkg: range"), std::string::npos);
    }
}

TEST_F(ServerTest, RangeNumbersOfAnyLengthAreClampedOrUnsatisfiable) {
    const std::string file = read_file(package("fabric"));
    const uint64_t n = file.size();
    const auto range = [&](const std::string& value) {
        return get(port(), "/materials/fabric.btfpkg", {{http::field::range, value}});
    };
    // A last position or a suffix beyond the file, however long its number, is clamped.
    for (const char* whole :
         {"bytes=0-99999999999", "bytes=0-18446744073709551615", "bytes=0-18446744073709551616",
          "bytes=0-99999999999999999999999999999999", "bytes=-18446744073709551615",
          "bytes=-99999999999999999999999999999999"}) {
        const Response res = range(whole);
        ASSERT_EQ(res.result(), http::status::partial_content) << whole;
        EXPECT_EQ(str(res[http::field::content_range]), fmt::format("bytes 0-{}/{}", n - 1, n))
            << whole;
        EXPECT_TRUE(res.body() == file) << whole;
    }
    const Response tail = range("bytes=100-18446744073709551615");
    ASSERT_EQ(tail.result(), http::status::partial_content);
    EXPECT_TRUE(tail.body() == file.substr(100));
    // A first position beyond the file, however long its number, cannot be satisfied.
    for (const char* beyond :
         {"bytes=18446744073709551615-", "bytes=18446744073709551616-",
          "bytes=99999999999999999999999999999999-99999999999999999999999999999999"}) {
        const Response res = range(beyond);
        EXPECT_EQ(res.result(), http::status::range_not_satisfiable) << beyond;
        EXPECT_EQ(str(res[http::field::content_range]), fmt::format("bytes */{}", n)) << beyond;
    }
}

TEST_F(ServerTest, RangeFieldsThatAreNotOneByteRangeAreIgnored) {
    const std::string file = read_file(package("fabric"));
    const std::string target = "/materials/fabric.btfpkg";
    const auto expect_whole = [&](const Response& res, const std::string& what) {
        EXPECT_EQ(res.result(), http::status::ok) << what;
        EXPECT_EQ(res.count(http::field::content_range), 0u) << what;
        EXPECT_TRUE(res.body() == file) << what;
    };
    // Two Range fields: which one the client meant is unknown.
    expect_whole(get(port(), target,
                     {{http::field::range, "bytes=0-9"}, {http::field::range, "bytes=20-29"}}),
                 "two Range fields");
    for (const char* value : {"bytes=0-1,5-6", "bytes=0-9, 0-9", "lines=1-2", "bytes=500-100",
                              "bytes=x-", "bytes=", "bytes=1-2-3", "bytes 0-9"})
        expect_whole(get(port(), target, {{http::field::range, value}}), value);
    // Range is defined for GET only, and If-Range names a validator the server does not send.
    const Response head =
        request(port(), http::verb::head, target, {{http::field::range, "bytes=0-9"}});
    EXPECT_EQ(head.result(), http::status::ok);
    EXPECT_EQ(str(head[http::field::content_length]), std::to_string(file.size()));
    expect_whole(
        get(port(), target, {{http::field::range, "bytes=0-9"}, {http::field::if_range, "\"x\""}}),
        "If-Range");
}

TEST_F(ServerTest, HeadAnswersHeadersOnlyAndKeepsTheConnection) {
    const uint64_t n = fs::file_size(package("fabric"));
    net::io_context ioc;
    tcp::socket socket(ioc);
    socket.connect(local(port()));
    beast::flat_buffer buffer;
    // HEAD then GET on one connection: a body sent for the HEAD would be read as the second
    // response's start.
    for (const http::verb method : {http::verb::head, http::verb::get, http::verb::head}) {
        http::request<http::empty_body> req(method, "/materials/fabric.btfpkg", 11);
        req.set(http::field::host, "x");
        http::write(socket, req);
        const Response res = read_response(socket, buffer, method == http::verb::head);
        ASSERT_EQ(res.result(), http::status::ok);
        EXPECT_EQ(str(res[http::field::content_length]), std::to_string(n));
        EXPECT_EQ(res.body().size(), method == http::verb::head ? 0u : n);
        EXPECT_TRUE(res.keep_alive());
    }
    const Response head = request(port(), http::verb::head, "/api/materials");
    EXPECT_EQ(head.result(), http::status::ok);
    EXPECT_GT(std::stoul(str(head[http::field::content_length])), 100u);
}

TEST_F(ServerTest, StreamsPackageOverWebSocket) {
    const std::string file = read_file(package("fabric"));
    const json entry = json::parse(get(port(), "/api/materials").body())["materials"][1];
    const Streamed s = stream(port(), "fabric");

    EXPECT_EQ(s.begin.at("type"), "begin");
    EXPECT_EQ(s.begin.at("id"), "fabric");
    EXPECT_EQ(s.begin.at("bytes"), entry.at("bytes"));
    EXPECT_EQ(s.begin.at("sections"), entry.at("sections"));
    EXPECT_EQ(s.end, json({{"type", "end"}}));
    EXPECT_EQ(s.close_code, 1000);
    ASSERT_EQ(s.bytes.size(), file.size());
    EXPECT_TRUE(s.bytes == file);

    // Message boundaries: at most 64 KiB, and every section boundary (the header's end included)
    // is a message boundary.
    std::vector<uint64_t> starts;
    uint64_t offset = 0;
    for (const std::string& m : s.messages) {
        EXPECT_GT(m.size(), 0u);
        EXPECT_LE(m.size(), 65536u);
        starts.push_back(offset);
        offset += m.size();
    }
    starts.push_back(offset);
    const auto is_start = [&](uint64_t b) {
        return std::find(starts.begin(), starts.end(), b) != starts.end();
    };
    EXPECT_TRUE(is_start(entry["header_bytes"].get<uint64_t>()));
    bool split_inside_a_section = false;
    for (const json& section : entry["sections"]) {
        const uint64_t begin = section["offset"], end = begin + section["size"].get<uint64_t>();
        EXPECT_TRUE(is_start(begin)) << section;
        EXPECT_TRUE(is_start(end)) << section;
        for (const uint64_t b : starts) split_inside_a_section |= b > begin && b < end;
    }
    EXPECT_TRUE(split_inside_a_section) << "the fixture should have sections above 64 KiB";
}

TEST_F(ServerTest, UnknownMaterialIsNotFoundBeforeTheUpgrade) {
    // The upgrade request by hand: Beast's client drops the response of a failed handshake.
    {
        net::io_context ioc;
        tcp::socket socket(ioc);
        socket.connect(local(port()));
        http::request<http::empty_body> req(http::verb::get, "/stream/no-such-material", 11);
        req.set(http::field::host, "127.0.0.1");
        req.set(http::field::connection, "Upgrade");
        req.set(http::field::upgrade, "websocket");
        req.set(http::field::sec_websocket_key, "dGhlIHNhbXBsZSBub25jZQ==");
        req.set(http::field::sec_websocket_version, "13");
        http::write(socket, req);
        beast::flat_buffer buffer;
        const Response res = read_response(socket, buffer);
        EXPECT_EQ(res.result(), http::status::not_found);
        EXPECT_EQ(error_text(res), "GET /stream/no-such-material: no such material");
    }
    net::io_context ioc;
    websocket::stream<tcp::socket> ws(ioc);
    ws.next_layer().connect(local(port()));
    beast::error_code ec;
    ws.handshake("127.0.0.1", "/stream/no-such-material", ec);
    EXPECT_TRUE(ec);

    Response r = get(port(), "/materials/no-such-material.btfpkg");
    EXPECT_EQ(r.result(), http::status::not_found);
    EXPECT_EQ(error_text(r), "GET /materials/no-such-material.btfpkg: no such material");
    // The stream endpoint without an upgrade.
    r = get(port(), "/stream/fabric");
    EXPECT_EQ(r.result(), http::status::bad_request);
    EXPECT_NE(error_text(r).find("WebSocket"), std::string::npos);
}

TEST_F(ServerTest, ServesTheWebRoot) {
    Response res = get(port(), "/");
    ASSERT_EQ(res.result(), http::status::ok);
    EXPECT_EQ(res.body(), "<!doctype html><title>viewer</title>");
    EXPECT_EQ(str(res[http::field::content_type]), "text/html; charset=utf-8");
    res = get(port(), "/app.js?v=3");
    ASSERT_EQ(res.result(), http::status::ok);
    EXPECT_EQ(str(res[http::field::content_type]), "text/javascript; charset=utf-8");
    res = get(port(), "/style.css");
    EXPECT_EQ(str(res[http::field::content_type]), "text/css; charset=utf-8");
    res = get(port(), "/sub/data.json");
    ASSERT_EQ(res.result(), http::status::ok);
    EXPECT_EQ(str(res[http::field::content_type]), "application/json");
    EXPECT_EQ(res.body(), "{\"a\": 1}");
    // A symbolic link that stays inside the root is followed.
    res = get(port(), "/alias.js");
    EXPECT_EQ(res.result(), http::status::ok);
    EXPECT_EQ(res.body(), "console.log('viewer');");
    EXPECT_EQ(get(port(), "/missing.js").result(), http::status::not_found);
    EXPECT_EQ(get(port(), "/sub").result(), http::status::not_found);
}

TEST_F(ServerTest, RefusesPathsOutsideTheRoots) {
    for (const char* target :
         {"/../secret.txt", "/sub/../../secret.txt", "/%2e%2e/secret.txt", "/%2E%2E/secret.txt",
          "/..%2fsecret.txt", "/%2e%2e%2fsecret.txt", "/sub%2f..%2f..%2fsecret.txt",
          "/sub/..%5c..%5csecret.txt", "/..\\secret.txt", "/app.js%00.png", "/escape.txt",
          "/.hidden", "/sub/./data.json", "/materials/../fabric.btfpkg",
          "/materials/%2e%2e%2fpackages%2ffabric.btfpkg", "/stream/..%2ffabric"}) {
        const Response res = get(port(), target);
        EXPECT_EQ(res.result(), http::status::not_found) << target;
        EXPECT_EQ(res.body().find("outside the web root"), std::string::npos) << target;
    }
    // Malformed escapes are malformed requests.
    EXPECT_EQ(get(port(), "/app.js%zz").result(), http::status::bad_request);
    EXPECT_EQ(get(port(), "/app.js%2").result(), http::status::bad_request);
}

TEST_F(ServerTest, AnswersBadRequestsAndKeepsRunning) {
    Response res = raw(port(), "GARBAGE\r\n\r\n");
    EXPECT_EQ(res.result(), http::status::bad_request);
    EXPECT_NE(error_text(res).find("malformed request"), std::string::npos);

    res = raw(port(),
              "GET / HTTP/1.1\r\nHost: x\r\nX-Filler: " + std::string(10000, 'a') + "\r\n\r\n");
    EXPECT_EQ(res.result(), http::status::payload_too_large);
    EXPECT_NE(error_text(res).find("request header exceeds 8192 bytes"), std::string::npos);

    res = raw(port(), "GET / HTTP/1.1\r\nHost: x\r\nContent-Length: 5\r\n\r\nhello");
    EXPECT_EQ(res.result(), http::status::payload_too_large);

    res = raw(port(), "POST /api/materials HTTP/1.1\r\nHost: x\r\nContent-Length: 2\r\n\r\n{}");
    EXPECT_EQ(res.result(), http::status::method_not_allowed);
    EXPECT_EQ(str(res[http::field::allow]), "GET, HEAD");
    EXPECT_EQ(error_text(res), "POST /api/materials: method not allowed (GET and HEAD only)");

    res = raw(port(), "GET relative HTTP/1.1\r\nHost: x\r\n\r\n");
    EXPECT_EQ(res.result(), http::status::bad_request);

    // A client that sends half a request and goes away.
    {
        net::io_context ioc;
        tcp::socket socket(ioc);
        socket.connect(local(port()));
        net::write(socket, net::buffer(std::string("GET /api/mat")));
    }
    EXPECT_EQ(get(port(), "/api/materials").result(), http::status::ok);
}

TEST_F(ServerTest, ClosesStreamWith1009OnOversizedClientMessage) {
    net::io_context ioc;
    websocket::stream<tcp::socket> ws(ioc);
    ws.next_layer().connect(local(port()));
    ws.handshake("127.0.0.1", "/stream/big");
    ws.binary(true);
    ws.write(net::buffer(std::string(5000, 'x')));
    // The server answers with a close frame after the message it is writing; read up to it.
    beast::error_code ec;
    uint64_t received = 0;
    for (;;) {
        beast::flat_buffer buffer;
        ws.read(buffer, ec);
        if (ec) break;
        received += buffer.size();
    }
    EXPECT_EQ(ec, websocket::error::closed) << ec.message();
    EXPECT_EQ(ws.reason().code, websocket::close_code::too_big);
    EXPECT_LT(received, fs::file_size(package("big")));

    // A small message is ignored.
    const std::string file = read_file(package("fabric"));
    websocket::stream<tcp::socket> ok(ioc);
    ok.next_layer().connect(local(port()));
    ok.handshake("127.0.0.1", "/stream/fabric");
    ok.text(true);
    ok.write(net::buffer(std::string("hello")));
    std::string bytes;
    for (;;) {
        beast::flat_buffer buffer;
        ok.read(buffer, ec);
        if (ec) break;
        if (!ok.got_text()) bytes += beast::buffers_to_string(buffer.data());
    }
    EXPECT_EQ(ok.reason().code, websocket::close_code::normal);
    EXPECT_TRUE(bytes == file);
}

TEST_F(ServerTest, RawClientReadsAWholeStream) {
    // The tests below rely on this client: a masked message within the limit is ignored and the
    // stream ends normally.
    const std::string file = read_file(package("fabric"));
    RawClient client(port());
    const auto res = client.upgrade("/stream/fabric", upgrade_fields());
    ASSERT_EQ(res.result_int(), 101);
    EXPECT_EQ(str(res[http::field::sec_websocket_accept]), "s3pPLMBiTxaQ9kYGzzhZRbK+xOo=");
    client.send(encode(Frame{.opcode = 0x1, .payload = "hello"}));
    const Ending end = client.read_to_close();
    EXPECT_EQ(end.close_code, 1000) << end.error;
    EXPECT_TRUE(end.then_closed) << end.error;
    EXPECT_EQ(end.data_bytes, file.size());
}

TEST_F(ServerTest, UnmaskedClientFrameFailsTheConnectionWith1002) {
    expect_failure(encode(Frame{.opcode = 0x2, .masked = false, .payload = "hello"}), 1002);
    expect_failure(encode(Frame{.opcode = 0x9, .masked = false, .payload = "ping"}), 1002);
}

TEST_F(ServerTest, ReservedOpcodeFailsTheConnectionWith1002) {
    for (const uint8_t opcode : {0x3, 0x4, 0x5, 0x6, 0x7, 0xb, 0xc, 0xd, 0xe, 0xf}) {
        SCOPED_TRACE(fmt::format("opcode {:#x}", opcode));
        expect_failure(encode(Frame{.opcode = opcode, .payload = "x"}), 1002);
    }
}

TEST_F(ServerTest, ReservedBitsFailTheConnectionWith1002) {
    // No extension is negotiated, so RSV1 (permessage-deflate's bit) is reserved too.
    for (const uint8_t rsv : {4, 2, 1, 7}) {
        SCOPED_TRACE(fmt::format("rsv {}", rsv));
        expect_failure(encode(Frame{.opcode = 0x2, .rsv = rsv, .payload = "x"}), 1002);
        expect_failure(encode(Frame{.opcode = 0x9, .rsv = rsv, .payload = "x"}), 1002);
    }
}

TEST_F(ServerTest, LengthWithTheTopBitSetFailsTheConnectionWith1002) {
    // RFC 6455 §5.2: the most significant bit of a 64-bit length must be 0. A frame declaring
    // 2^63 bytes or more is malformed, not merely too big.
    for (const uint64_t length : {uint64_t(1) << 63, ~uint64_t(0), (uint64_t(1) << 63) + 5}) {
        SCOPED_TRACE(fmt::format("length {}", length));
        expect_failure(encode(Frame{.opcode = 0x2, .length = length, .payload = "abcd"}), 1002);
        expect_failure(encode(Frame{.opcode = 0x0, .length = length}), 1002);
    }
}

TEST_F(ServerTest, MalformedFramesFailTheConnectionWith1002) {
    // A 16-bit length that would fit in 7 bits, a 64-bit one that would fit in 16.
    expect_failure(std::string("\x82\xfe\x00\x05", 4) + "keys" + "hello", 1002);
    expect_failure(std::string("\x82\xff\x00\x00\x00\x00\x00\x00\x01\x00", 10) + "keys", 1002);
    // A continuation with no message to continue; a new message inside a fragmented one.
    expect_failure(encode(Frame{.opcode = 0x0, .payload = "x"}), 1002);
    expect_failure(encode(Frame{.opcode = 0x2, .fin = false, .payload = "x"}) +
                       encode(Frame{.opcode = 0x2, .payload = "y"}),
                   1002);
    // Control frames: fragmented, longer than 125 bytes, a close frame with a 1-byte body.
    expect_failure(encode(Frame{.opcode = 0x9, .fin = false, .payload = "x"}), 1002);
    expect_failure(encode(Frame{.opcode = 0x9, .payload = std::string(126, 'x')}), 1002);
    expect_failure(encode(Frame{.opcode = 0x8, .payload = "x"}), 1002);
}

TEST_F(ServerTest, TextThatIsNotUtf8FailsTheConnectionWith1007) {
    expect_failure(encode(Frame{.opcode = 0x1, .payload = "caf\xc3"}), 1007);
}

TEST_F(ServerTest, OversizedClientMessageFailsTheConnectionWith1009) {
    // Larger than the socket buffers: the server stops reading it after its header.
    expect_failure(encode(Frame{.opcode = 0x2, .payload = std::string(256 << 10, 'x')}), 1009);
    // In fragments that are each within the limit.
    expect_failure(encode(Frame{.opcode = 0x2, .fin = false, .payload = std::string(3000, 'x')}) +
                       encode(Frame{.opcode = 0x0, .payload = std::string(3000, 'y')}),
                   1009);
    // A declared length alone, just below 2^63.
    expect_failure(encode(Frame{.opcode = 0x2, .length = (uint64_t(1) << 63) - 1}), 1009);
}

TEST_F(ServerTest, HandshakeNeedsABase64KeyOf16Bytes) {
    const auto status = [&](const std::vector<std::string>& fields) {
        RawClient client(port());
        return client.upgrade("/stream/fabric", fields).result_int();
    };
    EXPECT_EQ(status(upgrade_fields()), 101);
    EXPECT_EQ(status(with(upgrade_fields(), "Sec-WebSocket-Key", "MDEyMzQ1Njc4OWFiY2RlZg==")), 101);
    for (const char* key :
         {"", "not base64 at all!!!!!==", "dGhlIHNhbXBsZSBub25jZQ", "dGhlIHNhbXBsZSBub25jZQ=",
          "AAAAAAAAAAAAAAAAAAAA", "AAAAAAAAAAAAAAAAAAAAAAA=", "AAAAAAAAAAAAAAAAAAAAAAAA",
          "dGhlIHNhbXBsZSBub25jZR==", "dGhlIHNhbXBsZSBub25j ZQ==", "dGhlIHNhbXBsZSBub25jZQ==="})
        EXPECT_EQ(status(with(upgrade_fields(), "Sec-WebSocket-Key", key)), 400) << key;
    EXPECT_EQ(status(with(upgrade_fields(), "Sec-WebSocket-Key", std::nullopt)), 400);
    std::vector<std::string> twice = upgrade_fields();
    twice.push_back("Sec-WebSocket-Key: MDEyMzQ1Njc4OWFiY2RlZg==");
    EXPECT_EQ(status(twice), 400);

    const Response res = get(port(), "/stream/fabric",
                             {{http::field::connection, "Upgrade"},
                              {http::field::upgrade, "websocket"},
                              {http::field::sec_websocket_key, "c2hvcnQ="},
                              {http::field::sec_websocket_version, "13"}});
    EXPECT_EQ(res.result(), http::status::bad_request);
    EXPECT_EQ(error_text(res),
              "GET /stream/fabric: Sec-WebSocket-Key is not the base64 encoding of 16 bytes");
}

TEST_F(ServerTest, HandshakeNeedsWebSocketVersion13) {
    const auto answer = [&](const std::vector<std::string>& fields) {
        RawClient client(port());
        return client.upgrade("/stream/fabric", fields);
    };
    std::vector<std::pair<std::string, std::vector<std::string>>> requests;
    for (const char* version : {"8", "14", "", "13, 8", "013"})
        requests.emplace_back(version, with(upgrade_fields(), "Sec-WebSocket-Version", version));
    requests.emplace_back("none", with(upgrade_fields(), "Sec-WebSocket-Version", std::nullopt));
    requests.emplace_back("13 twice", upgrade_fields());
    requests.back().second.push_back("Sec-WebSocket-Version: 13");
    for (const auto& [what, fields] : requests) {
        const auto res = answer(fields);
        EXPECT_EQ(res.result_int(), 426) << what;
        EXPECT_EQ(str(res[http::field::sec_websocket_version]), "13") << what;
    }
}

TEST_F(ServerTest, HandshakeNeedsUpgradeConnectionAndHost) {
    const auto status = [&](const std::vector<std::string>& fields) {
        RawClient client(port());
        return client.upgrade("/stream/fabric", fields).result_int();
    };
    // Tokens in any case, among others.
    EXPECT_EQ(status(with(with(upgrade_fields(), "Connection", "keep-alive, UPGRADE"), "Upgrade",
                          "WebSocket")),
              101);
    EXPECT_EQ(status(with(upgrade_fields(), "Host", std::nullopt)), 400);
    EXPECT_EQ(status(with(upgrade_fields(), "Connection", "keep-alive")), 400);
    EXPECT_EQ(status(with(upgrade_fields(), "Upgrade", "h2c")), 400);
}

TEST_F(ServerTest, FiftyConcurrentStreamsAllComplete) {
    const std::string file = read_file(package("fabric"));
    constexpr int kClients = 50;
    std::vector<std::string> results(kClients);
    std::vector<int> codes(kClients, -1);
    std::vector<std::thread> clients;
    for (int i = 0; i < kClients; ++i)
        clients.emplace_back([&, i] {
            try {
                const Streamed s = stream(port(), "fabric");
                results[i] = s.bytes;
                codes[i] = s.close_code;
            } catch (const std::exception& e) {
                results[i] = e.what();
            }
        });
    for (std::thread& t : clients) t.join();
    for (int i = 0; i < kClients; ++i) {
        EXPECT_EQ(codes[i], 1000) << "client " << i << ": " << results[i].substr(0, 200);
        EXPECT_TRUE(results[i] == file) << "client " << i;
    }
}

TEST_F(ServerTest, ServesBuiltInPageWithoutAViewer) {
    ServerOptions o = options();
    o.web_root = s_dir / "packages";  // a folder without index.html
    Server server(Catalog::build({package("fabric")}), o);
    server.start();
    const Response res = get(server.port(), "/");
    ASSERT_EQ(res.result(), http::status::ok);
    EXPECT_EQ(str(res[http::field::content_type]), "text/html; charset=utf-8");
    EXPECT_NE(res.body().find("href=\"materials/fabric.btfpkg\""), std::string::npos);
    EXPECT_NE(res.body().find("has no index.html"), std::string::npos);
    EXPECT_NE(res.body().find("1 material,"), std::string::npos);
    EXPECT_EQ(get(server.port(), "/materials/fabric.btfpkg").result(), http::status::ok);

    // A viewer folder that appears while the server runs (the viewer built meanwhile).
    o.web_root = s_dir / "later";
    Server later(Catalog::build({package("fabric")}), o);
    later.start();
    EXPECT_NE(get(later.port(), "/").body().find("has no index.html"), std::string::npos);
    EXPECT_EQ(get(later.port(), "/index.html").result(), http::status::not_found);
    fs::create_directories(s_dir / "later");
    write_file(s_dir / "later" / "index.html", "built");
    EXPECT_EQ(get(later.port(), "/").body(), "built");
    fs::remove_all(s_dir / "later");
}

TEST_F(ServerTest, ClosesIdleConnections) {
    ServerOptions o = options();
    o.timeout = std::chrono::milliseconds(300);
    Server server(Catalog::build({package("fabric")}), o);
    server.start();
    // Taken before the connection exists: the server's timer starts after it accepted it, so
    // the close cannot come sooner than the timeout after this, however busy the machine.
    const auto start = Clock::now();
    net::io_context ioc;
    tcp::socket socket(ioc);
    socket.connect(local(server.port()));
    // The server closes it: the read ends with the end of the stream (the hang guard only
    // reports a server that never does).
    char byte;
    beast::error_code ec = net::error::timed_out;
    socket.async_read_some(net::buffer(&byte, 1), [&](beast::error_code e, size_t) { ec = e; });
    ioc.run_for(kHangGuard);
    EXPECT_EQ(ec, net::error::eof) << ec.message();
    EXPECT_GE(Clock::now() - start, o.timeout);
}

TEST_F(ServerTest, AnswersServiceUnavailableAtTheConnectionCap) {
    ServerOptions o = options();
    o.max_connections = 2;
    Server server(Catalog::build({package("fabric")}), o);
    server.start();
    net::io_context ioc;
    std::vector<tcp::socket> open;
    beast::flat_buffer buffer;
    for (int i = 0; i < 2; ++i) {
        open.emplace_back(ioc);
        open.back().connect(local(server.port()));
        http::request<http::empty_body> req(http::verb::get, "/api/materials", 11);
        http::write(open.back(), req);
        EXPECT_EQ(read_response(open.back(), buffer).result(), http::status::ok);
    }
    const Response res = get(server.port(), "/api/materials");
    EXPECT_EQ(res.result(), http::status::service_unavailable);
    EXPECT_NE(error_text(res).find("server busy"), std::string::npos);
    EXPECT_FALSE(res.keep_alive());
    // Closing them makes room again, once the server has seen them go (it cannot know sooner;
    // the wait ends there, the hang guard only reports a server that never notices).
    open.clear();
    ASSERT_TRUE(wait_for([&] { return server.connections() == 0; }));
    EXPECT_EQ(get(server.port(), "/api/materials").result(), http::status::ok);
}

TEST_F(ServerTest, StopEndsStalledStreamsAndIdleConnections) {
    ServerOptions o = options();
    o.shutdown_grace = std::chrono::milliseconds(300);
    auto server = std::make_unique<Server>(Catalog::build({package("big")}), o);
    server->start();
    net::io_context ioc;
    // Stalled readers: each takes the begin message and one chunk, then reads nothing while the
    // server has 32 MiB to send.
    std::vector<std::unique_ptr<websocket::stream<tcp::socket>>> readers;
    for (int i = 0; i < 4; ++i) {
        auto ws = std::make_unique<websocket::stream<tcp::socket>>(ioc);
        ws->next_layer().connect(local(server->port()));
        ws->handshake("127.0.0.1", "/stream/big");
        beast::flat_buffer buffer;
        ws->read(buffer);
        ws->read(buffer);
        readers.push_back(std::move(ws));
    }
    // And a keep-alive connection between requests: answered once, so it is open and idle.
    tcp::socket idle(ioc);
    idle.connect(local(server->port()));
    http::request<http::empty_body> req(http::verb::get, "/api/materials", 11);
    http::write(idle, req);
    beast::flat_buffer idle_buffer;
    const Response answered = read_response(idle, idle_buffer);
    EXPECT_EQ(answered.result(), http::status::ok);
    EXPECT_TRUE(answered.keep_alive());
    EXPECT_EQ(server->connections(), 5);

    // The stalled readers would hold their streams forever, so stop() returning at all shows
    // that it ended them after the grace period.
    server->stop();
    EXPECT_EQ(server->connections(), 0);
    // The stalled streams were cut, not finished.
    for (auto& ws : readers) {
        beast::error_code ec;
        for (int n = 0; n < 100000 && !ec; ++n) {
            beast::flat_buffer buffer;
            ws->read(buffer, ec);
        }
        EXPECT_TRUE(ec);
    }
    // And nothing listens any more.
    tcp::socket late(ioc);
    beast::error_code ec;
    late.connect(local(server->port()), ec);
    EXPECT_TRUE(ec);
}

TEST_F(ServerTest, ReportsBindErrors) {
    ServerOptions o = options();
    o.port = port();  // taken by the suite's server
    try {
        Server server(Catalog(), o);
        ADD_FAILURE() << "expected a btf::Error";
    } catch (const Error& e) {
        EXPECT_NE(std::string(e.what()).find(fmt::format("127.0.0.1:{}: cannot listen", port())),
                  std::string::npos)
            << e.what();
    }
    o.bind = "localhost.example";
    try {
        Server server(Catalog(), o);
        ADD_FAILURE() << "expected a btf::Error";
    } catch (const Error& e) {
        EXPECT_STREQ(e.what(), "bind address 'localhost.example' is not an IP address");
    }
}

}  // namespace
}  // namespace btf::stream
