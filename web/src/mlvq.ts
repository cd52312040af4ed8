// SPDX-License-Identifier: MIT
// The mlvq codec of a package (multi-level vector quantization, Havran, Filip, Myszkowski 2010;
// docs/formats.md "Vector-quantization sections (mlvq)"): the header reader, the decoder of the
// sections as they stream in, a CPU evaluator that computes what MlvqMaterial::eval and ::albedo
// compute (src/btf/codecs/mlvq/mlvq.cpp), and the GLSL that decodes the code-books per fragment
// (the paper's §4.6 GPU decoder) from the textures the decoder fills.
//
// What the shader reads: the decoded form of decoded.{h,cpp}, not the seven stored code-books.
// The C++ evaluator does not walk P6 → P4 → P3 → M → (P2 → P1, I2 → I1 → C) per query: it builds
// DecodedBooks once, and its values differ from a walk of the stored chain (the luminance of each
// sample is c_P2 · P1 rounded to an IEEE half, 2⁻¹¹ relative; the chromaticity is re-quantized
// to 8-bit codes over C's range). Decoding the same form makes the shader compute exactly what
// `btf eval` computes, with 2 dependent fetches per corner instead of 7 (84 fetches per light
// instead of the paper's 110), for 4 bytes per (M entry, α, β) sample: about the memory of the
// chain as 32-bit values (the HDR test package: 152 KiB of samples; its seven code-books would take
// 130 KiB), the same as the C++ evaluator holds.
//
// Texture layout. Every table is a 1-D array of entries wrapped into a 2-D array texture of rows
// of 1024 texels: entry i sits at (i & 1023, row % rows, row / rows) with row = i >> 10, `rows`
// the texture's height (uMlvqRows, one per table; rows are spread evenly over the layers so that
// the last layer is not mostly padding). Textures stay within 1024 × 4096 × 64 (MAX_TABLE).
//
//   uMlvqP6       RG32I   per texel t = y · W + x of the shown material: (P4 index, bits of the
//                         float c_P6). Texels of P6 levels not received yet hold the copy that
//                         read_texel_index makes (the texel rounded down to the finest level's grid).
//   uMlvqViews    RG32I   P4 ∘ P3 fused, per (P4 entry e, φv p, θv t) at (e · nφv + p) · nθv + t:
//                         (M index, bits of the float c_P4 · c_P3).
//   uMlvqEntries  R32UI   per (M entry m, α i, β j) at (m · nα + i) · nβ + j: bits 0–15 the half
//                         c_P2 · P1, bits 16–23 and 24–31 the two chromaticity codes; a code k
//                         decodes to lo + step · k (uMlvqChroma = lo₁, step₁, lo₂, step₂).
//   uMlvqAlbedo   RGBA32F per M entry (YCbCr only, else 1 texel): Σ_(i,j) light_weight(i, j) ·
//                         (Y, c₁, c₂) of its samples, what MlvqMaterial::albedo sums.
//
// Uniforms (MlvqDecoder.uniforms, the GLSL types in mlvqFragment): uMlvqGrid ivec4 (nα, nβ, nθv,
// nφv), uMlvqExtent ivec2, uMlvqRows ivec4, uMlvqChroma vec4, uMlvqColour int (0 YCbCr, 1 LogLuv).
//
// Fetches per fragment: 4 P6 and 16 views, then 64 samples per light; the environment's albedo 16
// more with YCbCr, but 16 · nα · nβ with LogLuv (1936 at the paper's 11 × 11 grid): its colour
// conversion is not linear, so the albedo is a sum over the grid of converted samples, as in C++.
//
// Progressive streaming: "codebooks" first, then P6 from the coarsest level ("P6.3": every 8th
// texel per axis) to "P6.0". A prefix holding the code-books and the coarsest level is a material
// (open_all); the P6 texture after each level is the index read_texel_index returns for that prefix.
//
// Several materials sharing the code-books: `btf eval` (Codec::open) shows the first material
// (open_all(...).front(); its coarsest level is the first P6 section of the stream), so the viewer
// shows it too. The other materials' sections are checked as the C++ reader checks them, then
// dropped.

// UnsupportedMaterial is the factor codecs' class (fmf.ts, since renamed factor.ts), so that the
// viewer's `instanceof` test catches both.
import { UnsupportedMaterial, wrapLerp } from "./factor";
import { floatToHalf, halfToFloat } from "./half";

export { UnsupportedMaterial };

export type MlvqColour = "ycbcr" | "logluv";

export interface MlvqGrid {
  nAlpha: number;
  nBeta: number;
  nThetaV: number;
  nPhiV: number;
}

/** A linear scalar quantizer (P1, C): lo and hi as the C++ holds them (floats). */
export interface LinearQuantizer {
  lo: number;
  hi: number;
  bits: number;
}

/** A logarithmic quantizer of scales (P2, P3, P4, P6): natural logs, doubles. */
export interface LogQuantizer {
  logLo: number;
  logHi: number;
  bits: number;
}

export interface MlvqMaterialEntry {
  name: string;
  /** Of its section names: "" for one material, "m<k>." for several. */
  prefix: string;
  width: number;
  height: number;
  hdr: boolean;
  p6: LogQuantizer;
  /** P6 levels (sections "<prefix>P6.<levels − 1>" … "<prefix>P6.0"). */
  levels: number;
}

export type BookName = "P1" | "P2" | "M" | "P3" | "P4" | "C" | "I1" | "I2";

export interface MlvqInfo {
  name: string;
  /** Extent of the material shown (the first). */
  width: number;
  height: number;
  hdr: boolean;
  grid: MlvqGrid;
  colour: MlvqColour;
  /** Entries per code-book. */
  sizes: Record<BookName, number>;
  quantization: { P1: LinearQuantizer; C0: LinearQuantizer; C1: LinearQuantizer; P2: LogQuantizer; P3: LogQuantizer; P4: LogQuantizer };
  /** Every material of the package; the viewer shows materials[0]. */
  materials: MlvqMaterialEntry[];
}

/** The largest table (texels of one texture) the viewer uploads: 1024 × 4096 × 64. */
export const MAX_TABLE = 1024 * 4096 * 64;
const TABLE_WIDTH = 1024;
const MAX_ROWS = 4096;

// ---- header -----------------------------------------------------------------------------------

const MAX_AXIS = 1024; // MlvqGrid::kMaxAxis
const MAX_GRID_SAMPLES = 2 ** 26; // MlvqGrid::kMaxSamples
const MAX_DIRECTIONS = 16384; // factor/model.cpp kMaxDirections

type Json = Record<string, unknown>;

