// XXH64 (seed 0 by default), the checksum of btfkit packages (docs/formats.md).
//
// JavaScript has no fast 64-bit integers (BigInt allocates per operation), so every 64-bit value
// is a pair of uint32 halves held in plain numbers. Functions return the low half and leave the
// high half in the module variable `H`, which keeps the hot loop free of allocations.

const P1H = 0x9e3779b1, P1L = 0x85ebca87;
const P2H = 0xc2b2ae3d, P2L = 0x27d4eb4f;
const P3H = 0x165667b1, P3L = 0x9e3779f9;
const P4H = 0x85ebca77, P4L = 0xc2b2ae63;
const P5H = 0x27d4eb2f, P5L = 0x165667c5;

let H = 0; // high half of the last result

// (ah:al) · (bh:bl) mod 2^64.
function mul(ah: number, al: number, bh: number, bl: number): number {
  // al · bl needs all 64 bits: split both into 16-bit halves so every partial product is exact.
  const a1 = al >>> 16, a0 = al & 0xffff, b1 = bl >>> 16, b0 = bl & 0xffff;
  const mid = a1 * b0 + a0 * b1; // < 2^33
  const low = a0 * b0 + (mid % 65536) * 65536; // < 2^33
  const lo = low >>> 0;
  const carry = Math.floor(low / 4294967296);
  H = (a1 * b1 + Math.floor(mid / 65536) + carry + Math.imul(ah, bl) + Math.imul(al, bh)) >>> 0;
  return lo;
}

function add(ah: number, al: number, bh: number, bl: number): number {
  const lo = al + bl;
  H = (ah + bh + (lo > 0xffffffff ? 1 : 0)) >>> 0;
  return lo >>> 0;
}

// Rotate left by r, 0 < r < 32 (every rotation XXH64 uses).
function rotl(h: number, l: number, r: number): number {
  const lo = ((l << r) | (h >>> (32 - r))) >>> 0;
  H = ((h << r) | (l >>> (32 - r))) >>> 0;
  return lo;
}

// acc + lane · P2, rotated by 31, times P1.
function round(ah: number, al: number, lh: number, ll: number): number {
  let l = mul(lh, ll, P2H, P2L);
  let h = H;
  l = add(ah, al, h, l);
  h = H;
  l = rotl(h, l, 31);
  h = H;
  return mul(h, l, P1H, P1L);
}

function merge(ah: number, al: number, vh: number, vl: number): number {
  let l = round(0, 0, vh, vl);
  let h = H;
  l = (al ^ l) >>> 0;
  h = (ah ^ h) >>> 0;
  l = mul(h, l, P1H, P1L);
  h = H;
  return add(h, l, P4H, P4L);
}

/** XXH64 of `data` as 16 lowercase hex digits (the form package headers store). */
export function xxh64(data: Uint8Array, seed = 0): string {
  const n = data.length;
  const view = new DataView(data.buffer, data.byteOffset, data.byteLength);
  let p = 0;
  let h: number, l: number;
  // The seed is a uint64 whose high half is 0 for the seeds btfkit uses (< 2^32).
  const sh = 0, sl = seed >>> 0;
  if (n >= 32) {
    let v1l = add(sh, sl, P1H, P1L), v1h = H;
    v1l = add(v1h, v1l, P2H, P2L); v1h = H;
    let v2l = add(sh, sl, P2H, P2L), v2h = H;
    let v3l = sl, v3h = sh;
    // seed − P1 = seed + (2^64 − P1) = seed + (~P1 + 1); P1's low half is nonzero, so the + 1
    // does not carry into the high half.
    let v4l = add(sh, sl, (~P1H) >>> 0, ((~P1L) + 1) >>> 0), v4h = H;
    const limit = n - 32;
    while (p <= limit) {
      v1l = round(v1h, v1l, view.getUint32(p + 4, true), view.getUint32(p, true)); v1h = H;
      v2l = round(v2h, v2l, view.getUint32(p + 12, true), view.getUint32(p + 8, true)); v2h = H;
      v3l = round(v3h, v3l, view.getUint32(p + 20, true), view.getUint32(p + 16, true)); v3h = H;
      v4l = round(v4h, v4l, view.getUint32(p + 28, true), view.getUint32(p + 24, true)); v4h = H;
      p += 32;
    }
    l = rotl(v1h, v1l, 1); h = H;
    let tl = rotl(v2h, v2l, 7), th = H;
    l = add(h, l, th, tl); h = H;
    tl = rotl(v3h, v3l, 12); th = H;
    l = add(h, l, th, tl); h = H;
    tl = rotl(v4h, v4l, 18); th = H;
    l = add(h, l, th, tl); h = H;
    l = merge(h, l, v1h, v1l); h = H;
    l = merge(h, l, v2h, v2l); h = H;
    l = merge(h, l, v3h, v3l); h = H;
    l = merge(h, l, v4h, v4l); h = H;
  } else {
    l = add(sh, sl, P5H, P5L); h = H;
  }
  // + length (packages stay far below 2^53 bytes)
  l = add(h, l, Math.floor(n / 4294967296) >>> 0, n >>> 0); h = H;
  while (p + 8 <= n) {
    const kl = round(0, 0, view.getUint32(p + 4, true), view.getUint32(p, true)), kh = H;
    l = (l ^ kl) >>> 0; h = (h ^ kh) >>> 0;
    l = rotl(h, l, 27); h = H;
    l = mul(h, l, P1H, P1L); h = H;
    l = add(h, l, P4H, P4L); h = H;
    p += 8;
  }
  if (p + 4 <= n) {
    const kl = mul(0, view.getUint32(p, true), P1H, P1L), kh = H;
    l = (l ^ kl) >>> 0; h = (h ^ kh) >>> 0;
    l = rotl(h, l, 23); h = H;
    l = mul(h, l, P2H, P2L); h = H;
    l = add(h, l, P3H, P3L); h = H;
    p += 4;
  }
  while (p < n) {
    const kl = mul(0, data[p], P5H, P5L), kh = H;
    l = (l ^ kl) >>> 0; h = (h ^ kh) >>> 0;
    l = rotl(h, l, 11); h = H;
    l = mul(h, l, P1H, P1L); h = H;
    p += 1;
  }
  // Avalanche: x ^= x >> 33; x *= P2; x ^= x >> 29; x *= P3; x ^= x >> 32.
  l = (l ^ (h >>> 1)) >>> 0;
  l = mul(h, l, P2H, P2L); h = H;
  l = (l ^ ((l >>> 29) | (h << 3))) >>> 0; h = (h ^ (h >>> 29)) >>> 0;
  l = mul(h, l, P3H, P3L); h = H;
  l = (l ^ h) >>> 0;
  return h.toString(16).padStart(8, "0") + l.toString(16).padStart(8, "0");
}
