// SPDX-License-Identifier: MIT
// The scene the viewer shows, from URL parameters or from a scene in the `btf render` JSON format
// (docs/scenes.md, a subset), so that a test or a comparison with the C++ renderer can fix every
// value of a frame. web/README.md lists the parameters.

import { SHAPES, type Shape, type ShapeParams } from "./meshes";
import { MAX_LIGHTS } from "./shader";

export type V3 = [number, number, number];

export interface CameraSpec {
  position: V3;
  look_at: V3;
  up: V3;
  /** Vertical field of view, degrees. */
  fov: number;
  /** Canvas pixels; null: fill the window. */
  width: number | null;
  height: number | null;
}

/** An object: its shape's parameters (meshes.ts) and where it is, with which material. */
export interface ObjectSpec extends ShapeParams {
  /** Material id (api/materials); null: the default material. */
  material: string | null;
  segments: number;
  position: V3;
  rotation: V3;
  scale: V3;
  uv_scale: [number, number];
  uv_rotation: number;
}

export interface LightSpec {
  type: "directional" | "point";
  /** directional: towards the light; point: its position. */
  vector: V3;
  /** directional: irradiance E; point: intensity I (W/sr). */
  power: V3;
}

export interface SceneSpec {
  camera: CameraSpec;
  exposure: number;
  objects: ObjectSpec[];
  lights: LightSpec[];
  /** Uniform environment radiance; [0, 0, 0] = off. */
  environment: V3;
  mip: boolean;
  deterministic: boolean;
  transport: "auto" | "websocket" | "http";
  hud: boolean;
  /** Keep the pixels of every frame that shows more data in the timeline (tests, benchmarks). */
  snapshots: boolean;
  debug: number;
  /** Where the material list is, relative to the page. */
  api: string;
  /** BSVTF materials: the tile cache's side in texels ((cache / tile stride)² tiles, as
   * `btf bsvtf-sim --cache`). */
  cache: number;
}

export const DEBUG_MODES = ["", "uv", "normal", "tangent", "view", "light"];

export class SceneError extends Error {}

function numbers(text: string, what: string, count: number[]): number[] {
  const parts = text.split(",").map((s) => s.trim());
  const values = parts.map(Number);
  if (!count.includes(values.length) || values.some((v) => !Number.isFinite(v)))
    throw new SceneError(`URL parameter '${what}': expected ${count.join(" or ")} comma-separated numbers, got '${text}'`);
  return values;
}
const vec3 = (text: string, what: string): V3 => numbers(text, what, [3]) as V3;
const rgb = (text: string, what: string): V3 => {
  const v = numbers(text, what, [1, 3]);
  return v.length === 1 ? [v[0], v[0], v[0]] : (v as V3);
};

export function defaultObject(shape: Shape = "sphere", material: string | null = null): ObjectSpec {
  return {
    shape,
    material,
    segments: 128,
    position: [0, 0, 0],
    rotation: [0, 0, 0],
    scale: [1, 1, 1],
    uv_scale: [1, 1],
    uv_rotation: 0,
  };
}

export function defaultScene(): SceneSpec {
  return {
    camera: { position: [0, 1, 4], look_at: [0, 0, 0], up: [0, 1, 0], fov: 40, width: null, height: null },
    exposure: 0,
    objects: [defaultObject()],
    // Irradiance π: the reflected radiance f · E / π then equals the BTF value.
    lights: [{ type: "directional", vector: [1, 1.5, 1], power: [Math.PI, Math.PI, Math.PI] }],
    environment: [0, 0, 0],
    mip: true,
    deterministic: false,
    transport: "auto",
    hud: true,
    snapshots: false,
    debug: 0,
    api: "api/materials",
    cache: 2048,
  };
}

function shapeOf(text: string, what: string): Shape {
  if (!SHAPES.includes(text as Shape)) throw new SceneError(`${what}: unknown shape '${text}' (known: ${SHAPES.join(", ")})`);
  return text as Shape;
}

