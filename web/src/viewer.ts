// SPDX-License-Identifier: MIT
// The viewer page: a three.js scene of BTF-shaded objects, an orbit camera, movable lights, a HUD,
// the material list of the server, and window.btfViewer for tests (web/README.md).

import * as THREE from "three";
import { OrbitControls } from "three/examples/jsm/controls/OrbitControls.js";
import { MaterialView, type GpuLimits, type MaterialState } from "./material";
import { makeShape, objectTransform, transformMesh, SHAPES, type Mesh, type Shape } from "./meshes";
import { toneMapChannel, traceHit, type RefCamera, type RefHit, type RefObject } from "./reference";
import { DEBUG_MODES, SceneError, defaultObject, sceneFromParams, type LightSpec, type ObjectSpec, type SceneSpec, type V3 } from "./scene";
import { MAX_LIGHTS, fragmentShader, vertexShader } from "./shader";
import { fetchMaterials, type MaterialEntry } from "./stream";
import { TileStreaming, defaultTileOptions, type TileStreamingState } from "./tilestream";

// Colour values pass through untouched: the shader writes display-ready sRGB itself.
THREE.ColorManagement.enabled = false;

interface ObjectView {
  spec: ObjectSpec;
  materialId: string;
  mesh: Mesh;
  object: THREE.Mesh;
  uniforms: Record<string, THREE.IUniform>;
}

export interface ViewParams {
  camera?: { position?: V3; target?: V3; up?: V3; fov?: number };
  lights?: LightSpec[];
  /** Shorthand for one directional light towards `light`. */
  light?: V3;
  exposure?: number;
  environment?: V3 | number;
  mip?: boolean;
  debug?: string;
}

const $ = <T extends HTMLElement>(id: string) => document.getElementById(id) as T;

function showMessage(text: string, kind: "error" | "warning" = "error"): void {
  const box = $("message");
  const line = document.createElement("div");
  line.className = kind;
  line.textContent = text;
  box.appendChild(line);
  box.hidden = false;
}

function formatBytes(n: number): string {
  if (n < 1024) return `${n} B`;
  if (n < 1024 * 1024) return `${(n / 1024).toFixed(1)} KiB`;
  return `${(n / 1024 / 1024).toFixed(2)} MiB`;
}

/**
 * A frame that showed more of the material than the frame before: the first frame, and each
 * frame after components arrived or a stream completed.
 */
export interface TimelineEntry {
  /** performance.now() (ms since the page's navigation started) once the frame was submitted,
   * or, with snapshots, once its pixels were read back. */
  t: number;
  frame: number;
  components: number;
  bytes: number;
  complete: boolean;
  /** BSVTF materials: tiles shown from the cache. */
  tiles: number;
  /** RGBA, top row first, base64 (with `snapshots=1`). */
  pixels?: string;
}

class Viewer {
  readonly renderer: THREE.WebGLRenderer;
  readonly gl: WebGL2RenderingContext;
  readonly scene = new THREE.Scene();
  readonly camera: THREE.PerspectiveCamera;
  readonly controls: OrbitControls;
  readonly materials = new Map<string, MaterialView>();
  readonly objects: ObjectView[] = [];
  entries: MaterialEntry[] = [];
  listError: string | null = null;
  frames = 0;
  frameMs = 0;
  readonly timeline: TimelineEntry[] = [];
  /** The tile cache of the BSVTF materials. */
  readonly tiles: TileStreaming;
  renderMs = 0;
  private lastFrame = 0;
  private renderQueued = false;
  private readonly global: Record<string, THREE.IUniform>;
  private readonly limits: GpuLimits;
  private readonly workerUrl: string;
  private readonly base = document.baseURI;
  private shownErrors = new Set<string>();

