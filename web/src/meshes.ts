// SPDX-License-Identifier: MIT
// The renderer's generated shapes (src/btf/render/mesh.cpp) rebuilt vertex for vertex: the same
// positions, normals, tangents (dP/du), uvs, triangles and winding, and the same object
// transform (scene_file.cpp: translate · Rz · Ry · Rx · scale), so that a browser frame and a
// C++ render of the same scene see the same surface parametrization.
//
// Conventions (mesh.h): world right-handed, +y up; winding counter-clockwise seen from outside;
// BTF frame z = normal, x = tangent (increasing u), y = normal × tangent (increasing v).
// - plane: in the xz-plane facing +y, u along +x, v along −z;
// - sphere, cylinder, torus: u = longitude φ around +y from +x towards −z;
//   sphere v from the south (v = 0) to the north pole; cylinder v from bottom to top;
//   torus v around the tube from the inner equator, down over the bottom, outer equator (0.5).

export interface Mesh {
  positions: Float32Array;
  normals: Float32Array;
  tangents: Float32Array;
  uvs: Float32Array;
  indices: Uint32Array;
}

type V3 = [number, number, number];

class Builder {
  positions: number[] = [];
  normals: number[] = [];
  tangents: number[] = [];
  uvs: number[] = [];
  indices: number[] = [];
  get count(): number {
    return this.positions.length / 3;
  }
  vertex(p: V3, n: V3, t: V3, u: number, v: number): number {
    const i = this.count;
    this.positions.push(...p);
    this.normals.push(...n);
    this.tangents.push(...t);
    this.uvs.push(u, v);
    return i;
  }
  triangle(a: number, b: number, c: number): void {
    this.indices.push(a, b, c);
  }
  // Float32 storage, as TriangleMesh holds its buffers.
  finish(): Mesh {
    return {
      positions: new Float32Array(this.positions),
      normals: new Float32Array(this.normals),
      tangents: new Float32Array(this.tangents),
      uvs: new Float32Array(this.uvs),
      indices: new Uint32Array(this.indices),
    };
  }
}

function longitude(column: number, segments: number): number {
  return (2 * Math.PI * (column % segments)) / segments;
}
function radial(phi: number): V3 {
  return [Math.cos(phi), 0, -Math.sin(phi)];
}
function longitudeTangent(phi: number): V3 {
  return [-Math.sin(phi), 0, -Math.cos(phi)];
}

export function makePlane(width: number, depth: number): Mesh {
  const x = width / 2, z = depth / 2;
  const up: V3 = [0, 1, 0], tangent: V3 = [1, 0, 0];
  const m = new Builder();
  const a = m.vertex([-x, 0, z], up, tangent, 0, 0);
  const b = m.vertex([x, 0, z], up, tangent, 1, 0);
  const c = m.vertex([x, 0, -z], up, tangent, 1, 1);
  const d = m.vertex([-x, 0, -z], up, tangent, 0, 1);
  m.triangle(a, b, c);
  m.triangle(a, c, d);
  return m.finish();
}

export function makeSphere(radius: number, segments: number): Mesh {
  const rings = Math.floor(segments / 2);
  const m = new Builder();
  const unitPoint = (v: number, phi: number): V3 => {
    const r = radial(phi), s = Math.sin(Math.PI * v);
    return [r[0] * s, -Math.cos(Math.PI * v), r[2] * s];
  };
  // One pole vertex per segment at the segment's middle longitude (a shared pole has no dP/du).
  const poleRow = (v: number, y: number): number => {
    const first = m.count;
    for (let i = 0; i < segments; ++i) {
      const u = (i + 0.5) / segments;
      m.vertex([0, y * radius, 0], [0, y, 0], longitudeTangent(2 * Math.PI * u), u, v);
    }
    return first;
  };
  const south = poleRow(0, -1);
  const firstRing = m.count;
  for (let j = 1; j < rings; ++j) {
    const v = j / rings;
    for (let i = 0; i <= segments; ++i) {
      const phi = longitude(i, segments);
      const n = unitPoint(v, phi);
      m.vertex([n[0] * radius, n[1] * radius, n[2] * radius], n, longitudeTangent(phi), i / segments, v);
    }
  }
  const north = poleRow(1, 1);
  const stride = segments + 1;
  const ring = (j: number, i: number) => firstRing + (j - 1) * stride + i;
  for (let i = 0; i < segments; ++i) m.triangle(south + i, ring(1, i + 1), ring(1, i));
  for (let j = 1; j + 1 < rings; ++j)
    for (let i = 0; i < segments; ++i) {
      m.triangle(ring(j, i), ring(j, i + 1), ring(j + 1, i + 1));
      m.triangle(ring(j, i), ring(j + 1, i + 1), ring(j + 1, i));
    }
  for (let i = 0; i < segments; ++i) m.triangle(ring(rings - 1, i), ring(rings - 1, i + 1), north + i);
  return m.finish();
}