// json_fields.cpp's checks and messages.
function shown(v: unknown): string {
  const text = JSON.stringify(v) ?? String(v);
  return text.length > 40 ? text.slice(0, 37) + "..." : text;
}
function isObject(v: unknown): v is Json {
  return typeof v === "object" && v !== null && !Array.isArray(v);
}
function at(o: Json, key: string, where: string): unknown {
  if (!(key in o)) throw new Error(`header field '${where ? where + "." : ""}${key}' is missing`);
  return o[key];
}
function object(o: Json, key: string, where = ""): Json {
  const v = at(o, key, where);
  if (!isObject(v)) throw new Error(`header field '${where ? where + "." : ""}${key}' must be an object`);
  return v;
}
function integer(v: unknown, name: string, lo: number, hi: number): number {
  if (typeof v !== "number" || !Number.isInteger(v) || v < lo || v > hi)
    throw new Error(`'${name}' must be an integer from ${lo} to ${hi}, not ${shown(v)}`);
  return v;
}
function gformat(x: number): string {
  // fmt's {:g}: 6 significant digits, exponent form below 1e-4 and from 1e6
  if (x === 0 || !Number.isFinite(x)) return String(x);
  const [mantissa, e] = x.toExponential(5).split("e");
  const exp = Number(e);
  const strip = (t: string) => (t.includes(".") ? t.replace(/\.?0+$/, "") : t);
  if (exp < -4 || exp >= 6) return `${strip(mantissa)}e${exp < 0 ? "-" : "+"}${String(Math.abs(exp)).padStart(2, "0")}`;
  return strip(x.toFixed(5 - exp));
}
function number(v: unknown, name: string, lo: number, hi: number): number {
  const x = typeof v === "number" ? v : NaN;
  if (!Number.isFinite(x) || x < lo || x > hi) throw new Error(`'${name}' must be a number from ${gformat(lo)} to ${gformat(hi)}, not ${shown(v)}`);
  return x;
}
function onlyKeys(v: unknown, name: string, known: string[]): Json {
  if (!isObject(v)) throw new Error(`'${name}' must be an object`);
  for (const k of Object.keys(v)) if (!known.includes(k)) throw new Error(`'${name}' has an unknown field '${k}'`);
  return v;
}
function string(o: Json, key: string, where: string): string {
  const v = at(o, key, where);
  if (typeof v !== "string") throw new Error(`header field '${where ? where + "." : ""}${key}' must be a string`);
  return v;
}
function jsonEqual(a: unknown, b: unknown): boolean {
  if (a === b) return true;
  if (Array.isArray(a) && Array.isArray(b)) return a.length === b.length && a.every((x, i) => jsonEqual(x, b[i]));
  if (isObject(a) && isObject(b)) {
    const ka = Object.keys(a), kb = Object.keys(b);
    return ka.length === kb.length && ka.every((k) => k in b && jsonEqual(a[k], b[k]));
  }
  return false;
}

function quantizerFields(j: unknown, name: string, loKey: string, hiKey: string): { lo: number; hi: number; bits: number } {
  if (!isObject(j)) throw new Error(`header field 'quantization.${name}' must be an object`);
  const lo = number(at(j, loKey, `quantization.${name}`), loKey, -1e30, 1e30);
  const hi = number(at(j, hiKey, `quantization.${name}`), hiKey, -1e30, 1e30);
  const bits = integer(at(j, "bits", `quantization.${name}`), "bits", 8, 16);
  if (bits !== 8 && bits !== 16) throw new Error(`quantization with ${bits} bits`);
  if (hi < lo) throw new Error(`quantization range [${lo}, ${hi}]`);
  return { lo, hi, bits };
}
const linearQuantizer = (j: unknown, name: string): LinearQuantizer => {
  const f = quantizerFields(j, name, "lo", "hi");
  return { lo: Math.fround(f.lo), hi: Math.fround(f.hi), bits: f.bits };
};
const logQuantizer = (j: unknown, name: string): LogQuantizer => {
  const f = quantizerFields(j, name, "log_lo", "log_hi");
  return { logLo: f.lo, logHi: f.hi, bits: f.bits };
};

// directions_from_json (factor/model.cpp): only the checks; the viewer does not need the sets.
function checkDirections(j: unknown): void {
  const d = onlyKeys(j, "directions", ["name", "theta", "phi"]);
  const theta = at(d, "theta", "directions"), phi = at(d, "phi", "directions");
  if (!Array.isArray(theta) || !Array.isArray(phi) || theta.length !== phi.length) throw new Error("direction arrays differ in length");
  if (theta.length === 0 || theta.length > MAX_DIRECTIONS) throw new Error(`${theta.length} directions (1 to ${MAX_DIRECTIONS} allowed)`);
  const slack = 1e-6;
  for (let i = 0; i < theta.length; ++i) {
    number(theta[i], "theta", -slack, Math.PI / 2 + slack);
    number(phi[i], "phi", -2 * Math.PI - slack, 2 * Math.PI + slack);
  }
  if (typeof at(d, "name", "directions") !== "string") throw new Error("header field 'directions.name' must be a string");
}

/** texel_index_levels (codebooks.cpp): P6 levels of an extent. */
export function texelIndexLevels(width: number, height: number): number {
  let levels = 1;
  while (levels < 4 && Math.min(width, height) >> levels >= 4) ++levels;
  return levels;
}

/** texel_level: the largest ℓ < levels with x, y multiples of 2^ℓ. */
function texelLevel(x: number, y: number, levels: number): number {
  let level = 0;
  while (level + 1 < levels && x % (2 << level) === 0 && y % (2 << level) === 0) ++level;
  return level;
}

/** ⌈log2 n⌉ bits of an index into a code-book of n entries (0 for n ≤ 1). */
export function indexBits(n: number): number {
  let bits = 0;
  while (bits < 32 && 2 ** bits < n) ++bits;
  return bits;
}

/**
 * Reads the codec fields of an mlvq package header with the checks of read_codebooks and
 * open_all. Throws UnsupportedMaterial for packages of other codecs and for code-books larger
 * than the viewer's textures (MAX_TABLE), Error("<name>: package (mlvq): …") for malformed fields.
 */
export function readMlvqHeader(name: string, json: Record<string, unknown>): MlvqInfo {
  if (json.codec !== "mlvq") throw new UnsupportedMaterial(`${name}: codec '${String(json.codec)}' is not mlvq`);
  let info: MlvqInfo;
  try {
    info = readFields(name, json);
  } catch (e) {
    throw new Error(`${name}: package (mlvq): ${(e as Error).message}`);
  }
  const g = info.grid, s = info.sizes;
  const tables: [string, number][] = [
    ["decoded M entries (M × nα × nβ samples)", s.M * g.nAlpha * g.nBeta],
    ["fused views (P4 × nφv × nθv)", s.P4 * g.nPhiV * g.nThetaV],
    ["texel index (width × height)", info.width * info.height],
    ["P1 values", s.P1 * g.nBeta],
    ["P2 entries", s.P2 * g.nAlpha],
    ["M entries", s.M],
    ["P3 entries", s.P3 * g.nThetaV],
    ["I1 entries", s.I1 * g.nBeta],
    ["I2 entries", s.I2 * g.nAlpha],
    ["C entries", s.C],
  ];
  for (const [what, n] of tables)
    if (n > MAX_TABLE)
      throw new UnsupportedMaterial(`${name}: the ${what} hold ${n} values, more than the viewer's limit of ${MAX_TABLE} per texture`);
  return info;
}

