// SPDX-License-Identifier: MIT
// A TCP proxy that limits what a server sends to each client to a fixed bit rate: a slow link on
// loopback, for any server (btf serve, nginx, test/server.mjs) and any protocol on top (HTTP,
// WebSocket). Requests go upstream unpaced. Each connection has its own link: bytes leave the
// proxy when the last of them would have arrived over a link of that rate, in pieces of a few
// milliseconds (a token bucket of 10 ms depth), and the server is read only as fast as the link
// drains.
//
// The proxy also reads the HTTP/1.1 it carries (requests; response heads, Content-Length and
// chunked bodies; WebSocket frames after a 101), so that a test can stop a transfer at chosen
// bytes of a file and let it on when the page has shown what those bytes brought: stages driven
// by the bytes delivered, never by how fast either side happens to run.
//  - hold(match, offsets): the bytes of a matching file (an HTTP body, at its place in the file
//    for a 206 answer; or a WebSocket's binary messages, concatenated) stop before each offset
//    until release() lets them pass the next one. A WebSocket message that would cross an offset
//    waits whole (btf serve's messages end at section boundaries, so section ends cut exactly).
//  - queue(match): matching responses wait, head and body, until the test releases each one
//    (link.waiting lists them with their request).
// `match` is a RegExp tried on the request's path, or a function of the request
// { method, path, range: { from, to } | null (to exclusive, null when open), websocket }.

import { connect, createServer } from "node:net";

/** Wall-clock time for the link's pacing; tests of the pacing pass a virtual clock instead. */
export const realClock = {
  now: () => performance.now(),
  sleep: (ms) => new Promise((r) => setTimeout(r, ms)),
};

/** "10mbit", "100Mbit", "512kbit", "1gbit" or a number of bits per second → bits per second. */
export function parseRate(text) {
  const m = /^\s*([\d.]+)\s*(k|m|g)?(bit|bps)?\s*$/i.exec(String(text));
  if (!m) throw new Error(`rate '${text}': expected e.g. 10mbit, 512kbit or 1000000`);
  const scale = { k: 1e3, m: 1e6, g: 1e9 }[(m[2] ?? "").toLowerCase()] ?? 1;
  const bits = Number(m[1]) * scale;
  if (!(bits > 0)) throw new Error(`rate '${text}' must be positive`);
  return bits;
}

/** The start line and headers (names in lower case) of an HTTP head without its blank line. */
function parseHead(text) {
  const [start, ...lines] = text.split("\r\n");
  const headers = {};
  for (const line of lines) {
    const colon = line.indexOf(":");
    if (colon > 0) headers[line.slice(0, colon).trim().toLowerCase()] = line.slice(colon + 1).trim();
  }
  return { start, headers };
}

/** A request's `Range: bytes=A-B` as { from: A, to: B + 1 } (to null for `bytes=A-`), else null. */
export function parseRange(header) {
  const m = /^bytes=(\d+)-(\d*)$/.exec(header ?? "");
  return m ? { from: Number(m[1]), to: m[2] === "" ? null : Number(m[2]) + 1 } : null;
}

const END = Buffer.from("\r\n\r\n");

/** Reads the requests a client sends (GET and HEAD without bodies; stops at an Upgrade). */
class RequestReader {
  constructor(onRequest) {
    this.onRequest = onRequest;
    this.buffer = Buffer.alloc(0);
    this.skip = 0;
    this.done = false;
  }

  push(data) {
    if (this.done) return;
    this.buffer = Buffer.concat([this.buffer, data]);
    for (;;) {
      if (this.skip > 0) {
        const n = Math.min(this.skip, this.buffer.length);
        this.skip -= n;
        this.buffer = this.buffer.subarray(n);
        if (this.skip > 0) return;
      }
      const end = this.buffer.indexOf(END);
      if (end < 0) return;
      const { start, headers } = parseHead(this.buffer.subarray(0, end).toString("latin1"));
      this.buffer = this.buffer.subarray(end + 4);
      const [method = "", target = ""] = start.split(" ");
      const websocket = /websocket/i.test(headers.upgrade ?? "");
      this.onRequest({ method, path: target.split("?")[0], range: parseRange(headers.range), websocket });
      // After an upgrade the client speaks WebSocket; a request body in chunks is not read.
      if (websocket || /chunked/i.test(headers["transfer-encoding"] ?? "")) {
        this.done = true;
        return;
      }
      this.skip = Number(headers["content-length"] ?? 0) || 0;
    }
  }
}

