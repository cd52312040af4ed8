// SPDX-License-Identifier: MIT
// `btf bundle` and `btf serve` as a user runs them: the static layout, refusals, error lines,
// a running server that answers and exits 0 on SIGTERM, and the cached demo material.

#include <arpa/inet.h>
#include <fmt/format.h>
#include <gtest/gtest.h>
#include <netinet/in.h>
#include <poll.h>
#include <signal.h>
#include <sys/socket.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <regex>
#include <string>
#include <thread>
#include <vector>

#include "btf/io/package.h"
#include "btf/testing/cli.h"
#include "btf/testing/support.h"

namespace btf {
namespace {

namespace fs = std::filesystem;
using json = nlohmann::json;
using test::CliResult;
using test::run;
using test::TempFolder;

using test::read_file;
using test::write_file;

// A package with the header fields the material list reads; `views` directions each way.
void make_package(const fs::path& path, const std::string& codec = "test", int size = 8,
                  int views = 2) {
    Package package;
    package.header = {{"codec", codec},
                      {"width", size},
                      {"height", size},
                      {"views", {{"theta", std::vector<double>(views, 0.0)}}},
                      {"lights", {{"theta", std::vector<double>(views, 0.0)}}}};
    PackageSection s;
    s.name = "data";
    s.data.assign(3000, 7);
    package.sections.push_back(std::move(s));
    write_package(path, package);
}

// `btf serve` as a child process whose output is read line by line.
class ServeProcess {
  public:
    ServeProcess(const std::vector<std::string>& args, const std::vector<std::string>& env = {}) {
        int fds[2];
        if (::pipe(fds) != 0) throw std::runtime_error("pipe failed");
        m_pid = ::fork();
        if (m_pid == 0) {
            ::dup2(fds[1], 1);
            ::dup2(fds[1], 2);
            ::close(fds[0]);
            ::close(fds[1]);
            for (const std::string& e : env) ::putenv(const_cast<char*>(e.c_str()));
            std::vector<const char*> argv = {BTF_TOOL_PATH, "--quiet", "serve"};
            for (const std::string& a : args) argv.push_back(a.c_str());
            argv.push_back(nullptr);
            ::execv(BTF_TOOL_PATH, const_cast<char* const*>(argv.data()));
            ::_exit(127);
        }
        ::close(fds[1]);
        m_out = fds[0];
    }
    ~ServeProcess() {
        if (m_pid > 0) {
            ::kill(m_pid, SIGKILL);
            ::waitpid(m_pid, nullptr, 0);
        }
        if (m_out >= 0) ::close(m_out);
    }

    // The next line of output, or "" after `timeout`.
    std::string line(std::chrono::milliseconds timeout = std::chrono::seconds(20)) {
        const auto end = std::chrono::steady_clock::now() + timeout;
        for (;;) {
            const size_t newline = m_buffer.find('\n');
            if (newline != std::string::npos) {
                std::string l = m_buffer.substr(0, newline);
                m_buffer.erase(0, newline + 1);
                return l;
            }
            const auto left = std::chrono::duration_cast<std::chrono::milliseconds>(
                end - std::chrono::steady_clock::now());
            if (left.count() <= 0) return "";
            pollfd p{m_out, POLLIN, 0};
            if (::poll(&p, 1, int(left.count())) <= 0) return "";
            char chunk[4096];
            const ssize_t n = ::read(m_out, chunk, sizeof chunk);
            if (n <= 0) return "";
            m_buffer.append(chunk, size_t(n));
        }
    }

    // Sends `signal` and returns the exit code (-1: killed by a signal or still running after
    // `timeout`).
    int stop(int signal, std::chrono::milliseconds timeout = std::chrono::seconds(10)) {
        ::kill(m_pid, signal);
        const auto end = std::chrono::steady_clock::now() + timeout;
        while (std::chrono::steady_clock::now() < end) {
            int status = 0;
            if (::waitpid(m_pid, &status, WNOHANG) == m_pid) {
                m_pid = -1;
                return WIFEXITED(status) ? WEXITSTATUS(status) : -1;
            }
            std::this_thread::sleep_for(std::chrono::milliseconds(20));
        }
        return -1;
    }