// A (columns + 1) × (rows + 1) vertex grid over uv ∈ [0, 1]², two triangles per cell.
function makeGrid(columns: number, rows: number, vertex: (m: Builder, i: number, j: number, u: number, v: number) => void): Mesh {
  const m = new Builder();
  for (let j = 0; j <= rows; ++j) for (let i = 0; i <= columns; ++i) vertex(m, i, j, i / columns, j / rows);
  const stride = columns + 1;
  const at = (i: number, j: number) => j * stride + i;
  for (let j = 0; j < rows; ++j)
    for (let i = 0; i < columns; ++i) {
      m.triangle(at(i, j), at(i + 1, j), at(i + 1, j + 1));
      m.triangle(at(i, j), at(i + 1, j + 1), at(i, j + 1));
    }
  return m.finish();
}

// std::round: halves away from zero (Math.round rounds them up).
function roundHalfAway(x: number): number {
  return Math.sign(x) * Math.round(Math.abs(x));
}

export function makeCylinder(radius: number, height: number, segments: number): Mesh {
  const wanted = (height * segments) / (2 * Math.PI * radius);
  const rows = Math.min(Math.max(roundHalfAway(wanted), 1), 8 * segments);
  return makeGrid(segments, rows, (m, i, _j, u, v) => {
    const phi = longitude(i, segments);
    const n = radial(phi);
    m.vertex([n[0] * radius, (v - 0.5) * height, n[2] * radius], n, longitudeTangent(phi), u, v);
  });
}

export function makeTorus(major: number, minor: number, majorSegments: number, minorSegments: number): Mesh {
  return makeGrid(majorSegments, minorSegments, (m, i, j, u, v) => {
    const phi = longitude(i, majorSegments);
    // ψ = π + 2π v: the v seam on the inner equator, turning down from there.
    const psi = Math.PI + longitude(j, minorSegments);
    const out = radial(phi);
    const n: V3 = [out[0] * Math.cos(psi), Math.sin(psi), out[2] * Math.cos(psi)];
    m.vertex(
      [out[0] * major + n[0] * minor, n[1] * minor, out[2] * major + n[2] * minor],
      n,
      longitudeTangent(phi),
      u,
      v,
    );
  });
}

// ---- transforms (mesh.cpp Transform) -------------------------------------------------------

/** Upper 3 × 4 of an affine matrix, row-major (m[row][3] = translation). */
export type Affine = number[][];

export function identity(): Affine {
  return [
    [1, 0, 0, 0],
    [0, 1, 0, 0],
    [0, 0, 1, 0],
  ];
}
export function translate(o: V3): Affine {
  const t = identity();
  t[0][3] = o[0];
  t[1][3] = o[1];
  t[2][3] = o[2];
  return t;
}
export function scale(f: V3): Affine {
  const t = identity();
  t[0][0] = f[0];
  t[1][1] = f[1];
  t[2][2] = f[2];
  return t;
}
/** Counter-clockwise by `degrees` about `axis` (right-hand rule). */
export function rotate(axis: V3, degrees: number): Affine {
  const len = Math.hypot(...axis);
  const a = axis.map((x) => x / len);
  const r = (degrees * Math.PI) / 180;
  const c = Math.cos(r), s = Math.sin(r), k = 1 - c;
  return [
    [c + a[0] * a[0] * k, a[0] * a[1] * k - a[2] * s, a[0] * a[2] * k + a[1] * s, 0],
    [a[1] * a[0] * k + a[2] * s, c + a[1] * a[1] * k, a[1] * a[2] * k - a[0] * s, 0],
    [a[2] * a[0] * k - a[1] * s, a[2] * a[1] * k + a[0] * s, c + a[2] * a[2] * k, 0],
  ];
}
/** a · b: b first, then a. */
export function compose(a: Affine, b: Affine): Affine {
  const r = identity();
  for (let i = 0; i < 3; ++i)
    for (let j = 0; j < 4; ++j) {
      let sum = j === 3 ? a[i][3] : 0;
      for (let k = 0; k < 3; ++k) sum += a[i][k] * b[k][j];
      r[i][j] = sum;
    }
  return r;
}

/** The object transform of a scene file: translate(position) · Rz · Ry · Rx · scale. */
export function objectTransform(position: V3, rotationDeg: V3, scaleXYZ: V3): Affine {
  let t = translate(position);
  t = compose(t, rotate([0, 0, 1], rotationDeg[2]));
  t = compose(t, rotate([0, 1, 0], rotationDeg[1]));
  t = compose(t, rotate([1, 0, 0], rotationDeg[0]));
  return compose(t, scale(scaleXYZ));
}

function cross(a: V3, b: V3): V3 {
  return [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]];
}
function dot(a: V3, b: V3): number {
  return a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
}
function normalize(a: V3): V3 {
  const l = Math.hypot(a[0], a[1], a[2]);
  return [a[0] / l, a[1] / l, a[2] / l];
}

