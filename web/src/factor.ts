// SPDX-License-Identifier: MIT
// The linear factor model of the factorization codecs (fmf, pca-views, lpca, perceptual; docs/
// formats.md "Factorization sections", src/btf/codecs/factor/model.h): what the header says, the
// decoding of its sections, the texture layouts the shader reads, and a CPU evaluator that
// computes exactly what src/btf/codecs/factor/material.cpp computes (the reference the shader is
// tested against).
//
// The model is split into blocks by colour plane × view group × texel cluster × spatial level ×
// angular level. The viewer handles every layout the C++ model allows:
// - view groups (pca-views): each view belongs to one group whose blocks hold its rows;
// - texel clusters (lpca): each texel belongs to one cluster whose blocks hold its columns; a
//   lookup evaluates each of its four texels with that texel's own cluster, as the C++ does;
// - spatial levels (perceptual): a block of level j stores b on a (W / 2^j) × (H / 2^j) grid
//   whose bilinear, wrapping up-sampling at the full texels' centres defines them;
// - angular levels (perceptual): a block of angular level m stores a on subsets of the views and
//   lights, up-sampled with the weights of section "angular";
// colour rgb, decorrelated, per-channel, model11 (UBO2014 DFMF colour model 11) or lab, with or
// without log; factors quantized f32, f16 or u8, or coded (coded.ts).

import { decodeCodedComponent } from "./coded";
import { halfToFloat } from "./half";
import { readTablesSection, type InterpTables, type Weights } from "./interp";

export type ColourBasis = "rgb" | "decorrelated" | "per-channel" | "model11" | "lab";
export type Quantization = "f32" | "f16" | "u8" | "coded";
/** The codecs whose packages hold a factor model. */
export const FACTOR_CODECS = ["fmf", "pca-views", "lpca", "perceptual"] as const;
export type FactorCodec = (typeof FACTOR_CODECS)[number];

/** The material is a valid package the viewer cannot render. */
export class UnsupportedMaterial extends Error {
  constructor(message: string) {
    super(message);
    this.name = "UnsupportedMaterial";
  }
}

export interface FactorBlock {
  plane: number;
  group: number;
  cluster: number;
  /** Spatial level: b holds (W >> level) × (H >> level) texels. */
  level: number;
  /** Angular level: a holds the rows of angularLevels[angular − 1] (0: every view and light). */
  angular: number;
  /** Components declared in the header (the package may hold fewer: a prefix). */
  components: number;
  mean: boolean;
}

export interface AngularLevel {
  views: number[];
  lights: number[];
}

