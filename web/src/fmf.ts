// The fmf factor model of a package (docs/formats.md "Factorization sections"): what the header
// says, the decoding of the means and component sections, the texture layouts the shader reads,
// and a CPU evaluator that computes exactly what src/btf/codecs/factor/material.cpp computes (the
// reference the shader is tested against).
//
// The viewer handles the models fmf writes: one view group, one texel cluster, one spatial level,
// no angular levels; colour rgb (one plane of 3 channels), decorrelated, per-channel or model11
// (UBO2014 DFMF colour model 11: log Y, U/Y, V/Y; 3 planes of 1 channel); with or without log;
// factors quantized f32, f16 or u8.

import { halfToFloat } from "./half";
import type { Weights } from "./interp";

export type ColourBasis = "rgb" | "decorrelated" | "per-channel" | "model11";
export type Quantization = "f32" | "f16" | "u8";

/** The material is a valid package the viewer cannot render (another codec or model layout). */
export class UnsupportedMaterial extends Error {
  constructor(message: string) {
    super(message);
    this.name = "UnsupportedMaterial";
  }
}

export interface FmfBlock {
  plane: number;
  /** Components declared in the header (the package may hold fewer: a prefix). */
  components: number;
  mean: boolean;
}

export interface FmfInfo {
  name: string;
  width: number;
  height: number;
  views: { theta: number[]; phi: number[] };
  lights: { theta: number[]; phi: number[] };
  nV: number;
  nL: number;
  colour: ColourBasis;
  log: boolean;
  logEps: number;
  quantization: Quantization;
  planes: number;
  channels: number;
  hdr: boolean;
  blocks: FmfBlock[];
  /** Slot of each view in the (single) view group: rows are ordered by slot. */
  slotOfView: number[];
  totalComponents: number;
}

function directions(j: unknown, what: string): { theta: number[]; phi: number[] } {
  const d = j as { theta?: unknown; phi?: unknown };
  if (!d || !Array.isArray(d.theta) || !Array.isArray(d.phi) || d.theta.length !== d.phi.length || d.theta.length === 0)
    throw new Error(`header field '${what}' must hold equally long, non-empty 'theta' and 'phi' arrays`);
  const ok = (a: unknown[]) => a.every((x) => typeof x === "number" && Number.isFinite(x));
  if (!ok(d.theta) || !ok(d.phi)) throw new Error(`header field '${what}' holds a non-number angle`);
  return { theta: d.theta as number[], phi: d.phi as number[] };
}

/**
 * Reads the codec fields of a package header. Throws UnsupportedMaterial for packages of other
 * codecs or model layouts, Error for malformed fields. Messages start with `name`.
 */
export function readFmfHeader(name: string, json: Record<string, unknown>): FmfInfo {
  const codec = json.codec;
  if (codec !== "fmf")
    throw new UnsupportedMaterial(
      `${name}: codec '${String(codec)}' is not supported by the viewer (it renders fmf packages: btf compress --codec fmf)`,
    );
  try {
    return readFields(name, json);
  } catch (e) {
    if (e instanceof UnsupportedMaterial) throw e;
    throw new Error(`${name}: package (fmf): ${(e as Error).message}`);
  }
}

