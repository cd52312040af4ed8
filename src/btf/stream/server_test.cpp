// The streaming server against a real Beast client on loopback: the protocol's endpoints, byte
// ranges, the WebSocket stream's message boundaries, refusals of unsafe or malformed requests,
// limits, concurrency and shutdown.

#include "btf/stream/server.h"

#include <gtest/gtest.h>
#include <unistd.h>

#include <boost/asio/connect.hpp>
#include <boost/asio/ip/tcp.hpp>
#include <boost/beast/core.hpp>
#include <boost/beast/http.hpp>
#include <boost/beast/websocket.hpp>
#include <chrono>
#include <filesystem>
#include <fstream>
#include <limits>
#include <nlohmann/json.hpp>
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
    for (const auto& [field, value] : fields) req.set(field, value);
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

    const std::vector<std::string> bad_ranges = {fmt::format("bytes={}-", n),
                                                 "bytes=500-100",
                                                 "bytes=0-1,5-6",
                                                 "bytes=-0",
                                                 "lines=1-2",
                                                 "bytes=x-"};
    for (const std::string& bad : bad_ranges) {
        res = range(bad);
        EXPECT_EQ(res.result(), http::status::range_not_satisfiable) << bad;
        EXPECT_EQ(str(res[http::field::content_range]), fmt::format("bytes */{}", n)) << bad;
        EXPECT_NE(error_text(res).find("GET /materials/fabric.btfpkg: range"), std::string::npos);
    }
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
    net::io_context ioc;
    tcp::socket socket(ioc);
    socket.connect(local(server.port()));
    const auto start = Clock::now();
    char byte;
    beast::error_code ec;
    socket.read_some(net::buffer(&byte, 1), ec);  // blocks until the server closes
    EXPECT_EQ(ec, net::error::eof);
    EXPECT_LT(Clock::now() - start, std::chrono::seconds(3));
    EXPECT_GE(Clock::now() - start, std::chrono::milliseconds(250));
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
    open.clear();  // closing one makes room again
    for (int tries = 0; tries < 100 && server.connections() > 0; ++tries)
        std::this_thread::sleep_for(std::chrono::milliseconds(10));
    EXPECT_EQ(get(server.port(), "/api/materials").result(), http::status::ok);
}

TEST_F(ServerTest, StopReturnsPromptlyWithStreamsRunning) {
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
    tcp::socket idle(ioc);  // and a keep-alive connection between requests
    idle.connect(local(server->port()));
    for (int tries = 0; tries < 200 && server->connections() < 5; ++tries)
        std::this_thread::sleep_for(std::chrono::milliseconds(5));
    EXPECT_EQ(server->connections(), 5);

    const auto start = Clock::now();
    server->stop();
    const auto took = Clock::now() - start;
    EXPECT_LT(took, std::chrono::milliseconds(2000));
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
