// SPDX-License-Identifier: MIT
// stream_load: many viewers streaming at once from one `btf serve` process.
//
// Starts `btf serve PKG --port 0` as a child process, reads its material list, fetches the package
// once over HTTP as the reference, then opens N WebSocket streams (docs/protocol.md) at the same
// time and reads them to the end: every stream must deliver the begin message, exactly the
// package's bytes in order, the end message and a normal close. Meanwhile the server's resident
// memory is sampled from /proc every 10 ms: all of it (VmRSS, which counts the pages of the
// shared libraries it maps) and its own heap and stacks (RssAnon). Prints one table row per round
// for docs/benchmarks.md:
//
//   stream_load --btf build/release/btf --package demo.btfpkg --clients 100 --rounds 3

#include <signal.h>
#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <memory>
#include <string>
#include <thread>
#include <vector>

#include <CLI/CLI.hpp>
#include <boost/asio.hpp>
#include <boost/beast.hpp>
#include <nlohmann/json.hpp>

extern char** environ;

namespace {

namespace net = boost::asio;
namespace beast = boost::beast;
namespace http = beast::http;
namespace websocket = beast::websocket;
using tcp = net::ip::tcp;
using Clock = std::chrono::steady_clock;

[[noreturn]] void die(const std::string& message) {
    std::fprintf(stderr, "stream_load: %s\n", message.c_str());
    std::exit(1);
}

// The server process: spawned with its stdout on a pipe, stopped with SIGTERM.
struct ServerProcess {
    pid_t pid = -1;
    int port = 0;

    ServerProcess(const std::string& btf, const std::vector<std::string>& packages) {
        int out[2];
        if (pipe(out) != 0) die("pipe failed");
        posix_spawn_file_actions_t actions;
        posix_spawn_file_actions_init(&actions);
        posix_spawn_file_actions_adddup2(&actions, out[1], STDOUT_FILENO);
        posix_spawn_file_actions_addclose(&actions, out[0]);
        std::vector<std::string> args = {btf, "--quiet", "serve"};
        args.insert(args.end(), packages.begin(), packages.end());
        args.insert(args.end(), {"--port", "0"});
        std::vector<char*> argv;
        for (std::string& a : args) argv.push_back(a.data());
        argv.push_back(nullptr);
        if (posix_spawn(&pid, btf.c_str(), &actions, nullptr, argv.data(), environ) != 0)
            die("cannot start " + btf);
        posix_spawn_file_actions_destroy(&actions);
        close(out[1]);
        std::string text;
        char buffer[256];
        for (;;) {
            const ssize_t n = read(out[0], buffer, sizeof buffer);
            if (n <= 0) die("btf serve ended before it served: " + text);
            text.append(buffer, size_t(n));
            const size_t at = text.find("http://127.0.0.1:");
            if (at != std::string::npos && text.find('\n', at) != std::string::npos) {
                port = std::stoi(text.substr(at + std::strlen("http://127.0.0.1:")));
                break;
            }
        }
        close(out[0]);
    }
    ~ServerProcess() {
        kill(pid, SIGTERM);
        int status = 0;
        waitpid(pid, &status, 0);
    }

    // A memory field of /proc/<pid>/status in bytes: VmRSS (resident), RssAnon, VmHWM (peak).
    long long memory(const char* field = "VmRSS:") const {
        std::ifstream in("/proc/" + std::to_string(pid) + "/status");
        std::string line;
        while (std::getline(in, line))
            if (line.rfind(field, 0) == 0)
                return std::stoll(line.substr(std::strlen(field))) * 1024;
        return 0;
    }
};

std::string http_get(int port, const std::string& target) {
    net::io_context ioc;
    beast::tcp_stream stream(ioc);
    stream.connect(tcp::endpoint(net::ip::make_address("127.0.0.1"), uint16_t(port)));
    http::request<http::empty_body> req{http::verb::get, target, 11};
    req.set(http::field::host, "127.0.0.1");
    http::write(stream, req);
    beast::flat_buffer buffer;
    http::response_parser<http::string_body> parser;
    parser.body_limit(1ull << 34);
    http::read(stream, buffer, parser);
    if (parser.get().result() != http::status::ok)
        die("GET " + target + ": HTTP " + std::to_string(parser.get().result_int()));
    return parser.get().body();
}

struct Result {
    bool ok = false;
    std::string why;
    double first_byte_s = 0, done_s = 0;
};

// One viewer: connects, streams, and checks every byte against the reference.
class Client : public std::enable_shared_from_this<Client> {
  public:
    Client(net::io_context& ioc, int port, std::string target, const std::string& expected,
           Result& result, Clock::time_point t0)
        : m_ws(ioc),
          m_port(port),
          m_target(std::move(target)),
          m_expected(expected),
          m_result(result),
          m_t0(t0) {}