function readFields(name: string, h: Record<string, unknown>): FmfInfo {
  const int = (v: unknown, what: string, lo: number, hi: number): number => {
    if (typeof v !== "number" || !Number.isInteger(v) || v < lo || v > hi)
      throw new Error(`header field '${what}' must be an integer in [${lo}, ${hi}], not ${JSON.stringify(v)}`);
    return v;
  };
  const width = int(h.width, "width", 1, 65536);
  const height = int(h.height, "height", 1, 65536);
  const views = directions(h.views, "views");
  const lights = directions(h.lights, "lights");
  const m = h.model as Record<string, unknown> | undefined;
  if (!m || typeof m !== "object") throw new Error("header field 'model' is missing");
  const colour = m.colour;
  if (colour === "lab")
    throw new UnsupportedMaterial(`${name}: colour '${colour}' is not supported by the viewer (rgb, decorrelated, per-channel or model11)`);
  if (colour !== "rgb" && colour !== "decorrelated" && colour !== "per-channel" && colour !== "model11")
    throw new Error(`unknown colour handling ${JSON.stringify(colour)}`);
  if (typeof m.log !== "boolean") throw new Error("header field 'model.log' must be a boolean");
  if (typeof m.log_eps !== "number") throw new Error("header field 'model.log_eps' must be a number");
  const quantization = m.quantization;
  if (quantization !== "f32" && quantization !== "f16" && quantization !== "u8")
    throw new Error(`unknown quantization ${JSON.stringify(quantization)} (known: f32, f16, u8)`);
  const nV = views.theta.length, nL = lights.theta.length;
  const groups = m.groups as unknown;
  if (!Array.isArray(groups) || groups.length === 0) throw new Error("header field 'model.groups' must be a non-empty array");
  if (groups.length !== 1)
    throw new UnsupportedMaterial(`${name}: ${groups.length} view groups are not supported by the viewer (fmf models have one)`);
  const group = groups[0] as unknown[];
  const slotOfView = new Array<number>(nV).fill(-1);
  if (!Array.isArray(group) || group.length !== nV) throw new Error(`the view group must hold all ${nV} views`);
  group.forEach((v, slot) => {
    const view = int(v, "model.groups[0]", 0, nV - 1);
    if (slotOfView[view] >= 0) throw new Error(`view ${view} is twice in the view group`);
    slotOfView[view] = slot;
  });
  if (m.clusters !== 1)
    throw new UnsupportedMaterial(`${name}: ${String(m.clusters)} texel clusters are not supported by the viewer (fmf models have one)`);
  if (m.levels !== undefined && m.levels !== 1)
    throw new UnsupportedMaterial(`${name}: ${String(m.levels)} spatial levels are not supported by the viewer`);
  if (m.angular_levels !== undefined)
    throw new UnsupportedMaterial(`${name}: angular levels are not supported by the viewer`);
  const planes = colour === "rgb" ? 1 : 3;
  const channels = colour === "rgb" ? 3 : 1;
  const blocksJson = m.blocks as unknown;
  if (!Array.isArray(blocksJson) || blocksJson.length !== planes)
    throw new Error(`${Array.isArray(blocksJson) ? blocksJson.length : "no"} blocks for ${planes} planes × 1 group × 1 cluster`);
  const blocks: FmfBlock[] = blocksJson.map((b: Record<string, unknown>, i: number) => {
    if (b.plane !== i || b.group !== 0 || b.cluster !== 0) throw new Error(`block ${i} is out of range or out of order`);
    const components = int(b.components, `model.blocks[${i}].components`, 0, 4096);
    if (typeof b.mean !== "boolean") throw new Error(`header field 'model.blocks[${i}].mean' must be a boolean`);
    if (!Array.isArray(b.energy) || b.energy.length !== components)
      throw new Error(`block ${i} declares ${components} components but ${Array.isArray(b.energy) ? b.energy.length : "no"} energies`);
    return { plane: i, components, mean: b.mean };
  });
  return {
    name,
    width,
    height,
    views,
    lights,
    nV,
    nL,
    colour,
    log: m.log,
    logEps: Math.fround(m.log_eps),
    quantization,
    planes,
    channels,
    hdr: h.hdr === true,
    blocks,
    slotOfView,
    totalComponents: blocks.reduce((s, b) => s + b.components, 0),
  };
}

/** Rows of a block (= of its a column and of its mean): views × lights × channels. */
export function blockRows(info: FmfInfo): number {
  return info.nV * info.nL * info.channels;
}

/** Bytes of one quantized column of n values (column_bytes in model.cpp). */
export function columnBytes(q: Quantization, n: number): number {
  return q === "f32" ? 4 * n : q === "f16" ? 2 * n : 8 + n;
}

