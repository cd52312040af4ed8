// SPDX-License-Identifier: MIT
#pragma once
/// The HTTP + WebSocket server of `btf serve` (docs/protocol.md): the viewer's files from a web
/// root, the material list (`api/materials`), the packages with byte ranges
/// (`materials/<id>.btfpkg`) and each package as a WebSocket stream (`stream/<id>`). Boost.Beast
/// on a multithreaded Asio io_context; the Beast types stay inside server.cpp.
///
/// Every file is sent in chunks read from disk as the socket accepts them, one write at a time,
/// so a slow client slows its own transfer and costs no memory. Requests are checked before
/// anything is touched: only files under the web root (after resolving symbolic links) and the
/// catalog's packages are served; malformed, oversized or unsupported requests get a JSON error
/// with the protocol's status code; idle and stalled connections time out. The rules for targets,
/// byte ranges and the WebSocket handshake are in request.h; a WebSocket client that breaks RFC
/// 6455 gets a close frame (1002, or 1009 for a message above websocket_message_limit) before
/// the connection closes.

#include <chrono>
#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <memory>
#include <string>

#include "btf/stream/catalog.h"

namespace btf::stream {

struct ServerOptions {
    /// Address to listen on (IPv4 or IPv6 literal).
    std::string bind = "127.0.0.1";
    /// TCP port; 0 lets the system choose a free one (Server::port() tells which).
    uint16_t port = 8080;
    /// The viewer's folder; empty serves no static files. `/` answers its index.html, or a
    /// built-in page listing the materials when there is none. The folder may appear (the viewer
    /// be built) while the server runs.
    std::filesystem::path web_root;
    /// Worker threads running the io_context; 0 = the hardware's.
    int threads = 0;
    /// Connections served at once; more are answered 503.
    int max_connections = 256;
    /// A connection without a complete request for this long is closed, and so is one whose
    /// write makes no progress for this long.
    std::chrono::milliseconds timeout{30000};
    /// Largest request header (request line and fields); larger is answered 413.
    size_t header_limit = 8 * 1024;
    /// Largest message a WebSocket client may send; larger closes the stream with 1009.
    size_t websocket_message_limit = 4 * 1024;
    /// Largest WebSocket binary message, and the chunk size of file responses.
    size_t chunk_bytes = 64 * 1024;
    /// How long stop() lets running responses and streams go on before it closes them.
    std::chrono::milliseconds shutdown_grace{5000};
};

class Server {
  public:
    /// Opens the listening socket (so port() is known at once); serving starts with start().
    /// Throws btf::Error for an address that is not an IP literal, a port that cannot be bound
    /// ("127.0.0.1:8080: cannot listen: Address already in use"), or a web root that exists and
    /// is not a folder.
    Server(Catalog catalog, ServerOptions options = {});
    /// stop()s the server if it is running.
    ~Server();
    Server(const Server&) = delete;
    Server& operator=(const Server&) = delete;

    /// The port it listens on.
    uint16_t port() const;
    /// Where a browser finds it: "http://127.0.0.1:8080/" (IPv6 addresses in brackets).
    std::string url() const;
    const Catalog& catalog() const;
    const ServerOptions& options() const;

    /// Starts the worker threads and returns; the server then runs until stop().
    void start();
    /// Graceful shutdown: stops accepting, closes idle connections, lets running responses and
    /// streams go on for up to options().shutdown_grace, closes what is left and joins the
    /// worker threads. Idempotent and thread-safe; call it from outside the worker threads.
    void stop();

    /// Connections open now (HTTP and WebSocket; for tests and status lines).
    int connections() const;

  private:
    struct Impl;
    std::unique_ptr<Impl> m_impl;
};

}  // namespace btf::stream