function anyOrthogonal(n: V3): V3 {
  const axis: V3 = Math.abs(n[0]) < 0.9 ? [1, 0, 0] : [0, 1, 0];
  const d = dot(n, axis);
  return normalize([axis[0] - n[0] * d, axis[1] - n[1] * d, axis[2] - n[2] * d]);
}

function orthogonalTangent(t: V3, n: V3): V3 {
  const d = dot(n, t);
  const p: V3 = [t[0] - n[0] * d, t[1] - n[1] * d, t[2] - n[2] * d];
  const len = Math.hypot(...p);
  if (!(len > 1e-6 * Math.hypot(...t))) return anyOrthogonal(n);
  return [p[0] / len, p[1] / len, p[2] / len];
}

/** transform(mesh, xf) of mesh.cpp: points, inverse-transpose normals, re-orthogonalized tangents. */
export function transformMesh(mesh: Mesh, m: Affine): Mesh {
  const col = (j: number): V3 => [m[0][j], m[1][j], m[2][j]];
  const a = col(0), b = col(1), c = col(2);
  const det = dot(a, cross(b, c));
  if (!(det !== 0 && Number.isFinite(det))) throw new Error("object transform: the linear part is singular");
  const bc = cross(b, c), ca = cross(c, a), ab = cross(a, b);
  const out: Mesh = {
    positions: new Float32Array(mesh.positions.length),
    normals: new Float32Array(mesh.normals.length),
    tangents: new Float32Array(mesh.tangents.length),
    uvs: mesh.uvs.slice(),
    indices: mesh.indices.slice(),
  };
  const linear = (v: V3): V3 => [
    m[0][0] * v[0] + m[0][1] * v[1] + m[0][2] * v[2],
    m[1][0] * v[0] + m[1][1] * v[1] + m[1][2] * v[2],
    m[2][0] * v[0] + m[2][1] * v[1] + m[2][2] * v[2],
  ];
  const read = (arr: Float32Array, i: number): V3 => [arr[3 * i], arr[3 * i + 1], arr[3 * i + 2]];
  const write = (arr: Float32Array, i: number, v: V3) => {
    arr[3 * i] = v[0];
    arr[3 * i + 1] = v[1];
    arr[3 * i + 2] = v[2];
  };
  const count = mesh.positions.length / 3;
  for (let i = 0; i < count; ++i) {
    const n = read(mesh.normals, i);
    const mapped: V3 = [
      bc[0] * n[0] + ca[0] * n[1] + ab[0] * n[2],
      bc[1] * n[0] + ca[1] * n[1] + ab[1] * n[2],
      bc[2] * n[0] + ca[2] * n[1] + ab[2] * n[2],
    ];
    const normal = normalize(det > 0 ? mapped : [-mapped[0], -mapped[1], -mapped[2]]);
    const p = linear(read(mesh.positions, i));
    write(out.positions, i, [p[0] + m[0][3], p[1] + m[1][3], p[2] + m[2][3]]);
    write(out.normals, i, normal);
    write(out.tangents, i, orthogonalTangent(linear(read(mesh.tangents, i)), normal));
  }
  if (det < 0)
    for (let t = 0; t + 2 < out.indices.length; t += 3) {
      const x = out.indices[t + 1];
      out.indices[t + 1] = out.indices[t + 2];
      out.indices[t + 2] = x;
    }
  return out;
}

export type Shape = "sphere" | "cylinder" | "torus" | "plane";
export const SHAPES: Shape[] = ["sphere", "cylinder", "torus", "plane"];

/** Shape parameters with the scene file's defaults (docs/scenes.md). */
export interface ShapeParams {
  shape: Shape;
  radius?: number;
  height?: number;
  major_radius?: number;
  minor_radius?: number;
  width?: number;
  depth?: number;
  segments?: number;
}

export function makeShape(p: ShapeParams): Mesh {
  const segments = p.segments ?? 128;
  switch (p.shape) {
    case "plane":
      return makePlane(p.width ?? 2, p.depth ?? 2);
    case "sphere":
      if (segments < 4) throw new Error("sphere: needs at least 4 segments");
      return makeSphere(p.radius ?? 1, segments);
    case "cylinder":
      if (segments < 3) throw new Error("cylinder: needs at least 3 segments");
      return makeCylinder(p.radius ?? 1, p.height ?? 2, segments);
    case "torus": {
      const major = p.major_radius ?? 1, minor = p.minor_radius ?? 0.3;
      if (!(minor > 0 && major > minor)) throw new Error("torus: needs 0 < minor_radius < major_radius");
      if (segments < 3) throw new Error("torus: needs at least 3 segments");
      return makeTorus(major, minor, segments, Math.max(3, Math.floor(segments / 2)));
    }
  }
}