  constructor(
    readonly canvas: HTMLCanvasElement,
    gl: WebGL2RenderingContext,
    readonly spec: SceneSpec,
  ) {
    this.gl = gl;
    this.renderer = new THREE.WebGLRenderer({ canvas, context: gl, antialias: false, preserveDrawingBuffer: true });
    this.renderer.outputColorSpace = THREE.LinearSRGBColorSpace;
    this.renderer.toneMapping = THREE.NoToneMapping;
    this.limits = { maxTextureSize: gl.getParameter(gl.MAX_TEXTURE_SIZE), maxArrayLayers: gl.getParameter(gl.MAX_ARRAY_TEXTURE_LAYERS) };
    this.workerUrl = new URL("worker.js", import.meta.url).toString();
    this.camera = new THREE.PerspectiveCamera(spec.camera.fov, 1, 0.01, 1000);
    this.controls = new OrbitControls(this.camera, canvas);
    this.controls.enableDamping = !spec.deterministic;
    this.controls.addEventListener("change", () => this.requestRender());
    this.global = {
      uLightCount: { value: 0 },
      uLightType: { value: new Array(MAX_LIGHTS).fill(0) },
      uLightVec: { value: Array.from({ length: MAX_LIGHTS }, () => new THREE.Vector3()) },
      uLightPower: { value: Array.from({ length: MAX_LIGHTS }, () => new THREE.Vector3()) },
      uEnvRadiance: { value: new THREE.Vector3() },
      uExposure: { value: 0 },
      uMip: { value: 1 },
      uDebug: { value: 0 },
    };
    this.tiles = new TileStreaming(this.base, { ...defaultTileOptions(), cacheTexels: spec.cache }, this.limits.maxArrayLayers, this.global.uMip);
    this.tiles.onChange = () => this.requestRender();
    this.resize();
    window.addEventListener("resize", () => {
      this.resize();
      this.requestRender();
    });
    this.setView({
      camera: { position: spec.camera.position, target: spec.camera.look_at, up: spec.camera.up, fov: spec.camera.fov },
      lights: spec.lights,
      exposure: spec.exposure,
      environment: spec.environment,
      mip: spec.mip,
      debug: DEBUG_MODES[spec.debug],
    });
  }

  resize(): void {
    const c = this.spec.camera;
    if (c.width !== null && c.height !== null) {
      this.renderer.setPixelRatio(1);
      this.renderer.setSize(c.width, c.height);
      this.camera.aspect = c.width / c.height;
    } else {
      this.renderer.setPixelRatio(window.devicePixelRatio);
      this.renderer.setSize(window.innerWidth, window.innerHeight);
      this.camera.aspect = window.innerWidth / window.innerHeight;
    }
    this.camera.updateProjectionMatrix();
  }

  setView(p: ViewParams): void {
    if (p.camera) {
      const c = p.camera;
      if (c.up) this.camera.up.set(...c.up);
      if (c.position) this.camera.position.set(...c.position);
      if (c.fov !== undefined) this.camera.fov = c.fov;
      if (c.target) this.controls.target.set(...c.target);
      this.camera.lookAt(this.controls.target);
      this.camera.updateProjectionMatrix();
      this.controls.update();
    }
    let lights = p.lights;
    if (p.light) lights = [{ type: "directional", vector: p.light, power: this.spec.lights[0]?.power ?? [Math.PI, Math.PI, Math.PI] }];
    if (lights) {
      if (lights.length > MAX_LIGHTS) throw new Error(`at most ${MAX_LIGHTS} lights`);
      this.spec.lights = lights.map((l) => ({ type: l.type, vector: [...l.vector] as V3, power: [...l.power] as V3 }));
      const g = this.global;
      g.uLightCount.value = lights.length;
      lights.forEach((l, i) => {
        (g.uLightType.value as number[])[i] = l.type === "point" ? 1 : 0;
        (g.uLightVec.value as THREE.Vector3[])[i].set(...l.vector);
        (g.uLightPower.value as THREE.Vector3[])[i].set(...l.power);
      });
    }
    if (p.exposure !== undefined) {
      this.spec.exposure = p.exposure;
      this.global.uExposure.value = p.exposure;
    }
    if (p.environment !== undefined) {
      const e = typeof p.environment === "number" ? ([p.environment, p.environment, p.environment] as V3) : p.environment;
      this.spec.environment = e;
      (this.global.uEnvRadiance.value as THREE.Vector3).set(...e);
    }
    if (p.mip !== undefined) {
      this.spec.mip = p.mip;
      this.global.uMip.value = p.mip ? 1 : 0;
    }
    if (p.debug !== undefined) {
      const d = DEBUG_MODES.indexOf(p.debug);
      if (d < 0) throw new Error(`debug: one of ${DEBUG_MODES.slice(1).join(", ")} or ""`);
      this.spec.debug = d;
      this.global.uDebug.value = d;
    }
    // Misses see the environment (as camera rays do in the C++ renderer): its tone-mapped radiance.
    const e = this.spec.environment;
    const bg = [0, 1, 2].map((i) => toneMapChannel(e[i], this.spec.exposure));
    this.renderer.setClearColor(new THREE.Color(bg[0], bg[1], bg[2]), 1);
    this.requestRender();
  }