export interface FactorInfo {
  name: string;
  codec: FactorCodec;
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
  groups: number[][];
  groupOfView: number[];
  /** Position of each view in its group: a group's rows are ordered by slot. */
  slotOfView: number[];
  clusters: number;
  levels: number;
  angularLevels: AngularLevel[];
  /** In the package's order: (((plane · G + group) · clusters + cluster) · levels + level) · (1 + angular levels) + angular. */
  blocks: FactorBlock[];
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
 * Reads the model fields of a factorization package's header. Throws UnsupportedMaterial for
 * packages of other codecs, Error for malformed fields. Messages start with `name`.
 */
export function readFactorHeader(name: string, json: Record<string, unknown>): FactorInfo {
  const codec = json.codec;
  if (typeof codec !== "string" || !(FACTOR_CODECS as readonly string[]).includes(codec))
    throw new UnsupportedMaterial(`${name}: codec '${String(codec)}' is not supported by the viewer (it renders ${FACTOR_CODECS.join(", ")}, mlvq and bsvtf packages)`);
  try {
    return readFields(name, codec as FactorCodec, json);
  } catch (e) {
    throw new Error(`${name}: package (${codec}): ${(e as Error).message}`);
  }
}

function readFields(name: string, codec: FactorCodec, h: Record<string, unknown>): FactorInfo {
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
  if (colour !== "rgb" && colour !== "decorrelated" && colour !== "per-channel" && colour !== "model11" && colour !== "lab")
    throw new Error(`unknown colour handling ${JSON.stringify(colour)}`);
  if (typeof m.log !== "boolean") throw new Error("header field 'model.log' must be a boolean");
  if (typeof m.log_eps !== "number") throw new Error("header field 'model.log_eps' must be a number");
  if (m.log && colour === "lab") throw new Error("log with lab colour");
  const quantization = m.quantization;
  if (quantization !== "f32" && quantization !== "f16" && quantization !== "u8" && quantization !== "coded")
    throw new Error(`unknown quantization ${JSON.stringify(quantization)} (known: f32, f16, u8, coded)`);
  const nV = views.theta.length, nL = lights.theta.length;

  const groupsJson = m.groups as unknown;
  if (!Array.isArray(groupsJson) || groupsJson.length === 0 || groupsJson.length > nV)
    throw new Error(`header field 'model.groups' must be an array of 1 to ${nV} view groups`);
  const groupOfView = new Array<number>(nV).fill(-1), slotOfView = new Array<number>(nV).fill(-1);
  const groups = groupsJson.map((group: unknown, g: number) => {
    if (!Array.isArray(group) || group.length === 0) throw new Error(`view group ${g} must be a non-empty array`);
    return group.map((v, slot) => {
      const view = int(v, `model.groups[${g}]`, 0, nV - 1);
      if (groupOfView[view] >= 0) throw new Error(`view ${view} is in two view groups`);
      groupOfView[view] = g;
      slotOfView[view] = slot;
      return view;
    });
  });
  const missing = groupOfView.indexOf(-1);
  if (missing >= 0) throw new Error(`view ${missing} is in no view group`);
  const clusters = int(m.clusters, "model.clusters", 1, width * height);
  const levels = m.levels === undefined ? 1 : int(m.levels, "model.levels", 1, 16);
  if (levels > 1 && (clusters !== 1 || width % (1 << (levels - 1)) !== 0 || height % (1 << (levels - 1)) !== 0))
    throw new Error(`${levels} spatial levels for ${width}×${height} texels in ${clusters} clusters`);
  const angularLevels: AngularLevel[] = [];
  if (m.angular_levels !== undefined) {
    if (!Array.isArray(m.angular_levels) || m.angular_levels.length > 15) throw new Error("header field 'model.angular_levels' must be an array of at most 15 levels");
    if (groups.length !== 1 || groups[0].some((v, i) => v !== i)) throw new Error("angular levels need one view group with the views in order");
    m.angular_levels.forEach((a: Record<string, unknown>, i: number) => {
      const subset = (list: unknown, what: string, n: number): number[] => {
        if (!Array.isArray(list) || list.length < 3 || list.length > n) throw new Error(`angular level ${i + 1} must keep 3 to ${n} ${what}`);
        return list.map((x, j) => {
          const v = int(x, `model.angular_levels[${i}].${what}`, 0, n - 1);
          if (j > 0 && v <= (list[j - 1] as number)) throw new Error(`angular level ${i + 1} ${what} must be ascending`);
          return v;
        });
      };
      angularLevels.push({ views: subset(a?.views, "views", nV), lights: subset(a?.lights, "lights", nL) });
    });
  }
  const planes = colour === "rgb" ? 1 : 3;
  const channels = colour === "rgb" ? 3 : 1;
  const angular = 1 + angularLevels.length;
  const expected = planes * groups.length * clusters * levels * angular;
  const blocksJson = m.blocks as unknown;
  if (!Array.isArray(blocksJson) || blocksJson.length !== expected)
    throw new Error(
      `${Array.isArray(blocksJson) ? blocksJson.length : "no"} blocks for ${planes} planes × ${groups.length} groups × ${clusters} clusters × ${levels} levels × ${angular} angular levels`,
    );
  const blocks: FactorBlock[] = blocksJson.map((b: Record<string, unknown>, i: number) => {
    const an = i % angular, level = Math.floor(i / angular) % levels;
    const cluster = Math.floor(i / (angular * levels)) % clusters;
    const group = Math.floor(i / (angular * levels * clusters)) % groups.length;
    const plane = Math.floor(i / (angular * levels * clusters * groups.length));
    if (!b || b.plane !== plane || b.group !== group || b.cluster !== cluster || (b.level ?? 0) !== level || (b.angular ?? 0) !== an)
      throw new Error(`block ${i} is out of range or out of order`);
    const components = int(b.components, `model.blocks[${i}].components`, 0, 4096);
    if (typeof b.mean !== "boolean") throw new Error(`header field 'model.blocks[${i}].mean' must be a boolean`);
    if (b.mean && an > 0) throw new Error(`block ${i} of angular level ${an} has row means`);
    if (!Array.isArray(b.energy) || b.energy.length !== components)
      throw new Error(`block ${i} declares ${components} components but ${Array.isArray(b.energy) ? b.energy.length : "no"} energies`);
    return { plane, group, cluster, level, angular: an, components, mean: b.mean };
  });
  return {
    name,
    codec,
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
    groups,
    groupOfView,
    slotOfView,
    clusters,
    levels,
    angularLevels,
    blocks,
    totalComponents: blocks.reduce((s, b) => s + b.components, 0),
  };
}

/** Index of a block in FactorInfo.blocks. */
export function blockIndex(info: FactorInfo, plane: number, group: number, cluster: number, level = 0, angular = 0): number {
  return (((plane * info.groups.length + group) * info.clusters + cluster) * info.levels + level) * (1 + info.angularLevels.length) + angular;
}

/** Rows of a block's mean and of its a columns after angular up-sampling: its group's views × lights × channels. */
export function groupRows(info: FactorInfo, group: number): number {
  return info.groups[group].length * info.nL * info.channels;
}

/** Rows of a block's a columns as stored (at its angular level). */
export function storedRows(info: FactorInfo, block: FactorBlock): number {
  if (block.angular === 0) return groupRows(info, block.group);
  const a = info.angularLevels[block.angular - 1];
  return a.views.length * a.lights.length * info.channels;
}

/** Bytes of one quantized column of n values (column_bytes in model.cpp; coded: the f16 size, an estimate). */
export function columnBytes(q: Quantization, n: number): number {
  return q === "f32" ? 4 * n : q === "f16" || q === "coded" ? 2 * n : 8 + n;
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

/** Up-sampling weights of one angular level: U_view (nV × nV′) and U_light (nL × nL′), row-major. */
export interface AngularUpsampling {
  views: Float32Array;
  lights: Float32Array;
}

/** Section "angular": the up-sampling of every angular level. */
export function readAngularSection(info: FactorInfo, data: Uint8Array): AngularUpsampling[] {
  const expected = info.angularLevels.reduce((n, a) => n + 4 * (info.nV * a.views.length + info.nL * a.lights.length), 0);
  if (data.length !== expected) throw new Error(`section 'angular' holds ${data.length} bytes, expected ${expected}`);
  const view = new DataView(data.buffer, data.byteOffset, data.byteLength);
  let at = 0;
  const take = (n: number) => {
    const out = new Float32Array(n);
    for (let i = 0; i < n; ++i, at += 4) out[i] = view.getFloat32(at, true);
    if (!out.every(Number.isFinite)) throw new Error("section 'angular' holds a weight that is not a finite number");
    return out;
  };
  return info.angularLevels.map((a) => ({ views: take(info.nV * a.views.length), lights: take(info.nL * a.lights.length) }));
}

/** Section "clusters": the cluster of every texel. */
export function readClustersSection(info: FactorInfo, data: Uint8Array): Int32Array {
  const n = info.width * info.height;
  if (data.length !== 4 * n) throw new Error(`section 'clusters' holds ${data.length} bytes, expected ${4 * n}`);
  const view = new DataView(data.buffer, data.byteOffset, data.byteLength);
  const out = new Int32Array(n);
  for (let t = 0; t < n; ++t) {
    out[t] = view.getInt32(4 * t, true);
    if (out[t] < 0 || out[t] >= info.clusters) throw new Error(`section 'clusters': texel ${t} is in cluster ${out[t]} of ${info.clusters}`);
  }
  return out;
}

// The coarse texels along one axis of n full texels at `level` that the bilinear interpolation
// at coordinate c reads through the up-sampling, with their weights (axis_taps of material.cpp).
function axisTaps(c: number, n: number, level: number): { index: number[]; weight: number[] } {
  const full = wrapLerp(c, n);
  const coarse = n >> level;
  const index: number[] = [], weight: number[] = [];
  const add = (i: number, w: number) => {
    const k = index.indexOf(i);
    if (k >= 0) weight[k] = Math.fround(weight[k] + w);
    else {
      index.push(i);
      weight.push(w);
    }
  };
  for (const [i, w] of [
    [full.i0, 1 - full.t],
    [full.i1, full.t],
  ]) {
    const up = wrapLerp((i + 0.5) / n, coarse);
    add(up.i0, Math.fround(w * (1 - up.t)));
    add(up.i1, Math.fround(w * up.t));
  }
  return { index, weight };
}

/** A spatial lookup at one level: texels (rows of the blocks' b) with weights and clusters. */
interface Taps {
  texel: number[];
  weight: number[];
  cluster: number[];
}

/** A decoded model: what arrived so far (components in order per block). */
export class FactorModel {
  /** [block][k]: the a column at every (view of the group, light) row (angular levels up-sampled). */
  readonly a: Float32Array[][];
  /** [block][k]: the b column as stored (the cluster's texels, or the level's grid). */
  readonly b: Float32Array[][];
  means: (Float32Array | null)[];
  /** Cluster of each texel and its position among its cluster's texels (null: one cluster). */
  cluster: Int32Array | null = null;
  local: Int32Array | null = null;
  clusterSize: number[];
  upsampling: AngularUpsampling[] | null = null;

  constructor(readonly info: FactorInfo) {
    this.a = info.blocks.map(() => []);
    this.b = info.blocks.map(() => []);
    this.means = info.blocks.map(() => null);
    this.clusterSize = [info.width * info.height];
  }

  get loadedComponents(): number {
    return this.a.reduce((s, c) => s + c.length, 0);
  }

  setClusters(data: Uint8Array): void {
    const cluster = readClustersSection(this.info, data);
    const local = new Int32Array(cluster.length);
    this.clusterSize = new Array(this.info.clusters).fill(0);
    for (let t = 0; t < cluster.length; ++t) local[t] = this.clusterSize[cluster[t]]++;
    this.cluster = cluster;
    this.local = local;
  }

  setAngular(data: Uint8Array): void {
    this.upsampling = readAngularSection(this.info, data);
  }

  /** Texels of a block's b (its cluster's, or its level's grid). */
  blockTexels(block: FactorBlock): number {
    if (block.level > 0) return (this.info.width >> block.level) * (this.info.height >> block.level);
    return this.info.clusters > 1 ? this.clusterSize[block.cluster] : this.info.width * this.info.height;
  }

  /** The means section: one float32 per row of every block that has one, blocks in order. */
  setMeans(data: Uint8Array): void {
    const info = this.info;
    const expected = info.blocks.reduce((n, b) => n + (b.mean ? groupRows(info, b.group) : 0), 0) * 4;
    if (data.length !== expected) throw new Error(`section 'means' holds ${data.length} bytes, expected ${expected}`);
    const view = new DataView(data.buffer, data.byteOffset, data.byteLength);
    let at = 0;
    this.means = info.blocks.map((b) => {
      if (!b.mean) return null;
      const out = new Float32Array(groupRows(info, b.group));
      for (let i = 0; i < out.length; ++i, at += 4) out[i] = view.getFloat32(at, true);
      return out;
    });
  }

  /**
   * Decodes any model section (means, clusters, angular, a component) into this model; returns the
   * component's block and k, or null for the other sections. Sections of no concern to the model
   * (tables, a BSVTF's) are left to the caller.
   */
  addSection(name: string, data: Uint8Array): { block: number; k: number } | null {
    if (name === "means") this.setMeans(data);
    else if (name === "clusters") this.setClusters(data);
    else if (name === "angular") this.setAngular(data);
    else return this.addComponent(name, data);
    return null;
  }

  /**
   * Decodes a component section into this model; returns the block and k. Throws for sections
   * out of order, undeclared or of the wrong size (the C++ reader's checks), and for sections the
   * model cannot place yet (clusters or angular up-sampling missing).
   */
  addComponent(name: string, data: Uint8Array): { block: number; k: number } {
    const id = parseComponentName(name);
    const info = this.info;
    if (!id || id.block >= info.blocks.length || id.k !== this.a[id.block].length || id.k >= info.blocks[id.block].components)
      throw new Error(`component section '${name}' is out of order or undeclared`);
    const block = info.blocks[id.block];
    if (info.clusters > 1 && !this.cluster) throw new Error(`section '${name}' arrives before section 'clusters'`);
    if (block.angular > 0 && !this.upsampling)
      throw new Error(`section '${name}' needs section 'angular' (the up-sampling of the angular levels), which this package lacks: compress it again with a current btf`);
    const rows = storedRows(info, block), texels = this.blockTexels(block);
    const q = info.quantization;
    if (q === "coded") {
      const image = info.clusters === 1 ? { width: info.width >> block.level, height: info.height >> block.level } : null;
      const lights = block.angular === 0 ? info.nL : info.angularLevels[block.angular - 1].lights.length;
      const { a, b } = decodeCodedComponent(data, rows, texels, image, name, { lights, channels: info.channels });
      this.a[id.block].push(block.angular > 0 ? this.upsample(a, block.angular) : a);
      this.b[id.block].push(b);
      return id;
    }
    const expected = columnBytes(q, rows) + columnBytes(q, texels);
    if (data.length !== expected) throw new Error(`section '${name}' holds ${data.length} bytes, expected ${expected}`);
    const a = decodeColumn(q, data, 0, rows);
    this.a[id.block].push(block.angular > 0 ? this.upsample(a, block.angular) : a);
    this.b[id.block].push(decodeColumn(q, data, columnBytes(q, rows), texels));
    return id;
  }

  // U_view · A · U_lightᵀ per channel (AngularResampler::upsample, in double as the C++).
  private upsample(coarse: Float32Array, angular: number): Float32Array {
    const info = this.info, C = info.channels, nV = info.nV, nL = info.nL;
    const level = info.angularLevels[angular - 1], u = this.upsampling![angular - 1];
    const cv = level.views.length, cl = level.lights.length;
    const out = new Float32Array(nV * nL * C);
    const tmp = new Float64Array(cl);
    for (let c = 0; c < C; ++c)
      for (let v = 0; v < nV; ++v) {
        tmp.fill(0);
        for (let vv = 0; vv < cv; ++vv) {
          const w = u.views[v * cv + vv];
          if (w === 0) continue;
          for (let ll = 0; ll < cl; ++ll) tmp[ll] += w * coarse[(vv * cl + ll) * C + c];
        }
        for (let l = 0; l < nL; ++l) {
          let s = 0;
          for (let ll = 0; ll < cl; ++ll) s += u.lights[l * cl + ll] * tmp[ll];
          out[(v * nL + l) * C + c] = s;
        }
      }
    return out;
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

  // The texels a lookup at (u, v) reads at each spatial level (material.cpp all_texels).
  private taps(u: number, v: number): Taps[] {
    const info = this.info, W = info.width, H = info.height;
    const lx = wrapLerp(u, W), ly = wrapLerp(v, H);
    const texel = [ly.i0 * W + lx.i0, ly.i0 * W + lx.i1, ly.i1 * W + lx.i0, ly.i1 * W + lx.i1];
    const weight = [(1 - lx.t) * (1 - ly.t), lx.t * (1 - ly.t), (1 - lx.t) * ly.t, lx.t * ly.t];
    const out: Taps[] = [{ texel, weight, cluster: texel.map((t) => (this.cluster ? this.cluster[t] : 0)) }];
    for (let level = 1; level < info.levels; ++level) {
      const tx = axisTaps(u, W, level), ty = axisTaps(v, H, level), row = W >> level;
      const t: Taps = { texel: [], weight: [], cluster: [] };
      ty.index.forEach((y, j) =>
        tx.index.forEach((x, i) => {
          t.texel.push(y * row + x);
          t.weight.push(ty.weight[j] * tx.weight[i]);
          t.cluster.push(0);
        }),
      );
      out.push(t);
    }
    return out;
  }

  /** Σ over the views' and the given lights' weights of the bilinear plane values. */
  planeValues(u: number, v: number, vw: Weights, lightIndex: number[], lightWeight: number[]): [number, number, number] {
    const info = this.info, C = info.channels, nL = info.nL;
    const taps = this.taps(u, v);
    const groups: number[] = [];
    for (let i = 0; i < 3; ++i) {
      if (vw.weight[i] === 0) continue;
      const g = info.groupOfView[vw.index[i]];
      if (!groups.includes(g)) groups.push(g);
    }
    const out: [number, number, number] = [0, 0, 0];
    for (let p = 0; p < info.planes; ++p)
      for (const g of groups)
        for (let level = 0; level < info.levels; ++level) {
          const t = taps[level];
          for (const c of new Set(t.cluster)) {
            // Spatial: Σ over the cluster's texels of w · b (the texel's own cluster only).
            let weightSum = 0;
            for (let j = 0; j < t.texel.length; ++j) if (t.cluster[j] === c) weightSum += t.weight[j];
            for (let an = 0; an <= info.angularLevels.length; ++an) {
              const bi = blockIndex(info, p, g, c, level, an);
              const a = this.a[bi], mean = this.means[bi];
              if (a.length === 0 && !mean) continue;
              const bsum = this.b[bi].map((col) => {
                let s = 0;
                for (let j = 0; j < t.texel.length; ++j) {
                  if (t.cluster[j] !== c) continue;
                  const texel = level === 0 && this.local ? this.local[t.texel[j]] : t.texel[j];
                  s += t.weight[j] * col[texel];
                }
                return s;
              });
              // Angular: Σ over the group's views and the lights of w · (mean · Σw + a · b).
              for (let i = 0; i < 3; ++i) {
                if (vw.weight[i] === 0 || info.groupOfView[vw.index[i]] !== g) continue;
                const slot = info.slotOfView[vw.index[i]];
                for (let j = 0; j < lightIndex.length; ++j) {
                  const w = vw.weight[i] * lightWeight[j];
                  if (w === 0) continue;
                  for (let ch = 0; ch < C; ++ch) {
                    const row = (slot * nL + lightIndex[j]) * C + ch;
                    let s = mean ? weightSum * mean[row] : 0;
                    for (let k = 0; k < a.length; ++k) s += a[k][row] * bsum[k];
                    out[p + ch] += w * s;
                  }
                }
              }
            }
          }
        }
    return out;
  }
}

// ---- texture layouts ------------------------------------------------------------------------

/**
 * Where everything lives in the textures the shader reads. The blocks of one (plane, group,
 * cluster) — an "eval block" — are one set of components after the angular up-sampling and the
 * spatial up-sampling (their a columns side by side, their b columns at full resolution), in
 * block order; component k of block i is number laneOffset[i] + k of its eval block.
 *
 * - A (RGBA float array texture): texel (l · C + ch, view, layer) holds a(row, 4j .. 4j + 3) of the
 *   view's group, row = (slot(view) · nL + l) · C + ch, layer = aBase[eval block] + j. Column
 *   l = nL is the uniform environment's pre-integrated "light" (Σ_l c_l a(row(l))).
 * - Means (R float array texture): texel (l · C + ch, view, plane · clusters + cluster), the same
 *   rows and the same environment column (the sum of the means of the eval block's blocks).
 * - B (RGBA float or half array texture): layer bBase[plane · G + group] + j holds, at each texel,
 *   components 4j .. 4j + 3 of the eval block of the texel's own cluster, as an atlas of the
 *   eigen-texture and its mip chain: level 0 at (0, 0) in W × H, level m ≥ 1 of
 *   max(1, W >> m) × max(1, H >> m) texels at (W, Σ_{1 ≤ i < m} height_i). Clustered models have
 *   no mip chain (averages across cluster borders would mix the clusters' factors).
 * - Blocks (RGBA int texture, TABLE_WIDTH wide): per eval block (aBase, layers holding loaded
 *   components, bBase, means layer).
 */
export interface Layout {
  aWidth: number;
  aHeight: number;
  aLayers: number;
  bLayers: number;
  /** Per eval block ((plane · G + group) · clusters + cluster). */
  aBase: number[];
  aCapacity: number[];
  /** Per (plane · G + group). */
  bBase: number[];
  /** Per block of FactorInfo.blocks. */
  laneOffset: number[];
  evalBlocks: number;
  meanLayers: number;
  atlasWidth: number;
  atlasHeight: number;
  mipLevels: number;
  /** Per mip level: x, y, width, height in the atlas. */
  mips: { x: number; y: number; w: number; h: number }[];
  half: boolean;
  /** The first layer of each plane's (single) eval block: the BSVTF mode's component groups. */
  layerBase: number[];
  layerCount: number[];
}

/** The eval block of a block. */
export function evalBlockOf(info: FactorInfo, b: FactorBlock): number {
  return (b.plane * info.groups.length + b.group) * info.clusters + b.cluster;
}

export function makeLayout(info: FactorInfo): Layout {
  const G = info.groups.length, evalBlocks = info.planes * G * info.clusters;
  const components = new Array<number>(evalBlocks).fill(0);
  const laneOffset = info.blocks.map((b) => {
    const e = evalBlockOf(info, b);
    const at = components[e];
    components[e] += b.components;
    return at;
  });
  const aBase: number[] = [], aCapacity: number[] = [];
  let aLayers = 0;
  for (let e = 0; e < evalBlocks; ++e) {
    aBase.push(aLayers);
    aCapacity.push(Math.ceil(components[e] / 4));
    aLayers += aCapacity[e];
  }
  const bBase: number[] = [];
  let bLayers = 0;
  for (let pg = 0; pg < info.planes * G; ++pg) {
    bBase.push(bLayers);
    let most = 0;
    for (let c = 0; c < info.clusters; ++c) most = Math.max(most, aCapacity[pg * info.clusters + c]);
    bLayers += most;
  }
  const W = info.width, H = info.height;
  const mipLevels = info.clusters > 1 ? 1 : Math.floor(Math.log2(Math.max(W, H))) + 1;
  const mips = [{ x: 0, y: 0, w: W, h: H }];
  let y = 0;
  for (let m = 1; m < mipLevels; ++m) {
    const w = Math.max(1, W >> m), h = Math.max(1, H >> m);
    mips.push({ x: W, y, w, h });
    y += h;
  }
  const planeBlocks = Array.from({ length: info.planes }, (_, p) => p * G * info.clusters);
  return {
    aWidth: (info.nL + 1) * info.channels,
    aHeight: info.nV,
    aLayers: Math.max(aLayers, 1),
    bLayers: Math.max(bLayers, 1),
    aBase,
    aCapacity,
    bBase,
    laneOffset,
    evalBlocks,
    meanLayers: info.planes * info.clusters,
    atlasWidth: mipLevels > 1 ? W + Math.max(1, W >> 1) : W,
    atlasHeight: Math.max(H, y),
    mipLevels,
    mips,
    // f16 and coded factors are half floats, which half textures hold exactly.
    half: info.quantization === "f16" || info.quantization === "coded",
    layerBase: planeBlocks.map((e) => aBase[e]),
    layerCount: planeBlocks.map((e) => aCapacity[e]),
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

/**
 * A b column of a spatial level j > 0 at full resolution: the bilinear, wrapping up-sampling of
 * its (W >> j) × (H >> j) grid at the full texels' centres, the model's definition of those texels.
 */
export function upsampleLevel(info: FactorInfo, column: Float32Array, level: number): Float32Array {
  const W = info.width, H = info.height, cw = W >> level, chh = H >> level;
  const out = new Float32Array(W * H);
  for (let y = 0; y < H; ++y) {
    const uy = wrapLerp((y + 0.5) / H, chh);
    for (let x = 0; x < W; ++x) {
      const ux = wrapLerp((x + 0.5) / W, cw);
      out[y * W + x] =
        (1 - ux.t) * (1 - uy.t) * column[uy.i0 * cw + ux.i0] +
        ux.t * (1 - uy.t) * column[uy.i0 * cw + ux.i1] +
        (1 - ux.t) * uy.t * column[uy.i1 * cw + ux.i0] +
        ux.t * uy.t * column[uy.i1 * cw + ux.i1];
    }
  }
  return out;
}

// ---- colour ----------------------------------------------------------------------------------

const DA = Math.fround(1 / Math.sqrt(3)), DB = Math.fround(1 / Math.sqrt(2)), DC = Math.fround(1 / Math.sqrt(6));

/** eps of UBO2014 colour model 11 (kUboLogEps, core/color.h). */
const UBO_LOG_EPS = Math.fround(1e-5);

// CIELab → XYZ (D65, Y = 1) → linear Rec. 709 RGB: lab_to_xyz and xyz_to_rgb of core/color.cpp.
const LAB_EPSILON = 216 / 24389, LAB_KAPPA = 24389 / 27;
const XYZ_TO_RGB = [3.2404542, -1.5371385, -0.4985314, -0.969266, 1.8760108, 0.041556, 0.0556434, -0.2040259, 1.0572252];
export function labToRgb(l: number, a: number, b: number): [number, number, number] {
  const fy = (l + 16) / 116, fx = fy + a / 500, fz = fy - b / 200;
  const inv = (f: number) => (f * f * f > LAB_EPSILON ? f * f * f : (116 * f - 16) / LAB_KAPPA);
  const x = inv(fx) * 0.95047, y = l > LAB_KAPPA * LAB_EPSILON ? fy * fy * fy : l / LAB_KAPPA, z = inv(fz) * 1.08883;
  const m = XYZ_TO_RGB;
  return [Math.fround(m[0] * x + m[1] * y + m[2] * z), Math.fround(m[3] * x + m[4] * y + m[5] * z), Math.fround(m[6] * x + m[7] * y + m[8] * z)];
}

/** Plane values → linear RGB (ColourHandling::inverse). */
export function inverseColour(info: FactorInfo, p: [number, number, number]): [number, number, number] {
  if (info.colour === "lab") return labToRgb(Math.fround(p[0]), Math.fround(p[1]), Math.fround(p[2]));
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

/**
 * A factorization package's model and interpolation tables from its decoded sections (in package
 * order): what the CPU reference evaluates. Throws as the model's decoders do.
 */
export function decodeFactorSections(
  name: string,
  json: Record<string, unknown>,
  sections: { entry: { name: string }; data: Uint8Array }[],
): { info: FactorInfo; model: FactorModel; tables: { views: InterpTables; lights: InterpTables } | null } {
  const info = readFactorHeader(name, json);
  const model = new FactorModel(info);
  let tables: { views: InterpTables; lights: InterpTables } | null = null;
  for (const s of sections) {
    if (s.entry.name === "tables") tables = readTablesSection(s.data, info.nV, info.nL);
    else model.addSection(s.entry.name, s.data);
  }
  return { info, model, tables };
}
