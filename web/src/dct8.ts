// SPDX-License-Identifier: MIT
// The 8 × 8 DCT of btfkit's transform coders (src/btf/util/dct8.cpp): the orthonormal DCT-II
// basis, the zig-zag order and the inverse transform in double, each sum in the C++ order, and
// the zig-zag-signed LEB128 varints of the coefficients.

const BASIS = (() => {
  const m = new Float64Array(64);
  for (let k = 0; k < 8; ++k) for (let n = 0; n < 8; ++n) m[k * 8 + n] = (k === 0 ? Math.sqrt(1 / 8) : Math.sqrt(2 / 8)) * Math.cos(((2 * n + 1) * k * Math.PI) / 16);
  return m;
})();

export const ZIGZAG = (() => {
  const order: number[] = [];
  for (let s = 0; s < 15; ++s)
    for (let t = 0; t <= s; ++t) {
      const r = s % 2 === 0 ? s - t : t, c = s - r;
      if (r < 8 && c < 8) order.push(r * 8 + c);
    }
  return order;
})();

export function inverseDct(coef: Float64Array, out: Float64Array, tmp: Float64Array): void {
  for (let c = 0; c < 8; ++c)
    for (let n = 0; n < 8; ++n) {
      let s = 0;
      for (let k = 0; k < 8; ++k) s += BASIS[k * 8 + n] * coef[k * 8 + c];
      tmp[n * 8 + c] = s;
    }
  for (let r = 0; r < 8; ++r)
    for (let n = 0; n < 8; ++n) {
      let s = 0;
      for (let k = 0; k < 8; ++k) s += BASIS[k * 8 + n] * tmp[r * 8 + k];
      out[r * 8 + n] = s;
    }
}

/** Reads zig-zag-signed LEB128 varints from `at` (dct8::get_varint); real coefficients stay far below 2⁵³. */
export class Varints {
  constructor(
    private readonly data: Uint8Array,
    public at: number,
    private readonly what: string,
  ) {}
  next(): number {
    let z = 0, scale = 1;
    for (let shift = 0; shift < 64; shift += 7) {
      if (this.at >= this.data.length) throw new Error(`${this.what}: the coefficients end early`);
      const b = this.data[this.at++];
      z += (b & 0x7f) * scale;
      scale *= 128;
      if (!(b & 0x80)) return z % 2 === 0 ? z / 2 : -(z + 1) / 2;
    }
    throw new Error(`${this.what}: a coefficient is longer than 64 bits`);
  }
}