/** Decodes one quantized column of n values starting at byte `at`. */
export function decodeColumn(q: Quantization, data: Uint8Array, at: number, n: number): Float32Array {
  const view = new DataView(data.buffer, data.byteOffset, data.byteLength);
  const out = new Float32Array(n);
  if (q === "f32") {
    for (let i = 0; i < n; ++i) out[i] = view.getFloat32(at + 4 * i, true);
  } else if (q === "f16") {
    for (let i = 0; i < n; ++i) out[i] = halfToFloat(view.getUint16(at + 2 * i, true));
  } else {
    const lo = view.getFloat32(at, true), step = view.getFloat32(at + 4, true);
    // value = min + q · step in float arithmetic, as get_column computes it
    for (let i = 0; i < n; ++i) out[i] = Math.fround(lo + Math.fround(step * data[at + 8 + i]));
  }
  return out;
}

/** The half bits of an f16 column, kept as stored so half textures get exactly these values. */
export function columnHalfBits(data: Uint8Array, at: number, n: number): Uint16Array {
  const view = new DataView(data.buffer, data.byteOffset, data.byteLength);
  const out = new Uint16Array(n);
  for (let i = 0; i < n; ++i) out[i] = view.getUint16(at + 2 * i, true);
  return out;
}

/** The block and component of a component section name "b<block>.k<k>", or null. */
export function parseComponentName(name: string): { block: number; k: number } | null {
  const m = /^b(\d+)\.k(\d+)$/.exec(name);
  return m ? { block: Number(m[1]), k: Number(m[2]) } : null;
}

/** The means section: one float32 per row of every block that has a mean, blocks in order. */
export function decodeMeans(info: FmfInfo, data: Uint8Array): (Float32Array | null)[] {
  const rows = blockRows(info);
  const expected = info.blocks.filter((b) => b.mean).length * rows * 4;
  if (data.length !== expected) throw new Error(`section 'means' holds ${data.length} bytes, expected ${expected}`);
  const view = new DataView(data.buffer, data.byteOffset, data.byteLength);
  let at = 0;
  return info.blocks.map((b) => {
    if (!b.mean) return null;
    const out = new Float32Array(rows);
    for (let i = 0; i < rows; ++i, at += 4) out[i] = view.getFloat32(at, true);
    return out;
  });
}

// ---- texture layouts ------------------------------------------------------------------------

/**
 * Where everything lives in the textures the shader reads.
 *
 * - A (RGBA float array texture): texel (l · C + ch, view, layer) holds a(row, 4j .. 4j + 3) for
 *   row = (slot(view) · nL + l) · C + ch, where layer = layerBase[plane] + j. Column l = nL is the
 *   uniform environment's pre-integrated "light" (Σ_l c_l a(row(l))).
 * - Means (R float array texture): texel (l · C + ch, view, plane), the same rows and the same
 *   environment column.
 * - B (RGBA float or half array texture): layer layerBase[plane] + j holds b(texel, 4j .. 4j + 3)
 *   as an atlas of the eigen-texture and its mip chain: level 0 at (0, 0) in W × H, level m ≥ 1
 *   of max(1, W >> m) × max(1, H >> m) texels at (W, Σ_{1 ≤ i < m} height_i).
 */
export interface Layout {
  aWidth: number;
  aHeight: number;
  layers: number;
  layerBase: number[];
  layerCount: number[];
  atlasWidth: number;
  atlasHeight: number;
  mipLevels: number;
  /** Per mip level: x, y, width, height in the atlas. */
  mips: { x: number; y: number; w: number; h: number }[];
  half: boolean;
}

