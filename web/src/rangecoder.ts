// SPDX-License-Identifier: MIT
// The adaptive binary range decoder and the integer model of btfkit's coded factor storage
// (src/btf/util/range_coder.h, whose comment defines both): 32-bit range, 11-bit probabilities
// adapted by 1/32, equiprobable direct bits; integers as a zero flag, a direct sign, the
// Exp-Golomb class in unary and the class's low bits, the flag and unary bits chosen by the
// previous magnitude in the same context. Integer arithmetic throughout, as the C++ decoder's.

const PROBABILITY_BITS = 11, ONE = 1 << PROBABILITY_BITS, ADAPT_SHIFT = 5, TOP = 1 << 24;
const HALF = 1024, CLASS_PROBABILITIES = 24;

export class RangeDecoder {
  private range = 0xffffffff;
  private code = 0;
  constructor(
    private readonly data: Uint8Array,
    private at: number,
    readonly what: string,
  ) {
    for (let i = 0; i < 5; ++i) this.code = ((this.code << 8) | this.next()) >>> 0;
  }
  private next(): number {
    if (this.at >= this.data.length) throw new Error(`${this.what}: the coded factors end early`);
    return this.data[this.at++];
  }
  private normalize(): void {
    while (this.range < TOP) {
      this.range = (this.range << 8) >>> 0;
      this.code = ((this.code << 8) | this.next()) >>> 0;
    }
  }
  /** One bit under probs[i] (the probability of a 0, out of 2048), which it updates. */
  bit(probs: Uint16Array, i: number): number {
    const p = probs[i];
    const bound = (this.range >>> PROBABILITY_BITS) * p;
    let bit: number;
    if (this.code < bound) {
      this.range = bound;
      probs[i] = p + ((ONE - p) >> ADAPT_SHIFT);
      bit = 0;
    } else {
      this.code -= bound;
      this.range -= bound;
      probs[i] = p - (p >> ADAPT_SHIFT);
      bit = 1;
    }
    this.normalize();
    return bit;
  }
  /** `bits` equiprobable bits, most significant first (exact up to 53 bits). */
  direct(bits: number): number {
    let v = 0;
    for (let i = 0; i < bits; ++i) {
      this.range = this.range >>> 1;
      let bit = 0;
      if (this.code >= this.range) {
        this.code -= this.range;
        bit = 1;
      }
      v = v * 2 + bit;
      this.normalize();
    }
    return v;
  }
  /** Bytes not read: 0 after everything a matching encoder wrote. */
  get remaining(): number {
    return this.data.length - this.at;
  }
}

/** Signed integers in `contexts` contexts (range_coder.h's IntegerModel). */
export class IntegerModel {
  // Per context and neighbourhood set (previous magnitude 0, 1–2, more): the zero flag's
  // probability, then the unary class bits'.
  private readonly probs: Uint16Array;
  private readonly last: Uint8Array;
  constructor(contexts: number) {
    this.probs = new Uint16Array(contexts * 3 * (1 + CLASS_PROBABILITIES)).fill(HALF);
    this.last = new Uint8Array(contexts);
  }
  get(coder: RangeDecoder, context: number): number {
    const previous = this.last[context];
    const set = (context * 3 + (previous === 0 ? 0 : previous <= 2 ? 1 : 2)) * (1 + CLASS_PROBABILITIES);
    let m = 0, v = 0;
    if (coder.bit(this.probs, set) !== 0) {
      const negative = coder.direct(1) !== 0;
      let k = 0;
      while (coder.bit(this.probs, set + 1 + Math.min(k, CLASS_PROBABILITIES - 1)) !== 0)
        if (++k > 62) throw new Error(`${coder.what}: a coded value is longer than 64 bits`);
      m = 2 ** k + coder.direct(k);
      v = negative ? -m : m;
    }
    this.last[context] = Math.min(m, 3);
    return v;
  }
}