  material(id: string): MaterialView {
    let m = this.materials.get(id);
    if (m) return m;
    const entry = this.entries.find((e) => e.id === id);
    if (!entry) throw new Error(`material '${id}' is not in the server's list (${this.entries.map((e) => e.id).join(", ") || "empty"})`);
    m = new MaterialView(entry, this.workerUrl, this.base, this.spec.transport, this.limits);
    m.onChange = () => this.requestRender();
    m.onProgress = () => updateHud(this);
    if (entry.codec === "bsvtf") m.onTileIndex = () => this.tiles.register(m!);
    this.materials.set(id, m);
    return m;
  }

  addObject(spec: ObjectSpec): ObjectView {
    const id = spec.material ?? this.entries[0]?.id;
    if (!id) throw new Error("the server lists no material");
    const mat = this.material(id);
    const mesh = transformMesh(makeShape(spec), objectTransform(spec.position, spec.rotation, spec.scale));
    const geometry = new THREE.BufferGeometry();
    geometry.setAttribute("position", new THREE.BufferAttribute(mesh.positions, 3));
    geometry.setAttribute("normal", new THREE.BufferAttribute(mesh.normals, 3));
    geometry.setAttribute("btfTangent", new THREE.BufferAttribute(mesh.tangents, 3));
    geometry.setAttribute("uv", new THREE.BufferAttribute(mesh.uvs, 2));
    geometry.setIndex(new THREE.BufferAttribute(mesh.indices, 1));
    geometry.computeBoundingSphere();
    const rot = (spec.uv_rotation * Math.PI) / 180;
    const uniforms: Record<string, THREE.IUniform> = {
      uUvScale: { value: new THREE.Vector2(spec.uv_scale[0], spec.uv_scale[1]) },
      uUvRotation: { value: new THREE.Vector2(Math.cos(rot), Math.sin(rot)) },
      uUvTurnsTangent: { value: spec.uv_rotation !== 0 || spec.uv_scale[0] !== spec.uv_scale[1] ? 1 : 0 },
    };
    const object = new THREE.Mesh(geometry, this.shaderMaterial(mat, uniforms));
    object.visible = false;
    this.scene.add(object);
    const view: ObjectView = { spec: { ...spec, material: id }, materialId: id, mesh, object, uniforms };
    this.objects.push(view);
    this.requestRender();
    return view;
  }

  private shaderMaterial(mat: MaterialView, objectUniforms: Record<string, THREE.IUniform>): THREE.RawShaderMaterial {
    return new THREE.RawShaderMaterial({
      glslVersion: THREE.GLSL3,
      vertexShader,
      fragmentShader: fragmentShader(mat.codecPart),
      uniforms: { ...mat.uniforms, ...this.global, ...objectUniforms },
      defines: mat.entry.codec === "bsvtf" ? { BSVTF: 1 } : {},
      side: THREE.DoubleSide,
    });
  }

  setObjectMaterial(index: number, id: string): void {
    const o = this.objects[index];
    const mat = this.material(id);
    (o.object.material as THREE.Material).dispose();
    o.object.material = this.shaderMaterial(mat, o.uniforms);
    o.materialId = id;
    o.spec.material = id;
    this.requestRender();
  }

  setObjectShape(index: number, shape: Shape): void {
    const o = this.objects[index];
    this.scene.remove(o.object);
    o.object.geometry.dispose();
    this.objects.splice(index, 1);
    const view = this.addObject({ ...o.spec, shape });
    // keep the object's place in the list
    this.objects.splice(this.objects.indexOf(view), 1);
    this.objects.splice(index, 0, view);
  }

