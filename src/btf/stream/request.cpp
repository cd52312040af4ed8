// SPDX-License-Identifier: MIT
// The request-level rules of the streaming server (request.h): targets, ranges, and the WebSocket
// opening handshake. Field lists (Connection, Upgrade) are split by Beast's RFC 7230 token list.

#include "btf/stream/request.h"

#include <algorithm>
#include <boost/beast/core/string.hpp>
#include <boost/beast/http/rfc7230.hpp>
#include <limits>
#include <optional>

namespace btf::stream {

namespace {

namespace http = boost::beast::http;

int hex_digit(char c) {
    if (c >= '0' && c <= '9') return c - '0';
    if (c >= 'a' && c <= 'f') return c - 'a' + 10;
    if (c >= 'A' && c <= 'F') return c - 'A' + 10;
    return -1;
}

// Optional white space (RFC 9110 §5.6.3) removed from both ends.
std::string_view trim(std::string_view s) {
    while (!s.empty() && (s.front() == ' ' || s.front() == '\t')) s.remove_prefix(1);
    while (!s.empty() && (s.back() == ' ' || s.back() == '\t')) s.remove_suffix(1);
    return s;
}

bool iequals(std::string_view a, std::string_view b) {
    return boost::beast::iequals({a.data(), a.size()}, {b.data(), b.size()});
}

// A decimal number of any length; past 2^64 − 1 it stays there (a position that large lies
// beyond any file, so saturating changes no answer). Nothing for an empty or non-digit string.
std::optional<uint64_t> saturating_number(std::string_view s) {
    if (s.empty()) return std::nullopt;
    constexpr uint64_t kMax = std::numeric_limits<uint64_t>::max();
    uint64_t n = 0;
    for (const char c : s) {
        if (c < '0' || c > '9') return std::nullopt;
        const uint64_t digit = uint64_t(c - '0');
        n = n > (kMax - digit) / 10 ? kMax : n * 10 + digit;
    }
    return n;
}

// True if some element of the comma-separated token lists in `fields` equals `token`, ignoring
// case.
bool has_token(const std::vector<std::string_view>& fields, std::string_view token) {
    for (const std::string_view field : fields)
        if (http::token_list({field.data(), field.size()}).exists({token.data(), token.size()}))
            return true;
    return false;
}

int base64_digit(char c) {
    if (c >= 'A' && c <= 'Z') return c - 'A';
    if (c >= 'a' && c <= 'z') return c - 'a' + 26;
    if (c >= '0' && c <= '9') return c - '0' + 52;
    if (c == '+') return 62;
    if (c == '/') return 63;
    return -1;
}

// True if `key` is the canonical base64 (RFC 4648 §4) of 16 bytes: 22 digits, the last of which
// carries only 2 bits of data (its 4 low bits are the padding bits, zero), then "==".
bool is_websocket_key(std::string_view key) {
    if (key.size() != 24 || key.substr(22) != "==") return false;
    for (size_t i = 0; i < 22; ++i)
        if (base64_digit(key[i]) < 0) return false;
    return (base64_digit(key[21]) & 0x0f) == 0;
}

}  // namespace

DecodedTarget decode_target(std::string_view target) {
    DecodedTarget out;
    if (target.empty() || target[0] != '/') {
        out.status = 400;
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
            out.status = 400;
            return out;
        }
        out.path += static_cast<char>(hi * 16 + lo);
        i += 2;
    }
    if (out.path.find('\0') != std::string::npos || out.path.find('\\') != std::string::npos) {
        out.status = 404;
        return out;
    }
    size_t start = 1;
    while (start <= out.path.size()) {
        size_t end = out.path.find('/', start);
        if (end == std::string::npos) end = out.path.size();
        std::string segment = out.path.substr(start, end - start);
        if (!segment.empty()) {
            if (segment[0] == '.') {
                out.status = 404;
                return out;
            }
            out.segments.push_back(std::move(segment));
        }
        start = end + 1;
    }
    return out;
}

RangeAnswer parse_range(const std::vector<std::string_view>& fields, uint64_t size) {
    const RangeAnswer whole{200, 0, size};
    const RangeAnswer unsatisfiable{416, 0, 0};
    // One field only: the field is not a list, so a second one is not more of the same; which
    // one the client meant is unknown.
    if (fields.size() != 1) return whole;
    std::string_view value = trim(fields[0]);
    const size_t equals = value.find('=');
    if (equals == std::string_view::npos || !iequals(value.substr(0, equals), "bytes"))
        return whole;
    // range-set = 1#range-spec: one element after skipping empty ones (RFC 9110 §5.6.1.2).
    std::string_view spec;
    int elements = 0;
    for (std::string_view rest = value.substr(equals + 1);;) {
        const size_t comma = rest.find(',');
        const std::string_view element = trim(rest.substr(0, comma));
        if (!element.empty()) spec = element, ++elements;
        if (comma == std::string_view::npos) break;
        rest.remove_prefix(comma + 1);
    }
    if (elements != 1) return whole;
    const size_t dash = spec.find('-');
    if (dash == std::string_view::npos) return whole;
    const std::string_view a = spec.substr(0, dash), b = spec.substr(dash + 1);
    if (a.empty()) {
        // suffix-range: the last n bytes, all of them if the file is shorter.
        const auto n = saturating_number(b);
        if (!n) return whole;
        if (*n == 0) return unsatisfiable;
        // The whole of an empty file is no range at all (Content-Range cannot name it).
        if (size == 0) return whole;
        return {206, size - std::min(*n, size), size};
    }
    const auto first = saturating_number(a);
    if (!first) return whole;
    std::optional<uint64_t> last;
    if (!b.empty()) {
        last = saturating_number(b);
        if (!last || *last < *first) return whole;  // invalid, not unsatisfiable
    }
    if (*first >= size) return unsatisfiable;
    const uint64_t end = last ? std::min(*last, size - 1) + 1 : size;
    return {206, *first, end};
}

HandshakeCheck check_websocket_handshake(const HandshakeRequest& request) {
    const auto bad = [](std::string message) { return HandshakeCheck{400, std::move(message)}; };
    if (request.method != "GET") return bad("a WebSocket upgrade must be a GET");
    if (request.version < 11) return bad("a WebSocket upgrade needs HTTP/1.1");
    if (!has_token(request.upgrade, "websocket") || !has_token(request.connection, "upgrade"))
        return bad("a WebSocket endpoint: send a GET with Upgrade: websocket");
    if (request.host.size() != 1) return bad("a WebSocket upgrade needs one Host field");
    if (request.key.size() != 1)
        return bad(request.key.empty() ? "Sec-WebSocket-Key is missing"
                                       : "Sec-WebSocket-Key appears more than once");
    if (!is_websocket_key(trim(request.key[0])))
        return bad("Sec-WebSocket-Key is not the base64 encoding of 16 bytes");
    if (request.websocket_version.size() != 1 || trim(request.websocket_version[0]) != "13")
        return {426, "Sec-WebSocket-Version must be 13 (once)"};
    return {};
}

std::string ascii_lower(std::string_view text) {
    std::string out(text);
    for (char& c : out)
        if (c >= 'A' && c <= 'Z') c = char(c - 'A' + 'a');
    return out;
}

bool inside(const std::filesystem::path& path, const std::filesystem::path& root) {
    auto p = path.begin();
    for (auto r = root.begin(); r != root.end(); ++r, ++p)
        if (p == path.end() || *p != *r) return false;
    return p != path.end();
}

}  // namespace btf::stream
