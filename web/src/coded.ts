// SPDX-License-Identifier: MIT
// Coded factor storage (model.quantization "coded"; docs/formats.md, "Factorization sections";
// src/btf/codecs/factor/coded.cpp): one component section holds a's codes, differences at a
// prediction distance or by channel prediction, and b's, either alike or as 8 × 8 DCT blocks of
// the periodically extended texel image written band by band; format 2 range-codes the integers
// (./rangecoder), format 1 wrote varints. Decoded as the C++ reader decodes: the inverse DCT in
// double in the same order, every value rounded to the nearest half float.

import { inverseDct, Varints, ZIGZAG } from "./dct8";
import { floatToHalf, halfToFloat } from "./half";
import { IntegerModel, RangeDecoder } from "./rangecoder";

const RANGE_FORMAT = 2, VARINT_FORMAT = 1, PLAIN = 0, DCT_IMAGE = 1, HEAD = 12, MAX_STRIDE = 64;
// a's prediction by neighbouring directions, and a's planes as DCT-coded images of views × lights
// (format 2; coded.cpp's kNeighbours and kDctPlanes).
const NEIGHBOURS = 128, DCT_PLANES = 129;
// The integer streams (contexts) of format 2, as coded.cpp's Stream: an image's DC differences in
// DC (b) or ANGULAR_DC (a's images of directions), its band k in that stream + 1 + the band's
// group.
const ANGULAR = 0, ANGULAR_CHROMA = 1, TEXELS = 2, DC = 3, ANGULAR_DC = 13, STREAMS = ANGULAR_DC + 10;
const bandGroup = (k: number): number => {
  let group = 1;
  for (const start of [3, 6, 10, 15, 21, 28, 36]) if (k >= start) ++group;
  return group;
};

interface Reader {
  get(stream: number): number;
}

const asHalf = (v: number): number => halfToFloat(floatToHalf(Math.fround(v)));

/** The layout of a's rows: `channels` values per (view, light) pair, `lights` pairs per view. */
export interface AngularRows {
  lights: number;
  channels: number;
}

const neighboursFit = (rows: AngularRows | undefined, n: number): rows is AngularRows =>
  !!rows && rows.lights > 0 && (rows.channels === 1 || rows.channels === 3) && n % (rows.lights * rows.channels) === 0;

// The value of plane j of a pair: 3 channels: the middle channel, then the outer ones' offsets
// to it; otherwise the channel itself.
function planeOf(codes: Float64Array, channels: number, pair: number, j: number): number {
  const q = pair * channels;
  if (channels !== 3) return codes[q + j];
  return j === 0 ? codes[q + 1] : codes[q + (j === 1 ? 0 : 2)] - codes[q + 1];
}

// Each plane predicted by the floor of the mean of the previous light's and the previous view's
// (the one there is at a view's first light or in the first view; 0 for the first pair).
function neighbourPrediction(codes: Float64Array, rows: AngularRows, pair: number, j: number): number {
  const left = pair % rows.lights > 0, up = pair >= rows.lights;
  if (left && up) return Math.floor((planeOf(codes, rows.channels, pair - 1, j) + planeOf(codes, rows.channels, pair - rows.lights, j)) / 2);
  if (left) return planeOf(codes, rows.channels, pair - 1, j);
  if (up) return planeOf(codes, rows.channels, pair - rows.lights, j);
  return 0;
}

// Differences at a distance, or (stride 0, rows of 3 channels) the middle channel's differences
// along the rows, then the outer channels' offsets to it as differences along the rows, or
// (NEIGHBOURS) planes predicted from the neighbouring directions.
function plain(v: Reader, n: number, step: number, stride: number, stream: number, rows?: AngularRows): Float32Array {
  const codes = new Float64Array(n), out = new Float32Array(n);
  if (stride === NEIGHBOURS) {
    const { channels } = rows!;
    const planes = [0, 0, 0];
    for (let pair = 0; pair < n / channels; ++pair) {
      for (let j = 0; j < channels; ++j)
        planes[j] = v.get(channels === 3 && j > 0 ? ANGULAR_CHROMA : ANGULAR) + neighbourPrediction(codes, rows!, pair, j);
      const q = pair * channels;
      if (channels === 3) {
        codes[q + 1] = planes[0];
        codes[q] = planes[1] + planes[0];
        codes[q + 2] = planes[2] + planes[0];
      } else {
        codes[q] = planes[0];
      }
    }
  } else if (stride === 0) {
    for (let i = 0; i < n; i += 3) {
      const before = i >= 3;
      codes[i + 1] = v.get(ANGULAR) + (before ? codes[i - 2] : 0);
      for (const ch of [0, 2])
        codes[i + ch] = v.get(ANGULAR_CHROMA) + (before ? codes[i - 3 + ch] - codes[i - 2] : 0) + codes[i + 1];
    }
  } else {
    for (let i = 0; i < n; ++i) codes[i] = v.get(stream) + (i >= stride ? codes[i - stride] : 0);
  }
  for (let i = 0; i < n; ++i) out[i] = asHalf(codes[i] * step);
  return out;
}