  /** Aggregated over the materials the objects show. */
  get state() {
    const used = [...new Set(this.objects.map((o) => o.materialId))].map((id) => this.materials.get(id)!.state);
    const sum = (f: (s: MaterialState) => number) => used.reduce((a, s) => a + f(s), 0);
    return {
      bytes: sum((s) => s.bytes),
      total: sum((s) => s.total),
      components: sum((s) => s.components),
      totalComponents: sum((s) => s.totalComponents),
      ready: used.length > 0 && used.every((s) => s.ready || !!s.error),
      done: used.length > 0 && used.every((s) => s.done),
      complete: used.length > 0 && used.every((s) => s.complete),
      error: this.listError ?? used.find((s) => s.error)?.error ?? null,
      frames: this.frames,
      frameMs: this.frameMs,
      renderMs: this.renderMs,
      bsvtf: { ...this.tiles.state } as TileStreamingState,
      materials: [...this.materials.values()].map((m) => ({ ...m.state, applied: [...m.state.applied], times: { ...m.state.times } })),
      objects: this.objects.map((o) => ({ shape: o.spec.shape, material: o.materialId, visible: o.object.visible })),
    };
  }

  requestRender(): void {
    if (!this.spec.deterministic || this.renderQueued) return;
    this.renderQueued = true;
    setTimeout(() => {
      this.renderQueued = false;
      this.renderFrame(Infinity);
    }, 0);
  }

  /** Applies queued texture uploads within `budgetMs`, then draws one frame. */
  renderFrame(budgetMs: number): void {
    for (const m of this.materials.values()) {
      if (m.applyPending(budgetMs)) this.requestRenderIfPending(m);
      if (m.state.error && !this.shownErrors.has(m.state.error)) {
        this.shownErrors.add(m.state.error);
        showMessage(m.state.unsupported ? `Material cannot be shown: ${m.state.error}` : `Material failed to load: ${m.state.error}`);
      }
    }
    for (const o of this.objects) {
      const s = this.materials.get(o.materialId)!.state;
      o.object.visible = s.ready;
    }
    const t0 = performance.now();
    // BSVTF: feedback, requests and cache operations before the frame that uses them.
    const objects = this.objects.map((o) => ({ object: o.object, material: this.materials.get(o.materialId)!, uniforms: o.uniforms }));
    if (this.tiles.update(this.renderer, this.scene, this.camera, objects)) this.requestRender();
    this.renderer.render(this.scene, this.camera);
    this.renderMs = performance.now() - t0;
    this.frames += 1;
    this.record();
    updateHud(this);
  }

  private record(): void {
    const s = this.state;
    const last = this.timeline[this.timeline.length - 1];
    const tiles = s.bsvtf.shown;
    if (last && last.components === s.components && last.complete === s.complete && last.tiles === tiles) return;
    const entry: TimelineEntry = { t: 0, frame: this.frames, components: s.components, bytes: s.bytes, complete: s.complete, tiles };
    if (this.spec.snapshots) entry.pixels = this.pixels().data;
    entry.t = performance.now();
    this.timeline.push(entry);
  }

  private requestRenderIfPending(m: MaterialView): void {
    if (m.hasPending) this.requestRender();
  }

  loop = (now: number): void => {
    this.frameMs = this.lastFrame ? 0.9 * this.frameMs + 0.1 * (now - this.lastFrame) : 0;
    this.lastFrame = now;
    this.controls.update();
    this.renderFrame(4);
    requestAnimationFrame(this.loop);
  };

  /** Renders now with everything received applied; resolves once the GPU has finished. */
  renderNow(): { frame: number; components: number; ms: number } {
    const t0 = performance.now();
    this.renderFrame(Infinity);
    const px = new Uint8Array(4);
    this.gl.readPixels(0, 0, 1, 1, this.gl.RGBA, this.gl.UNSIGNED_BYTE, px); // waits for the GPU
    const ms = performance.now() - t0;
    this.renderMs = ms;
    updateHud(this);
    return { frame: this.frames, components: this.state.components, ms };
  }