    void start() {
        beast::get_lowest_layer(m_ws).expires_after(std::chrono::seconds(120));
        beast::get_lowest_layer(m_ws).async_connect(
            tcp::endpoint(net::ip::make_address("127.0.0.1"), uint16_t(m_port)),
            [self = shared_from_this()](beast::error_code ec) {
                if (ec) return self->fail("connect: " + ec.message());
                self->m_ws.async_handshake("127.0.0.1", self->m_target,
                                           [self](beast::error_code ec2) {
                                               if (ec2)
                                                   return self->fail("handshake: " + ec2.message());
                                               self->read();
                                           });
            });
    }

  private:
    void read() {
        m_ws.async_read(m_buffer, [self = shared_from_this()](beast::error_code ec, size_t) {
            self->on_read(ec);
        });
    }
    void on_read(beast::error_code ec) {
        if (ec == websocket::error::closed) {
            if (m_ws.reason().code != websocket::close_code::normal)
                return fail("closed with code " + std::to_string(m_ws.reason().code));
            if (!m_begin) return fail("closed without the begin message");
            if (!m_end || m_offset != m_expected.size())
                return fail("closed after " + std::to_string(m_offset) + " bytes without the end");
            m_result.ok = true;
            m_result.done_s = seconds();
            return;
        }
        if (ec) return fail("read: " + ec.message());
        const auto data = m_buffer.cdata();
        const char* bytes = static_cast<const char*>(data.data());
        if (m_ws.got_text()) {
            const auto message = nlohmann::json::parse(std::string(bytes, data.size()));
            const std::string type = message.value("type", "");
            if (type == "begin") {
                if (m_begin || m_offset != 0) return fail("begin after the stream started");
                if (message.value("bytes", uint64_t(0)) != m_expected.size())
                    return fail("begin names another size");
                m_begin = true;
            } else if (type == "end") {
                m_end = true;
            } else {
                return fail("unexpected message " + message.dump());
            }
        } else {
            if (!m_begin) return fail("package bytes before the begin message");
            if (m_offset == 0) m_result.first_byte_s = seconds();
            if (m_offset + data.size() > m_expected.size() ||
                std::memcmp(bytes, m_expected.data() + m_offset, data.size()) != 0)
                return fail("bytes differ from the package at offset " + std::to_string(m_offset));
            m_offset += data.size();
        }
        m_buffer.consume(m_buffer.size());
        read();
    }
    void fail(std::string why) {
        m_result.ok = false;
        m_result.why = std::move(why);
        beast::get_lowest_layer(m_ws).close();
    }
    double seconds() const { return std::chrono::duration<double>(Clock::now() - m_t0).count(); }

    websocket::stream<beast::tcp_stream> m_ws;
    beast::flat_buffer m_buffer;
    int m_port;
    std::string m_target;
    const std::string& m_expected;
    Result& m_result;
    Clock::time_point m_t0;
    size_t m_offset = 0;
    bool m_begin = false, m_end = false;
};

double percentile(std::vector<double> v, double q) {
    if (v.empty()) return 0;
    std::sort(v.begin(), v.end());
    return v[std::min(v.size() - 1, size_t(q * double(v.size())))];
}

}  // namespace