/** The scene of a page URL's query string (see web/README.md). */
export function sceneFromParams(params: URLSearchParams): SceneSpec {
  const s = defaultScene();
  const get = (k: string) => params.get(k);
  const sceneJson = get("scene");
  if (sceneJson !== null) {
    let json: unknown;
    try {
      json = JSON.parse(sceneJson);
    } catch (e) {
      throw new SceneError(`URL parameter 'scene' is not valid JSON: ${(e as Error).message}`);
    }
    applySceneJson(s, json);
  }
  const material = get("material");
  const segments = get("segments");
  const shape = get("object");
  if (get("objects") !== null) {
    s.objects = get("objects")!
      .split(";")
      .filter((x) => x.trim() !== "")
      .map((entry) => {
        // shape[:material][@x,y,z]
        const [head, at] = entry.split("@");
        const [shapeText, mat] = head.split(":");
        const o = defaultObject(shapeOf(shapeText.trim(), "URL parameter 'objects'"), mat ? mat.trim() : null);
        if (at !== undefined) o.position = vec3(at, "objects");
        return o;
      });
    if (s.objects.length === 0) throw new SceneError("URL parameter 'objects' names no object");
  } else if (shape !== null) {
    s.objects = [defaultObject(shapeOf(shape, "URL parameter 'object'"))];
  }
  for (const o of s.objects) {
    if (material !== null && o.material === null) o.material = material;
    if (segments !== null) o.segments = numbers(segments, "segments", [1])[0];
    if (get("uvscale") !== null) {
      const v = numbers(get("uvscale")!, "uvscale", [1, 2]);
      o.uv_scale = v.length === 1 ? [v[0], v[0]] : [v[0], v[1]];
    }
    if (get("uvrot") !== null) o.uv_rotation = numbers(get("uvrot")!, "uvrot", [1])[0];
  }
  const cam = get("camera") ?? get("cam");
  if (cam !== null) s.camera.position = vec3(cam, "camera");
  if (get("target") !== null) s.camera.look_at = vec3(get("target")!, "target");
  if (get("up") !== null) s.camera.up = vec3(get("up")!, "up");
  if (get("fov") !== null) s.camera.fov = numbers(get("fov")!, "fov", [1])[0];
  if (get("size") !== null) {
    const m = /^(\d+)x(\d+)$/.exec(get("size")!);
    if (!m) throw new SceneError(`URL parameter 'size': expected WIDTHxHEIGHT, got '${get("size")}'`);
    s.camera.width = Number(m[1]);
    s.camera.height = Number(m[2]);
  }
  if (get("light") !== null || get("lightpos") !== null) {
    const point = get("lightpos") !== null;
    const power = point
      ? rgb(get("intensity") ?? "10", "intensity")
      : rgb(get("irradiance") ?? String(Math.PI), "irradiance");
    s.lights = [{ type: point ? "point" : "directional", vector: vec3(point ? get("lightpos")! : get("light")!, point ? "lightpos" : "light"), power }];
  } else {
    if (get("irradiance") !== null && s.lights.length && s.lights[0].type === "directional") s.lights[0].power = rgb(get("irradiance")!, "irradiance");
    if (get("intensity") !== null && s.lights.length && s.lights[0].type === "point") s.lights[0].power = rgb(get("intensity")!, "intensity");
  }
  if (get("nolight") === "1") s.lights = [];
  if (get("env") !== null) {
    const v = get("env")!;
    s.environment = v === "0" || v === "off" ? [0, 0, 0] : v === "on" ? [1, 1, 1] : rgb(v, "env");
  }
  if (get("exposure") !== null) s.exposure = numbers(get("exposure")!, "exposure", [1])[0];
  if (get("mip") !== null) s.mip = get("mip") !== "0";
  if (get("deterministic") !== null) s.deterministic = get("deterministic") !== "0";
  if (get("transport") !== null) {
    const t = get("transport")!;
    if (t !== "auto" && t !== "websocket" && t !== "http") throw new SceneError(`URL parameter 'transport': auto, websocket or http, not '${t}'`);
    s.transport = t;
  }
  if (get("hud") !== null) s.hud = get("hud") !== "0";
  if (get("snapshots") !== null) s.snapshots = get("snapshots") !== "0";
  if (get("debug") !== null) {
    const d = DEBUG_MODES.indexOf(get("debug")!);
    if (d < 1) throw new SceneError(`URL parameter 'debug': one of ${DEBUG_MODES.slice(1).join(", ")}`);
    s.debug = d;
  }
  if (get("api") !== null) s.api = get("api")!;
  if (get("cache") !== null) {
    const c = numbers(get("cache")!, "cache", [1])[0];
    if (!Number.isInteger(c) || c < 8 || c > 65536) throw new SceneError(`URL parameter 'cache': the tile cache's side in texels, an integer in [8, 65536], not '${get("cache")}'`);
    s.cache = c;
  }
  validate(s);
  return s;
}