function readFields(name: string, h: Json): MlvqInfo {
  // read_codebooks
  const gj = onlyKeys(at(h, "grid", ""), "grid", ["n_alpha", "n_beta", "n_theta_v", "n_phi_v"]);
  const grid: MlvqGrid = {
    nAlpha: integer(at(gj, "n_alpha", "grid"), "n_alpha", 2, MAX_AXIS),
    nBeta: integer(at(gj, "n_beta", "grid"), "n_beta", 2, MAX_AXIS),
    nThetaV: integer(at(gj, "n_theta_v", "grid"), "n_theta_v", 2, MAX_AXIS),
    nPhiV: integer(at(gj, "n_phi_v", "grid"), "n_phi_v", 1, MAX_AXIS),
  };
  validateGrid(grid);
  const colour = string(h, "colour", "");
  if (colour !== "ycbcr" && colour !== "logluv") throw new Error(`colour model '${colour}': expected ycbcr or logluv`);
  const books: BookName[] = ["P1", "P2", "M", "P3", "P4", "C", "I1", "I2"];
  const sj = onlyKeys(at(h, "codebooks", ""), "codebooks", books);
  const sizes = {} as Record<BookName, number>;
  for (const b of books) sizes[b] = integer(at(sj, b, "codebooks"), b, 0, 2 ** 31);
  const q = object(h, "quantization");
  const quantization = {
    P1: linearQuantizer(at(q, "P1", "quantization"), "P1"),
    C0: linearQuantizer(at(q, "C0", "quantization"), "C0"),
    C1: linearQuantizer(at(q, "C1", "quantization"), "C1"),
    P2: logQuantizer(at(q, "P2", "quantization"), "P2"),
    P3: logQuantizer(at(q, "P3", "quantization"), "P3"),
    P4: logQuantizer(at(q, "P4", "quantization"), "P4"),
  };
  // open_all
  const list = at(h, "materials", "");
  if (!Array.isArray(list) || list.length === 0) throw new Error("no materials");
  for (const key of ["width", "height", "views", "lights"])
    if (!jsonEqual(at(h, key, ""), isObject(list[0]) ? list[0][key] : undefined)) throw new Error(`'${key}' differs from the first material's`);
  const materials = list.map((m: unknown, k: number): MlvqMaterialEntry => {
    if (!isObject(m)) throw new Error(`header field 'materials[${k}]' must be an object`);
    const where = `materials[${k}]`;
    const mname = string(m, "name", where);
    const width = integer(at(m, "width", where), "width", 1, 1 << 16);
    const height = integer(at(m, "height", where), "height", 1, 1 << 16);
    if (width * height > 67108864)
      throw new Error(
        `extent: image of ${width}×${height} texels exceeds the limit of 67108864 texels ` +
          "(raise it with --max-image-pixels or BTF_MAX_IMAGE_PIXELS)",
      );
    checkDirections(at(m, "views", where));
    checkDirections(at(m, "lights", where));
    const hdr = m.hdr ?? false;
    if (typeof hdr !== "boolean") throw new Error(`header field '${where}.hdr' must be a boolean`);
    const prefix = string(m, "prefix", where);
    // read_texel_index's checks, done here for every material (the C++ does them when the
    // material's coarsest P6 level is present)
    const levels = texelIndexLevels(width, height);
    const declared = integer(at(m, "P6_levels", where), "P6_levels", 1, 16);
    if (declared !== levels) throw new Error(`${declared} P6 levels for ${width}×${height} texels, expected ${levels}`);
    const f = quantizerFields(at(m, "P6", where), "P6", "log_lo", "log_hi");
    return { name: mname, prefix, width, height, hdr, levels, p6: { logLo: f.lo, logHi: f.hi, bits: f.bits } };
  });
  const prefixes = new Set<string>();
  for (const m of materials) {
    if (prefixes.has(m.prefix)) throw new Error(`two materials have the section prefix '${m.prefix}'`);
    prefixes.add(m.prefix);
  }
  return {
    name,
    width: materials[0].width,
    height: materials[0].height,
    hdr: materials[0].hdr,
    grid,
    colour,
    sizes,
    quantization,
    materials,
  };
}

// MlvqGrid::validate
function validateGrid(g: MlvqGrid): void {
  const axis = (name: string, n: number, least: number, why: string) => {
    if (n < least) throw new Error(`mlvq grid: ${name} = ${n} is below ${least} (${why})`);
    if (n > MAX_AXIS) throw new Error(`mlvq grid: ${name} = ${n} is above the limit ${MAX_AXIS}`);
  };
  axis("n_alpha", g.nAlpha, 3, "with 2 slices both lie on the horizon");
  axis("n_beta", g.nBeta, 3, "with 2 samples per slice both are the poles on the horizon");
  axis("n_theta_v", g.nThetaV, 2, "the view elevations span 0 to 90 degrees");
  axis("n_phi_v", g.nPhiV, 1, "1 means isotropic");
  if (g.nPhiV === 2)
    throw new Error(
      "mlvq grid: n_phi_v = 2 cannot tell view azimuths φ and −φ apart (both blend the samples at 0 and 180 degrees alike); " +
        "use 1 (isotropic) or at least 3",
    );
  const samples = g.nPhiV * g.nThetaV * g.nAlpha * g.nBeta;
  if (samples > MAX_GRID_SAMPLES)
    throw new Error(
      `mlvq grid: ${g.nPhiV}x${g.nThetaV}x${g.nAlpha}x${g.nBeta} = ${samples} samples per texel and channel exceed the limit ${MAX_GRID_SAMPLES}`,
    );
}

// ---- bit-packed sections ----------------------------------------------------------------------

/** codebooks.cpp's BitReader: least significant bit first; its checks and messages. */
class BitReader {
  private pos = 0;
  private bit = 0;
  constructor(
    private readonly data: Uint8Array,
    private readonly what: string,
  ) {}

  get(bits: number): number {
    if (this.pos * 8 + this.bit + bits > this.data.length * 8) throw new Error(`section '${this.what}' is too short`);
    let value = 0;
    for (let done = 0; done < bits; ) {
      const take = Math.min(8 - this.bit, bits - done);
      value += ((this.data[this.pos] >>> this.bit) & ((1 << take) - 1)) * 2 ** done;
      done += take;
      this.bit += take;
      if (this.bit === 8) {
        this.bit = 0;
        ++this.pos;
      }
    }
    return value;
  }

  align(): void {
    if (this.bit) {
      this.bit = 0;
      ++this.pos;
    }
  }

  /** Before allocating `count` entries of `bitsEach` bits: the section must hold them. */
  reserve(count: number, bitsEach: number, book: string): void {
    const left = (this.data.length - this.pos) * 8 - this.bit;
    if (count * bitsEach > left) throw new Error(`section '${this.what}' is too short for the ${count} entries of ${book} its header declares`);
  }

  finish(): void {
    this.align();
    if (this.pos !== this.data.length) throw new Error(`section '${this.what}' holds ${this.data.length} bytes, expected ${this.pos}`);
  }
}

function decodeLinear(q: LinearQuantizer, code: number): number {
  if (!(q.hi > q.lo)) return q.lo;
  return Math.fround(q.lo + ((q.hi - q.lo) * code) / (2 ** q.bits - 1));
}

function decodeLog(q: LogQuantizer, code: number): number {
  if (code === 0) return 0;
  if (!(q.logHi > q.logLo)) return Math.fround(Math.exp(q.logLo));
  return Math.fround(Math.exp(q.logLo + ((q.logHi - q.logLo) * (code - 1)) / (2 ** q.bits - 2)));
}

/** Entries of (index, scale) as the code-books store them. */
interface Entries {
  index: Uint32Array;
  scale: Float32Array;
}

/** The stored code-books, decoded (Codebooks of codebooks.h). */
export interface Codebooks {
  p1: Float32Array;
  p2: Entries;
  m: Uint32Array; // (P2, I2) pairs
  p3: Entries;
  p4: Entries;
  c: Float32Array; // (c₁, c₂) pairs
  i1: Uint32Array;
  i2: Uint32Array;
}

/** read_codebooks: the "codebooks" section; throws with the C++ reader's messages. */
export function readCodebooks(info: MlvqInfo, data: Uint8Array): Codebooks {
  const g = info.grid, s = info.sizes, q = info.quantization;
  const r = new BitReader(data, "codebooks");
  const entries = (count: number, target: number, quant: LogQuantizer, book: string): Entries => {
    const bits = indexBits(target);
    r.reserve(count, bits + quant.bits, book);
    const out = { index: new Uint32Array(count), scale: new Float32Array(count) };
    for (let i = 0; i < count; ++i) {
      out.index[i] = r.get(bits);
      out.scale[i] = decodeLog(quant, r.get(quant.bits));
    }
    r.align();
    return out;
  };
  const indices = (count: number, target: number, book: string): Uint32Array => {
    const bits = indexBits(target);
    r.reserve(count, bits, book);
    const out = new Uint32Array(count);
    for (let i = 0; i < count; ++i) out[i] = r.get(bits);
    r.align();
    return out;
  };
  r.reserve(s.P1 * g.nBeta, q.P1.bits, "P1");
  const p1 = new Float32Array(s.P1 * g.nBeta);
  for (let i = 0; i < p1.length; ++i) p1[i] = decodeLinear(q.P1, r.get(q.P1.bits));
  r.align();
  const p2 = entries(s.P2 * g.nAlpha, s.P1, q.P2, "P2");
  const b2 = indexBits(s.P2), bi2 = indexBits(s.I2);
  r.reserve(s.M, b2 + bi2, "M");
  const m = new Uint32Array(2 * s.M);
  for (let i = 0; i < s.M; ++i) {
    m[2 * i] = r.get(b2);
    m[2 * i + 1] = r.get(bi2);
  }
  r.align();
  const p3 = entries(s.P3 * g.nThetaV, s.M, q.P3, "P3");
  const p4 = entries(s.P4 * g.nPhiV, s.P3, q.P4, "P4");
  r.reserve(s.C, 16, "C");
  const c = new Float32Array(2 * s.C);
  for (let i = 0; i < s.C; ++i) {
    // two 8-bit codes whatever the header's bits (write_codebooks writes 8)
    c[2 * i] = decodeLinear(q.C0, r.get(8));
    c[2 * i + 1] = decodeLinear(q.C1, r.get(8));
  }
  r.align();
  const i1 = indices(s.I1 * g.nBeta, s.C, "I1");
  const i2 = indices(s.I2 * g.nAlpha, s.I1, "I2");
  r.finish();
  const books = { p1, p2, m, p3, p4, c, i1, i2 };
  validateCodebooks(info, books);
  return books;
}

