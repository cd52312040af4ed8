// SPDX-License-Identifier: MIT
// The server's request-level rules alone (request.h): target decoding, the Range policy, and the
// WebSocket handshake check. server_test.cpp checks the same rules through real connections.

#include "btf/stream/request.h"

#include <gtest/gtest.h>

#include <cstdint>
#include <string>
#include <vector>

namespace btf::stream {
namespace {

constexpr uint64_t kMax = UINT64_MAX;

TEST(RequestTest, DecodesTargets) {
    DecodedTarget t = decode_target("/materials/a%2Eb.btfpkg?x=1#y");
    EXPECT_EQ(t.status, 200);
    EXPECT_EQ(t.path, "/materials/a.b.btfpkg");
    EXPECT_EQ(t.segments, (std::vector<std::string>{"materials", "a.b.btfpkg"}));
    t = decode_target("//sub///data.json");
    EXPECT_EQ(t.status, 200);
    EXPECT_EQ(t.segments, (std::vector<std::string>{"sub", "data.json"}));
    EXPECT_EQ(decode_target("/").segments.size(), 0u);

    for (const char* not_found :
         {"/../x", "/%2e%2e/x", "/a%2f..%2fb", "/.hidden", "/a/./b", "/a%5cb", "/a\\b", "/a%00b"})
        EXPECT_EQ(decode_target(not_found).status, 404) << not_found;
    for (const char* bad : {"", "x", "*", "http://host/x", "/a%zz", "/a%2", "/a%"})
        EXPECT_EQ(decode_target(bad).status, 400) << bad;
}

// parse_range() of one field.
RangeAnswer range(std::string_view value, uint64_t size) {
    return parse_range({value}, size);
}

void expect_answer(const RangeAnswer& a, int status, uint64_t first, uint64_t end) {
    EXPECT_EQ(a.status, status);
    EXPECT_EQ(a.first, first);
    EXPECT_EQ(a.end, end);
}

TEST(RequestTest, HonoursOneByteRange) {
    expect_answer(parse_range({}, 1000), 200, 0, 1000);
    expect_answer(range("bytes=100-199", 1000), 206, 100, 200);
    expect_answer(range("bytes=100-", 1000), 206, 100, 1000);
    expect_answer(range("bytes=-300", 1000), 206, 700, 1000);
    expect_answer(range("bytes=999-999", 1000), 206, 999, 1000);
    expect_answer(range(" Bytes=0-0 ", 1000), 206, 0, 1);
    expect_answer(range("bytes=, 5-9 ,", 1000), 206, 5, 10);
}

TEST(RequestTest, ClampsNumbersOfAnyLength) {
    // Beyond the file, beyond 2^64 − 1: clamped to the file alike.
    for (const char* value :
         {"bytes=0-1000", "bytes=0-99999999999", "bytes=0-18446744073709551615",
          "bytes=0-18446744073709551616", "bytes=0-999999999999999999999999999999999999999",
          "bytes=-1000", "bytes=-18446744073709551615", "bytes=-99999999999999999999999999"})
        expect_answer(range(value, 1000), 206, 0, 1000);
    expect_answer(range("bytes=0-18446744073709551615", kMax), 206, 0, kMax);
    expect_answer(range("bytes=18446744073709551614-", kMax), 206, kMax - 1, kMax);
    // A first position past the end, however long its number, is unsatisfiable.
    for (const char* value : {"bytes=1000-", "bytes=1000-2000", "bytes=18446744073709551615-",
                              "bytes=18446744073709551616-", "bytes=99999999999999999999999999-"})
        expect_answer(range(value, 1000), 416, 0, 0);
    expect_answer(range("bytes=-0", 1000), 416, 0, 0);
    expect_answer(range("bytes=0-", 0), 416, 0, 0);
    expect_answer(range("bytes=-5", 0), 200, 0, 0);
}

TEST(RequestTest, IgnoresRangeFieldsThatAreNotOneByteRange) {
    expect_answer(parse_range({"bytes=0-9", "bytes=0-9"}, 1000), 200, 0, 1000);
    expect_answer(parse_range({"bytes=0-9", "bytes=20-29"}, 1000), 200, 0, 1000);
    for (const char* value :
         {"bytes=0-1,5-6", "bytes=0-9, 0-9", "bytes=2000-,3000-", "lines=1-2", "bytes 0-9", "=0-9",
          "bytes=", "bytes=,", "bytes=5", "bytes=-", "bytes=9-5", "bytes=x-", "bytes=1-x",
          "bytes=-x", "bytes=+1-2", "bytes=1 -2", "bytes=1-2-3", "bytes=--1", ""})
        expect_answer(range(value, 1000), 200, 0, 1000);
}

HandshakeRequest good_handshake() {
    return {.method = "GET",
            .version = 11,
            .host = {"127.0.0.1"},
            .connection = {"Upgrade"},
            .upgrade = {"websocket"},
            .key = {"dGhlIHNhbXBsZSBub25jZQ=="},
            .websocket_version = {"13"}};
}

TEST(RequestTest, AcceptsAWellFormedHandshake) {
    EXPECT_EQ(check_websocket_handshake(good_handshake()).status, 101);
    EXPECT_EQ(check_websocket_handshake(good_handshake()).message, "");
    HandshakeRequest r = good_handshake();
    r.connection = {"keep-alive", "UPGRADE"};
    r.upgrade = {"h2c, WebSocket"};
    r.key = {"MDEyMzQ1Njc4OWFiY2RlZg=="};
    r.version = 20;
    EXPECT_EQ(check_websocket_handshake(r).status, 101);
    r.key = {"+/+/+/+/+/+/+/+/+/+/+w=="};
    EXPECT_EQ(check_websocket_handshake(r).status, 101);
}

TEST(RequestTest, RefusesMalformedHandshakes) {
    const auto status = [](auto change) {
        HandshakeRequest r = good_handshake();
        change(r);
        return check_websocket_handshake(r).status;
    };
    EXPECT_EQ(status([](HandshakeRequest& r) { r.method = "HEAD"; }), 400);
    EXPECT_EQ(status([](HandshakeRequest& r) { r.version = 10; }), 400);
    EXPECT_EQ(status([](HandshakeRequest& r) { r.host = {}; }), 400);
    EXPECT_EQ(status([](HandshakeRequest& r) { r.host = {"a", "b"}; }), 400);
    EXPECT_EQ(status([](HandshakeRequest& r) { r.connection = {"keep-alive"}; }), 400);
    EXPECT_EQ(status([](HandshakeRequest& r) { r.upgrade = {}; }), 400);
    EXPECT_EQ(status([](HandshakeRequest& r) { r.upgrade = {"websockets"}; }), 400);
    EXPECT_EQ(status([](HandshakeRequest& r) { r.key = {}; }), 400);
    EXPECT_EQ(status([](HandshakeRequest& r) { r.key.push_back(r.key[0]); }), 400);
    for (const char* key :
         {"", "=", "dGhlIHNhbXBsZSBub25jZQ", "dGhlIHNhbXBsZSBub25jZQ=", "dGhlIHNhbXBsZSBub25jZQ===",
          "AAAAAAAAAAAAAAAAAAAA", "AAAAAAAAAAAAAAAAAAAAAAA=", "AAAAAAAAAAAAAAAAAAAAAAAA",
          "dGhlIHNhbXBsZSBub25jZR==", "dGhlIHNhbXBsZSBub25j ZQ==", "dGhlIHNhbXBsZSBub25jZ-==",
          "dGhlIHNhbXBsZSBub25jZQ%3D%3D"}) {
        HandshakeRequest r = good_handshake();
        r.key = {key};
        const HandshakeCheck check = check_websocket_handshake(r);
        EXPECT_EQ(check.status, 400) << key;
        EXPECT_EQ(check.message, "Sec-WebSocket-Key is not the base64 encoding of 16 bytes") << key;
    }
    for (const std::vector<std::string_view>& versions : std::vector<std::vector<std::string_view>>{
             {}, {"8"}, {"14"}, {""}, {"13, 8"}, {"13", "13"}}) {
        HandshakeRequest r = good_handshake();
        r.websocket_version = versions;
        EXPECT_EQ(check_websocket_handshake(r).status, 426);
    }
}

}  // namespace
}  // namespace btf::stream