function validate(s: SceneSpec): void {
  if (!(s.camera.fov > 0 && s.camera.fov < 180)) throw new SceneError(`camera fov ${s.camera.fov} is outside (0, 180) degrees`);
  if (s.camera.width !== null && !(s.camera.width >= 1 && s.camera.width <= 8192 && s.camera.height! >= 1 && s.camera.height! <= 8192))
    throw new SceneError(`canvas size ${s.camera.width}x${s.camera.height} is outside 1..8192`);
  if (s.lights.length > MAX_LIGHTS) throw new SceneError(`${s.lights.length} lights: the viewer shades with at most ${MAX_LIGHTS}`);
  for (const o of s.objects) {
    if (!(o.segments >= 3 && o.segments <= 4096 && Number.isInteger(o.segments))) throw new SceneError(`segments ${o.segments}: an integer in [3, 4096]`);
    if (!(o.uv_scale[0] > 0 && o.uv_scale[1] > 0)) throw new SceneError("uv scale must be positive");
  }
}

// ---- the scene file format (subset) ---------------------------------------------------------

type Json = Record<string, unknown>;

function jsonVec3(v: unknown, where: string): V3 {
  if (!Array.isArray(v) || v.length !== 3 || !v.every((x) => typeof x === "number"))
    throw new SceneError(`scene: ${where} must be three numbers`);
  return v as V3;
}
function jsonRgb(v: unknown, where: string): V3 {
  if (typeof v === "number") return [v, v, v];
  return jsonVec3(v, where);
}
function jsonNumber(v: unknown, where: string): number {
  if (typeof v !== "number" || !Number.isFinite(v)) throw new SceneError(`scene: ${where} must be a number`);
  return v;
}
function allow(o: Json, keys: string[], where: string): void {
  for (const k of Object.keys(o)) if (!keys.includes(k)) throw new SceneError(`scene: ${where}: unknown key "${k}"`);
}

/** Material id of a scene material: "id", or a "file" whose name without .btfpkg or .bsvtf is the id. */
function materialId(m: unknown, where: string): string | null {
  if (m === undefined) return null;
  if (typeof m !== "object" || m === null) throw new SceneError(`scene: ${where} must be an object`);
  const mat = m as Json;
  if (mat.type !== undefined && mat.type !== "btf")
    throw new SceneError(`scene: ${where}: material type '${String(mat.type)}' is not shown by the viewer (btf only)`);
  if (typeof mat.id === "string") return mat.id;
  if (typeof mat.file === "string") {
    const base = mat.file.split(/[\\/]/).pop()!;
    return base.replace(/\.(btfpkg|bsvtf)$/, "");
  }
  return null;
}