  private:
    pid_t m_pid = -1;
    int m_out = -1;
    std::string m_buffer;
};

// One HTTP/1.0 GET over a plain socket: the whole response, headers and body.
std::string http_get(int port, const std::string& target) {
    const int fd = ::socket(AF_INET, SOCK_STREAM, 0);
    sockaddr_in address{};
    address.sin_family = AF_INET;
    address.sin_port = htons(uint16_t(port));
    address.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
    std::string response;
    if (::connect(fd, reinterpret_cast<sockaddr*>(&address), sizeof address) == 0) {
        const std::string request = "GET " + target + " HTTP/1.0\r\nHost: localhost\r\n\r\n";
        if (::write(fd, request.data(), request.size()) == ssize_t(request.size())) {
            char chunk[4096];
            ssize_t n;
            while ((n = ::read(fd, chunk, sizeof chunk)) > 0) response.append(chunk, size_t(n));
        }
    }
    ::close(fd);
    return response;
}

int port_of(const std::string& line) {
    std::smatch m;
    static const std::regex pattern(R"(^serving (\d+) materials? at http://127\.0\.0\.1:(\d+)/$)");
    return std::regex_match(line, m, pattern) ? std::stoi(m[2]) : -1;
}

TEST(BundleCli, WritesTheStaticLayoutAndRefusesANonEmptyOutput) {
    TempFolder dir;
    const fs::path packages = dir.path() / "packages";
    fs::create_directories(packages);
    make_package(packages / "wool.btfpkg");
    make_package(packages / "silk.btfpkg");
    const fs::path web = dir.path() / "web";
    fs::create_directories(web / "assets");
    write_file(web / "index.html", "<!doctype html><title>btfkit viewer</title>");
    write_file(web / "assets" / "viewer.js", "export {};");
    const fs::path site = dir.path() / "site";

    CliResult r = run(fmt::format("bundle '{}' -o '{}' --web '{}'", packages.string(),
                                  site.string(), web.string()));
    ASSERT_EQ(r.code, 0) << r.output;
    EXPECT_EQ(read_file(site / "index.html"), "<!doctype html><title>btfkit viewer</title>");
    EXPECT_EQ(read_file(site / "assets" / "viewer.js"), "export {};");
    for (const char* id : {"silk", "wool"})
        EXPECT_EQ(read_file(site / "materials" / (std::string(id) + ".btfpkg")),
                  read_file(packages / (std::string(id) + ".btfpkg")));
    const json list = json::parse(read_file(site / "api" / "materials"));
    EXPECT_EQ(list.at("protocol"), 1);
    ASSERT_EQ(list.at("materials").size(), 2u);
    EXPECT_EQ(list["materials"][0].at("id"), "silk");
    EXPECT_EQ(list["materials"][0].at("package"), "materials/silk.btfpkg");
    EXPECT_TRUE(list["materials"][0].at("stream").is_null());

    r = run(fmt::format("bundle '{}' -o '{}' --web '{}'", packages.string(), site.string(),
                        web.string()));
    EXPECT_EQ(r.code, 1);
    EXPECT_EQ(r.output, fmt::format("btf: error: {}: folder exists and is not empty (bundle "
                                    "writes a new folder)\n",
                                    site.string()));

    // Without a viewer build the site's start page lists the materials.
    const fs::path plain = dir.path() / "plain";
    fs::create_directories(plain);  // an empty folder is accepted
    const fs::path no_viewer = dir.path() / "no-viewer";
    fs::create_directories(no_viewer);
    r = run(fmt::format("bundle '{}' -o '{}' --web '{}'", (packages / "wool.btfpkg").string(),
                        plain.string(), no_viewer.string()));
    ASSERT_EQ(r.code, 0) << r.output;
    EXPECT_NE(read_file(plain / "index.html").find("href=\"materials/wool.btfpkg\""),
              std::string::npos);

    r = run(fmt::format("bundle '{}' -o '{}'", (dir.path() / "nope.btfpkg").string(),
                        (dir.path() / "other").string()));
    EXPECT_EQ(r.code, 1);
    EXPECT_EQ(r.output, "btf: error: " + (dir.path() / "nope.btfpkg").string() +
                            ": no such file or folder\n");
    EXPECT_FALSE(fs::exists(dir.path() / "other"));
}

// A UBO2014 file is bundled (and served) as the package of its own factors, made once into the
// cache folder: the same bytes as `btf convert X.btf X.btfpkg`.
TEST(BundleCli, AUbo2014FileIsBundledAsThePackageOfItsFactors) {
    TempFolder dir;
    const std::string h5 = (dir.path() / "m.h5").string(), btf = (dir.path() / "wool.btf").string();
    ASSERT_EQ(run("synth --preset woven_fabric --size 8 -o " + h5).code, 0);
    ASSERT_EQ(run("convert " + h5 + " " + btf + " --components 4 --colour model11").code, 0);
    const std::string pkg = (dir.path() / "wool.btfpkg").string();
    ASSERT_EQ(run("convert " + btf + " " + pkg).code, 0);
    const std::string cache = "export BTF_CACHE_DIR='" + (dir.path() / "cache").string() + "'";
    for (const char* site : {"site1", "site2"}) {  // the second reuses the cached package
        const CliResult r =
            run(fmt::format("bundle '{}' -o '{}' --web '{}'", btf, (dir.path() / site).string(),
                            (dir.path() / "no-viewer").string()),
                "mkdir -p '" + (dir.path() / "no-viewer").string() + "' && " + cache);
        ASSERT_EQ(r.code, 0) << r.output;
        EXPECT_EQ(read_file(dir.path() / site / "materials" / "wool.btfpkg"), read_file(pkg));
        const json list = json::parse(read_file(dir.path() / site / "api" / "materials"));
        ASSERT_EQ(list.at("materials").size(), 1u);
        EXPECT_EQ(list["materials"][0].at("id"), "wool");
        EXPECT_EQ(list["materials"][0].at("codec"), "fmf");
    }
    size_t cached = 0;
    for (const auto& e : fs::recursive_directory_iterator(dir.path() / "cache"))
        cached += e.is_regular_file();
    EXPECT_EQ(cached, 1u);
}

TEST(ServeCli, BadPackageGivesOneLineAndExitOne) {
    TempFolder dir;
    const fs::path missing = dir.path() / "missing.btfpkg";
    CliResult r = run(fmt::format("serve '{}' --port 0", missing.string()));
    EXPECT_EQ(r.code, 1);
    EXPECT_EQ(r.output, "btf: error: " + missing.string() + ": no such file or folder\n");

    const fs::path text = dir.path() / "text.btfpkg";
    write_file(text, "not a package");
    r = run(fmt::format("serve '{}' --port 0", text.string()));
    EXPECT_EQ(r.code, 1);
    EXPECT_EQ(r.output, "btf: error: " + text.string() + ": not a btfkit package (bad magic)\n");

    make_package(dir.path() / "ok.btfpkg");
    r = run(fmt::format("serve '{}' --port 0 --bind not-an-address",
                        (dir.path() / "ok.btfpkg").string()));
    EXPECT_EQ(r.code, 1);
    EXPECT_EQ(r.output, "btf: error: bind address 'not-an-address' is not an IP address\n");
}

TEST(ServeCli, ServesUntilSigterm) {
    TempFolder dir;
    make_package(dir.path() / "wool.btfpkg");
    const fs::path web = dir.path() / "web";
    fs::create_directories(web);
    write_file(web / "index.html", "viewer page");
    ServeProcess serve(
        {(dir.path() / "wool.btfpkg").string(), "--port", "0", "--web", web.string()});
    const std::string line = serve.line();
    const int port = port_of(line);
    ASSERT_GT(port, 0) << line;
    EXPECT_NE(line.find("serving 1 material at"), std::string::npos);

    std::string response = http_get(port, "/api/materials");
    EXPECT_TRUE(response.starts_with("HTTP/1.0 200 OK\r\n")) << response;
    EXPECT_NE(response.find("\"id\": \"wool\""), std::string::npos) << response;
    response = http_get(port, "/");
    EXPECT_NE(response.find("viewer page"), std::string::npos) << response;
    EXPECT_EQ(serve.stop(SIGTERM), 0);
}

TEST(ServeCli, ReusesTheCachedDemoMaterial) {
    TempFolder dir;
    // A file with the demo's header fields stands in for the minute-long first start.
    fs::create_directories(dir.path() / "demo");
    make_package(dir.path() / "demo" / "woven_fabric.btfpkg", "fmf", 128, 81);
    ServeProcess serve({"--port", "0"}, {"BTF_CACHE_DIR=" + dir.path().string()});
    const std::string line = serve.line();
    const int port = port_of(line);
    ASSERT_GT(port, 0) << line;
    const std::string response = http_get(port, "/api/materials");
    EXPECT_NE(response.find("\"id\": \"woven_fabric\""), std::string::npos) << response;
    EXPECT_EQ(serve.stop(SIGINT), 0);
}

}  // namespace
}  // namespace btf