// Codebooks::validate("code-books")
function validateCodebooks(info: MlvqInfo, b: Codebooks): void {
  const s = info.sizes;
  for (let i = 0; i < b.p1.length; ++i) if (!Number.isFinite(b.p1[i])) throw new Error(`code-books: P1 value ${i} is not finite`);
  for (let i = 0; i < s.C; ++i)
    if (!Number.isFinite(b.c[2 * i]) || !Number.isFinite(b.c[2 * i + 1])) throw new Error(`code-books: C entry ${i} is not finite`);
  const indices = (v: Uint32Array, limit: number, book: string, target: string) => {
    for (let i = 0; i < v.length; ++i)
      if (v[i] >= limit) throw new Error(`code-books: ${book} entry ${i} points to ${target} ${v[i]} of ${limit}`);
  };
  const scales = (v: Float32Array, book: string) => {
    for (let i = 0; i < v.length; ++i)
      if (!Number.isFinite(v[i]) || v[i] < 0) throw new Error(`code-books: ${book} entry ${i} has scale ${v[i]}`);
  };
  indices(b.p2.index, s.P1, "P2", "P1");
  scales(b.p2.scale, "P2");
  for (let i = 0; i < s.M; ++i) {
    if (b.m[2 * i] >= s.P2) throw new Error(`code-books: M entry ${i} points to P2 ${b.m[2 * i]} of ${s.P2}`);
    if (b.m[2 * i + 1] >= s.I2) throw new Error(`code-books: M entry ${i} points to I2 ${b.m[2 * i + 1]} of ${s.I2}`);
  }
  indices(b.p3.index, s.M, "P3", "M");
  scales(b.p3.scale, "P3");
  indices(b.p4.index, s.P3, "P4", "P3");
  scales(b.p4.scale, "P4");
  indices(b.i1, s.C, "I1", "C");
  indices(b.i2, s.I1, "I2", "I1");
}

/**
 * One P6 level section of a material (read_texel_index for that level): the entries of the
 * level's texels in row order, checked; the coarsest level's size is checked before anything is
 * read (a tiny section cannot declare a huge extent).
 */
function readP6Level(info: MlvqInfo, m: MlvqMaterialEntry, level: number, data: Uint8Array, section: string): Entries {
  const bits = indexBits(info.sizes.P4), q = m.p6;
  const texels: number[] = [];
  for (let y = 0; y < m.height; ++y) for (let x = 0; x < m.width; ++x) if (texelLevel(x, y, m.levels) === level) texels.push(y * m.width + x);
  const r = new BitReader(data, section);
  if (level === m.levels - 1) r.reserve(texels.length, bits + q.bits, `P6 level ${level}`);
  const out = { index: new Uint32Array(texels.length), scale: new Float32Array(texels.length) };
  for (let k = 0; k < texels.length; ++k) {
    const index = r.get(bits);
    out.scale[k] = decodeLog(q, r.get(q.bits));
    if (index >= info.sizes.P4) {
      const t = texels[k];
      throw new Error(`P6 of texel (${t % m.width}, ${Math.floor(t / m.width)}) points to P4 ${index} of ${info.sizes.P4}`);
    }
    out.index[k] = index;
  }
  r.finish();
  return out;
}

// ---- the decoded form (decoded.cpp) -----------------------------------------------------------

export type Shape = { width: number; height: number; depth: number };

/** A table of n entries wrapped into a 2-D array texture of rows of 1024 (the layout at the top). */
export function tableShape(n: number): Shape {
  const rows = Math.max(1, Math.ceil(n / TABLE_WIDTH));
  const depth = Math.ceil(rows / MAX_ROWS);
  return { width: Math.max(1, Math.min(n, TABLE_WIDTH)), height: Math.ceil(rows / depth), depth };
}

/** DecodedBooks plus the per-entry integrals the albedo sums. */
interface Decoded {
  /** (M index, c_P4 · c_P3 bits) per (P4 entry, φv, θv): the uMlvqViews texture data. */
  views: Int32Array;
  viewScale: Float32Array; // the same buffer as floats
  /** half Y | code₁ << 16 | code₂ << 24 per (M entry, α, β): the uMlvqEntries texture data. */
  samples: Uint32Array;
  chromaLo: [number, number];
  chromaStep: [number, number];
  /** Per M entry Σ light_weight · (Y, c₁, c₂): doubles for the CPU, floats for the shader. */
  albedo: Float64Array;
  albedoTexture: Float32Array;
}

/** LinearQuantizer::fit over the values then encode(): DecodedBooks' chroma codes. */
function chromaCodes(values: Float32Array): { lo: number; step: number; codes: Uint8Array } {
  let lo = 0, hi = 0;
  if (values.length) {
    lo = Infinity;
    hi = -Infinity;
    for (const v of values) {
      lo = Math.min(lo, v);
      hi = Math.max(hi, v);
    }
  }
  const codes = new Uint8Array(values.length);
  if (hi > lo)
    for (let i = 0; i < values.length; ++i) codes[i] = Math.min(255, Math.max(0, Math.round(((values[i] - lo) / (hi - lo)) * 255)));
  return { lo, step: Math.fround(Math.fround(hi - lo) / 255), codes };
}

/** MlvqGrid::light_weight: the solid angle of light sample (i, j) in a hemisphere sum. */
export function lightWeight(g: MlvqGrid, i: number, j: number): number {
  const ta = i === 0 || i === g.nAlpha - 1 ? 0.5 : 1, tb = j === 0 || j === g.nBeta - 1 ? 0.5 : 1;
  return (Math.PI / (g.nAlpha - 1)) * (2 / (g.nBeta - 1)) * ta * tb;
}