/** Applies a scene in the `btf render` JSON format: camera, render.exposure, objects, lights. */
export function applySceneJson(s: SceneSpec, json: unknown): void {
  if (typeof json !== "object" || json === null || Array.isArray(json)) throw new SceneError("scene: must be a JSON object");
  const j = json as Json;
  allow(j, ["camera", "render", "objects", "lights"], "scene");
  if (j.camera !== undefined) {
    const c = j.camera as Json;
    allow(c, ["position", "look_at", "up", "fov", "width", "height"], "camera");
    if (c.position !== undefined) s.camera.position = jsonVec3(c.position, "camera.position");
    if (c.look_at !== undefined) s.camera.look_at = jsonVec3(c.look_at, "camera.look_at");
    if (c.up !== undefined) s.camera.up = jsonVec3(c.up, "camera.up");
    if (c.fov !== undefined) s.camera.fov = jsonNumber(c.fov, "camera.fov");
    if (c.width !== undefined || c.height !== undefined) {
      s.camera.width = jsonNumber(c.width ?? 512, "camera.width");
      s.camera.height = jsonNumber(c.height ?? 512, "camera.height");
    }
  }
  if (j.render !== undefined) {
    const r = j.render as Json;
    if (r.exposure !== undefined) s.exposure = jsonNumber(r.exposure, "render.exposure");
  }
  if (j.objects !== undefined) {
    if (!Array.isArray(j.objects)) throw new SceneError("scene: objects must be an array");
    s.objects = (j.objects as Json[]).map((o, i) => {
      const where = `objects[${i}]`;
      allow(
        o,
        ["name", "shape", "material", "position", "rotation", "scale", "uv_scale", "uv_rotation", "radius", "height", "major_radius", "minor_radius", "width", "depth", "segments"],
        where,
      );
      const spec = defaultObject(shapeOf(String(o.shape), where), materialId(o.material, `${where}.material`));
      for (const k of ["radius", "height", "major_radius", "minor_radius", "width", "depth", "segments"] as const)
        if (o[k] !== undefined) (spec as unknown as Json)[k] = jsonNumber(o[k], `${where}.${k}`);
      if (o.position !== undefined) spec.position = jsonVec3(o.position, `${where}.position`);
      if (o.rotation !== undefined) spec.rotation = jsonVec3(o.rotation, `${where}.rotation`);
      if (o.scale !== undefined) spec.scale = jsonRgb(o.scale, `${where}.scale`);
      if (o.uv_scale !== undefined) {
        const v = o.uv_scale;
        spec.uv_scale = typeof v === "number" ? [v, v] : (jsonVec2(v, `${where}.uv_scale`) as [number, number]);
      }
      if (o.uv_rotation !== undefined) spec.uv_rotation = jsonNumber(o.uv_rotation, `${where}.uv_rotation`);
      return spec;
    });
  }
  if (j.lights !== undefined) {
    if (!Array.isArray(j.lights)) throw new SceneError("scene: lights must be an array");
    s.lights = [];
    for (const [i, l] of (j.lights as Json[]).entries()) {
      const where = `lights[${i}]`;
      if (l.type === "point")
        s.lights.push({ type: "point", vector: l.position !== undefined ? jsonVec3(l.position, `${where}.position`) : [0, 4, 0], power: l.intensity !== undefined ? jsonRgb(l.intensity, `${where}.intensity`) : [10, 10, 10] });
      else if (l.type === "directional")
        s.lights.push({ type: "directional", vector: l.direction !== undefined ? jsonVec3(l.direction, `${where}.direction`) : [0, 1, 0], power: l.irradiance !== undefined ? jsonRgb(l.irradiance, `${where}.irradiance`) : [1, 1, 1] });
      else if (l.type === "environment") {
        // The viewer's environment is uniform: "radiance" (viewer only), else 1 × "scale".
        s.environment = l.radiance !== undefined ? jsonRgb(l.radiance, `${where}.radiance`) : jsonRgb(l.scale ?? 1, `${where}.scale`);
      } else throw new SceneError(`scene: ${where}: light type '${String(l.type)}' is not shown by the viewer (point, directional, environment)`);
    }
  }
}

function jsonVec2(v: unknown, where: string): number[] {
  if (!Array.isArray(v) || v.length !== 2 || !v.every((x) => typeof x === "number" && x > 0))
    throw new SceneError(`scene: ${where} must be a positive number or two`);
  return v as number[];
}
