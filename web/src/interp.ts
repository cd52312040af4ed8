// SPDX-License-Identifier: MIT
// The AngularInterpolator tables of a package's "tables" section and the lookup they serve
// (docs/interpolation.md). The fragment shader performs this lookup on the GPU; this CPU copy
// serves the environment pre-integration, the reference evaluator the tests compare pixels with,
// and the checks of the tables before they reach the GPU.

export interface InterpTables {
  /** R: the grid has R × R cells over the square. */
  R: number;
  /** N: the set's directions; vertices at and above index N are auxiliary (below the horizon). */
  N: number;
  /** V: all vertices. */
  V: number;
  /** All directions lie on the horizon: queries are lifted to θ = 45° first. */
  lifted: boolean;
  /** T: triangles. */
  T: number;
  /** M: entries of cellTriangles. */
  M: number;
  vertices: Float32Array; // 3V
  triangles: Int32Array; // 3T
  inverse: Float32Array; // 9T, rows of [v0 v1 v2]⁻¹
  cellOffsets: Int32Array; // R² + 1
  cellTriangles: Int32Array; // M
}

export interface Weights {
  /** Direction indices; entries with weight 0 may hold anything. */
  index: [number, number, number];
  weight: [number, number, number];
}

const SIN45 = Math.SQRT1_2;

/** Reads one set's tables starting at byte `at`; returns them and the byte after them. */
export function readTables(data: Uint8Array, at: number, what: string): { tables: InterpTables; next: number } {
  const fail = (m: string): never => {
    throw new Error(`section 'tables' (${what}): ${m}`);
  };
  const view = new DataView(data.buffer, data.byteOffset, data.byteLength);
  if (at + 24 > data.length) fail(`${data.length - at} bytes left where 24 header bytes are needed`);
  const head = [0, 1, 2, 3, 4, 5].map((i) => view.getInt32(at + 4 * i, true));
  const [R, N, V, liftedFlag, T, M] = head;
  if (!(R >= 1 && R <= 1024) || N < 1 || V < N || T < 1 || M < 1 || (liftedFlag !== 0 && liftedFlag !== 1))
    fail(`bad header ${head.join(", ")}`);
  let p = at + 24;
  const need = 4 * (3 * V + 3 * T + 9 * T + R * R + 1 + M);
  if (p + need > data.length) fail(`${data.length - p} bytes left where ${need} are needed`);
  const floats = (n: number) => {
    const out = new Float32Array(n);
    for (let i = 0; i < n; ++i, p += 4) out[i] = view.getFloat32(p, true);
    return out;
  };
  const ints = (n: number) => {
    const out = new Int32Array(n);
    for (let i = 0; i < n; ++i, p += 4) out[i] = view.getInt32(p, true);
    return out;
  };
  const vertices = floats(3 * V);
  const triangles = ints(3 * T);
  const inverse = floats(9 * T);
  const cellOffsets = ints(R * R + 1);
  const cellTriangles = ints(M);
  for (let i = 0; i < 3 * T; ++i) if (triangles[i] < 0 || triangles[i] >= V) fail(`triangle ${Math.floor(i / 3)} names vertex ${triangles[i]} of ${V}`);
  if (cellOffsets[0] !== 0 || cellOffsets[R * R] !== M) fail("cell offsets do not span the cell triangles");
  for (let k = 0; k < R * R; ++k)
    if (cellOffsets[k + 1] <= cellOffsets[k]) fail(`cell ${k} has no candidate triangle`);
  for (let i = 0; i < M; ++i) if (cellTriangles[i] < 0 || cellTriangles[i] >= T) fail(`cell triangle ${i} names triangle ${cellTriangles[i]} of ${T}`);
  for (let i = 0; i < inverse.length; ++i) if (!Number.isFinite(inverse[i])) fail(`inverse matrix ${Math.floor(i / 9)} is not finite`);
  return {
    tables: { R, N, V, lifted: liftedFlag === 1, T, M, vertices, triangles, inverse, cellOffsets, cellTriangles },
    next: p,
  };
}

