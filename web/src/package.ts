// SPDX-License-Identifier: MIT
// Incremental reader of a btfkit package (.btfpkg, docs/formats.md "btfkit package"): bytes go in
// as they arrive from the network, and every section is handed out, checked and decoded, as soon
// as its last byte is there. The checks and their messages follow the C++ reader
// (src/btf/io/package.cpp), so a broken file reads the same in the browser and on the command
// line.

import { decompress } from "fzstd";
import xxhash from "xxhash-wasm";

export const MAGIC = [0x89, 0x42, 0x54, 0x46, 0x50, 0x4b, 0x47, 0x0a];
export const PREAMBLE_BYTES = 24;
export const PACKAGE_VERSION = 1;
export const MAX_HEADER_BYTES = 64 * 1024 * 1024;
export const MAX_RAW_SIZE = 2 ** 34;

export interface SectionEntry {
  name: string;
  /** From the end of the JSON header. */
  offset: number;
  size: number;
  raw_size: number;
  coding: "raw" | "zstd";
  xxh64: string;
}

export interface PackageHeader {
  /** The whole JSON header (format, version and sections included). */
  json: Record<string, unknown>;
  /** 24 + the JSON header's length: where the first section starts in the file. */
  headerBytes: number;
  sections: SectionEntry[];
  /** The file's length when complete. */
  totalBytes: number;
}

export interface DecodedSection {
  index: number;
  entry: SectionEntry;
  /** Decoded bytes (raw_size of them). */
  data: Uint8Array;
  /** Where the section's stored bytes start in the file. */
  fileOffset: number;
}

/** XXH64 (seed 0) of some bytes as 16 lowercase hex digits, the form package headers store. */
export type Checksum = (data: Uint8Array) => string;

let checksum: Promise<Checksum> | null = null;

/**
 * The packages' checksum, XXH64 from xxhash-wasm. Its WebAssembly module is instantiated on the
 * first call (asynchronously); every later call returns the same promise.
 */
export function loadChecksum(): Promise<Checksum> {
  checksum ??= xxhash().then(({ h64Raw }) => (data: Uint8Array) => h64Raw(data, 0n).toString(16).padStart(16, "0"));
  return checksum;
}

/** A package that cannot be read; the message is one line starting with the package's name. */
export class PackageError extends Error {
  constructor(message: string) {
    super(message);
    this.name = "PackageError";
  }
}

export interface PackageHandlers {
  header?(header: PackageHeader): void;
  section?(section: DecodedSection): void;
}

/** The largest stored size zstd may need for `n` bytes (ZSTD_COMPRESSBOUND). */
function zstdBound(n: number): number {
  const small = 128 * 1024;
  return n + Math.floor(n / 256) + (n < small ? Math.floor((small - n) / 2048) : 0);
}

const SECTION_FIELDS = ["name", "offset", "size", "raw_size", "coding", "xxh64"];

function isNonNegativeInteger(v: unknown): v is number {
  return typeof v === "number" && Number.isInteger(v) && v >= 0;
}

/** Validates the JSON header's fields and section table (everything before any section is read). */
export function checkHeader(name: string, json: unknown, headerBytes: number): PackageHeader {
  const fail = (what: string): never => {
    throw new PackageError(`${name}: ${what}`);
  };
  if (typeof json !== "object" || json === null || Array.isArray(json))
    fail("header is not a JSON object");
  const h = json as Record<string, unknown>;
  for (const field of ["format", "version", "sections"])
    if (!(field in h)) fail(`header field '${field}' is missing`);
  if (h.format !== "btfpkg") fail(`header field 'format' is ${JSON.stringify(h.format)}, expected "btfpkg"`);
  if (h.version !== PACKAGE_VERSION)
    fail(`header field 'version' is ${JSON.stringify(h.version)} but the preamble says ${PACKAGE_VERSION}`);
  if (!Array.isArray(h.sections)) fail("header field 'sections' must be an array");
  const sections: SectionEntry[] = [];
  const names = new Set<string>();
  let end = 0;
  (h.sections as unknown[]).forEach((raw, i) => {
    if (typeof raw !== "object" || raw === null || Array.isArray(raw))
      fail(`header: section ${i} is not an object`);
    const s = raw as Record<string, unknown>;
    for (const f of SECTION_FIELDS) if (!(f in s)) fail(`header: section ${i} has no field '${f}'`);
    for (const f of Object.keys(s))
      if (!SECTION_FIELDS.includes(f)) fail(`header: section ${i} has an unknown field '${f}'`);
    if (typeof s.name !== "string" || s.name === "") fail(`header: section ${i} field 'name' must be a non-empty string`);
    for (const f of ["offset", "size", "raw_size"])
      if (!isNonNegativeInteger(s[f]))
        fail(`header: section ${i} field '${f}' must be a non-negative integer, not ${JSON.stringify(s[f])}`);
    if (s.coding !== "raw" && s.coding !== "zstd")
      fail(`header: section '${s.name}' has coding ${JSON.stringify(s.coding)}, expected "raw" or "zstd"`);
    if (typeof s.xxh64 !== "string" || !/^[0-9a-f]{16}$/.test(s.xxh64))
      fail(`header: section '${s.name}' field 'xxh64' must be 16 lowercase hex digits, not ${JSON.stringify(s.xxh64)}`);
    const e = s as unknown as SectionEntry;
    if (names.has(e.name)) fail(`inconsistent header: two sections are named '${e.name}'`);
    names.add(e.name);
    if (e.offset !== end)
      fail(`inconsistent header: section ${i} ('${e.name}') starts at offset ${e.offset} but the section before it ends at ${end}`);
    if (e.raw_size > MAX_RAW_SIZE)
      fail(`inconsistent header: section '${e.name}' declares ${e.raw_size} decoded bytes, more than the limit of ${MAX_RAW_SIZE}`);
    if (e.coding === "raw" && e.size !== e.raw_size)
      fail(`inconsistent header: raw section '${e.name}' stores ${e.size} bytes but declares ${e.raw_size} decoded bytes`);
    if (e.coding === "zstd") {
      if (e.size > zstdBound(e.raw_size))
        fail(`inconsistent header: zstd section '${e.name}' stores ${e.size} bytes, more than zstd needs for ${e.raw_size}`);
      if (e.raw_size > 32768 * e.size)
        fail(`inconsistent header: zstd section '${e.name}' declares ${e.raw_size} decoded bytes, more than ${e.size} stored bytes can hold`);
    }
    end = e.offset + e.size;
    sections.push({ name: e.name, offset: e.offset, size: e.size, raw_size: e.raw_size, coding: e.coding, xxh64: e.xxh64 });
  });
  return { json: h, headerBytes, sections, totalBytes: headerBytes + end };
}

