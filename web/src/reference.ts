// SPDX-License-Identifier: MIT
// A CPU reference of the viewer's frame at chosen pixels, computed the way the C++ renderer does
// (src/btf/render/scene.cpp Camera::ray and Scene::intersect, integrator.cpp's next-event
// estimation for delta lights, quality::tone_map): ray through the pixel centre, closest
// triangle, interpolated shading frame, the material's CPU evaluator (the worker's copy of
// FactorMaterial::eval). Tests compare it with the shader's pixels.

import type { Mesh } from "./meshes";
import type { LightSpec, V3 } from "./scene";

export interface RefCamera {
  position: V3;
  target: V3;
  up: V3;
  fov: number;
  width: number;
  height: number;
}

export interface RefObject {
  mesh: Mesh;
  uvScale: [number, number];
  uvRotationDeg: number;
}

/** Where a pixel's ray meets the scene and what the material must be evaluated at. */
export interface RefHit {
  object: number;
  uv: [number, number];
  wo: V3;
  /** Per light: local wi and irradiance, or null when the light does not reach the point. */
  lights: ({ wi: V3; irradiance: V3 } | null)[];
}

const sub = (a: V3, b: V3): V3 => [a[0] - b[0], a[1] - b[1], a[2] - b[2]];
const add = (a: V3, b: V3): V3 => [a[0] + b[0], a[1] + b[1], a[2] + b[2]];
const mul = (a: V3, s: number): V3 => [a[0] * s, a[1] * s, a[2] * s];
const dot = (a: V3, b: V3) => a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
const cross = (a: V3, b: V3): V3 => [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]];
const len = (a: V3) => Math.hypot(a[0], a[1], a[2]);
const norm = (a: V3): V3 => mul(a, 1 / len(a));

/** Camera::ray for image position (x, y) in pixels. */
export function cameraRay(c: RefCamera, x: number, y: number): { origin: V3; dir: V3 } {
  const forward = norm(sub(c.target, c.position));
  const right = norm(cross(forward, c.up));
  const trueUp = cross(right, forward);
  const tanHalf = Math.tan((c.fov * Math.PI) / 360);
  const aspect = c.width / c.height;
  const sx = ((2 * x) / c.width - 1) * tanHalf * aspect;
  const sy = (1 - (2 * y) / c.height) * tanHalf;
  return { origin: c.position, dir: norm(add(add(forward, mul(right, sx)), mul(trueUp, sy))) };
}

function orthonormalS(n: V3): V3 {
  const sign = n[2] >= 0 ? 1 : -1;
  const a = -1 / (sign + n[2]), b = n[0] * n[1] * a;
  return [1 + sign * n[0] * n[0] * a, sign * b, -sign * n[0]];
}