/** The "tables" section: the views' tables, then the lights'. */
export function readTablesSection(data: Uint8Array, views: number, lights: number): { views: InterpTables; lights: InterpTables } {
  const v = readTables(data, 0, "views");
  const l = readTables(data, v.next, "lights");
  if (l.next !== data.length) throw new Error(`section 'tables' has ${data.length - l.next} bytes after the lights' tables`);
  if (v.tables.N !== views) throw new Error(`section 'tables': the views' tables have ${v.tables.N} directions, the header ${views}`);
  if (l.tables.N !== lights) throw new Error(`section 'tables': the lights' tables have ${l.tables.N} directions, the header ${lights}`);
  return { views: v.tables, lights: l.tables };
}

// atan on [−1, 1], Abramowitz & Stegun 4.4.49: the polynomial the C++ grid lookup uses, so that a
// query lands in the same cell.
export function approximateAtan(t: number): number {
  const t2 = t * t;
  return t * (0.999866 + t2 * (-0.3302995 + t2 * (0.180141 + t2 * (-0.085133 + t2 * 0.0208351))));
}

// The query as the lookup uses it: clamped to the horizon, lifted for horizon-only sets, and +x
// on the horizon when it has no direction.
function prepare(t: InterpTables, x: number, y: number, z: number): [number, number, number] {
  z = z > 0 ? z : 0; // also NaN → 0
  const len2 = x * x + y * y + z * z;
  if (!t.lifted && len2 >= 1e-200 && len2 <= 1e200) return [x, y, z];
  const m = Math.max(Math.abs(x), Math.abs(y), z);
  if (!(m > 0) || !Number.isFinite(m)) return t.lifted ? [SIN45, 0, SIN45] : [1, 0, 0];
  x /= m;
  y /= m;
  z /= m;
  if (t.lifted) {
    const r = Math.sqrt(x * x + y * y);
    if (!(r > 0)) return [SIN45, 0, SIN45];
    return [(x / r) * SIN45, (y / r) * SIN45, SIN45];
  }
  return [x, y, z];
}

/** The grid cell of a prepared query (hemisphere → square, then the cell). */
export function cellOf(t: InterpTables, d: [number, number, number]): number {
  const [x, y, z] = d;
  const xy2 = x * x + y * y;
  const len2 = xy2 + z * z;
  const r = Math.sqrt(xy2 / (len2 + Math.sqrt(len2) * z));
  const xMajor = Math.abs(x) >= Math.abs(y);
  const major = xMajor ? x : y;
  const minor = xMajor ? y : x;
  const ratio = minor / (major !== 0 ? major : 1);
  const along = major < 0 || Object.is(major, -0) ? -r : r;
  const across = along * (4 / Math.PI) * approximateAtan(ratio);
  const a = xMajor ? along : across;
  const b = xMajor ? across : along;
  const n = t.R;
  const half = 0.5 * n;
  const col = Math.min(Math.trunc((a + 1) * half), n - 1);
  const row = Math.min(Math.trunc((b + 1) * half), n - 1);
  return row * n + col;
}

function finish(t: InterpTables, tri: number, l0: number, l1: number, l2: number): Weights {
  const v0 = t.triangles[3 * tri], v1 = t.triangles[3 * tri + 1], v2 = t.triangles[3 * tri + 2];
  const w0 = Math.max(l0, 0) * (v0 < t.N ? 1 : 0);
  const w1 = Math.max(l1, 0) * (v1 < t.N ? 1 : 0);
  const w2 = Math.max(l2, 0) * (v2 < t.N ? 1 : 0);
  const sum = w0 + w1 + w2;
  // Auxiliary vertices carry weight 0; their index is replaced by the first (always real) one.
  const index: [number, number, number] = [v0, v1 < t.N ? v1 : v0, v2 < t.N ? v2 : v0];
  if (!(sum > 0)) return { index, weight: [1, 0, 0] };
  // float weights, as AngularWeights stores them
  return { index, weight: [Math.fround(w0 / sum), Math.fround(w1 / sum), Math.fround(w2 / sum)] };
}