// The content size a zstd frame declares, or null when it declares none.
function zstdContentSize(data: Uint8Array): number | null {
  if (data.length < 5 || data[0] !== 0x28 || data[1] !== 0xb5 || data[2] !== 0x2f || data[3] !== 0xfd)
    throw new Error("not a zstd frame (bad magic number)");
  const fhd = data[4];
  const fcsFlag = fhd >>> 6;
  const singleSegment = (fhd >>> 5) & 1;
  const dictBytes = [0, 1, 2, 4][fhd & 3];
  const fcsBytes = fcsFlag === 0 ? singleSegment : [0, 2, 4, 8][fcsFlag];
  if (fcsBytes === 0) return null;
  let p = 5 + (singleSegment ? 0 : 1) + dictBytes;
  if (p + fcsBytes > data.length) throw new Error("truncated frame header");
  let value = 0;
  for (let i = fcsBytes - 1; i >= 0; --i) value = value * 256 + data[p + i];
  return fcsBytes === 2 ? value + 256 : value;
}

/**
 * Feeds on the package's bytes in order and calls `handlers.header` once the header is complete
 * and `handlers.section` for each complete section, in file order. Throws PackageError.
 * `xxh64` checks the header and the sections: the function `loadChecksum` resolves to.
 */
export class PackageStream {
  /** Bytes pushed so far. */
  received = 0;
  header: PackageHeader | null = null;
  /** Sections handed out so far. */
  sectionsDone = 0;

  private preamble = new Uint8Array(PREAMBLE_BYTES);
  private headerLength = -1;
  private headerChecksum = "";
  private headerBuffer: Uint8Array | null = null;
  private headerFill = 0;
  private sectionBuffer: Uint8Array | null = null;
  private sectionFill = 0;
  private failed = false;

  constructor(
    readonly name: string,
    private readonly handlers: PackageHandlers,
    private readonly xxh64: Checksum,
  ) {}

  private fail(what: string): never {
    this.failed = true;
    throw new PackageError(`${this.name}: ${what}`);
  }

  push(chunk: Uint8Array): void {
    if (this.failed) return;
    let p = 0;
    while (p < chunk.length) {
      if (this.received < PREAMBLE_BYTES) {
        const n = Math.min(PREAMBLE_BYTES - this.received, chunk.length - p);
        this.preamble.set(chunk.subarray(p, p + n), this.received);
        this.received += n;
        p += n;
        this.checkMagic(this.received);
        if (this.received === PREAMBLE_BYTES) this.readPreamble();
        continue;
      }
      if (this.headerBuffer && this.headerFill < this.headerLength) {
        const n = Math.min(this.headerLength - this.headerFill, chunk.length - p);
        this.headerBuffer.set(chunk.subarray(p, p + n), this.headerFill);
        this.headerFill += n;
        this.received += n;
        p += n;
        if (this.headerFill === this.headerLength) this.readHeader();
        continue;
      }
      const header = this.header!;
      if (this.sectionsDone >= header.sections.length) {
        this.fail(`trailing bytes after the last section (from byte ${header.totalBytes})`);
      }
      const entry = header.sections[this.sectionsDone];
      if (!this.sectionBuffer) {
        this.sectionBuffer = new Uint8Array(entry.size);
        this.sectionFill = 0;
      }
      const n = Math.min(entry.size - this.sectionFill, chunk.length - p);
      this.sectionBuffer.set(chunk.subarray(p, p + n), this.sectionFill);
      this.sectionFill += n;
      this.received += n;
      p += n;
      this.drainComplete();
    }
  }

