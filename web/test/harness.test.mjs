// SPDX-License-Identifier: MIT
// Tests of the test harness itself, in node without a browser or a btf binary: the throttling
// proxy (test/throttle.mjs) on a virtual clock and with its holds, and the first-run build of
// build/web/btf (test/fixtures.mjs) with stand-ins for cmake and ninja.

import { test } from "node:test";
import assert from "node:assert/strict";
import { chmodSync, existsSync, mkdirSync, mkdtempSync, readFileSync, rmSync, writeFileSync } from "node:fs";
import { createServer as createHttpServer } from "node:http";
import { connect, createServer } from "node:net";
import { createHash } from "node:crypto";
import os from "node:os";
import path from "node:path";
import { btfBinary } from "./fixtures.mjs";
import { parseRange, parseRate, startThrottle } from "./throttle.mjs";

const listen = (server) => new Promise((r) => server.listen(0, "127.0.0.1", () => r(server.address().port)));
const closeServer = (server) => new Promise((r) => server.close(() => r()));
const pattern = (n, seed = 7919) => {
  const b = Buffer.alloc(n);
  for (let i = 0; i < n; ++i) b[i] = (i * seed + (i >> 8)) & 0xff;
  return b;
};

test("the throttling proxy paces a server's bytes at the link rate and passes them unchanged", async () => {
  assert.equal(parseRate("10mbit"), 1e7);
  assert.equal(parseRate("512kbit"), 512e3);
  assert.throws(() => parseRate("fast"), /expected e\.g\. 10mbit/);
  const payload = pattern(500000);
  const origin = createServer((s) => s.end(payload));
  const rate = 16e6; // 2000 bytes per ms: 250 ms of link time for the payload, pieces of 8000 bytes
  // A virtual clock: the link's waits advance it instead of passing, so what is checked is the
  // schedule the proxy computes, whatever the machine's load.
  let now = 0;
  const sleeps = [];
  const clock = {
    now: () => now,
    sleep: async (ms) => {
      sleeps.push(ms);
      now += ms;
    },
  };
  const link = await startThrottle(await listen(origin), rate, { clock });
  try {
    const got = await new Promise((resolve, reject) => {
      const chunks = [];
      const c = connect(link.port, "127.0.0.1");
      c.on("data", (d) => chunks.push(d));
      c.on("end", () => resolve(Buffer.concat(chunks)));
      c.on("error", reject);
    });
    assert.ok(got.equals(payload), "the bytes changed on the way");
    // The last bytes left when the whole payload had crossed the link: its bits over the rate
    // (less a last wait under 0.5 ms, which the proxy skips), and no wait longer than one piece
    // (4 ms) and a skipped wait before it.
    const expected = ((payload.length * 8) / rate) * 1000;
    assert.ok(now <= expected + 1e-6 && now >= expected - 0.5, `${now} ms of link time for ${expected} ms`);
    assert.ok(Math.max(...sleeps) <= 4 + 0.5, `a wait of ${Math.max(...sleeps)} ms`);
    assert.ok(Math.abs(sleeps.reduce((a, b) => a + b, 0) - now) < 1e-6);
  } finally {
    await link.close();
    await closeServer(origin);
  }
});

/** Reads a body until `n` bytes (or its end) arrived; returns how many have. */
async function readTo(body, n) {
  while (body.got < n) {
    const { done, value } = await body.reader.read();
    if (done) break;
    body.chunks.push(Buffer.from(value));
    body.got += value.length;
  }
  return body.got;
}
const openBody = (response) => ({ reader: response.body.getReader(), chunks: [], got: 0 });

/** A WebSocket client on a raw socket: the binary messages' bytes and what came in all. */
function webSocketClient(port, target) {
  const c = connect(port, "127.0.0.1");
  const state = { raw: 0, head: null, payload: [], binary: 0, texts: [], closed: false, waiters: [] };
  let buffer = Buffer.alloc(0);
  const check = () => {
    for (const w of state.waiters.splice(0)) if (!w()) state.waiters.push(w);
  };
  c.on("data", (d) => {
    state.raw += d.length;
    buffer = Buffer.concat([buffer, d]);
    if (!state.head) {
      const end = buffer.indexOf("\r\n\r\n");
      if (end < 0) return;
      state.head = buffer.subarray(0, end).toString();
      buffer = buffer.subarray(end + 4);
    }
    for (;;) {
      if (buffer.length < 2) break;
      const short = buffer[1] & 0x7f;
      const size = short < 126 ? 2 : short === 126 ? 4 : 10;
      if (buffer.length < size) break;
      const n = short < 126 ? short : short === 126 ? buffer.readUInt16BE(2) : Number(buffer.readBigUInt64BE(2));
      if (buffer.length < size + n) break;
      const op = buffer[0] & 0x0f, body = buffer.subarray(size, size + n);
      if (op === 2) (state.payload.push(Buffer.from(body)), (state.binary += n));
      else if (op === 1) state.texts.push(body.toString());
      else if (op === 8) state.closed = true;
      buffer = buffer.subarray(size + n);
    }
    check();
  });
  c.write(`GET ${target} HTTP/1.1\r\nHost: x\r\nUpgrade: websocket\r\nConnection: Upgrade\r\nSec-WebSocket-Key: dGhlIHNhbXBsZSBub25jZQ==\r\nSec-WebSocket-Version: 13\r\n\r\n`);
  state.until = (f) => new Promise((r) => (f() ? r() : state.waiters.push(() => (f() ? (r(), true) : false))));
  state.socket = c;
  return state;
}

