// SPDX-License-Identifier: MIT
// Getting a material's bytes (docs/protocol.md): the WebSocket stream when the server offers one,
// otherwise (or when the socket fails) the package file over HTTP, read as its body arrives. A
// transfer cut short resumes with a Range request from the first byte not yet received.

export interface MaterialEntry {
  id: string;
  name?: string;
  codec?: string;
  width?: number;
  height?: number;
  views?: number;
  lights?: number;
  bytes?: number;
  header_bytes?: number;
  sections?: { name: string; offset: number; size: number }[];
  package: string;
  stream?: string | null;
}

export interface StreamHandlers {
  /** The total size when known (from the list, the WebSocket's begin or Content-Length). */
  total(bytes: number): void;
  /** The next bytes of the file, in order. */
  chunk(data: Uint8Array): void;
  /** The whole file arrived. */
  end(): void;
  error(message: string): void;
  transport(kind: "websocket" | "http"): void;
}

export interface StreamOptions {
  transport: "auto" | "websocket" | "http";
  /** Retries of an HTTP transfer cut short. */
  retries?: number;
}

/** Streams `entry`'s package; returns a function that stops the transfer. */
export function openStream(entry: MaterialEntry, base: string, handlers: StreamHandlers, options: StreamOptions): () => void {
  let received = 0;
  let stopped = false;
  let finished = false;
  let socket: WebSocket | null = null;
  let abort: AbortController | null = null;
  const retries = options.retries ?? 3;

  const deliver = (data: Uint8Array) => {
    if (stopped || finished || data.length === 0) return;
    received += data.length;
    handlers.chunk(data);
  };
  const finish = () => {
    if (stopped || finished) return;
    finished = true;
    handlers.end();
  };
  const failWith = (message: string) => {
    if (stopped || finished) return;
    finished = true;
    handlers.error(message);
  };

  const http = async (attempt: number): Promise<void> => {
    handlers.transport("http");
    const url = new URL(entry.package, base).toString();
    abort = new AbortController();
    const from = received;
    let response: Response;
    try {
      response = await fetch(url, { headers: from > 0 ? { Range: `bytes=${from}-` } : {}, signal: abort.signal, cache: "no-store" });
    } catch (e) {
      if (stopped) return;
      if (attempt < retries && from > 0) return http(attempt + 1);
      return failWith(`cannot fetch ${entry.package}: ${(e as Error).message || "network error"}`);
    }
    if (stopped) return;
    if (!response.ok) return failWith(`cannot fetch ${entry.package}: HTTP ${response.status} ${response.statusText}`);
    let skip = 0;
    if (from > 0) {
      if (response.status === 206) {
        const range = /bytes (\d+)-/.exec(response.headers.get("Content-Range") ?? "");
        if (!range || Number(range[1]) !== from) return failWith(`${entry.package}: the server answered the range from byte ${from} with ${response.headers.get("Content-Range")}`);
      } else {
        skip = from; // the server ignored Range: drop what we have already
      }
    } else {
      const length = Number(response.headers.get("Content-Length"));
      if (length > 0 && !entry.bytes) handlers.total(length);
    }
    if (!response.body) {
      const bytes = new Uint8Array(await response.arrayBuffer());
      deliver(bytes.subarray(skip));
      return finish();
    }
    const reader = response.body.getReader();
    try {
      for (;;) {
        const { done, value } = await reader.read();
        if (stopped) return;
        if (done) break;
        let chunk = value;
        if (skip > 0) {
          const n = Math.min(skip, chunk.length);
          skip -= n;
          chunk = chunk.subarray(n);
        }
        deliver(chunk);
      }
    } catch (e) {
      if (stopped) return;
      if (attempt < retries) return http(attempt + 1);
      return failWith(`${entry.package}: the transfer broke off after ${received} bytes: ${(e as Error).message}`);
    }
    if (entry.bytes && received < entry.bytes && attempt < retries) return http(attempt + 1);
    finish();
  };

  const websocket = () => {
    handlers.transport("websocket");
    const url = new URL(entry.stream!, base);
    url.protocol = url.protocol === "https:" ? "wss:" : "ws:";
    let ended = false;
    try {
      socket = new WebSocket(url.toString());
    } catch {
      void http(0);
      return;
    }
    socket.binaryType = "arraybuffer";
    socket.onmessage = (event: MessageEvent) => {
      if (typeof event.data === "string") {
        let msg: { type?: string; bytes?: number };
        try {
          msg = JSON.parse(event.data);
        } catch {
          return;
        }
        if (msg.type === "begin") {
          if (typeof msg.bytes === "number") handlers.total(msg.bytes);
        } else if (msg.type === "end") {
          ended = true;
        }
        return;
      }
      deliver(new Uint8Array(event.data as ArrayBuffer));
    };
    socket.onclose = () => {
      if (stopped || finished) return;
      if (ended) return finish();
      // Refused, unreachable or cut short: the package file over HTTP, from the first byte the
      // socket did not deliver.
      void http(0);
    };
  };

  if (options.transport !== "http" && entry.stream) websocket();
  else void http(0);

  return () => {
    stopped = true;
    socket?.close();
    abort?.abort();
  };
}

/** Fetches the material list; throws with a message for the page. */
export async function fetchMaterials(api: string, base: string): Promise<MaterialEntry[]> {
  const url = new URL(api, base).toString();
  let response: Response;
  try {
    response = await fetch(url, { cache: "no-store" });
  } catch (e) {
    throw new Error(`The btfkit server does not answer: GET ${api} failed (${(e as Error).message || "network error"}). Is btf serve running, or the bundle served?`);
  }
  if (!response.ok)
    throw new Error(`The btfkit server cannot list materials: GET ${api} answered HTTP ${response.status} ${response.statusText}.`);
  let json: { protocol?: number; materials?: MaterialEntry[] };
  try {
    json = await response.json();
  } catch {
    throw new Error(`The material list at ${api} is not valid JSON.`);
  }
  if (json.protocol !== 1) throw new Error(`The material list at ${api} speaks protocol ${String(json.protocol)}; this viewer speaks protocol 1.`);
  if (!Array.isArray(json.materials)) throw new Error(`The material list at ${api} has no 'materials' array.`);
  return json.materials;
}

/**
 * Bytes [from, to) of a material's package file by an HTTP Range request (BSVTF tiles and
 * packets). Throws with a message naming the package when the server does not answer with
 * exactly those bytes.
 */
export async function fetchRange(entry: MaterialEntry, base: string, from: number, to: number, signal?: AbortSignal): Promise<Uint8Array> {
  const url = new URL(entry.package, base).toString();
  let response: Response;
  try {
    response = await fetch(url, { headers: { Range: `bytes=${from}-${to - 1}` }, cache: "no-store", signal });
  } catch (e) {
    throw new Error(`${entry.package}: GET bytes ${from}–${to - 1} failed (${(e as Error).message || "network error"})`);
  }
  if (response.status !== 206)
    throw new Error(`${entry.package}: the server answered a byte-range request with HTTP ${response.status} (BSVTF materials need Range support)`);
  const data = new Uint8Array(await response.arrayBuffer());
  if (data.length !== to - from) throw new Error(`${entry.package}: asked for ${to - from} bytes from byte ${from}, received ${data.length}`);
  return data;
}