  /** The stream ended: returns whether the package is complete; throws if it ended mid-section. */
  end(): boolean {
    if (this.failed) return false;
    if (this.received < PREAMBLE_BYTES)
      this.fail(`truncated in the header: ${this.received} of the ${PREAMBLE_BYTES} preamble bytes present`);
    if (!this.header)
      this.fail(`truncated in the header: ${this.headerFill} of its ${this.headerLength} JSON bytes present (from byte ${PREAMBLE_BYTES})`);
    const header = this.header!;
    if (this.sectionsDone < header.sections.length && this.sectionFill > 0) {
      const e = header.sections[this.sectionsDone];
      this.fail(`section '${e.name}' is truncated: ${this.sectionFill} of ${e.size} bytes present (from byte ${header.headerBytes + e.offset})`);
    }
    return this.sectionsDone === header.sections.length;
  }

  private checkMagic(count: number): void {
    for (let i = 0; i < Math.min(count, MAGIC.length); ++i)
      if (this.preamble[i] !== MAGIC[i]) this.fail("not a btfkit package (bad magic)");
  }

  private readPreamble(): void {
    const v = new DataView(this.preamble.buffer);
    const version = v.getUint32(8, true);
    if (version !== PACKAGE_VERSION)
      this.fail(`unsupported package version ${version} (this viewer reads ${PACKAGE_VERSION})`);
    this.headerLength = v.getUint32(12, true);
    if (this.headerLength > MAX_HEADER_BYTES)
      this.fail(`byte 12: header length ${this.headerLength} exceeds the limit of ${MAX_HEADER_BYTES} bytes`);
    this.headerChecksum =
      v.getUint32(20, true).toString(16).padStart(8, "0") + v.getUint32(16, true).toString(16).padStart(8, "0");
    this.headerBuffer = new Uint8Array(this.headerLength);
    this.headerFill = 0;
    if (this.headerLength === 0) this.readHeader();
  }

  private readHeader(): void {
    const bytes = this.headerBuffer!;
    const computed = this.xxh64(bytes);
    if (computed !== this.headerChecksum)
      this.fail(`header checksum mismatch (bytes ${PREAMBLE_BYTES}..${PREAMBLE_BYTES + bytes.length}): stored ${this.headerChecksum}, computed ${computed}`);
    let json: unknown;
    try {
      json = JSON.parse(new TextDecoder("utf-8", { fatal: true }).decode(bytes));
    } catch (e) {
      this.fail(`header (byte ${PREAMBLE_BYTES}) is not valid JSON: ${(e as Error).message}`);
    }
    try {
      this.header = checkHeader(this.name, json, PREAMBLE_BYTES + bytes.length);
    } catch (e) {
      this.failed = true;
      throw e;
    }
    this.headerBuffer = null;
    this.handlers.header?.(this.header);
    this.drainComplete();
  }

  // Hands out every section whose bytes are all present (empty sections need none).
  private drainComplete(): void {
    const header = this.header!;
    while (this.sectionsDone < header.sections.length) {
      const entry = header.sections[this.sectionsDone];
      if (entry.size > 0 && (!this.sectionBuffer || this.sectionFill < entry.size)) return;
      const stored = this.sectionBuffer ?? new Uint8Array(0);
      this.sectionBuffer = null;
      this.sectionFill = 0;
      const index = this.sectionsDone++;
      const data = this.decodeSection(entry, stored, header.headerBytes + entry.offset);
      this.handlers.section?.({ index, entry, data, fileOffset: header.headerBytes + entry.offset });
    }
  }

  /**
   * A section's decoded bytes from its stored bytes (checksum checked, zstd decompressed); `at`
   * is its byte offset in the file, for messages. Also for sections fetched on their own.
   */
  decodeSection(entry: SectionEntry, stored: Uint8Array, at: number): Uint8Array {
    const computed = this.xxh64(stored);
    if (computed !== entry.xxh64)
      this.fail(`checksum mismatch in section '${entry.name}' (bytes ${at}..${at + entry.size}): stored ${entry.xxh64}, computed ${computed}`);
    if (entry.coding === "raw") return stored;
    let declared: number | null;
    try {
      declared = zstdContentSize(stored);
    } catch (e) {
      this.fail(`section '${entry.name}' (byte ${at}): not a zstd frame: ${(e as Error).message}`);
    }
    if (declared === null) this.fail(`section '${entry.name}' (byte ${at}): zstd frame does not declare its size`);
    if (declared !== entry.raw_size)
      this.fail(`section '${entry.name}' (byte ${at}): zstd frame holds ${declared} bytes but the header declares ${entry.raw_size}`);
    let out: Uint8Array;
    try {
      out = decompress(stored);
    } catch (e) {
      this.fail(`section '${entry.name}' (byte ${at}): cannot decompress: ${(e as Error).message}`);
    }
    if (out.length !== entry.raw_size)
      this.fail(`section '${entry.name}' (byte ${at}): zstd frame holds ${out.length} bytes but the header declares ${entry.raw_size}`);
    return out;
  }
}