test("the throttling proxy holds a file at given offsets over HTTP and WebSocket, and queued responses until released", { timeout: 120000 }, async () => {
  assert.deepEqual(parseRange("bytes=5-9"), { from: 5, to: 10 });
  assert.deepEqual(parseRange("bytes=5-"), { from: 5, to: null });
  assert.equal(parseRange(undefined), null);
  const file = pattern(100000);
  const small = Buffer.from("small file\n");
  // An origin with keep-alive, Content-Length and chunked bodies, Range, and a WebSocket stream
  // that sends `file` in binary messages of 20000 bytes after a text message.
  const origin = createHttpServer((req, res) => {
    const p = new URL(req.url, "http://x").pathname;
    if (p === "/small.txt") return res.writeHead(200, { "Content-Length": small.length }).end(small);
    if (p === "/chunked") {
      res.writeHead(200, { "Content-Type": "text/plain" });
      res.write("first part, ");
      return res.end("second part");
    }
    if (!/^\/(materials\/[xy]\.btfpkg|q\.bin)$/.test(p)) return res.writeHead(404, { "Content-Length": 0 }).end();
    const m = /^bytes=(\d+)-$/.exec(req.headers.range ?? "");
    const from = m ? Number(m[1]) : 0;
    const headers = { "Content-Length": file.length - from };
    if (m) headers["Content-Range"] = `bytes ${from}-${file.length - 1}/${file.length}`;
    res.writeHead(m ? 206 : 200, headers);
    res.end(req.method === "HEAD" ? undefined : file.subarray(from));
    if (p === "/q.bin") res.once("finish", () => origin.onQ?.());
  });
  origin.on("upgrade", (req, socket) => {
    const accept = createHash("sha1").update(req.headers["sec-websocket-key"] + "258EAFA5-E914-47DA-95CA-C5AB0DC85B11").digest("base64");
    socket.write(`HTTP/1.1 101 Switching Protocols\r\nUpgrade: websocket\r\nConnection: Upgrade\r\nSec-WebSocket-Accept: ${accept}\r\n\r\n`);
    const text = Buffer.from('{"type":"begin"}');
    socket.write(Buffer.concat([Buffer.from([0x81, text.length]), text]));
    for (let at = 0; at < file.length; at += 20000) {
      const head = Buffer.from([0x82, 126, 0, 0]);
      head.writeUInt16BE(20000, 2);
      socket.write(Buffer.concat([head, file.subarray(at, at + 20000)]));
    }
    socket.end(Buffer.from([0x88, 2, 0x03, 0xe8]));
  });
  const link = await startThrottle(await listen(origin), 1e9);
  const get = (target, init) => fetch(`${link.url}${target}`, init);
  try {
    // Responses the holds do not match pass whole, on a connection kept alive between them.
    assert.equal(await (await get("small.txt")).text(), "small file\n");
    assert.equal(await (await get("chunked")).text(), "first part, second part");
    assert.equal((await get("materials/x.btfpkg", { method: "HEAD" })).headers.get("content-length"), "100000");
    assert.equal(await (await get("small.txt")).text(), "small file\n");

    // A body held at 30000 and 70000: it stops exactly there until each release.
    link.hold(/^\/materials\/x\.btfpkg$/, [30000, 70000]);
    const x = openBody(await get("materials/x.btfpkg"));
    assert.equal(await readTo(x, 30000), 30000);
    link.release();
    assert.equal(await readTo(x, 70000), 70000);
    link.release();
    assert.equal(await readTo(x, Infinity), 100000);
    assert.ok(Buffer.concat(x.chunks).equals(file));

    // A 206 answer counts from its first byte's place in the file.
    link.hold(/^\/materials\/y\.btfpkg$/, [60000, 75000]);
    const y = openBody(await get("materials/y.btfpkg", { headers: { Range: "bytes=50000-" } }));
    assert.equal(await readTo(y, 10000), 10000);
    link.release();
    assert.equal(await readTo(y, 25000), 25000);
    link.release();
    assert.equal(await readTo(y, Infinity), 50000);
    assert.ok(Buffer.concat(y.chunks).equals(file.subarray(50000)));

    // WebSocket: offsets count the binary messages' bytes; the message that would cross 30000
    // (20000 to 40000) waits whole, so 20000 arrive; then the rest and the close.
    link.hold(/^\/stream\/x$/, [30000]);
    const ws = webSocketClient(link.port, "/stream/x");
    await ws.until(() => ws.binary >= 20000);
    assert.match(ws.head, /^HTTP\/1\.1 101 /);
    assert.deepEqual(ws.texts, ['{"type":"begin"}']);
    assert.equal(ws.binary, 20000);
    link.release();
    await ws.until(() => ws.closed);
    assert.ok(Buffer.concat(ws.payload).equals(file));
    ws.socket.destroy();

    // Queued responses wait, head and all, until the test releases each: the first is held
    // while a second one, asked for after the server had sent the first, is released and read.
    link.queue(/^\/q\.bin$/);
    let answered = false;
    const sent = new Promise((r) => (origin.onQ = r));
    const first = get("q.bin", { headers: { Range: "bytes=99990-" } }).then((r) => ((answered = true), r));
    await sent;
    while (link.waiting.length === 0) await new Promise((r) => setImmediate(r));
    const second = get("q.bin", { headers: { Range: "bytes=99000-" } });
    while (link.waiting.length < 2) await new Promise((r) => setImmediate(r));
    assert.deepEqual(
      link.waiting.map((w) => [w.request.method, w.request.path, w.request.range]),
      [
        ["GET", "/q.bin", { from: 99990, to: null }],
        ["GET", "/q.bin", { from: 99000, to: null }],
      ],
    );
    link.waiting[1].release();
    assert.ok(Buffer.from(await (await second).arrayBuffer()).equals(file.subarray(99000)));
    assert.equal(answered, false, "a queued response came before its release");
    link.waiting[0].release();
    const r = await first;
    assert.equal(r.status, 206);
    assert.ok(Buffer.from(await r.arrayBuffer()).equals(file.subarray(99990)));
    assert.equal(link.waiting.length, 0);
    assert.deepEqual(
      link.requests.map((w) => `${w.method} ${w.path}`),
      ["GET /small.txt", "GET /chunked", "HEAD /materials/x.btfpkg", "GET /small.txt", "GET /materials/x.btfpkg", "GET /materials/y.btfpkg", "GET /stream/x", "GET /q.bin", "GET /q.bin"],
    );
  } finally {
    await link.close();
    origin.closeAllConnections?.();
    await closeServer(origin);
  }
});