/**
 * Splits what a server sends into pieces that each belong to one part of one response: its head,
 * bytes of its body (with their offset in the file), chunk framing, or a WebSocket frame's header
 * and payload. Responses are matched with the connection's requests in order.
 */
class ResponseReader {
  constructor(requests) {
    this.requests = requests; // requests not yet answered, oldest first
    this.mode = "head";
    this.buffer = Buffer.alloc(0); // a head or a frame header not yet complete
    this.response = null;
    this.left = 0; // body bytes (or chunk bytes) to come
    this.frame = null;
    this.wsOffset = 0; // binary payload bytes so far
    this.dataOpcode = 0; // of the message a continuation frame continues
  }

  split(data) {
    const out = [];
    let at = 0;
    const take = (n) => {
      const part = data.subarray(at, at + n);
      at += n;
      return part;
    };
    if (this.mode === "raw") return [{ bytes: data, response: null, kind: "raw" }];
    while (at < data.length) {
      const r = this.response;
      if (this.mode === "head") {
        // The head goes out once complete (with the request it answers known).
        const before = this.buffer.length;
        this.buffer = Buffer.concat([this.buffer, data.subarray(at)]);
        if (!(this.buffer.length < 5 ? "HTTP/".startsWith(this.buffer.toString("latin1")) : this.buffer.subarray(0, 5).toString("latin1") === "HTTP/")) {
          // Not HTTP: the rest of the connection passes as it comes.
          this.mode = "raw";
          out.push({ bytes: this.buffer, response: null, kind: "raw" });
          at = data.length;
          this.buffer = Buffer.alloc(0);
          break;
        }
        const end = this.buffer.indexOf(END);
        if (end < 0) {
          at = data.length;
          break;
        }
        const head = this.buffer.subarray(0, end + 4);
        at += end + 4 - before;
        this.buffer = Buffer.alloc(0);
        const response = this.begin(parseHead(head.subarray(0, end).toString("latin1")));
        out.push({ bytes: head, response, kind: "head" });
        continue;
      }
      if (this.mode === "body" || this.mode === "chunk-data") {
        const n = Math.min(this.left, data.length - at);
        out.push({ bytes: take(n), response: r, kind: "body", offset: r.offset });
        r.offset += n;
        this.left -= n;
        if (this.left === 0) {
          if (this.mode === "body") this.finish();
          else (this.mode = "chunk-crlf"), (this.left = 2);
        }
        continue;
      }
      if (this.mode === "until-close") {
        const n = data.length - at;
        out.push({ bytes: take(n), response: r, kind: "body", offset: r.offset });
        r.offset += n;
        continue;
      }
      if (this.mode === "chunk-crlf") {
        const n = Math.min(this.left, data.length - at);
        out.push({ bytes: take(n), response: r, kind: "framing" });
        this.left -= n;
        if (this.left === 0) this.mode = "chunk-size";
        continue;
      }
      if (this.mode === "chunk-size" || this.mode === "trailer") {
        // A chunk's size line, or a line of the trailer (an empty one ends the response).
        const before = this.buffer.length;
        this.buffer = Buffer.concat([this.buffer, data.subarray(at)]);
        const crlf = this.buffer.indexOf("\r\n");
        if (crlf < 0) {
          out.push({ bytes: take(data.length - at), response: r, kind: "framing" });
          continue;
        }
        const line = this.buffer.subarray(0, crlf).toString("latin1");
        out.push({ bytes: take(crlf + 2 - before), response: r, kind: "framing" });
        this.buffer = Buffer.alloc(0);
        if (this.mode === "trailer") {
          if (line === "") this.finish();
        } else {
          const size = parseInt(line, 16);
          if (size === 0) this.mode = "trailer";
          else (this.mode = "chunk-data"), (this.left = size);
        }
        continue;
      }
      // WebSocket frames from the server (unmasked).
      if (!this.frame) {
        const before = this.buffer.length;
        this.buffer = Buffer.concat([this.buffer, data.subarray(at)]);
        const b = this.buffer;
        if (b.length < 2) {
          at = data.length;
          break;
        }
        const short = b[1] & 0x7f;
        const size = short < 126 ? 2 : short === 126 ? 4 : 10;
        if (b.length < size) {
          at = data.length;
          break;
        }
        const length = short < 126 ? short : short === 126 ? b.readUInt16BE(2) : Number(b.readBigUInt64BE(2));
        const opcode = b[0] & 0x0f;
        if (opcode === 1 || opcode === 2) this.dataOpcode = opcode;
        const binary = opcode === 2 || (opcode === 0 && this.dataOpcode === 2);
        const frame = { left: length, binary, from: this.wsOffset, to: binary ? this.wsOffset + length : this.wsOffset };
        if (binary) this.wsOffset += length;
        at += size - before;
        this.buffer = Buffer.alloc(0);
        out.push({ bytes: b.subarray(0, size), response: r, kind: "frame", frame });
        this.frame = frame.left > 0 ? frame : null;
        continue;
      }
      const n = Math.min(this.frame.left, data.length - at);
      out.push({ bytes: take(n), response: r, kind: "payload" });
      this.frame.left -= n;
      if (this.frame.left === 0) this.frame = null;
    }
    return out;
  }

