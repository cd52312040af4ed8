// SPDX-License-Identifier: MIT
// BSVTF packages in the viewer (docs/bsvtf.md, src/btf/bsvtf/file.h): the header's "bsvtf"
// fields, the tile index, and the decoding of a tile payload (src/btf/bsvtf/tile_codec.cpp) from
// the bytes of the raw "tiles" section and the decoded parent (predict_child of pyramid.cpp).
//
// The decoding follows the C++ operation by operation; the C++ may fuse multiply-adds where the
// build allows, so a decoded value can differ from the C++ one in its last half-float bit.

import { inverseDct, Varints, ZIGZAG } from "./dct8";
import { halfToFloat, floatToHalf } from "./half";
import { TileLayout, type Group, type TileId } from "./cache";

export interface BsvtfInfo {
  width: number;
  height: number;
  tile: number;
  pad: number;
  levels: number;
  groups: Group[];
  step: number;
  relativeError: number;
  tiles: number;
  uFormat: "f16" | "f32";
}

/** The "bsvtf" header fields; throws Error naming the field. */
export function readBsvtfHeader(json: Record<string, unknown>): BsvtfInfo {
  const b = json.bsvtf as Record<string, unknown> | undefined;
  if (!b || typeof b !== "object") throw new Error("header field 'bsvtf' is missing");
  const int = (f: string, lo: number, hi: number): number => {
    const v = b[f];
    if (typeof v !== "number" || !Number.isInteger(v) || v < lo || v > hi) throw new Error(`header field 'bsvtf.${f}' must be an integer in [${lo}, ${hi}], not ${JSON.stringify(v)}`);
    return v;
  };
  const num = (f: string): number => {
    const v = b[f];
    if (typeof v !== "number" || !Number.isFinite(v) || v < 0) throw new Error(`header field 'bsvtf.${f}' must be a non-negative number`);
    return v;
  };
  const groups = b.groups;
  if (!Array.isArray(groups) || groups.length === 0) throw new Error("header field 'bsvtf.groups' must be a non-empty array");
  const info: BsvtfInfo = {
    width: int("width", 1, 65536),
    height: int("height", 1, 65536),
    tile: int("tile", 8, 4096),
    pad: int("pad", 2, 64),
    levels: int("levels", 1, 17),
    groups: groups.map((g, i) => {
      if (!Array.isArray(g) || g.length !== 3 || !g.every((x) => Number.isInteger(x) && x >= 0)) throw new Error(`header field 'bsvtf.groups[${i}]' must be [plane, first, count]`);
      return { plane: g[0], first: g[1], count: g[2] };
    }),
    step: num("step"),
    relativeError: num("relative_error"),
    tiles: int("tiles", 1, 2 ** 31),
    uFormat: b.u_format === "f16" ? "f16" : b.u_format === "f32" ? "f32" : (() => { throw new Error(`header field 'bsvtf.u_format' must be "f16" or "f32"`); })(),
  };
  const layout = layoutOf(info);
  if (layout.levels !== info.levels || layout.tileCount !== info.tiles)
    throw new Error(`header field 'bsvtf': ${info.levels} levels and ${info.tiles} tiles do not fit ${info.width} × ${info.height} texels in tiles of ${info.tile}`);
  return info;
}

export function layoutOf(info: BsvtfInfo): TileLayout {
  return new TileLayout(info.width, info.height, info.tile, info.pad, info.groups);
}

/** The tiles.index section: per tile its weight (equation 8), payload size and offset in "tiles". */
export interface TileIndex {
  weights: Float32Array;
  sizes: Uint32Array;
  offsets: Float64Array;
}

export function readTileIndex(data: Uint8Array, tiles: number, tilesBytes: number): TileIndex {
  if (data.length !== 16 * tiles) throw new Error(`section 'tiles.index' holds ${data.length} bytes, expected ${16 * tiles}`);
  const view = new DataView(data.buffer, data.byteOffset, data.byteLength);
  const out: TileIndex = { weights: new Float32Array(tiles), sizes: new Uint32Array(tiles), offsets: new Float64Array(tiles) };
  for (let t = 0; t < tiles; ++t) {
    out.weights[t] = view.getFloat32(16 * t, true);
    out.sizes[t] = view.getUint32(16 * t + 4, true);
    out.offsets[t] = Number(view.getBigUint64(16 * t + 8, true));
    if (out.offsets[t] + out.sizes[t] > tilesBytes) throw new Error(`section 'tiles.index': tile ${t} lies beyond the ${tilesBytes} bytes of section 'tiles'`);
  }
  return out;
}

