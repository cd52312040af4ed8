// SPDX-License-Identifier: MIT
// The server's request rules (stream/request.h): decode_target(), parse_range() and
// check_websocket_handshake() on a request written as HTTP text ("GET /a HTTP/1.1", then
// "Name: value" lines), and the promises their documentation makes checked on every answer.
// WebSocket frames are not fuzzed here: Boost.Beast parses them inside the server.
#include <cstdlib>
#include <string>
#include <string_view>
#include <vector>

#include "btf/stream/request.h"
#include "fuzz/support/fuzz.h"

namespace {

using namespace btf::stream;

bool iequals(std::string_view a, std::string_view b) {
    if (a.size() != b.size()) return false;
    for (size_t i = 0; i < a.size(); ++i)
        if (std::tolower(static_cast<unsigned char>(a[i])) !=
            std::tolower(static_cast<unsigned char>(b[i])))
            return false;
    return true;
}

void check_target(std::string_view target) {
    const DecodedTarget t = decode_target(target);
    if (t.status != 200 && t.status != 400 && t.status != 404) std::abort();
    if (t.status != 200) return;
    // A usable path starts with '/' and names nothing hidden or outside the roots.
    if (t.path.empty() || t.path[0] != '/') std::abort();
    for (const std::string& s : t.segments)
        if (s.empty() || s[0] == '.' || s.find('/') != std::string::npos ||
            s.find('\\') != std::string::npos || s.find('\0') != std::string::npos)
            std::abort();
}

void check_range(const std::vector<std::string_view>& fields) {
    for (const uint64_t size :
         {uint64_t(0), uint64_t(1), uint64_t(100), uint64_t(1) << 40, ~uint64_t(0)}) {
        const RangeAnswer a = parse_range(fields, size);
        switch (a.status) {
            case 200:
                if (a.first != 0 || a.end != size) std::abort();
                break;
            case 206:
                if (!(a.first < a.end && a.end <= size)) std::abort();
                break;
            case 416:
                if (a.first != 0 || a.end != 0) std::abort();
                break;
            default:
                std::abort();
        }
    }
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
    const std::string text(reinterpret_cast<const char*>(data), size);
    std::vector<std::string_view> lines;
    for (size_t start = 0; start <= text.size();) {
        size_t end = text.find('\n', start);
        if (end == std::string::npos) end = text.size();
        std::string_view line(text.data() + start, end - start);
        if (!line.empty() && line.back() == '\r') line.remove_suffix(1);
        lines.push_back(line);
        start = end + 1;
    }
    // The request line: METHOD TARGET HTTP/x.y
    HandshakeRequest request;
    std::string_view target;
    const std::string_view first = lines.empty() ? std::string_view() : lines[0];
    const size_t sp1 = first.find(' ');
    request.method = first.substr(0, sp1);
    if (sp1 != std::string_view::npos) {
        const size_t sp2 = first.find(' ', sp1 + 1);
        target = first.substr(sp1 + 1, sp2 == std::string_view::npos ? sp2 : sp2 - sp1 - 1);
        if (sp2 != std::string_view::npos) {
            const std::string_view version = first.substr(sp2 + 1);
            request.version = version.size() == 8 && version.substr(0, 5) == "HTTP/"
                                  ? unsigned((version[5] - '0') * 10 + (version[7] - '0'))
                                  : 0;
        }
    }
    std::vector<std::string_view> ranges;
    for (size_t i = 1; i < lines.size(); ++i) {
        const size_t colon = lines[i].find(':');
        if (colon == std::string_view::npos) continue;
        const std::string_view name = lines[i].substr(0, colon);
        std::string_view value = lines[i].substr(colon + 1);
        // Optional whitespace around a field value is not part of it (RFC 9110 §5.5); the
        // server's HTTP parser strips it before these functions see the value.
        while (!value.empty() && (value.front() == ' ' || value.front() == '\t'))
            value.remove_prefix(1);
        while (!value.empty() && (value.back() == ' ' || value.back() == '\t'))
            value.remove_suffix(1);
        if (iequals(name, "range")) ranges.push_back(value);
        if (iequals(name, "host")) request.host.push_back(value);
        if (iequals(name, "connection")) request.connection.push_back(value);
        if (iequals(name, "upgrade")) request.upgrade.push_back(value);
        if (iequals(name, "sec-websocket-key")) request.key.push_back(value);
        if (iequals(name, "sec-websocket-version")) request.websocket_version.push_back(value);
    }
    return btf::fuzz::run([&] {
        check_target(target);
        check_range(ranges);
        const HandshakeCheck h = check_websocket_handshake(request);
        if (h.status != 101 && h.status != 400 && h.status != 426) std::abort();
        if (h.status == 101 && (request.key.size() != 1 || request.key[0].size() != 24 ||
                                !request.key[0].ends_with("==") || !h.message.empty()))
            std::abort();
    });
}