  /** The drawing buffer as RGBA bytes, top row first, base64. */
  pixels(): { width: number; height: number; data: string } {
    const gl = this.gl;
    const w = gl.drawingBufferWidth, h = gl.drawingBufferHeight;
    const raw = new Uint8Array(w * h * 4);
    gl.readPixels(0, 0, w, h, gl.RGBA, gl.UNSIGNED_BYTE, raw);
    const flipped = new Uint8Array(raw.length);
    for (let y = 0; y < h; ++y) flipped.set(raw.subarray((h - 1 - y) * w * 4, (h - y) * w * 4), y * w * 4);
    let text = "";
    for (let i = 0; i < flipped.length; i += 0x8000) text += String.fromCharCode(...flipped.subarray(i, i + 0x8000));
    return { width: w, height: h, data: btoa(text) };
  }

  /**
   * The CPU reference of pixels (x, y) (top-left origin, drawing-buffer pixels): display values
   * in [0, 1] (tone-mapped, sRGB-encoded) or null where the ray misses or the material is not
   * ready. Level-0 lookup only: compare with mip off, or where the texture is magnified.
   */
  /** Where the rays of pixels (x, y) meet the scene: object, mapped uv, local wo and wi. */
  trace(points: [number, number][]): (RefHit | null)[] {
    const { camera, objects } = this.referenceScene();
    return points.map(([x, y]) => traceHit(camera, objects, this.spec.lights, x, y));
  }

  private referenceScene(): { camera: RefCamera; objects: RefObject[] } {
    const gl = this.gl;
    const camera: RefCamera = {
      position: this.camera.position.toArray() as V3,
      target: this.controls.target.toArray() as V3,
      up: this.camera.up.toArray() as V3,
      fov: this.camera.fov,
      width: gl.drawingBufferWidth,
      height: gl.drawingBufferHeight,
    };
    const objects: RefObject[] = this.objects.map((o) => ({ mesh: o.mesh, uvScale: o.spec.uv_scale, uvRotationDeg: o.spec.uv_rotation }));
    return { camera, objects };
  }

  async reference(points: [number, number][]): Promise<(number[] | null)[]> {
    const env = this.spec.environment;
    const envOn = env.some((x) => x > 0);
    const hits = this.trace(points);
    const out: (number[] | null)[] = [];
    for (const hit of hits) {
      if (!hit) {
        out.push(null);
        continue;
      }
      const mat = this.materials.get(this.objects[hit.object].materialId)!;
      if (!mat.state.ready || mat.state.error) {
        out.push(null);
        continue;
      }
      const lit = hit.lights.filter((l) => l !== null) as { wi: V3; irradiance: V3 }[];
      const q = new Float64Array(8 * Math.max(lit.length, 1));
      lit.forEach((l, i) => q.set([hit.uv[0], hit.uv[1], ...l.wi, ...hit.wo], 8 * i));
      const radiance = [0, 0, 0];
      if (lit.length) {
        const values = await mat.evaluate(q, false);
        lit.forEach((l, i) => {
          for (let c = 0; c < 3; ++c) radiance[c] += (Math.max(values[3 * i + c], 0) * l.irradiance[c]) / Math.PI;
        });
      }
      if (envOn) {
        const e = new Float64Array(8);
        e.set([hit.uv[0], hit.uv[1], 0, 0, 1, ...hit.wo]);
        const v = await mat.evaluate(e, true);
        const scale = mat.uniforms.uEnvScale.value as number;
        for (let c = 0; c < 3; ++c) radiance[c] += Math.max(v[c], 0) * scale * env[c];
      }
      out.push(radiance.map((r) => toneMapChannel(r, this.spec.exposure)));
    }
    return out;
  }
}

// ---- HUD and controls -----------------------------------------------------------------------