function image(v: Reader, width: number, height: number, step: number, dc = DC): Float32Array {
  const bw = Math.ceil(width / 8), bh = Math.ceil(height / 8), blocks = bw * bh;
  const codes = new Float64Array(blocks * 64);
  for (let k = 0; k < 64; ++k) {
    let previous = 0;
    const stream = k === 0 ? dc : dc + 1 + bandGroup(k);
    for (let b = 0; b < blocks; ++b) {
      const d = v.get(stream);
      const value = k === 0 ? d + previous : d;
      codes[b * 64 + k] = value;
      previous = value;
    }
  }
  const out = new Float32Array(width * height), coef = new Float64Array(64), px = new Float64Array(64), tmp = new Float64Array(64);
  for (let by = 0; by < bh; ++by)
    for (let bx = 0; bx < bw; ++bx) {
      const base = (by * bw + bx) * 64;
      for (let k = 0; k < 64; ++k) coef[ZIGZAG[k]] = codes[base + k] * step;
      inverseDct(coef, px, tmp);
      for (let r = 0; r < 8; ++r)
        for (let n = 0; n < 8; ++n) {
          const y = by * 8 + r, x = bx * 8 + n;
          if (y < height && x < width) out[y * width + x] = asHalf(px[r * 8 + n]);
        }
    }
  return out;
}

// DCT_PLANES: a's planes (as for NEIGHBOURS) each an image of views × lights, coded like b's
// images in streams of their own; the outer channels are their offsets plus the middle one.
function angularImages(v: Reader, n: number, step: number, rows: AngularRows): Float32Array {
  const { lights, channels } = rows, pairs = n / channels;
  const planes: Float32Array[] = [];
  for (let j = 0; j < channels; ++j) planes.push(image(v, lights, pairs / lights, step, ANGULAR_DC));
  if (channels !== 3) return planes[0];
  const out = new Float32Array(n);
  for (let p = 0; p < pairs; ++p) {
    const middle = planes[0][p];
    out[3 * p + 1] = middle;
    out[3 * p] = asHalf(planes[1][p] + middle);
    out[3 * p + 2] = asHalf(planes[2][p] + middle);
  }
  return out;
}

/**
 * Decodes a coded component section: `rows` values of a (laid out as `layout`), `texels` values
 * of b, b an image of `width` × `height` texels where given (one cluster), else plain. Throws
 * "section '<name>': …" like the C++ reader for a damaged payload.
 */
export function decodeCodedComponent(
  data: Uint8Array,
  rows: number,
  texels: number,
  texelImage: { width: number; height: number } | null,
  name: string,
  layout?: AngularRows,
): { a: Float32Array; b: Float32Array } {
  const what = `section '${name}'`;
  if (data.length < HEAD) throw new Error(`${what}: ${data.length} bytes, shorter than a coded component's head`);
  const format = data[0];
  if (format !== RANGE_FORMAT && format !== VARINT_FORMAT) throw new Error(`${what}: unknown coded format ${format}`);
  const aStride = data[1], kind = data[2], bStride = data[3];
  const view = new DataView(data.buffer, data.byteOffset, data.byteLength);
  const steps = [view.getFloat32(4, true), view.getFloat32(8, true)];
  const isImage = !!texelImage && texelImage.width > 0 && texelImage.height > 0 && texelImage.width * texelImage.height === texels;
  // Predictions 0 (channels, for rows of 3 channels), NEIGHBOURS and DCT_PLANES (for the rows'
  // layout) are format 2's.
  if (aStride === DCT_PLANES) {
    if (format === VARINT_FORMAT) throw new Error(`${what}: a as images of directions in format 1`);
    if (!neighboursFit(layout, rows)) throw new Error(`${what}: a as images of directions, but the factor's rows are not laid out by directions`);
  } else if (aStride === NEIGHBOURS) {
    if (format === VARINT_FORMAT) throw new Error(`${what}: prediction by neighbouring directions in format 1`);
    if (!neighboursFit(layout, rows)) throw new Error(`${what}: prediction by neighbouring directions, but the factor's rows are not laid out by directions`);
  } else if (aStride > MAX_STRIDE || (aStride === 0 && (format === VARINT_FORMAT || rows % 3 !== 0))) {
    throw new Error(`${what}: prediction distance ${aStride}`);
  }
  if (kind !== PLAIN && kind !== DCT_IMAGE) throw new Error(`${what}: unknown texel coding ${kind}`);
  if (kind === DCT_IMAGE && !isImage) throw new Error(`${what}: DCT-coded texels, but the block's texels are not an image`);
  if (kind === PLAIN && (bStride < 1 || bStride > MAX_STRIDE)) throw new Error(`${what}: prediction distance ${bStride}`);
  for (const s of steps) if (!(s > 0) || !Number.isFinite(s)) throw new Error(`${what}: quantization step ${s}`);
  let reader: Reader, left: () => number;
  if (format === VARINT_FORMAT) {
    const v = new Varints(data, HEAD, what);
    reader = { get: () => v.next() };
    left = () => data.length - v.at;
  } else {
    const coder = new RangeDecoder(data, HEAD, what), model = new IntegerModel(STREAMS);
    reader = { get: (stream) => model.get(coder, stream) };
    left = () => coder.remaining;
  }
  const a = aStride === DCT_PLANES ? angularImages(reader, rows, steps[0], layout!) : plain(reader, rows, steps[0], aStride, ANGULAR, layout);
  const b = kind === DCT_IMAGE ? image(reader, texelImage!.width, texelImage!.height, steps[1]) : plain(reader, texels, steps[1], bStride, TEXELS);
  if (left() !== 0) throw new Error(`${what}: ${left()} bytes after the coded factors`);
  return { a, b };
}