function decodeBooks(info: MlvqInfo, b: Codebooks): Decoded {
  const g = info.grid, s = info.sizes;
  const nViews = g.nPhiV * g.nThetaV, perEntry = g.nAlpha * g.nBeta;
  const viewShape = tableShape(s.P4 * nViews);
  const views = new Int32Array(2 * viewShape.width * viewShape.height * viewShape.depth);
  const viewScale = new Float32Array(views.buffer);
  for (let e4 = 0; e4 < s.P4; ++e4)
    for (let p = 0; p < g.nPhiV; ++p) {
      const k4 = e4 * g.nPhiV + p, i3 = b.p4.index[k4];
      for (let t = 0; t < g.nThetaV; ++t) {
        const k3 = i3 * g.nThetaV + t, o = 2 * (k4 * g.nThetaV + t);
        views[o] = b.p3.index[k3];
        viewScale[o + 1] = Math.fround(b.p4.scale[k4] * b.p3.scale[k3]);
      }
    }
  const c0 = new Float32Array(s.C), c1 = new Float32Array(s.C);
  for (let i = 0; i < s.C; ++i) {
    c0[i] = b.c[2 * i];
    c1[i] = b.c[2 * i + 1];
  }
  const q0 = chromaCodes(c0), q1 = chromaCodes(c1);
  const sampleShape = tableShape(s.M * perEntry);
  const samples = new Uint32Array(sampleShape.width * sampleShape.height * sampleShape.depth);
  const albedo = new Float64Array(3 * s.M);
  const albedoShape = tableShape(info.colour === "ycbcr" ? s.M : 0);
  const albedoTexture = new Float32Array(4 * albedoShape.width * albedoShape.height * albedoShape.depth);
  const weights = new Float64Array(perEntry);
  for (let i = 0; i < g.nAlpha; ++i) for (let j = 0; j < g.nBeta; ++j) weights[i * g.nBeta + j] = lightWeight(g, i, j);
  for (let e = 0; e < s.M; ++e) {
    const p2 = b.m[2 * e], i2 = b.m[2 * e + 1];
    let sy = 0, s1 = 0, s2 = 0;
    for (let i = 0; i < g.nAlpha; ++i) {
      const k2 = p2 * g.nAlpha + i, scale = b.p2.scale[k2], slice = b.p2.index[k2] * g.nBeta;
      const chroma = b.i2[i2 * g.nAlpha + i] * g.nBeta;
      for (let j = 0; j < g.nBeta; ++j) {
        const half = floatToHalf(Math.fround(scale * b.p1[slice + j]));
        const c = b.i1[chroma + j], k0 = q0.codes[c], k1 = q1.codes[c];
        samples[e * perEntry + i * g.nBeta + j] = (half | (k0 << 16) | (k1 << 24)) >>> 0;
        const lw = weights[i * g.nBeta + j];
        sy += lw * halfToFloat(half);
        s1 += lw * Math.fround(q0.lo + Math.fround(q0.step * k0));
        s2 += lw * Math.fround(q1.lo + Math.fround(q1.step * k1));
      }
    }
    albedo.set([sy, s1, s2], 3 * e);
    if (info.colour === "ycbcr") albedoTexture.set([sy, s1, s2, 0], 4 * e);
  }
  return { views, viewScale, samples, chromaLo: [q0.lo, q1.lo], chromaStep: [q0.step, q1.step], albedo, albedoTexture };
}

// ---- the [α, β] parametrization (parametrization.cpp) -----------------------------------------

type Vec3 = [number, number, number];

/** The query conventions of the lookup: z clamped to ≥ 0, no direction → +x, else normalized. */
function prepare(d: readonly number[]): Vec3 {
  let x = d[0], y = d[1], z = d[2] > 0 ? d[2] : 0;
  if (!Number.isFinite(x) || !Number.isFinite(y) || !Number.isFinite(z)) return [1, 0, 0];
  const m = Math.max(Math.abs(x), Math.abs(y), z);
  if (!(m > 0)) return [1, 0, 0];
  x /= m;
  y /= m;
  z /= m;
  const len = Math.sqrt(x * x + y * y + z * z);
  return [x / len, y / len, z / len];
}

/** The two neighbouring samples along an axis and their weights (AxisWeights). */
export interface Axis {
  index: [number, number];
  weight: [number, number];
}

function clampedAxis(x: number, n: number): Axis {
  if (!(x > 0)) x = 0;
  if (x > n - 1) x = n - 1;
  const i0 = Math.min(Math.trunc(x), n - 2);
  const w1 = Math.fround(x - i0);
  return { index: [i0, i0 + 1], weight: [Math.fround(1 - w1), w1] };
}

function periodicAxis(x: number, n: number): Axis {
  if (n === 1) return { index: [0, 0], weight: [1, 0] };
  if (!Number.isFinite(x)) x = 0;
  const f = Math.floor(x);
  let i0 = f % n;
  if (i0 < 0) i0 += n;
  if (i0 >= n) i0 -= n;
  const w1 = Math.fround(Math.min(1, Math.max(0, x - f)));
  return { index: [i0, (i0 + 1) % n], weight: [Math.fround(1 - w1), w1] };
}

/** MlvqWeights: the 2 × 2 × 2 × 2 grid samples around a query, and its view azimuth's frame. */
export interface Lookup {
  alpha: Axis;
  beta: Axis;
  thetaV: Axis;
  phiV: Axis;
  /** cos φv, sin φv of the view (1, 0 for a view along the normal) */
  c: number;
  s: number;
}

/** lookup(grid, wi, wo): view (θv, φv) of wo, light (α, u = sin β) of wi in the onion frame of φv. */
export function lookup(g: MlvqGrid, wi: readonly number[], wo: readonly number[]): Lookup {
  const o = prepare(wo), i = prepare(wi);
  const rho = Math.sqrt(o[0] * o[0] + o[1] * o[1]);
  const theta = Math.atan2(rho, o[2]);
  let phi = 0, c = 1, s = 0;
  if (rho > 0) {
    phi = Math.atan2(o[1], o[0]);
    if (phi < 0) phi += 2 * Math.PI;
    if (phi >= 2 * Math.PI) phi -= 2 * Math.PI;
    c = o[0] / rho;
    s = o[1] / rho;
  }
  const u = Math.min(1, Math.max(-1, -s * i[0] + c * i[1])); // · e_β
  const a = -c * i[0] - s * i[1]; // · e_α
  const alpha = a === 0 && i[2] === 0 ? 0 : Math.atan2(a, i[2]);
  return {
    alpha: clampedAxis(((alpha + Math.PI / 2) / Math.PI) * (g.nAlpha - 1), g.nAlpha),
    beta: clampedAxis(((u + 1) / 2) * (g.nBeta - 1), g.nBeta),
    thetaV: clampedAxis((theta / (Math.PI / 2)) * (g.nThetaV - 1), g.nThetaV),
    phiV: periodicAxis((phi / (2 * Math.PI)) * g.nPhiV, g.nPhiV),
    c,
    s,
  };
}

/** direction_from_onion_u in the frame of (cos φv, sin φv): the light of slice α at u = sin β. */
export function onionDirection(alpha: number, u: number, c: number, s: number): Vec3 {
  u = Math.min(1, Math.max(-1, u));
  const cb = Math.sqrt(Math.max(0, 1 - u * u)), sa = Math.sin(alpha) * cb, ca = Math.cos(alpha) * cb;
  // e_β = (−s, c, 0), e_α = (−c, −s, 0), n = (0, 0, 1)
  return [-s * u - c * sa, c * u - s * sa, ca];
}

// ---- colour (codebooks.cpp from_planes, core/color.cpp) ---------------------------------------

const F = Math.fround;
const K1402 = F(1.402), K1772 = F(1.772), K0299 = F(0.299), K0114 = F(0.114), K0587 = F(0.587);
const XYZ_TO_RGB = [
  [3.2404542, -1.5371385, -0.4985314],
  [-0.969266, 1.8760108, 0.041556],
  [0.0556434, -0.2040259, 1.0572252],
];

/** Planes (Y, c₁, c₂) → linear RGB (from_planes). */
export function fromPlanes(colour: MlvqColour, y: number, c1: number, c2: number): Vec3 {
  y = F(y);
  c1 = F(c1);
  c2 = F(c2);
  if (colour === "ycbcr") {
    const r = F(y + F(K1402 * c2)), b = F(y + F(K1772 * c1));
    return [r, F(F(F(y - F(K0299 * r)) - F(K0114 * b)) / K0587), b];
  }
  if (!(y > 0)) return [0, 0, 0];
  // luminance_uv_to_xyz, then xyz_to_rgb
  let X = 0, Z = 0;
  if (c2 > 0) {
    X = (y * 9 * c1) / (4 * c2);
    Z = (y * (12 - 3 * c1 - 20 * c2)) / (4 * c2);
  }
  const M = XYZ_TO_RGB;
  return [F(M[0][0] * X + M[0][1] * y + M[0][2] * Z), F(M[1][0] * X + M[1][1] * y + M[1][2] * Z), F(M[2][0] * X + M[2][1] * y + M[2][2] * Z)];
}

// ---- the decoder ------------------------------------------------------------------------------

