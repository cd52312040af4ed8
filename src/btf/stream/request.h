// SPDX-License-Identifier: MIT
#pragma once
/// The request-level rules of `btf serve` (docs/protocol.md), apart from the server so that they
/// can be tested and fuzzed alone: what a request target names, which bytes a Range field asks
/// for, and whether a WebSocket upgrade request is well formed. Plain values in, plain values
/// out (HTTP statuses as numbers); the server turns the answers into responses.

#include <cstdint>
#include <filesystem>
#include <string>
#include <string_view>
#include <vector>

namespace btf::stream {

/// A request target decoded by decode_target().
struct DecodedTarget {
    /// 200 when the target is usable; 400 for a malformed one (not starting with '/', a bad
    /// percent-escape); 404 for one that names something never served (see decode_target()).
    int status = 200;
    /// The decoded path, starting with '/', without query or fragment.
    std::string path;
    /// The path's non-empty segments, in order.
    std::vector<std::string> segments;
};

/// Decodes the path of an origin-form request target ("/materials/a.btfpkg?x=1"). Percent-escapes
/// are decoded before any check, so %2e%2e is a dot segment and %2f a separator like '/'. Dot
/// segments, segments starting with '.' (hidden files, temporary folders), backslashes and NUL
/// are answered 404: nothing outside the server's roots, and nothing hidden inside them, exists
/// as far as a client can tell.
DecodedTarget decode_target(std::string_view target);

/// `text` with ASCII letters in lower case (file extensions, catalog ids: no locale).
std::string ascii_lower(std::string_view text);

/// True if canonical `path` lies inside canonical folder `root` (and is not `root` itself): what
/// the server serves and the bundle copies from the web root.
bool inside(const std::filesystem::path& path, const std::filesystem::path& root);

/// The part of a file a GET answers, from parse_range().
struct RangeAnswer {
    /// 200: the whole file (no Range field, or one that is ignored); 206: bytes [first, end);
    /// 416: one byte range that lies outside the file (answered with `Content-Range: bytes */N`).
    int status = 200;
    /// The first byte sent and one past the last (0 and the size for 200, 0 and 0 for 416).
    uint64_t first = 0;
    uint64_t end = 0;
};

/// Applies the server's Range policy (RFC 9110 §14) to the values of every Range field of a GET
/// of a file of `size` bytes, in the order received. Exactly one field holding one byte range
/// (`bytes=a-b`, `bytes=a-`, `bytes=-n`; the unit in any case, empty list elements skipped) is
/// honoured: 206, a last position or suffix beyond the file clamped to it, or 416 when the range
/// starts at or after the end (or is the suffix `-0`). Everything else is ignored and the whole
/// file answered (200), as RFC 9110 §14.2 lets a server do: several Range fields, several ranges
/// in one field, another unit, a malformed value, a last position before the first. Numbers have
/// any number of digits; one beyond 2^64 − 1 counts as 2^64 − 1 (beyond any file).
RangeAnswer parse_range(const std::vector<std::string_view>& fields, uint64_t size);

/// What check_websocket_handshake() reads of an upgrade request. Each list holds the values of
/// every field line of that name, in order (none when the field is absent).
struct HandshakeRequest {
    /// The method as sent ("GET").
    std::string_view method;
    /// The HTTP version times ten: 11 for HTTP/1.1.
    unsigned version = 11;
    std::vector<std::string_view> host;
    std::vector<std::string_view> connection;
    std::vector<std::string_view> upgrade;
    std::vector<std::string_view> key;                // Sec-WebSocket-Key
    std::vector<std::string_view> websocket_version;  // Sec-WebSocket-Version
};

/// The verdict of check_websocket_handshake().
struct HandshakeCheck {
    /// 101: the upgrade may proceed; 400: a malformed handshake; 426: a WebSocket version other
    /// than 13 (answered with `Sec-WebSocket-Version: 13`).
    int status = 101;
    /// What is wrong, for the error response ("" for 101).
    std::string message;
};

/// Checks an opening handshake against RFC 6455 §4.2.1: a GET of HTTP/1.1 or later with a Host
/// field, `Upgrade: websocket` and `Connection: upgrade` (tokens in any case, among others),
/// exactly one `Sec-WebSocket-Key` that is the canonical base64 of 16 bytes (24 characters
/// ending in "=="), and exactly one `Sec-WebSocket-Version`, which is 13 (426 otherwise).
HandshakeCheck check_websocket_handshake(const HandshakeRequest& request);

}  // namespace btf::stream