  // A response head: what follows it, and which request it answers. Returns the response.
  begin({ start, headers }) {
    const status = Number(start.split(" ")[1]);
    const interim = status >= 100 && status < 200 && status !== 101;
    const request = (interim ? this.requests[0] : this.requests.shift()) ?? null;
    const range = /^bytes (\d+)-/.exec(headers["content-range"] ?? "");
    const response = { request, queued: interim ? null : request?.queued ?? null, status, offset: status === 206 && range ? Number(range[1]) : 0 };
    this.response = response;
    if (status === 101) this.mode = "ws";
    else if (interim || status === 204 || status === 304 || request?.method === "HEAD") this.finish();
    else if (/chunked/i.test(headers["transfer-encoding"] ?? "")) this.mode = "chunk-size";
    else if (headers["content-length"] !== undefined) {
      this.left = Number(headers["content-length"]);
      this.mode = "body";
      if (this.left === 0) this.finish();
    } else this.mode = "until-close";
    return response;
  }

  finish() {
    this.mode = "head";
    this.response = null;
  }
}

/**
 * Starts the proxy on 127.0.0.1 (a free port) in front of `upstreamPort`. Returns
 * { port, url, close, connections, hold, release, releaseAll, queue, waiting, requests }.
 */
export async function startThrottle(upstreamPort, bitsPerSecond, { upstreamHost = "127.0.0.1", clock = realClock } = {}) {
  const bytesPerMs = bitsPerSecond / 8 / 1000;
  // A piece is ~4 ms of the link (at least one Ethernet frame's payload).
  const piece = Math.max(1448, Math.round(bytesPerMs * 4));
  const sockets = new Set();
  let connections = 0;
  const requests = []; // every request seen, in order
  const holds = []; // { match, offsets, passed }
  const queues = []; // match
  const waiting = []; // queued responses not yet released: { request, release() }
  let wake = [];
  const changed = () => {
    const w = wake;
    wake = [];
    for (const r of w) r();
  };
  const nextChange = () => new Promise((r) => wake.push(r));
  const matches = (match, request) => !!request && (typeof match === "function" ? match(request) : match.test(request.path));

  // The first offset (of the file a response carries) its bytes may not reach yet.
  const limit = (request) => {
    const h = holds.find((x) => matches(x.match, request));
    return h ? h.offsets[h.passed] ?? Infinity : Infinity;
  };

  // How many of the segment's bytes from `at` may leave now; waits until at least one may.
  async function allowed(segment, at) {
    const { response: r, kind } = segment;
    const rest = segment.bytes.length - at;
    for (;;) {
      if (kind === "head" && r.queued && !r.queued.released) {
        await nextChange();
        continue;
      }
      if (kind === "body") {
        const room = limit(r.request) - (segment.offset + at);
        if (room > 0) return Math.min(rest, room);
        await nextChange();
        continue;
      }
      if (kind === "frame" && segment.frame.binary && limit(r.request) < segment.frame.to) {
        await nextChange();
        continue;
      }
      return rest;
    }
  }

  const server = createServer((client) => {
    connections += 1;
    const upstream = connect(upstreamPort, upstreamHost);
    sockets.add(client);
    sockets.add(upstream);
    client.setNoDelay(true);
    upstream.setNoDelay(true);
    let linkFree = 0; // when the link is free again (ms, clock.now())
    let queue = Promise.resolve();
    const pending = [];
    const requestReader = new RequestReader((request) => {
      requests.push(request);
      pending.push(request);
      if (queues.some((m) => matches(m, request))) {
        const entry = {
          request,
          released: false,
          release() {
            if (entry.released) return;
            entry.released = true;
            waiting.splice(waiting.indexOf(entry), 1);
            changed();
          },
        };
        Object.defineProperty(request, "queued", { value: entry }); // not enumerable: requests stay printable
        waiting.push(entry);
      }
    });
    const responses = new ResponseReader(pending);

    const end = () => {
      client.destroy();
      upstream.destroy();
      sockets.delete(client);
      sockets.delete(upstream);
      // Queued responses of this connection that never went out no longer wait.
      for (const r of pending) {
        const i = r.queued ? waiting.indexOf(r.queued) : -1;
        if (i >= 0) waiting.splice(i, 1);
      }
      changed();
    };
    client.on("error", end);
    upstream.on("error", end);
    client.on("close", end);
    client.on("data", (d) => {
      requestReader.push(d);
      upstream.write(d);
    });
    client.on("end", () => upstream.end());
    upstream.on("data", (data) => {
      // Read no more from the server until this block has crossed the link.
      upstream.pause();
      queue = queue.then(async () => {
        for (const segment of responses.split(data)) {
          for (let at = 0; at < segment.bytes.length && !client.destroyed; ) {
            const n = Math.min(piece, await allowed(segment, at));
            if (client.destroyed) break;
            const part = segment.bytes.subarray(at, at + n);
            at += n;
            // Timers fire late by a millisecond or so; the link keeps 10 ms of credit so that the
            // lateness does not add up to a lower rate.
            linkFree = Math.max(linkFree, clock.now() - 10) + part.length / bytesPerMs;
            const wait = linkFree - clock.now();
            if (wait > 0.5) await clock.sleep(wait);
            if (!client.write(part)) await new Promise((r) => client.once("drain", r));
          }
        }
        upstream.resume();
      });
    });
    upstream.on("end", () => {
      queue = queue.then(() => client.end());
    });
  });
  await new Promise((resolve, reject) => {
    server.once("error", reject);
    server.listen(0, "127.0.0.1", resolve);
  });
  const port = server.address().port;
  return {
    port,
    url: `http://127.0.0.1:${port}/`,
    get connections() {
      return connections;
    },
    /** Every request the link carried, in order: { method, path, range, websocket }. */
    requests,
    /** Queued responses not yet released, in the order of their requests: { request, release() }. */
    waiting,
    hold(match, offsets) {
      holds.push({ match, offsets: [...offsets].sort((a, b) => a - b), passed: 0 });
    },
    /** Lets the held files pass their next offset. */
    release() {
      for (const h of holds) h.passed += 1;
      changed();
    },
    releaseAll() {
      for (const h of holds) h.passed = Infinity;
      for (const w of [...waiting]) w.release();
      changed();
    },
    queue(match) {
      queues.push(match);
    },
    close: () =>
      new Promise((resolve) => {
        for (const h of holds) h.passed = Infinity;
        for (const w of [...waiting]) w.release();
        changed();
        for (const s of sockets) s.destroy();
        server.close(() => resolve());
      }),
  };
}