function updateHud(v: Viewer): void {
  const hud = $("hud");
  if (hud.hidden) return;
  const lines: string[] = [];
  for (const m of v.materials.values()) {
    const s = m.state;
    const status = s.error ? "error" : s.complete ? "complete" : s.done ? "ended early" : s.ready ? "refining" : "loading";
    lines.push(
      `${s.id} (${s.codec ?? "?"}): ${formatBytes(s.bytes)} / ${s.total ? formatBytes(s.total) : "?"} · ` +
        `${s.components}/${s.totalComponents || "?"} ${s.unit} · ${s.transport || "…"} · ${status}`,
    );
  }
  const t = v.tiles.state;
  if (t.capacity > 0)
    lines.push(
      `tile cache: ${t.shown} shown / ${t.resident} resident / ${t.capacity} · tiles ${formatBytes(t.tileBytes)}, U packets ${formatBytes(t.packetBytes)} · ` +
        `${t.inFlight} in flight · ${t.settled ? "settled" : "refining"}`,
    );
  const fps = v.frameMs > 0 ? ` (${(1000 / v.frameMs).toFixed(0)} fps)` : "";
  lines.push(`frame ${v.spec.deterministic ? v.renderMs.toFixed(1) : v.frameMs.toFixed(1)} ms${v.spec.deterministic ? " (on demand)" : fps} · submit ${v.renderMs.toFixed(1)} ms · frame #${v.frames}`);
  hud.textContent = lines.join("\n");
}

function buildPanel(v: Viewer): void {
  const panel = $("panel");
  const objectSel = $<HTMLSelectElement>("ui-object");
  const materialSel = $<HTMLSelectElement>("ui-material");
  const shapeSel = $<HTMLSelectElement>("ui-shape");
  const lightType = $<HTMLSelectElement>("ui-light-type");
  const az = $<HTMLInputElement>("ui-light-azimuth");
  const el = $<HTMLInputElement>("ui-light-elevation");
  const power = $<HTMLInputElement>("ui-light-power");
  const envOn = $<HTMLInputElement>("ui-env");
  const envLevel = $<HTMLInputElement>("ui-env-level");
  const exposure = $<HTMLInputElement>("ui-exposure");
  const mip = $<HTMLInputElement>("ui-mip");
  const addButton = $<HTMLButtonElement>("ui-add");

  const fill = () => {
    objectSel.innerHTML = "";
    v.objects.forEach((o, i) => objectSel.add(new Option(`${i + 1}: ${o.spec.shape}`, String(i))));
  };
  materialSel.innerHTML = "";
  for (const e of v.entries) materialSel.add(new Option(`${e.name ?? e.id}${e.codec && e.codec !== "fmf" ? ` (${e.codec})` : ""}`, e.id));
  shapeSel.innerHTML = "";
  for (const s of SHAPES) shapeSel.add(new Option(s, s));
  const current = () => v.objects[Number(objectSel.value) || 0];
  const sync = () => {
    const o = current();
    if (!o) return;
    materialSel.value = o.materialId;
    shapeSel.value = o.spec.shape;
  };
  fill();
  sync();
  objectSel.onchange = sync;
  materialSel.onchange = () => v.setObjectMaterial(Number(objectSel.value) || 0, materialSel.value);
  shapeSel.onchange = () => {
    v.setObjectShape(Number(objectSel.value) || 0, shapeSel.value as Shape);
    fill();
  };
  addButton.onclick = () => {
    const o = current();
    const spec = defaultObject(shapeSel.value as Shape, materialSel.value);
    spec.position = [2.5 * v.objects.length, 0, 0];
    if (o) spec.uv_scale = [...o.spec.uv_scale];
    v.addObject(spec);
    fill();
    objectSel.value = String(v.objects.length - 1);
  };

  // Light direction from azimuth (from +x towards +z) and elevation above the xz-plane.
  const l0 = v.spec.lights[0];
  if (l0) {
    const d = new THREE.Vector3(...l0.vector).normalize();
    az.value = String(Math.round((Math.atan2(d.z, d.x) * 180) / Math.PI));
    el.value = String(Math.round((Math.asin(Math.max(-1, Math.min(1, d.y))) * 180) / Math.PI));
    lightType.value = l0.type;
    power.value = String(l0.power[0]);
  }
  const applyLight = () => {
    const a = (Number(az.value) * Math.PI) / 180, e = (Number(el.value) * Math.PI) / 180;
    const dir: V3 = [Math.cos(e) * Math.cos(a), Math.sin(e), Math.cos(e) * Math.sin(a)];
    const p = Number(power.value);
    const type = lightType.value as "point" | "directional";
    v.setView({ lights: [{ type, vector: type === "point" ? (dir.map((x) => 4 * x) as V3) : dir, power: [p, p, p] }] });
  };
  for (const input of [az, el, power]) input.oninput = applyLight;
  lightType.onchange = () => {
    power.value = lightType.value === "point" ? String(10 * Math.PI) : String(Math.PI);
    applyLight();
  };
  envOn.checked = v.spec.environment.some((x) => x > 0);
  if (envOn.checked) envLevel.value = String(v.spec.environment[0]);
  const applyEnv = () => v.setView({ environment: envOn.checked ? Number(envLevel.value) : 0 });
  envOn.onchange = applyEnv;
  envLevel.oninput = applyEnv;
  exposure.value = String(v.spec.exposure);
  exposure.oninput = () => v.setView({ exposure: Number(exposure.value) });
  mip.checked = v.spec.mip;
  mip.onchange = () => v.setView({ mip: mip.checked });

  // Alt + drag on the canvas moves the light (the orbit controls keep the plain drags).
  let dragging = false;
  v.canvas.addEventListener("pointerdown", (e) => {
    if (!e.altKey) return;
    dragging = true;
    v.controls.enabled = false;
    e.preventDefault();
  });
  window.addEventListener("pointermove", (e) => {
    if (!dragging) return;
    az.value = String(Number(az.value) + e.movementX * 0.5);
    el.value = String(Math.max(-89, Math.min(89, Number(el.value) - e.movementY * 0.5)));
    applyLight();
  });
  window.addEventListener("pointerup", () => {
    if (!dragging) return;
    dragging = false;
    v.controls.enabled = true;
  });
  panel.hidden = false;
}

