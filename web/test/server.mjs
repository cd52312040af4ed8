// SPDX-License-Identifier: MIT
// A small static server for the viewer's tests: serves a bundle folder (docs/protocol.md layout:
// index.html, the viewer's assets, api/materials, materials/<id>.btfpkg) with HTTP Range support,
// the WebSocket stream/<id> of `btf serve`, and gates that hold a package's body at chosen byte
// offsets until the test releases them, so a test can watch the viewer between two sections.

import { createHash } from "node:crypto";
import { createServer } from "node:http";
import { readFile, stat } from "node:fs/promises";
import path from "node:path";

const TYPES = {
  ".html": "text/html; charset=utf-8",
  ".js": "text/javascript; charset=utf-8",
  ".mjs": "text/javascript; charset=utf-8",
  ".map": "application/json",
  ".json": "application/json",
  ".txt": "text/plain; charset=utf-8",
  ".btfpkg": "application/octet-stream",
  ".png": "image/png",
};

/** Byte ranges a package is sent in: messages end at section boundaries and are ≤ 64 KiB. */
export function messageRanges(total, boundaries, limit = 64 * 1024) {
  const cuts = [...new Set([0, ...boundaries.filter((b) => b > 0 && b < total), total])].sort((a, b) => a - b);
  const out = [];
  for (let i = 0; i + 1 < cuts.length; ++i)
    for (let at = cuts[i]; at < cuts[i + 1]; at += limit) out.push([at, Math.min(at + limit, cuts[i + 1])]);
  return out;
}

/** Section boundaries (file offsets) of a package file's bytes. */
export function packageBoundaries(bytes) {
  const h = bytes.readUInt32LE(12);
  const header = JSON.parse(bytes.subarray(24, 24 + h).toString("utf8"));
  const base = 24 + h;
  return { headerBytes: base, header, boundaries: [base, ...header.sections.map((s) => base + s.offset + s.size)] };
}

const sleep = (ms) => new Promise((r) => setTimeout(r, ms));

/**
 * Starts the server on 127.0.0.1 (a free port). Returns { url, close, hold, release, releaseAll,
 * requests }. hold(id, offsets): the package's body (HTTP or WebSocket) stops before each offset
 * until release(id) lets it pass the next one.
 */