export function makeLayout(info: FmfInfo): Layout {
  const layerBase: number[] = [], layerCount: number[] = [];
  let layers = 0;
  for (const b of info.blocks) {
    layerBase.push(layers);
    const n = Math.ceil(b.components / 4);
    layerCount.push(n);
    layers += n;
  }
  const W = info.width, H = info.height;
  const mipLevels = Math.floor(Math.log2(Math.max(W, H))) + 1;
  const mips = [{ x: 0, y: 0, w: W, h: H }];
  let y = 0;
  for (let m = 1; m < mipLevels; ++m) {
    const w = Math.max(1, W >> m), h = Math.max(1, H >> m);
    mips.push({ x: W, y, w, h });
    y += h;
  }
  return {
    aWidth: (info.nL + 1) * info.channels,
    aHeight: info.nV,
    layers: Math.max(layers, 1),
    layerBase,
    layerCount,
    atlasWidth: mipLevels > 1 ? W + Math.max(1, W >> 1) : W,
    atlasHeight: Math.max(H, y),
    mipLevels,
    mips,
    half: info.quantization === "f16",
  };
}

/**
 * The mip chain of one eigen-texture column (level 0 = the column itself): each level averages
 * 2 × 2 texels of the one before (an odd last row or column is dropped), which for a linear model
 * is the average of the material's plane values over those texels.
 */
export function mipChain(layout: Layout, column: Float32Array): Float32Array[] {
  const out = [column];
  for (let m = 1; m < layout.mipLevels; ++m) {
    const src = out[m - 1], s = layout.mips[m - 1], d = layout.mips[m];
    const level = new Float32Array(d.w * d.h);
    for (let y = 0; y < d.h; ++y) {
      const y0 = Math.min(2 * y, s.h - 1), y1 = Math.min(2 * y + 1, s.h - 1);
      for (let x = 0; x < d.w; ++x) {
        const x0 = Math.min(2 * x, s.w - 1), x1 = Math.min(2 * x + 1, s.w - 1);
        level[y * d.w + x] =
          0.25 * (src[y0 * s.w + x0] + src[y0 * s.w + x1] + src[y1 * s.w + x0] + src[y1 * s.w + x1]);
      }
    }
    out.push(level);
  }
  return out;
}

// ---- colour ----------------------------------------------------------------------------------

const DA = Math.fround(1 / Math.sqrt(3)), DB = Math.fround(1 / Math.sqrt(2)), DC = Math.fround(1 / Math.sqrt(6));

/** eps of UBO2014 colour model 11 (kUboLogEps, core/color.h). */
const UBO_LOG_EPS = Math.fround(1e-5);

/** Plane values → linear RGB (ColourHandling::inverse). */
export function inverseColour(info: FmfInfo, p: [number, number, number]): [number, number, number] {
  if (info.colour === "model11") {
    // ubo_model11_to_rgb: Y = exp(log Y) − eps, U and V from U/Y and V/Y, then YUV → RGB.
    const y = Math.fround(Math.exp(p[0]) - UBO_LOG_EPS), s = y + UBO_LOG_EPS;
    const u = p[1] * s, v = p[2] * s;
    return [y + 1.13983 * v, y - 0.39465 * u - 0.5806 * v, y + 2.03211 * u];
  }
  let v = p;
  if (info.colour === "decorrelated")
    v = [DA * p[0] + DB * p[1] + DC * p[2], DA * p[0] - DB * p[1] + DC * p[2], DA * p[0] - 2 * DC * p[2]];
  if (info.log) v = [Math.exp(v[0]) - info.logEps, Math.exp(v[1]) - info.logEps, Math.exp(v[2]) - info.logEps];
  return v;
}

// ---- CPU evaluation ---------------------------------------------------------------------------

/** The wrapping linear interpolation of btf_lookup.h (texel centres at (i + 0.5) / size). */
export function wrapLerp(c: number, size: number): { i0: number; i1: number; t: number } {
  let x = c * size - 0.5;
  if (!Number.isFinite(x)) x = -0.5;
  if (!(x >= 0 && x < size)) x -= size * Math.floor(x / size);
  if (!(x >= 0 && x < size)) x = 0;
  const i0 = Math.trunc(x);
  return { i0, i1: i0 + 1 === size ? 0 : i0 + 1, t: Math.fround(x - i0) };
}

/** A decoded model: what arrived so far (components in order per block). */
export class FmfModel {
  readonly a: Float32Array[][]; // [block][k]: rows
  readonly b: Float32Array[][]; // [block][k]: texels
  means: (Float32Array | null)[];