/**
 * The barycentric weights of the direction (x, y, z) (local frame, any length), exactly as
 * AngularInterpolator::weights: the grid's candidates first, every triangle as the fallback.
 */
export function lookup(t: InterpTables, x: number, y: number, z: number, inside = 1e-10): Weights {
  const d = prepare(t, x, y, z);
  const cell = cellOf(t, d);
  const m = t.inverse;
  for (let k = t.cellOffsets[cell]; k < t.cellOffsets[cell + 1]; ++k) {
    const tri = t.cellTriangles[k];
    const o = 9 * tri;
    const l0 = m[o] * d[0] + m[o + 1] * d[1] + m[o + 2] * d[2];
    const l1 = m[o + 3] * d[0] + m[o + 4] * d[1] + m[o + 5] * d[2];
    const l2 = m[o + 6] * d[0] + m[o + 7] * d[1] + m[o + 8] * d[2];
    if (Math.min(l0, l1, l2) >= -inside * (l0 + l1 + l2)) return finish(t, tri, l0, l1, l2);
  }
  return lookupBruteForce(t, d);
}

function lookupBruteForce(t: InterpTables, d: [number, number, number]): Weights {
  let best = -1, bestScore = -Infinity;
  let b0 = 0, b1 = 0, b2 = 0;
  const m = t.inverse;
  for (let tri = 0; tri < t.T; ++tri) {
    if (t.triangles[3 * tri] >= t.N) continue; // auxiliary only (real vertices come first)
    const o = 9 * tri;
    const l0 = m[o] * d[0] + m[o + 1] * d[1] + m[o + 2] * d[2];
    const l1 = m[o + 3] * d[0] + m[o + 4] * d[1] + m[o + 5] * d[2];
    const l2 = m[o + 6] * d[0] + m[o + 7] * d[1] + m[o + 8] * d[2];
    const sum = l0 + l1 + l2;
    if (!(sum > 0)) continue;
    const score = Math.min(l0, l1, l2) / sum;
    if (score > bestScore) {
      bestScore = score;
      best = tri;
      b0 = l0;
      b1 = l1;
      b2 = l2;
    }
  }
  if (best < 0) return { index: [0, 0, 0], weight: [1, 0, 0] };
  return finish(t, best, b0, b1, b2);
}

/** The square [0,1]² → upper hemisphere map (Shirley–Chiu concentric, then Lambert). */
export function squareToHemisphere(u: number, v: number): [number, number, number] {
  const a = 2 * u - 1, b = 2 * v - 1;
  let r: number, phi: number;
  if (a === 0 && b === 0) return [0, 0, 1];
  if (Math.abs(a) > Math.abs(b)) {
    r = a;
    phi = (Math.PI / 4) * (b / a);
  } else {
    r = b;
    phi = Math.PI / 2 - (Math.PI / 4) * (a / b);
  }
  const dx = r * Math.cos(phi), dy = r * Math.sin(phi);
  const r2 = dx * dx + dy * dy;
  const s = Math.sqrt(Math.max(2 - r2, 0));
  return [dx * s, dy * s, 1 - r2];
}

/**
 * Light weights of a uniform environment: c_l = (1/π) ∫ w_l(ωi) dωi over the upper hemisphere,
 * so that the radiance reflected under uniform incident radiance L is L · Σ_l c_l f(·, l, ·)
 * (a BTF value is π f_r cos θi). Integrated over an n × n grid of the area-preserving square
 * (each cell 2π / n² sr), sampled at cell centres.
 */
export function uniformEnvironmentWeights(t: InterpTables, n = 128): Float64Array {
  const c = new Float64Array(t.N);
  const cell = 2 / (n * n); // (1/π) · 2π / n²
  for (let j = 0; j < n; ++j)
    for (let i = 0; i < n; ++i) {
      const d = squareToHemisphere((i + 0.5) / n, (j + 0.5) / n);
      const w = lookup(t, d[0], d[1], d[2]);
      for (let k = 0; k < 3; ++k) if (w.weight[k] > 0) c[w.index[k]] += w.weight[k] * cell;
    }
  return c;
}