/** The hit at pixel centre (px + 0.5, py + 0.5), or null for the background. */
export function traceHit(camera: RefCamera, objects: RefObject[], lights: LightSpec[], px: number, py: number): RefHit | null {
  const ray = cameraRay(camera, px + 0.5, py + 0.5);
  let best = Infinity, bestObject = -1, bestTri = -1, bu = 0, bv = 0;
  objects.forEach((o, oi) => {
    const P = o.mesh.positions, I = o.mesh.indices;
    for (let t = 0; t < I.length; t += 3) {
      const i0 = I[t], i1 = I[t + 1], i2 = I[t + 2];
      const p0: V3 = [P[3 * i0], P[3 * i0 + 1], P[3 * i0 + 2]];
      const e1 = sub([P[3 * i1], P[3 * i1 + 1], P[3 * i1 + 2]], p0);
      const e2 = sub([P[3 * i2], P[3 * i2 + 1], P[3 * i2 + 2]], p0);
      const pv = cross(ray.dir, e2);
      const det = dot(e1, pv);
      if (Math.abs(det) < 1e-14) continue;
      const inv = 1 / det;
      const tv = sub(ray.origin, p0);
      const u = dot(tv, pv) * inv;
      if (u < 0 || u > 1) continue;
      const qv = cross(tv, e1);
      const v = dot(ray.dir, qv) * inv;
      if (v < 0 || u + v > 1) continue;
      const dist = dot(e2, qv) * inv;
      if (dist > 1e-9 && dist < best) {
        best = dist;
        bestObject = oi;
        bestTri = t;
        bu = u;
        bv = v;
      }
    }
  });
  if (bestObject < 0) return null;
  const o = objects[bestObject];
  const m = o.mesh;
  const tri = [m.indices[bestTri], m.indices[bestTri + 1], m.indices[bestTri + 2]];
  const b = [1 - bu - bv, bu, bv];
  const lerp3 = (arr: Float32Array): V3 => {
    const r: V3 = [0, 0, 0];
    for (let k = 0; k < 3; ++k) for (let c = 0; c < 3; ++c) r[c] += arr[3 * tri[k] + c] * b[k];
    return r;
  };
  const lerpUv = (axis: number) => m.uvs[2 * tri[0] + axis] * b[0] + m.uvs[2 * tri[1] + axis] * b[1] + m.uvs[2 * tri[2] + axis] * b[2];
  const position = add(ray.origin, mul(ray.dir, best));
  const vtx = (k: number): V3 => [m.positions[3 * tri[k]], m.positions[3 * tri[k] + 1], m.positions[3 * tri[k] + 2]];
  const e1 = sub(vtx(1), vtx(0)), e2 = sub(vtx(2), vtx(0));
  let ng = norm(cross(e1, e2));
  let n = lerp3(m.normals);
  n = len(n) > 0 ? norm(n) : ng;
  if (dot(ng, n) < 0) ng = mul(ng, -1);
  let t = lerp3(m.tangents);
  const u = lerpUv(0), v = lerpUv(1);
  if (dot(ng, ray.dir) > 0) {
    n = mul(n, -1);
    ng = mul(ng, -1);
  }
  t = sub(t, mul(n, dot(t, n)));
  if (len(t) < 1e-8) t = orthonormalS(n);
  t = norm(t);
  let bt = cross(n, t);
  const rot = (o.uvRotationDeg * Math.PI) / 180, c = Math.cos(rot), s = Math.sin(rot);
  const su = u * o.uvScale[0], sv = v * o.uvScale[1];
  const uv: [number, number] = [c * su - s * sv, s * su + c * sv];
  if (o.uvRotationDeg !== 0 || o.uvScale[0] !== o.uvScale[1]) {
    const uvOf = (k: number, axis: number) => m.uvs[2 * tri[k] + axis];
    const du1 = uvOf(1, 0) - uvOf(0, 0), dv1 = uvOf(1, 1) - uvOf(0, 1);
    const du2 = uvOf(2, 0) - uvOf(0, 0), dv2 = uvOf(2, 1) - uvOf(0, 1);
    const det = du1 * dv2 - du2 * dv1;
    let lenU = 1, lenV = 1;
    let alongV = bt;
    if (Math.abs(det) > 1e-20) {
      const dpdv = mul(sub(mul(e2, du1), mul(e1, du2)), 1 / det);
      lenU = len(mul(sub(mul(e1, dv2), mul(e2, dv1)), 1 / det));
      lenV = len(dpdv);
      if (dot(dpdv, bt) < 0) alongV = mul(bt, -1);
    }
    t = norm(sub(mul(t, (c * lenU) / o.uvScale[0]), mul(alongV, (s * lenV) / o.uvScale[1])));
    bt = cross(n, t);
  }
  const toLocal = (w: V3): V3 => [dot(w, t), dot(w, bt), dot(w, n)];
  let wo = toLocal(mul(ray.dir, -1));
  if (wo[2] < 1e-4) wo = norm([wo[0], wo[1], 1e-4]);
  const lightHits = lights.map((l) => {
    let wiWorld: V3, irradiance: V3;
    if (l.type === "point") {
      const d = sub(l.vector, position);
      const d2 = dot(d, d);
      wiWorld = mul(d, 1 / Math.sqrt(d2));
      irradiance = mul(l.power, 1 / d2);
    } else {
      wiWorld = norm(l.vector);
      irradiance = l.power;
    }
    if (dot(wiWorld, ng) <= 0) return null;
    const wi = toLocal(wiWorld);
    if (wi[2] <= 0) return null;
    return { wi, irradiance };
  });
  return { object: bestObject, uv, wo, lights: lightHits };
}

/** quality::tone_map of one channel (float arithmetic), then the sRGB transfer. */
export function toneMapChannel(value: number, exposure: number): number {
  const f = Math.fround;
  const x = Math.max(0, f(value * f(2 ** exposure)));
  const y = Math.min(1, Math.max(0, f(f(x * f(f(2.51 * x) + 0.03)) / f(f(x * f(f(2.43 * x) + 0.59)) + 0.14))));
  return y <= 0.0031308 ? 12.92 * y : 1.055 * Math.pow(y, 1 / 2.4) - 0.055;
}