  constructor(readonly info: FmfInfo) {
    this.a = info.blocks.map(() => []);
    this.b = info.blocks.map(() => []);
    this.means = info.blocks.map(() => null);
  }

  get loadedComponents(): number {
    return this.a.reduce((s, c) => s + c.length, 0);
  }

  /**
   * Decodes a component section into this model; returns the block and k. Throws for sections
   * out of order, undeclared or of the wrong size (the C++ reader's checks).
   */
  addComponent(name: string, data: Uint8Array): { block: number; k: number } {
    const id = parseComponentName(name);
    const info = this.info;
    if (!id || id.block >= info.blocks.length || id.k !== this.a[id.block].length || id.k >= info.blocks[id.block].components)
      throw new Error(`component section '${name}' is out of order or undeclared`);
    const rows = blockRows(info), texels = info.width * info.height;
    const q = info.quantization;
    const expected = columnBytes(q, rows) + columnBytes(q, texels);
    if (data.length !== expected) throw new Error(`section '${name}' holds ${data.length} bytes, expected ${expected}`);
    this.a[id.block].push(decodeColumn(q, data, 0, rows));
    this.b[id.block].push(decodeColumn(q, data, columnBytes(q, rows), texels));
    return id;
  }

  /**
   * The material's value (linear RGB, before clamping) at texture position (u, v) for the view
   * and light weights of the interpolator lookups: lookup6d over the plane values, then the
   * inverse colour transform (FactorMaterial::eval).
   */
  evalWeights(u: number, v: number, vw: Weights, lw: Weights): [number, number, number] {
    return inverseColour(this.info, this.planeValues(u, v, vw, lw.index, lw.weight));
  }

  /**
   * The uniform environment's value at (u, v) for the view weights: Σ_l c_l · planes(l) decoded
   * (c: uniformEnvironmentWeights, normalized for log models, whose decoded value the caller
   * scales by Σ c_l), what the shader's environment column holds.
   */
  evalEnvironment(u: number, v: number, vw: Weights, c: Float64Array): [number, number, number] {
    const index = Array.from(c.keys());
    return inverseColour(this.info, this.planeValues(u, v, vw, index, Array.from(c)));
  }

  /** Σ over the views' and the given lights' weights of the bilinear plane values. */
  planeValues(u: number, v: number, vw: Weights, lightIndex: number[], lightWeight: number[]): [number, number, number] {
    const info = this.info;
    const W = info.width, H = info.height, C = info.channels, nL = info.nL;
    const lx = wrapLerp(u, W), ly = wrapLerp(v, H);
    const tex = [ly.i0 * W + lx.i0, ly.i0 * W + lx.i1, ly.i1 * W + lx.i0, ly.i1 * W + lx.i1];
    const sw = [(1 - lx.t) * (1 - ly.t), lx.t * (1 - ly.t), (1 - lx.t) * ly.t, lx.t * ly.t];
    const out: [number, number, number] = [0, 0, 0];
    for (let p = 0; p < info.planes; ++p) {
      const a = this.a[p], b = this.b[p], mean = this.means[p];
      const bsum = b.map((col) => sw[0] * col[tex[0]] + sw[1] * col[tex[1]] + sw[2] * col[tex[2]] + sw[3] * col[tex[3]]);
      for (let i = 0; i < 3; ++i) {
        if (vw.weight[i] === 0) continue;
        const slot = info.slotOfView[vw.index[i]];
        for (let j = 0; j < lightIndex.length; ++j) {
          const w = vw.weight[i] * lightWeight[j];
          if (w === 0) continue;
          for (let ch = 0; ch < C; ++ch) {
            const row = (slot * nL + lightIndex[j]) * C + ch;
            let s = mean ? mean[row] : 0;
            for (let k = 0; k < a.length; ++k) s += a[k][row] * bsum[k];
            out[p + ch] += w * s;
          }
        }
      }
    }
    return out;
  }
}