test("without BTF_BIN the first run configures and builds build/web/btf with the documented commands, once", () => {
  const root = mkdtempSync(path.join(os.tmpdir(), "btf-first-run-"));
  try {
    // Stand-ins for cmake and ninja that log their arguments; ninja makes the binary, as the real
    // build would. Both print, as the real ones do (the output must not break the run).
    const bin = path.join(root, "bin"), repo = path.join(root, "repo"), log = path.join(root, "log");
    mkdirSync(bin);
    mkdirSync(repo);
    const tool = (name, body) => {
      writeFileSync(path.join(bin, name), `#!/bin/sh\necho "${name} $*" >> "${log}"\necho "${name} says hello"\n${body}\n`);
      chmodSync(path.join(bin, name), 0o755);
    };
    tool("cmake", 'mkdir -p "$4"');
    tool("ninja", 'touch "$2/$3"');
    const env = { PATH: `${bin}:${process.env.PATH}` };
    const out = btfBinary({ env, repo });
    assert.equal(out, path.join(repo, "build/web/btf"));
    assert.ok(existsSync(out));
    const dir = path.join(repo, "build/web");
    assert.deepEqual(readFileSync(log, "utf8").trim().split("\n"), [
      `cmake -S ${repo} -B ${dir} -G Ninja -DCMAKE_BUILD_TYPE=Release -DBTF_BUILD_BENCH=OFF -DBTF_BUILD_TESTS=OFF`,
      `ninja -C ${dir} btf`,
    ]);
    // The second run finds it; BTF_BIN wins over it.
    assert.equal(btfBinary({ env, repo }), out);
    assert.equal(readFileSync(log, "utf8").trim().split("\n").length, 2);
    assert.equal(btfBinary({ env: { ...env, BTF_BIN: "/somewhere/btf" }, repo }), "/somewhere/btf");
    // A failed build says what failed and what to do.
    rmSync(out);
    tool("ninja", "exit 3");
    assert.throws(() => btfBinary({ env, repo }), /building .*build\/web\/btf: ninja -C .* btf failed \(exit 3\); or set BTF_BIN/);
    tool("ninja", "true");
    assert.throws(() => btfBinary({ env, repo }), /ninja -C .* btf finished without making/);
    assert.throws(() => btfBinary({ env: { PATH: "/nonexistent" }, repo }), /cmake is not installed/);
  } finally {
    rmSync(root, { recursive: true, force: true });
  }
});