export async function startServer(root, options = {}) {
  const gates = new Map(); // id → { offsets: number[], passed: number, waiters: [] }
  const requests = [];
  const delayMs = options.delayMs ?? 0;

  const gate = (id) => gates.get(id);
  // Resolves once the body may proceed past `offset`.
  const waitFor = async (id, offset) => {
    const g = gate(id);
    if (!g) return;
    for (;;) {
      const blocking = g.offsets.filter((o) => o <= offset && o > 0).length;
      if (g.passed >= blocking) return;
      await new Promise((resolve) => g.waiters.push(resolve));
    }
  };
  const wake = (g) => {
    const w = g.waiters.splice(0);
    for (const r of w) r();
  };

  const packageFile = (id) => path.join(root, "materials", `${id}.btfpkg`);

  // Sends bytes [from, to) of a package in message-sized pieces through the gate.
  async function pump(id, bytes, from, to, write) {
    const { boundaries } = packageBoundaries(bytes);
    const g = gate(id);
    const cuts = g ? [...boundaries, ...g.offsets] : boundaries;
    for (const [a, b] of messageRanges(bytes.length, cuts)) {
      if (b <= from || a >= to) continue;
      const s = Math.max(a, from), e = Math.min(b, to);
      await waitFor(id, s);
      if (delayMs) await sleep(delayMs);
      if (!(await write(bytes.subarray(s, e)))) return false;
    }
    return true;
  }

  const server = createServer(async (req, res) => {
    const url = new URL(req.url, "http://localhost");
    let rel = decodeURIComponent(url.pathname);
    requests.push({ method: req.method, path: rel, range: req.headers.range ?? null });
    if (rel.includes("..") || rel.includes("\0")) {
      res.writeHead(404).end();
      return;
    }
    if (rel.endsWith("/")) rel += "index.html";
    const file = path.join(root, rel);
    let info;
    try {
      info = await stat(file);
    } catch {
      res.writeHead(404, { "Content-Type": "application/json" }).end(JSON.stringify({ error: "not found" }));
      return;
    }
    if (!info.isFile()) {
      res.writeHead(404).end();
      return;
    }
    const type = rel === "/api/materials" ? "application/json" : TYPES[path.extname(rel)] ?? "application/octet-stream";
    const size = info.size;
    let start = 0, end = size; // [start, end)
    let status = 200;
    const headers = { "Content-Type": type, "Accept-Ranges": "bytes", "Cache-Control": "no-store" };
    const range = req.headers.range;
    if (range) {
      const m = /^bytes=(\d*)-(\d*)$/.exec(range);
      if (!m || (m[1] === "" && m[2] === "")) {
        res.writeHead(416, { "Content-Range": `bytes */${size}` }).end();
        return;
      }
      if (m[1] === "") {
        start = Math.max(0, size - Number(m[2]));
      } else {
        start = Number(m[1]);
        end = m[2] === "" ? size : Math.min(size, Number(m[2]) + 1);
      }
      if (start >= size || start >= end) {
        res.writeHead(416, { "Content-Range": `bytes */${size}` }).end();
        return;
      }
      status = 206;
      headers["Content-Range"] = `bytes ${start}-${end - 1}/${size}`;
    }
    headers["Content-Length"] = String(end - start);
    res.writeHead(status, headers);
    if (req.method === "HEAD") {
      res.end();
      return;
    }
    const bytes = await readFile(file);
    const pkg = /^\/materials\/([^/]+)\.btfpkg$/.exec(rel);
    if (!pkg) {
      res.end(bytes.subarray(start, end));
      return;
    }
    let closed = false;
    res.on("close", () => {
      closed = true;
    });
    await pump(pkg[1], bytes, start, end, async (piece) => {
      if (closed) return false;
      if (!res.write(piece)) await new Promise((r) => res.once("drain", r));
      return !closed;
    });
    res.end();
  });

  // WebSocket stream/<id> (docs/protocol.md): begin, the file's bytes, end, close 1000.
  server.on("upgrade", async (req, socket) => {
    const url = new URL(req.url, "http://localhost");
    requests.push({ method: "UPGRADE", path: url.pathname, range: null });
    const m = /^\/stream\/([^/]+)$/.exec(url.pathname);
    const key = req.headers["sec-websocket-key"];
    let bytes;
    try {
      bytes = m && key ? await readFile(packageFile(m[1])) : null;
    } catch {
      bytes = null;
    }
    if (!bytes || options.refuseWebSocket) {
      socket.end("HTTP/1.1 404 Not Found\r\nContent-Length: 0\r\nConnection: close\r\n\r\n");
      return;
    }
    const accept = createHash("sha1").update(key + "258EAFA5-E914-47DA-95CA-C5AB0DC85B11").digest("base64");
    socket.write(`HTTP/1.1 101 Switching Protocols\r\nUpgrade: websocket\r\nConnection: Upgrade\r\nSec-WebSocket-Accept: ${accept}\r\n\r\n`);
    let closed = false;
    socket.on("close", () => {
      closed = true;
    });
    socket.on("error", () => {
      closed = true;
    });
    socket.on("data", () => {}); // the client sends nothing that matters
    const frame = (opcode, payload) => {
      const n = payload.length;
      const head = n < 126 ? Buffer.from([0x80 | opcode, n]) : n < 65536 ? Buffer.alloc(4) : Buffer.alloc(10);
      if (n >= 126) {
        head[0] = 0x80 | opcode;
        if (n < 65536) {
          head[1] = 126;
          head.writeUInt16BE(n, 2);
        } else {
          head[1] = 127;
          head.writeBigUInt64BE(BigInt(n), 2);
        }
      }
      return Buffer.concat([head, payload]);
    };
    const send = async (opcode, payload) => {
      if (closed) return false;
      if (!socket.write(frame(opcode, payload))) await new Promise((r) => socket.once("drain", r));
      return !closed;
    };
    const { headerBytes, header } = packageBoundaries(bytes);
    const sections = header.sections.map((s) => ({ name: s.name, offset: headerBytes + s.offset, size: s.size }));
    await send(1, Buffer.from(JSON.stringify({ type: "begin", id: m[1], bytes: bytes.length, sections })));
    const ok = await pump(m[1], bytes, 0, options.cutWebSocketAt ?? bytes.length, (piece) => send(2, Buffer.from(piece)));
    if (options.cutWebSocketAt !== undefined) {
      socket.destroy(); // a connection lost mid-stream
      return;
    }
    if (ok) await send(1, Buffer.from(JSON.stringify({ type: "end" })));
    const code = Buffer.alloc(2);
    code.writeUInt16BE(1000);
    await send(8, code);
    socket.end();
  });

  await new Promise((resolve) => server.listen(0, "127.0.0.1", resolve));
  const { port } = server.address();
  const sockets = new Set();
  server.on("connection", (s) => {
    sockets.add(s);
    s.on("close", () => sockets.delete(s));
  });
  return {
    url: `http://127.0.0.1:${port}/`,
    port,
    requests,
    hold(id, offsets) {
      gates.set(id, { offsets: [...offsets].sort((a, b) => a - b), passed: 0, waiters: [] });
    },
    release(id) {
      const g = gate(id);
      if (!g) return;
      g.passed += 1;
      wake(g);
    },
    releaseAll(id) {
      const g = gate(id);
      if (!g) return;
      g.passed = Infinity;
      wake(g);
    },
    close() {
      for (const g of gates.values()) {
        g.passed = Infinity;
        wake(g);
      }
      for (const s of sockets) s.destroy();
      return new Promise((resolve) => server.close(resolve));
    },
  };
}