export interface TextureSpec {
  uniform: string;
  kind: "2d" | "2d-array";
  width: number;
  height: number;
  depth: number;
  format:
    | "R32F" | "RG32F" | "RGBA32F" | "R16F" | "RGBA16F" | "R32I" | "RG32I" | "RGBA32I" | "R32UI" | "RGBA32UI" | "R8UI" | "RGBA8UI" | "R8" | "RGBA8";
  data: Float32Array | Uint16Array | Int32Array | Uint32Array | Uint8Array;
}

/** A query's 16 (texel, φv, θv) corners: M entries, luminance scales and chromaticity weights. */
interface Gathered {
  entry: number[]; // M entry · nα · nβ
  yScale: number[];
  cWeight: number[];
}

/**
 * Decodes an mlvq package's sections as they arrive, keeps what the shader reads, and evaluates
 * like MlvqMaterial on exactly the sections received. An error in a section leaves the decoder as
 * it was before that section and makes it ignore every later one (one error per package).
 */
export class MlvqDecoder {
  books: Codebooks | null = null;
  private decoded: Decoded | null = null;
  /** The P6 of the shown material: (P4 index, c_P6 bits) per texel, the uMlvqP6 texture data. */
  private readonly p6: Int32Array;
  private readonly p6Scale: Float32Array;
  /** Levels of the shown material received so far (its own, by level). */
  private readonly levelData: (Entries | null)[];
  /** The finest level of the contiguous run from the coarsest (levels: none yet). */
  private finest: number;
  private readonly seen = new Set<string>();
  private failed: Error | null = null;
  private readonly material: MlvqMaterialEntry;
  private readonly shapes: { p6: Shape; views: Shape; samples: Shape; albedo: Shape };

  constructor(readonly info: MlvqInfo) {
    const m = (this.material = info.materials[0]);
    const g = info.grid, s = info.sizes;
    this.shapes = {
      p6: tableShape(m.width * m.height),
      views: tableShape(s.P4 * g.nPhiV * g.nThetaV),
      samples: tableShape(s.M * g.nAlpha * g.nBeta),
      albedo: tableShape(info.colour === "ycbcr" ? s.M : 0),
    };
    const sh = this.shapes.p6;
    this.p6 = new Int32Array(2 * sh.width * sh.height * sh.depth);
    this.p6Scale = new Float32Array(this.p6.buffer);
    this.levelData = new Array(m.levels).fill(null);
    this.finest = m.levels;
  }

  /** The error that stopped the decoder, if any. */
  get error(): Error | null {
    return this.failed;
  }

  addSection(name: string, data: Uint8Array): void {
    if (this.failed) return;
    try {
      this.decodeSection(name, data);
    } catch (e) {
      let message = (e as Error).message;
      if (!message.includes(`section '${name}'`)) message = `section '${name}': ${message}`;
      this.failed = new Error(`${this.info.name}: package (mlvq): ${message}`);
      throw this.failed;
    }
  }

  private decodeSection(name: string, data: Uint8Array): void {
    if (this.seen.has(name)) throw new Error("arrived twice");
    if (name === "codebooks") {
      const books = readCodebooks(this.info, data);
      this.decoded = decodeBooks(this.info, books);
      this.books = books;
      this.seen.add(name);
      return;
    }
    for (const [k, m] of this.info.materials.entries()) {
      if (!name.startsWith(m.prefix + "P6.")) continue;
      const level = /^\d+$/.test(name.slice(m.prefix.length + 3)) ? Number(name.slice(m.prefix.length + 3)) : -1;
      if (level < 0 || level >= m.levels || name !== `${m.prefix}P6.${level}`) continue;
      const entries = readP6Level(this.info, m, level, data, name);
      this.seen.add(name);
      if (k === 0) {
        this.levelData[level] = entries;
        this.updateP6();
      }
      return;
    }
    throw new Error(`unknown section '${name}'`);
  }

  // The texel index read_texel_index returns for the levels received: the contiguous run from the
  // coarsest level, texels of finer levels copying the texel rounded down to the finest's grid.
  private updateP6(): void {
    const m = this.material, W = m.width, H = m.height;
    let finest = m.levels;
    while (finest > 0 && this.levelData[finest - 1]) --finest;
    if (finest === this.finest) return;
    this.finest = finest;
    const next = new Array<number>(m.levels).fill(0);
    for (let y = 0; y < H; ++y)
      for (let x = 0; x < W; ++x) {
        const level = texelLevel(x, y, m.levels);
        if (level < finest) continue;
        const e = this.levelData[level]!, k = next[level]++, t = y * W + x;
        this.p6[2 * t] = e.index[k];
        this.p6Scale[2 * t + 1] = e.scale[k];
      }
    if (finest > 0) {
      const mask = ~((1 << finest) - 1);
      for (let y = 0; y < H; ++y)
        for (let x = 0; x < W; ++x)
          if (texelLevel(x, y, m.levels) < finest) {
            const t = y * W + x, from = (y & mask) * W + (x & mask);
            this.p6[2 * t] = this.p6[2 * from];
            this.p6[2 * t + 1] = this.p6[2 * from + 1];
          }
    }
  }

  /** Code-books and the shown material's coarsest P6 level are there (open_all's prefix rule). */
  get ready(): boolean {
    return this.decoded !== null && this.finest < this.material.levels;
  }

  progress(): { present: number; total: number; unit: string } {
    return { present: this.material.levels - this.finest, total: this.material.levels, unit: "P6 levels" };
  }

  // ---- CPU evaluation ----

  private corners(u: number, v: number): { texel: number[]; weight: number[] } {
    const W = this.material.width, H = this.material.height;
    const lx = wrapLerp(u, W), ly = wrapLerp(v, H);
    const r0 = ly.i0 * W, r1 = ly.i1 * W;
    return {
      texel: [r0 + lx.i0, r0 + lx.i1, r1 + lx.i0, r1 + lx.i1],
      weight: [F(F(1 - lx.t) * F(1 - ly.t)), F(lx.t * F(1 - ly.t)), F(F(1 - lx.t) * ly.t), F(lx.t * ly.t)],
    };
  }

  // MlvqMaterial::gather: all 16 corners, zero weights included.
  private gather(u: number, v: number, w: Lookup): Gathered {
    const d = this.decoded!, g = this.info.grid, perEntry = g.nAlpha * g.nBeta;
    const { texel, weight } = this.corners(u, v);
    const out: Gathered = { entry: [], yScale: [], cWeight: [] };
    for (let k = 0; k < 4; ++k) {
      const p4 = this.p6[2 * texel[k]], s6 = this.p6Scale[2 * texel[k] + 1];
      for (let p = 0; p < 2; ++p)
        for (let t = 0; t < 2; ++t) {
          const o = 2 * ((p4 * g.nPhiV + w.phiV.index[p]) * g.nThetaV + w.thetaV.index[t]);
          const wt = F(weight[k] * F(w.phiV.weight[p] * w.thetaV.weight[t]));
          out.entry.push(d.views[o] * perEntry);
          out.yScale.push(F(F(wt * s6) * d.viewScale[o + 1]));
          out.cWeight.push(wt);
        }
    }
    return out;
  }

  /** Luminance and chromaticity codes of a sample. */
  private sample(at: number): [number, number, number] {
    const s = this.decoded!.samples[at];
    return [halfToFloat(s & 0xffff), (s >>> 16) & 0xff, s >>> 24];
  }

  // DecodedBooks::blend over the (α, β) corners of the lookup.
  private blend(gathered: Gathered, w: Lookup): [number, number, number] {
    const d = this.decoded!, nBeta = this.info.grid.nBeta;
    const off = [w.alpha.index[0] * nBeta + w.beta.index[0], w.alpha.index[1] * nBeta + w.beta.index[0]];
    let y = 0, c1 = 0, c2 = 0, total = 0;
    for (let c = 0; c < gathered.entry.length; ++c) {
      for (let a = 0; a < 2; ++a)
        for (let q = 0; q < 2; ++q) {
          const wq = F(w.alpha.weight[a] * w.beta.weight[q]);
          const [lum, k1, k2] = this.sample(gathered.entry[c] + off[a] + q);
          y += gathered.yScale[c] * wq * lum;
          c1 += gathered.cWeight[c] * wq * k1;
          c2 += gathered.cWeight[c] * wq * k2;
        }
      total += gathered.cWeight[c];
    }
    return [y, d.chromaLo[0] * total + d.chromaStep[0] * c1, d.chromaLo[1] * total + d.chromaStep[1] * c2];
  }