// ---- tile decoding ----------------------------------------------------------------------------


async function inflate(data: Uint8Array, size: number): Promise<Uint8Array> {
  const stream = new Blob([data as Uint8Array<ArrayBuffer>]).stream().pipeThrough(new DecompressionStream("deflate-raw"));
  let out: Uint8Array;
  try {
    out = new Uint8Array(await new Response(stream).arrayBuffer());
  } catch {
    throw new Error("tile: the deflate stream is damaged");
  }
  if (out.length !== size) throw new Error(`tile: the deflate stream holds ${out.length} bytes, the header says ${size}`);
  return out;
}

/**
 * The up-sampling of a parent tile onto the texels of its child `child` (predict_child): per
 * value, the parent's level interpolated bilinearly at the child texel's centre, in float
 * arithmetic.
 */
export function predictChild(parent: Uint16Array, layout: TileLayout, child: TileId): Float32Array {
  const T = layout.tile, P = layout.pad, S = layout.stride;
  const axis = (origin: number, local: number): [number, number] => {
    const u = origin * T + local - P;
    const c = (u + 0.5) / 2 - 0.5 - Math.floor(origin / 2) * T + P;
    const i0 = Math.floor(c);
    return [i0, Math.fround(c - i0)];
  };
  const f = Math.fround;
  const out = new Float32Array(layout.values);
  for (let ly = 0; ly < S; ++ly) {
    const [y0, ty] = axis(child.y, ly);
    for (let lx = 0; lx < S; ++lx) {
      const [x0, tx] = axis(child.x, lx);
      const r0 = (y0 * S + x0) * 4, r1 = r0 + S * 4;
      for (let c = 0; c < 4; ++c) {
        // from_half(a) * (1 − tx) * (1 − ty) + … evaluated left to right in float
        const a = f(f(halfToFloat(parent[r0 + c]) * f(1 - tx)) * f(1 - ty));
        const b = f(f(halfToFloat(parent[r0 + 4 + c]) * tx) * f(1 - ty));
        const d = f(f(halfToFloat(parent[r1 + c]) * f(1 - tx)) * ty);
        const e = f(f(halfToFloat(parent[r1 + 4 + c]) * tx) * ty);
        out[(ly * S + lx) * 4 + c] = f(f(f(a + b) + d) + e);
      }
    }
  }
  return out;
}

/**
 * decode_tile: the tile's half-float bits from its payload and the prediction from its decoded
 * parent (null for a coarsest tile). Throws Error for a damaged payload.
 */
export async function decodeTile(payload: Uint8Array, prediction: Float32Array | null, layout: TileLayout): Promise<Uint16Array> {
  const values = layout.values;
  if (payload.length < 9) throw new Error("tile: the payload is shorter than its header");
  const view = new DataView(payload.buffer, payload.byteOffset, payload.byteLength);
  const format = payload[0], step = view.getFloat32(1, true), inflated = view.getUint32(5, true);
  if (format !== 1 && format !== 2) throw new Error(`tile: unknown format ${format}`);
  if (inflated > values * 10) throw new Error("tile: the inflated size is implausible");
  const raw = await inflate(payload.subarray(9), inflated);
  const out = new Uint16Array(values);
  if (format === 2) {
    if (inflated !== values * 2) throw new Error("tile: a lossless tile has the wrong size");
    for (let i = 0; i < values; ++i) out[i] = (raw[i] << 8) | raw[values + i];
    return out;
  }
  if (!(step > 0) || !Number.isFinite(step)) throw new Error("tile: the quantization step is invalid");
  const S = layout.stride, blocks = S / 8;
  const codes = new Varints(raw, 0, "tile");
  const coef = new Float64Array(64), block = new Float64Array(64), tmp = new Float64Array(64);
  for (let c = 0; c < 4; ++c)
    for (let by = 0; by < blocks; ++by)
      for (let bx = 0; bx < blocks; ++bx) {
        for (let k = 0; k < 64; ++k) coef[ZIGZAG[k]] = codes.next() * step;
        inverseDct(coef, block, tmp);
        for (let r = 0; r < 8; ++r)
          for (let n = 0; n < 8; ++n) {
            const i = ((by * 8 + r) * S + bx * 8 + n) * 4 + c;
            out[i] = floatToHalf(Math.fround(block[r * 8 + n] + (prediction ? prediction[i] : 0)));
          }
      }
  if (codes.at !== raw.length) throw new Error("tile: bytes after the coefficients");
  return out;
}