int main(int argc, char** argv) {
    CLI::App app{"N concurrent WebSocket streams from one btf serve process"};
    std::string btf = "build/release/btf";
    std::vector<std::string> packages;
    int clients = 100, rounds = 3, threads = 1;
    app.add_option("--btf", btf, "the btf command");
    app.add_option("--package", packages, "packages to serve (none: the built-in demo material)");
    app.add_option("--clients", clients, "concurrent streams")->check(CLI::Range(1, 10000));
    app.add_option("--rounds", rounds, "waves of streams, one after the other")
        ->check(CLI::Range(1, 100));
    app.add_option("--client-threads", threads, "threads running the clients")
        ->check(CLI::Range(1, 64));
    CLI11_PARSE(app, argc, argv);

    ServerProcess server(btf, packages);
    const auto list = nlohmann::json::parse(http_get(server.port, "/api/materials"));
    const auto& material = list.at("materials").at(0);
    const std::string id = material.at("id");
    const std::string expected =
        http_get(server.port, "/" + material.at("package").get<std::string>());
    if (expected.size() != material.at("bytes").get<size_t>())
        die("the package's size differs from the list");
    const std::string target = "/" + material.at("stream").get<std::string>();

    std::printf(
        "# %d concurrent streams of '%s' (%.2f MiB) from btf serve (pid %d), %d client "
        "thread%s, %u cores\n",
        clients, id.c_str(), double(expected.size()) / 1048576.0, int(server.pid), threads,
        threads == 1 ? "" : "s", std::thread::hardware_concurrency());
    std::printf(
        "| round | streams | failed | wall s | MiB/s | Gbit/s | first byte p50 / p95 s | "
        "complete p50 / p95 s | server RSS before → peak MiB | of it anonymous MiB |\n");
    std::printf("|---|---|---|---|---|---|---|---|---|---|\n");
    int total_failures = 0;
    for (int round = 1; round <= rounds; ++round) {
        const long long before = server.memory(), before_anon = server.memory("RssAnon:");
        std::vector<Result> results(static_cast<size_t>(clients));
        net::io_context ioc;
        const Clock::time_point t0 = Clock::now();
        for (int i = 0; i < clients; ++i)
            std::make_shared<Client>(ioc, server.port, target, expected, results[size_t(i)], t0)
                ->start();
        std::atomic<bool> running{true};
        std::atomic<long long> peak{before}, peak_anon{before_anon};
        std::thread sampler([&] {
            while (running) {
                peak = std::max(peak.load(), server.memory());
                peak_anon = std::max(peak_anon.load(), server.memory("RssAnon:"));
                std::this_thread::sleep_for(std::chrono::milliseconds(10));
            }
        });
        std::vector<std::thread> pool;
        for (int t = 1; t < threads; ++t) pool.emplace_back([&] { ioc.run(); });
        ioc.run();
        for (std::thread& t : pool) t.join();
        const double wall = std::chrono::duration<double>(Clock::now() - t0).count();
        running = false;
        sampler.join();

        std::vector<double> first, done;
        int failures = 0;
        for (const Result& r : results) {
            if (!r.ok) {
                if (failures++ < 3)
                    std::fprintf(stderr, "stream_load: a stream failed: %s\n", r.why.c_str());
                continue;
            }
            first.push_back(r.first_byte_s);
            done.push_back(r.done_s);
        }
        total_failures += failures;
        const double mib = double(expected.size()) * double(clients - failures) / 1048576.0;
        std::printf(
            "| %d | %d | %d | %.2f | %.0f | %.2f | %.3f / %.3f | %.2f / %.2f | %.1f → %.1f | "
            "%.1f → %.1f |\n",
            round, clients, failures, wall, mib / wall, mib * 1048576.0 * 8 / wall / 1e9,
            percentile(first, 0.5), percentile(first, 0.95), percentile(done, 0.5),
            percentile(done, 0.95), double(before) / 1048576.0, double(peak.load()) / 1048576.0,
            double(before_anon) / 1048576.0, double(peak_anon.load()) / 1048576.0);
        std::fflush(stdout);
    }
    std::printf("server peak resident memory over the whole run (VmHWM): %.1f MiB\n",
                double(server.memory("VmHWM:")) / 1048576.0);
    return total_failures == 0 ? 0 : 2;
}