  /** MlvqMaterial::eval (linear RGB before clamping) with the sections received; zeros until ready. */
  eval(u: number, v: number, wi: [number, number, number], wo: [number, number, number]): [number, number, number] {
    if (!this.ready) return [0, 0, 0];
    const w = lookup(this.info.grid, wi, wo);
    const p = this.blend(this.gather(u, v, w), w);
    return fromPlanes(this.info.colour, p[0], p[1], p[2]);
  }

  /**
   * MlvqMaterial::albedo: (1/π) ∫ eval dωi. YCbCr: the decoded planes' integrals (exact, linear).
   * LogLuv: Σ light_weight(i, j) · RGB of grid sample (i, j), as the C++ sums eval at the grid's
   * light directions; except at the two pole rows, where this takes each slice's own pole sample
   * (the C++ evaluates the pole direction, whose α is undefined: rounding picks a slice).
   */
  albedo(u: number, v: number, wo: [number, number, number]): [number, number, number] {
    if (!this.ready) return [0, 0, 0];
    const d = this.decoded!, g = this.info.grid;
    const view = lookup(g, [0, 0, 1], wo);
    const gathered = this.gather(u, v, view);
    if (this.info.colour === "ycbcr") {
      let y = 0, c1 = 0, c2 = 0;
      for (let c = 0; c < 16; ++c) {
        const a = (gathered.entry[c] / (g.nAlpha * g.nBeta)) * 3;
        y += gathered.yScale[c] * d.albedo[a];
        c1 += gathered.cWeight[c] * d.albedo[a + 1];
        c2 += gathered.cWeight[c] * d.albedo[a + 2];
      }
      const rgb = fromPlanes("ycbcr", y, c1, c2);
      return [F(rgb[0] / Math.PI), F(rgb[1] / Math.PI), F(rgb[2] / Math.PI)];
    }
    const sum = [0, 0, 0];
    for (let i = 0; i < g.nAlpha; ++i)
      for (let j = 0; j < g.nBeta; ++j) {
        const at: Lookup = { ...view, alpha: { index: [i, i], weight: [1, 0] }, beta: { index: [j, j], weight: [1, 0] } };
        const p = this.blend(gathered, at);
        const rgb = fromPlanes("logluv", p[0], p[1], p[2]);
        const lw = lightWeight(g, i, j);
        for (let ch = 0; ch < 3; ++ch) sum[ch] += lw * rgb[ch];
      }
    return [F(sum[0] / Math.PI), F(sum[1] / Math.PI), F(sum[2] / Math.PI)];
  }

  // ---- what the shader reads ----

  textures(): TextureSpec[] {
    const d = this.decoded, sh = this.shapes;
    const spec = (uniform: string, shape: Shape, format: TextureSpec["format"], data: TextureSpec["data"]): TextureSpec => ({
      uniform,
      kind: "2d-array",
      ...shape,
      format,
      data,
    });
    const zeros = (shape: Shape, channels: number) => shape.width * shape.height * shape.depth * channels;
    return [
      spec("uMlvqP6", sh.p6, "RG32I", this.p6),
      spec("uMlvqViews", sh.views, "RG32I", d ? d.views : new Int32Array(zeros(sh.views, 2))),
      spec("uMlvqEntries", sh.samples, "R32UI", d ? d.samples : new Uint32Array(zeros(sh.samples, 1))),
      spec("uMlvqAlbedo", sh.albedo, "RGBA32F", d ? d.albedoTexture : new Float32Array(zeros(sh.albedo, 4))),
    ];
  }

  uniforms(): Record<string, number | number[]> {
    const g = this.info.grid, d = this.decoded, sh = this.shapes;
    return {
      uMlvqGrid: [g.nAlpha, g.nBeta, g.nThetaV, g.nPhiV],
      uMlvqExtent: [this.material.width, this.material.height],
      uMlvqRows: [sh.p6.height, sh.views.height, sh.samples.height, sh.albedo.height],
      uMlvqChroma: d ? [d.chromaLo[0], d.chromaStep[0], d.chromaLo[1], d.chromaStep[1]] : [0, 0, 0, 0],
      uMlvqColour: this.info.colour === "ycbcr" ? 0 : 1,
    };
  }
}

// ---- the shader -------------------------------------------------------------------------------

/**
 * GLSL ES 3.00: the samplers and uniforms above and codecEvaluate (see MlvqDecoder.eval and
 * .albedo for what it computes). Names start with mlvq / uMlvq. Uses wrapLerp, MAX_LIGHTS and PI
 * of the shared shader.
 */