// ---- start ----------------------------------------------------------------------------------

async function main(): Promise<void> {
  const hook: Record<string, unknown> = { state: { error: null, ready: false, done: false, frames: 0 } };
  (window as unknown as { btfViewer: unknown }).btfViewer = hook;
  let spec: SceneSpec;
  try {
    spec = sceneFromParams(new URLSearchParams(location.search));
  } catch (e) {
    const message = e instanceof SceneError ? e.message : String(e);
    hook.state = { error: message };
    showMessage(message);
    return;
  }
  $("hud").hidden = !spec.hud;
  const canvas = $<HTMLCanvasElement>("view");
  const gl = canvas.getContext("webgl2", { antialias: false, preserveDrawingBuffer: true, alpha: false });
  if (!gl) {
    const message =
      "This browser cannot show the viewer: WebGL2 is not available (it may be switched off, or the graphics driver is blocked). " +
      "Try a current Chrome, Edge, Firefox or Safari with hardware acceleration enabled.";
    hook.state = { error: message, webgl2: false };
    showMessage(message);
    return;
  }
  const viewer = new Viewer(canvas, gl, spec);
  Object.defineProperty(hook, "state", { get: () => viewer.state });
  Object.assign(hook, {
    viewer,
    scene: spec,
    setView: (p: ViewParams) => viewer.setView(p),
    render: () => viewer.renderNow(),
    pixels: () => viewer.pixels(),
    timeline: () => viewer.timeline,
    reference: (points: [number, number][]) => viewer.reference(points),
    trace: (points: [number, number][]) => viewer.trace(points),
    setMaterial: (index: number, id: string) => viewer.setObjectMaterial(index, id),
    setShape: (index: number, shape: Shape) => viewer.setObjectShape(index, shape),
    addObject: (o: Partial<ObjectSpec>) => viewer.addObject({ ...defaultObject(), ...o }),
  });
  try {
    viewer.entries = await fetchMaterials(spec.api, document.baseURI);
  } catch (e) {
    viewer.listError = (e as Error).message;
    showMessage(viewer.listError);
    return;
  }
  if (viewer.entries.length === 0) {
    viewer.listError = "The server lists no materials (give btf serve some .btfpkg files).";
    showMessage(viewer.listError, "warning");
    return;
  }
  try {
    for (const o of spec.objects) viewer.addObject(o);
  } catch (e) {
    viewer.listError = (e as Error).message;
    showMessage(viewer.listError);
    return;
  }
  if (spec.hud) buildPanel(viewer);
  if (spec.deterministic) viewer.requestRender();
  else requestAnimationFrame(viewer.loop);
}

void main();
