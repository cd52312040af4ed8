// Coded factor storage (model.quantization "coded"; docs/formats.md, "Factorization sections";
// src/btf/codecs/factor/coded.cpp): one component section holds a's codes, differences at a
// prediction distance, and b's, either alike or as 8 × 8 DCT blocks of the periodically extended
// texel image written band by band. Decoded as the C++ reader decodes: the inverse DCT in double
// in the same order, every value rounded to the nearest half float.

import { inverseDct, Varints, ZIGZAG } from "./dct8";
import { floatToHalf, halfToFloat } from "./half";

const FORMAT = 1, PLAIN = 0, DCT_IMAGE = 1, HEAD = 12, MAX_STRIDE = 64;

const asHalf = (v: number): number => halfToFloat(floatToHalf(Math.fround(v)));

function plain(v: Varints, n: number, step: number, stride: number): Float32Array {
  const codes = new Float64Array(n), out = new Float32Array(n);
  for (let i = 0; i < n; ++i) {
    codes[i] = v.next() + (i >= stride ? codes[i - stride] : 0);
    out[i] = asHalf(codes[i] * step);
  }
  return out;
}

function image(v: Varints, width: number, height: number, step: number): Float32Array {
  const bw = Math.ceil(width / 8), bh = Math.ceil(height / 8), blocks = bw * bh;
  const codes = new Float64Array(blocks * 64);
  for (let k = 0; k < 64; ++k) {
    let previous = 0;
    for (let b = 0; b < blocks; ++b) {
      const d = v.next();
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

/**
 * Decodes a coded component section: `rows` values of a, `texels` values of b, b an image of
 * `width` × `height` texels where given (one cluster), else plain. Throws "section '<name>': …"
 * like the C++ reader for a damaged payload.
 */
export function decodeCodedComponent(
  data: Uint8Array,
  rows: number,
  texels: number,
  texelImage: { width: number; height: number } | null,
  name: string,
): { a: Float32Array; b: Float32Array } {
  const what = `section '${name}'`;
  if (data.length < HEAD) throw new Error(`${what}: ${data.length} bytes, shorter than a coded component's head`);
  if (data[0] !== FORMAT) throw new Error(`${what}: unknown coded format ${data[0]}`);
  const aStride = data[1], kind = data[2], bStride = data[3];
  const view = new DataView(data.buffer, data.byteOffset, data.byteLength);
  const steps = [view.getFloat32(4, true), view.getFloat32(8, true)];
  const isImage = !!texelImage && texelImage.width > 0 && texelImage.height > 0 && texelImage.width * texelImage.height === texels;
  if (aStride < 1 || aStride > MAX_STRIDE) throw new Error(`${what}: prediction distance ${aStride}`);
  if (kind !== PLAIN && kind !== DCT_IMAGE) throw new Error(`${what}: unknown texel coding ${kind}`);
  if (kind === DCT_IMAGE && !isImage) throw new Error(`${what}: DCT-coded texels, but the block's texels are not an image`);
  if (kind === PLAIN && (bStride < 1 || bStride > MAX_STRIDE)) throw new Error(`${what}: prediction distance ${bStride}`);
  for (const s of steps) if (!(s > 0) || !Number.isFinite(s)) throw new Error(`${what}: quantization step ${s}`);
  const v = new Varints(data, HEAD, what);
  const a = plain(v, rows, steps[0], aStride);
  const b = kind === DCT_IMAGE ? image(v, texelImage!.width, texelImage!.height, steps[1]) : plain(v, texels, steps[1], bStride);
  if (v.at !== data.length) throw new Error(`${what}: ${data.length - v.at} bytes after the coded factors`);
  return { a, b };
}
