// A TCP proxy that limits what a server sends to each client to a fixed bit rate: a slow link on
// loopback, for any server (btf serve, nginx, test/server.mjs) and any protocol on top (HTTP,
// WebSocket). Requests go upstream unpaced. Each connection has its own link: bytes leave the
// proxy when the last of them would have arrived over a link of that rate, in pieces of a few
// milliseconds (a token bucket of 10 ms depth), and the server is read only as fast as the link
// drains.

import { connect, createServer } from "node:net";

const sleep = (ms) => new Promise((r) => setTimeout(r, ms));

/** "10mbit", "100Mbit", "512kbit", "1gbit" or a number of bits per second → bits per second. */
export function parseRate(text) {
  const m = /^\s*([\d.]+)\s*(k|m|g)?(bit|bps)?\s*$/i.exec(String(text));
  if (!m) throw new Error(`rate '${text}': expected e.g. 10mbit, 512kbit or 1000000`);
  const scale = { k: 1e3, m: 1e6, g: 1e9 }[(m[2] ?? "").toLowerCase()] ?? 1;
  const bits = Number(m[1]) * scale;
  if (!(bits > 0)) throw new Error(`rate '${text}' must be positive`);
  return bits;
}

/**
 * Starts the proxy on 127.0.0.1 (a free port) in front of `upstreamPort`. Returns
 * { port, url, close, connections }.
 */
export async function startThrottle(upstreamPort, bitsPerSecond, { upstreamHost = "127.0.0.1" } = {}) {
  const bytesPerMs = bitsPerSecond / 8 / 1000;
  // A piece is ~4 ms of the link (at least one Ethernet frame's payload).
  const piece = Math.max(1448, Math.round(bytesPerMs * 4));
  const sockets = new Set();
  let connections = 0;

  const server = createServer((client) => {
    connections += 1;
    const upstream = connect(upstreamPort, upstreamHost);
    sockets.add(client);
    sockets.add(upstream);
    client.setNoDelay(true);
    upstream.setNoDelay(true);
    let clock = 0; // when the link is free again (ms, performance.now())
    let queue = Promise.resolve();

    const end = () => {
      client.destroy();
      upstream.destroy();
      sockets.delete(client);
      sockets.delete(upstream);
    };
    client.on("error", end);
    upstream.on("error", end);
    client.on("close", end);
    client.on("data", (d) => upstream.write(d));
    client.on("end", () => upstream.end());
    upstream.on("data", (data) => {
      // Read no more from the server until this block has crossed the link.
      upstream.pause();
      queue = queue.then(async () => {
        for (let at = 0; at < data.length && !client.destroyed; at += piece) {
          const part = data.subarray(at, Math.min(at + piece, data.length));
          // Timers fire late by a millisecond or so; the link keeps 10 ms of credit so that the
          // lateness does not add up to a lower rate.
          clock = Math.max(clock, performance.now() - 10) + part.length / bytesPerMs;
          const wait = clock - performance.now();
          if (wait > 0.5) await sleep(wait);
          if (!client.write(part)) await new Promise((r) => client.once("drain", r));
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
    close: () =>
      new Promise((resolve) => {
        for (const s of sockets) s.destroy();
        server.close(() => resolve());
      }),
  };
}