export const mlvqFragment = /* glsl */ `
uniform highp isampler2DArray uMlvqP6;      // (P4 index, c_P6 bits) per texel y * W + x
uniform highp isampler2DArray uMlvqViews;   // (M index, c_P4 * c_P3 bits) per (P4, phi_v, theta_v)
uniform highp usampler2DArray uMlvqEntries; // half Y | code1 << 16 | code2 << 24 per (M, alpha, beta)
uniform highp sampler2DArray uMlvqAlbedo;   // per M: sums of light_weight * (Y, c1, c2) (YCbCr)
uniform highp ivec4 uMlvqGrid;              // n_alpha, n_beta, n_theta_v, n_phi_v
uniform highp ivec2 uMlvqExtent;            // width, height
uniform highp ivec4 uMlvqRows;              // rows per layer of the four tables
uniform highp vec4 uMlvqChroma;             // chroma codes: lo1, step1, lo2, step2
uniform highp int uMlvqColour;              // 0 YCbCr, 1 LogLuv

// Entry i of a table: rows of 1024 texels, 'rows' rows per layer.
ivec3 mlvqAt(int i, int rows) {
  int row = i >> 10;
  return ivec3(i & 1023, row % rows, row / rows);
}

// The lookup's query conventions: z clamped to >= 0, no direction -> +x, otherwise normalized.
vec3 mlvqPrepare(vec3 d) {
  float z = d.z > 0.0 ? d.z : 0.0;
  if (isnan(d.x) || isnan(d.y) || isinf(d.x) || isinf(d.y) || isinf(z)) return vec3(1.0, 0.0, 0.0);
  float m = max(max(abs(d.x), abs(d.y)), z);
  if (!(m > 0.0)) return vec3(1.0, 0.0, 0.0);
  vec3 v = vec3(d.xy, z) / m;
  return v / sqrt(dot(v, v));
}

// Two neighbouring samples along an axis and their weights (clamped_axis, periodic_axis).
struct MlvqAxis {
  ivec2 i;
  vec2 w;
};
MlvqAxis mlvqClamped(float x, int n) {
  if (!(x > 0.0)) x = 0.0;
  if (x > float(n - 1)) x = float(n - 1);
  int i0 = min(int(x), n - 2);
  float w1 = x - float(i0);
  return MlvqAxis(ivec2(i0, i0 + 1), vec2(1.0 - w1, w1));
}
MlvqAxis mlvqPeriodic(float x, int n) {
  if (n == 1) return MlvqAxis(ivec2(0), vec2(1.0, 0.0));
  if (isnan(x) || isinf(x)) x = 0.0;
  float f = floor(x);
  int i0 = int(max(f, 0.0)) % n;
  float w1 = clamp(x - f, 0.0, 1.0);
  return MlvqAxis(ivec2(i0, (i0 + 1) % n), vec2(1.0 - w1, w1));
}

// Planes (Y, c1, c2) -> linear RGB (from_planes).
vec3 mlvqFromPlanes(float y, float c1, float c2) {
  if (uMlvqColour == 0) {
    float r = y + 1.402 * c2, b = y + 1.772 * c1;
    return vec3(r, (y - 0.299 * r - 0.114 * b) / 0.587, b);
  }
  if (!(y > 0.0)) return vec3(0.0);
  vec3 xyz = vec3(0.0, y, 0.0);
  if (c2 > 0.0) xyz = vec3(y * 9.0 * c1 / (4.0 * c2), y, y * (12.0 - 3.0 * c1 - 20.0 * c2) / (4.0 * c2));
  return mat3(3.2404542, -0.9692660, 0.0556434, -1.5371385, 1.8760108, -0.2040259, -0.4985314, 0.0415560, 1.0572252) * xyz;
}

// Luminance and the two chroma codes of (M entry, alpha, beta) sample i.
vec3 mlvqSample(int i) {
  uint s = texelFetch(uMlvqEntries, mlvqAt(i, uMlvqRows.z), 0).r;
  return vec3(unpackHalf2x16(s & 0xffffu).x, float((s >> 16) & 0xffu), float(s >> 24));
}

void codecEvaluate(vec2 uv, vec2 sx, vec2 sy, vec3 wo, vec3 wi[MAX_LIGHTS], bool lit[MAX_LIGHTS], int lightCount, bool env,
                   out vec3 value[MAX_LIGHTS], out vec3 ambient) {
  int nAlpha = uMlvqGrid.x, nBeta = uMlvqGrid.y, nTheta = uMlvqGrid.z, nPhi = uMlvqGrid.w;
  for (int l = 0; l < MAX_LIGHTS; ++l) value[l] = vec3(0.0);
  ambient = vec3(0.0);

  // The view: theta_v, phi_v of wo and the onion frame of its azimuth (phi_v = 0 along the normal).
  vec3 o = mlvqPrepare(wo);
  float rho = sqrt(o.x * o.x + o.y * o.y);
  float phi = 0.0;
  vec2 cs = vec2(1.0, 0.0);
  if (rho > 0.0) {
    // atan(±0, x) explicitly: GLSL leaves the sign of zero to the implementation (SwiftShader's
    // atan(-0.0, 1.0) is not 0), the C++ wraps atan2's ±π to π.
    phi = o.y == 0.0 ? (o.x > 0.0 ? 0.0 : PI) : atan(o.y, o.x);
    if (phi < 0.0) phi += 2.0 * PI;
    if (phi >= 2.0 * PI) phi -= 2.0 * PI;
    cs = o.xy / rho;
  }
  MlvqAxis th = mlvqClamped((rho > 0.0 ? atan(rho, o.z) : 0.0) / (0.5 * PI) * float(nTheta - 1), nTheta);
  MlvqAxis ph = mlvqPeriodic(phi / (2.0 * PI) * float(nPhi), nPhi);

  // The 16 (texel, phi_v, theta_v) corners: P6 -> P4 o P3 -> M entry, scales and weights.
  int x0, x1, y0, y1;
  float tx, ty;
  wrapLerp(uv.x, uMlvqExtent.x, x0, x1, tx);
  wrapLerp(uv.y, uMlvqExtent.y, y0, y1, ty);
  int texel[4] = int[4](y0 * uMlvqExtent.x + x0, y0 * uMlvqExtent.x + x1, y1 * uMlvqExtent.x + x0, y1 * uMlvqExtent.x + x1);
  float spatial[4] = float[4]((1.0 - tx) * (1.0 - ty), tx * (1.0 - ty), (1.0 - tx) * ty, tx * ty);
  int perEntry = nAlpha * nBeta;
  int entry[16];
  float yScale[16], cWeight[16];
  for (int k = 0; k < 4; ++k) {
    ivec2 p6 = texelFetch(uMlvqP6, mlvqAt(texel[k], uMlvqRows.x), 0).xy;
    float s6 = intBitsToFloat(p6.y);
    for (int p = 0; p < 2; ++p)
      for (int t = 0; t < 2; ++t) {
        ivec2 v = texelFetch(uMlvqViews, mlvqAt((p6.x * nPhi + ph.i[p]) * nTheta + th.i[t], uMlvqRows.y), 0).xy;
        int c = k * 4 + p * 2 + t;
        float wt = spatial[k] * (ph.w[p] * th.w[t]);
        entry[c] = v.x * perEntry;
        yScale[c] = wt * s6 * intBitsToFloat(v.y);
        cWeight[c] = wt;
      }
  }

  // Each light: alpha, u = sin(beta) in the onion frame, the 2 x 2 samples of the 16 entries.
  for (int l = 0; l < MAX_LIGHTS; ++l) {
    if (l >= lightCount) break;
    if (!lit[l]) continue;
    vec3 d = mlvqPrepare(wi[l]);
    float u = clamp(-cs.y * d.x + cs.x * d.y, -1.0, 1.0);
    float a = -cs.x * d.x - cs.y * d.y;
    float alpha = a == 0.0 ? 0.0 : atan(a, d.z);  // α = ±0 along the plane through the normal and e_beta
    MlvqAxis al = mlvqClamped((alpha + 0.5 * PI) / PI * float(nAlpha - 1), nAlpha);
    MlvqAxis be = mlvqClamped((u + 1.0) * 0.5 * float(nBeta - 1), nBeta);
    int off0 = al.i.x * nBeta + be.i.x, off1 = al.i.y * nBeta + be.i.x;
    vec4 w = vec4(al.w.x * be.w.x, al.w.x * be.w.y, al.w.y * be.w.x, al.w.y * be.w.y);
    float y = 0.0, total = 0.0;
    vec2 codes = vec2(0.0);
    for (int c = 0; c < 16; ++c) {
      vec3 s00 = mlvqSample(entry[c] + off0), s01 = mlvqSample(entry[c] + off0 + 1);
      vec3 s10 = mlvqSample(entry[c] + off1), s11 = mlvqSample(entry[c] + off1 + 1);
      vec3 blend = w.x * s00 + w.y * s01 + w.z * s10 + w.w * s11;
      y += yScale[c] * blend.x;
      codes += cWeight[c] * blend.yz;
      total += cWeight[c];
    }
    value[l] = mlvqFromPlanes(y, uMlvqChroma.x * total + uMlvqChroma.y * codes.x, uMlvqChroma.z * total + uMlvqChroma.w * codes.y);
  }

  if (!env) return;
  // The albedo: with YCbCr the entries' integrals (linear); with LogLuv the sum over the grid's
  // light samples of their RGB values (16 * n_alpha * n_beta fetches).
  float dAlpha = PI / float(nAlpha - 1), dU = 2.0 / float(nBeta - 1);
  if (uMlvqColour == 0) {
    float y = 0.0;
    vec2 chroma = vec2(0.0);
    for (int c = 0; c < 16; ++c) {
      vec3 s = texelFetch(uMlvqAlbedo, mlvqAt(entry[c] / perEntry, uMlvqRows.w), 0).xyz;
      y += yScale[c] * s.x;
      chroma += cWeight[c] * s.yz;
    }
    ambient = mlvqFromPlanes(y, chroma.x, chroma.y) / PI;
    return;
  }
  vec3 sum = vec3(0.0);
  for (int i = 0; i < nAlpha; ++i)
    for (int j = 0; j < nBeta; ++j) {
      float y = 0.0, total = 0.0;
      vec2 codes = vec2(0.0);
      for (int c = 0; c < 16; ++c) {
        vec3 s = mlvqSample(entry[c] + i * nBeta + j);
        y += yScale[c] * s.x;
        codes += cWeight[c] * s.yz;
        total += cWeight[c];
      }
      float lw = dAlpha * dU * (i == 0 || i == nAlpha - 1 ? 0.5 : 1.0) * (j == 0 || j == nBeta - 1 ? 0.5 : 1.0);
      sum += lw * mlvqFromPlanes(y, uMlvqChroma.x * total + uMlvqChroma.y * codes.x, uMlvqChroma.z * total + uMlvqChroma.w * codes.y);
    }
  ambient = sum / PI;
}
`;
