// SPDX-License-Identifier: MIT
// The viewer's BSVTF mode (docs/bsvtf.md, Schwartz et al. 2013): the tile cache shared by every
// BSVTF material of the page, what the frames need of it, and the requests that fill it. Each
// frame
//  1. draws a feedback pass at a quarter of the resolution (shader.ts, feedbackFragmentShader):
//     per pixel the material, the level it needs and the tile, read back as votes (equation 9);
//  2. asks the server for what matters most by HTTP byte ranges of the package file
//     (docs/protocol.md "BSVTF materials"): add candidates by P = w·v, the coarsest tiles, and
//     the U packets by Σ v·w over the group's tiles on screen (the weight standing in for ‖T‖²);
//     runs of tiles that lie back to back in the file come in one request; the worker decodes
//     them against their parents into an LRU store;
//  3. applies the decision rule (TileCache.decide, the C++ decisions exactly, cache.ts) with the
//     tiles the store holds, copies the tiles that came in into their layers of the cache
//     texture, and rewrites each material's indirection texture;
//  4. the surface shader then reads every eigen-texture through the cache (sampleCached).

import * as THREE from "three";
import { TileCache, Votes, type TileKey } from "./cache";
import type { MaterialView } from "./material";
import { feedbackFragmentShader, vertexShader } from "./shader";
import { fetchRange } from "./stream";

export interface TileStreamingOptions {
  /** Side of the cache in texels: (cacheTexels / stride)² tiles, at most the GPU's array layers. */
  cacheTexels: number;
  /** The feedback pass is this much smaller in each direction. */
  feedbackDivisor: number;
  /** Bytes of decoded tiles the client keeps (least recently used leave first; resident stay). */
  storeBytes: number;
  /** Tiles and U packets asked for and not yet decoded, at most. */
  maxInFlight: number;
  /** Cache operations per frame, at most. */
  operations: number;
}

export const defaultTileOptions = (): TileStreamingOptions => ({ cacheTexels: 2048, feedbackDivisor: 4, storeBytes: 256 << 20, maxInFlight: 64, operations: 256 });

export interface TileStreamingState {
  capacity: number;
  /** Tiles in the cache, and of them the ones whose data is in their layer (shown). */
  resident: number;
  shown: number;
  stored: number;
  requests: number;
  inFlight: number;
  tileBytes: number;
  packetBytes: number;
  adds: number;
  swaps: number;
  /** Add candidates the frame votes for (P > 0) that the cache does not hold. */
  unmet: number;
  feedbackPasses: number;
  /** Nothing in flight, nothing to ask for, no operation left: the frame shows what it can. */
  settled: boolean;
}

/** An object of the page as the feedback pass needs it. */
export interface TileObject {
  object: THREE.Mesh;
  material: MaterialView;
  uniforms: Record<string, THREE.IUniform>;
}

interface Material {
  view: MaterialView;
  /** Per tile index: the cache layer holding its data, or −1. */
  uploaded: Int32Array;
  /** U packets received, per group. */
  packets: boolean[];
  tilesOffset: number;
}

export class TileStreaming {
  readonly state: TileStreamingState = {
    capacity: 0,
    resident: 0,
    shown: 0,
    stored: 0,
    requests: 0,
    inFlight: 0,
    tileBytes: 0,
    packetBytes: 0,
    adds: 0,
    swaps: 0,
    unmet: 0,
    feedbackPasses: 0,
    settled: false,
  };
  /** Called when something arrived that a new frame would use. */
  onChange: () => void = () => {};

  private readonly materials: Material[] = [];
  private cache: TileCache | null = null;
  private votes: Votes | null = null;
  private atlas: THREE.DataArrayTexture | null = null;
  private stride = 0;
  private readonly store = new Map<string, Uint16Array>(); // insertion order = least recent first
  private storeBytes = 0;
  private readonly inFlight = new Set<string>();
  private wanted: TileKey[] = [];
  private target: THREE.WebGLRenderTarget | null = null;
  private pixels = new Uint8Array(0);
  private readonly feedbackMaterials = new WeakMap<THREE.Mesh, { view: MaterialView; material: THREE.RawShaderMaterial; index: THREE.IUniform }>();

  constructor(
    private readonly base: string,
    private readonly options: TileStreamingOptions,
    private readonly maxLayers: number,
    private readonly mip: THREE.IUniform,
  ) {}

  /** Adds a BSVTF material whose tile index arrived; the cache starts again with every material. */
  register(view: MaterialView): void {
    const b = view.bsvtf!;
    const stride = b.layout.stride;
    if (this.atlas && stride !== this.stride)
      return view.fail(`${view.entry.id}: tiles of ${b.info.tile} + 2 × ${b.info.pad} texels, but the page's tile cache holds tiles of ${this.stride} texels`);
    const tiles = view.entry.sections?.find((s) => s.name === "tiles");
    if (!tiles) return view.fail(`${view.entry.id}: the material list gives no section 'tiles' for this BSVTF package`);
    if (!this.atlas) {
      this.stride = stride;
      const side = Math.floor(this.options.cacheTexels / stride);
      this.state.capacity = Math.min(side * side, this.maxLayers);
      const values = stride * stride * 4;
      this.atlas = new THREE.DataArrayTexture(new Uint16Array(values * this.state.capacity), stride, stride, this.state.capacity);
      this.atlas.format = THREE.RGBAFormat;
      this.atlas.type = THREE.HalfFloatType;
      this.atlas.minFilter = this.atlas.magFilter = THREE.NearestFilter;
      this.atlas.generateMipmaps = false;
      this.atlas.unpackAlignment = 1;
      this.atlas.needsUpdate = true;
    }
    const layouts = [...this.materials.map((m) => m.view.bsvtf!.layout), b.layout];
    const weights = [...this.materials.map((m) => m.view.bsvtf!.index!.weights), b.index!.weights];
    let cache: TileCache;
    try {
      cache = new TileCache(layouts, weights, this.state.capacity);
    } catch (e) {
      return view.fail(`${view.entry.id}: ${(e as Error).message} (a larger cache: the URL parameter 'cache')`);
    }
    const mi = this.materials.length;
    this.materials.push({ view, uploaded: new Int32Array(b.layout.tileCount).fill(-1), packets: b.info.groups.map(() => false), tilesOffset: tiles.offset });
    for (const m of this.materials) m.uploaded.fill(-1);
    this.cache = cache;
    this.votes = new Votes(layouts);
    view.uniforms.uAtlas.value = this.atlas;
    view.onTile = (index, data, error) => this.received(mi, index, data, error);
    this.state.settled = false;
    this.onChange();
  }

  private key(material: number, index: number): string {
    return `${material}/${index}`;
  }
  private tileKey(t: TileKey): string {
    return this.key(t.material, this.cache!.layout(t.material).index(t));
  }

  private received(mi: number, index: number, data: Uint16Array | null, error: string | null): void {
    const key = this.key(mi, index);
    this.inFlight.delete(key);
    if (!data) {
      this.materials[mi].view.fail(error ?? `tile ${index} could not be decoded`);
      this.onChange();
      return;
    }
    this.put(key, data);
    this.onChange();
  }

  private put(key: string, data: Uint16Array): void {
    if (this.store.has(key)) return;
    this.store.set(key, data);
    this.storeBytes += data.byteLength;
    for (const [k, d] of this.store) {
      if (this.storeBytes <= this.options.storeBytes) break;
      if (k === key || this.isResident(k)) continue;
      this.store.delete(k);
      this.storeBytes -= d.byteLength;
    }
  }

  private isResident(key: string): boolean {
    const [m, i] = key.split("/").map(Number);
    return this.cache!.slots(m)[i] >= 0;
  }

  private touch(key: string): void {
    const d = this.store.get(key);
    if (!d) return;
    this.store.delete(key);
    this.store.set(key, d);
  }

  /** One frame's feedback, requests and cache operations; true when another frame would change more. */
  update(renderer: THREE.WebGLRenderer, scene: THREE.Scene, camera: THREE.Camera, objects: TileObject[]): boolean {
    const cache = this.cache;
    if (!cache) return false;
    // A material that failed takes no more requests: its requests in flight are forgotten, its
    // pixels vote for nothing and its tiles are not asked for.
    for (const [mi, m] of this.materials.entries())
      if (m.view.state.error) for (const key of this.inFlight) if (key.startsWith(`${mi}/`)) this.inFlight.delete(key);
    for (const [mi, m] of this.materials.entries())
      m.packets.forEach((have, g) => {
        if (have || !m.view.state.applied.includes(`u${g}`)) return;
        m.packets[g] = true;
        this.inFlight.delete(`${mi}/u${g}`);
      });
    this.feedback(renderer, scene, camera, objects);
    const asked = this.request();
    const d = cache.decide(this.votes!, (t) => this.store.has(this.tileKey(t)), this.options.operations);
    for (const op of d.operations) {
      if (op.kind === "add") this.state.adds += 1;
      else this.state.swaps += 1;
    }
    if (d.wanted) this.wanted.push(d.wanted);
    this.upload();
    for (const t of cache.tiles()) this.touch(this.tileKey(t));
    const s = this.state;
    s.resident = cache.size;
    s.unmet = 0;
    cache.forEachAddCandidate(this.votes!, () => (s.unmet += 1));
    s.stored = this.store.size;
    s.inFlight = this.inFlight.size;
    s.settled = d.operations.length === 0 && !d.wanted && asked === 0 && this.inFlight.size === 0;
    for (const m of this.materials) {
      if (m.view.state.error) continue; // done, with its error
      m.view.state.done = m.view.state.complete = s.settled;
      m.view.state.components = m.packets.reduce((n, have, g) => n + (have ? m.view.bsvtf!.info.groups[g].count : 0), 0);
    }
    // Another frame now only if it would decide more; arrivals ask for frames themselves.
    return d.operations.length > 0 || (!!d.wanted && !this.inFlight.has(this.tileKey(d.wanted)));
  }

  private failed(mi: number): boolean {
    return !!this.materials[mi].view.state.error;
  }

  private feedback(renderer: THREE.WebGLRenderer, scene: THREE.Scene, camera: THREE.Camera, objects: TileObject[]): void {
    const size = renderer.getDrawingBufferSize(new THREE.Vector2());
    const div = this.options.feedbackDivisor;
    const w = Math.max(1, Math.floor(size.x / div)), h = Math.max(1, Math.floor(size.y / div));
    if (!this.target || this.target.width !== w || this.target.height !== h) {
      this.target?.dispose();
      this.target = new THREE.WebGLRenderTarget(w, h, { format: THREE.RGBAFormat, type: THREE.UnsignedByteType, minFilter: THREE.NearestFilter, magFilter: THREE.NearestFilter, generateMipmaps: false, depthBuffer: true });
      this.pixels = new Uint8Array(w * h * 4);
    }
    const saved = objects.map((o) => o.object.material);
    for (const o of objects) o.object.material = this.feedbackMaterial(o, div);
    const previousTarget = renderer.getRenderTarget();
    const clear = renderer.getClearColor(new THREE.Color());
    const alpha = renderer.getClearAlpha();
    renderer.setRenderTarget(this.target);
    renderer.setClearColor(0x000000, 0);
    renderer.clear();
    renderer.render(scene, camera);
    renderer.readRenderTargetPixels(this.target, 0, 0, w, h, this.pixels);
    renderer.setRenderTarget(previousTarget);
    renderer.setClearColor(clear, alpha);
    objects.forEach((o, i) => (o.object.material = saved[i]));
    const votes = this.votes!;
    votes.clear();
    const p = this.pixels;
    for (let i = 0; i < p.length; i += 4) {
      if (p[i] === 0 || p[i] > this.materials.length) continue;
      const mi = p[i] - 1;
      if (this.failed(mi)) continue;
      const l = this.cache!.layout(mi);
      const level = Math.min(p[i + 1], l.levels - 1);
      votes.addTile(mi, level, Math.min(p[i + 2], l.tilesX(level) - 1), Math.min(p[i + 3], l.tilesY(level) - 1));
    }
    this.state.feedbackPasses += 1;
  }

  private feedbackMaterial(o: TileObject, divisor: number): THREE.RawShaderMaterial {
    let f = this.feedbackMaterials.get(o.object);
    const mi = this.materials.findIndex((m) => m.view === o.material);
    if (!f || f.view !== o.material) {
      f?.material.dispose();
      const index: THREE.IUniform = { value: -1 };
      const u = o.material.uniforms;
      const material = new THREE.RawShaderMaterial({
        glslVersion: THREE.GLSL3,
        vertexShader,
        fragmentShader: feedbackFragmentShader,
        uniforms: {
          uSize: u.uSize,
          uLevels: u.uLevels ?? { value: 1 },
          uTile: u.uTile ?? { value: 64 },
          uUvScale: o.uniforms.uUvScale,
          uUvRotation: o.uniforms.uUvRotation,
          uMip: this.mip,
          uMaterialIndex: index,
          uFootprintScale: { value: 1 / divisor },
        },
        side: THREE.DoubleSide,
      });
      f = { view: o.material, material, index };
      this.feedbackMaterials.set(o.object, f);
    }
    f.index.value = mi;
    return f.material;
  }

  // Chooses what to ask for, by priority, and asks; returns how many requests it made.
  private request(): number {
    const cache = this.cache!, votes = this.votes!;
    interface Want {
      priority: number;
      material: number;
      /** Tile index, or −1 − g for the U packet of group g. */
      index: number;
    }
    const wants: Want[] = [];
    const seen = new Set<string>();
    const want = (priority: number, material: number, index: number) => {
      const key = index >= 0 ? this.key(material, index) : `${material}/u${-1 - index}`;
      if (this.failed(material) || this.inFlight.has(key) || seen.has(key) || (index >= 0 && this.store.has(key))) return;
      seen.add(key);
      wants.push({ priority, material, index });
    };
    const resident = cache.tiles();
    this.materials.forEach((m, mi) => {
      const l = cache.layout(mi), w = m.view.bsvtf!.index!.weights, top = l.levels - 1;
      for (let g = 0; g < l.groups.length; ++g) {
        for (let y = 0; y < l.tilesY(top); ++y)
          for (let x = 0; x < l.tilesX(top); ++x) {
            const i = l.index({ group: g, level: top, x, y });
            const v = votes.get(mi, { group: g, level: top, x, y });
            if (v > 0) want(v * w[i], mi, i);
          }
        if (m.packets[g]) continue;
        // §6: U_g is worth what the group's tiles on screen would show with it.
        let p = 0;
        for (const t of resident)
          if (t.material === mi && t.group === g && this.store.has(this.tileKey(t))) p += votes.get(mi, t) * w[l.index(t)];
        if (p > 0) want(p, mi, -1 - g);
      }
    });
    cache.forEachAddCandidate(votes, (t, p) => {
      const l = cache.layout(t.material);
      if (this.store.has(this.tileKey(t)) || !this.store.has(this.key(t.material, l.index(l.parent(t))))) return;
      want(p, t.material, l.index(t));
    });
    for (const t of this.wanted) want(Infinity, t.material, cache.layout(t.material).index(t));
    this.wanted = [];
    wants.sort((a, b) => b.priority - a.priority);
    const chosen = wants.slice(0, Math.max(0, this.options.maxInFlight - this.inFlight.size));
    // Tiles of a material that lie back to back in the file come in one request.
    const byMaterial = new Map<number, number[]>();
    for (const c of chosen) {
      if (c.index < 0) {
        this.fetchPacket(c.material, -1 - c.index);
        continue;
      }
      if (!byMaterial.has(c.material)) byMaterial.set(c.material, []);
      byMaterial.get(c.material)!.push(c.index);
    }
    for (const [mi, indices] of byMaterial) {
      const index = this.materials[mi].view.bsvtf!.index!;
      indices.sort((a, b) => index.offsets[a] - index.offsets[b]);
      let run: number[] = [];
      for (const i of indices) {
        const last = run[run.length - 1];
        if (run.length && index.offsets[last] + index.sizes[last] !== index.offsets[i]) {
          this.fetchTiles(mi, run);
          run = [];
        }
        run.push(i);
      }
      if (run.length) this.fetchTiles(mi, run);
    }
    this.state.requests += chosen.length;
    return chosen.length;
  }

  private fetchPacket(mi: number, g: number): void {
    const m = this.materials[mi];
    const name = `u${g}`;
    const section = m.view.entry.sections?.find((s) => s.name === name);
    if (!section) return m.view.fail(`${m.view.entry.id}: the material list gives no section '${name}' for this BSVTF package`);
    this.inFlight.add(`${mi}/${name}`);
    fetchRange(m.view.entry, this.base, section.offset, section.offset + section.size).then(
      (data) => {
        this.state.packetBytes += data.length;
        m.view.decodePacket(name, data);
      },
      (e: Error) => {
        this.inFlight.delete(`${mi}/${name}`);
        m.view.fail(`${m.view.entry.id}: ${e.message}`);
        this.onChange();
      },
    );
  }

  private fetchTiles(mi: number, run: number[]): void {
    const m = this.materials[mi];
    const index = m.view.bsvtf!.index!, layout = m.view.bsvtf!.layout;
    for (const i of run) this.inFlight.add(this.key(mi, i));
    const from = index.offsets[run[0]];
    const to = index.offsets[run[run.length - 1]] + index.sizes[run[run.length - 1]];
    fetchRange(m.view.entry, this.base, m.tilesOffset + from, m.tilesOffset + to).then(
      (data) => {
        this.state.tileBytes += data.length;
        for (const i of run) {
          const id = layout.id(i);
          const parent = layout.hasParent(id) ? this.store.get(this.key(mi, layout.index(layout.parent(id)))) : null;
          if (parent === undefined) {
            // Its parent left the store meanwhile: asked for again by a later frame.
            this.inFlight.delete(this.key(mi, i));
            this.onChange();
            continue;
          }
          m.view.decodeTile(i, data.subarray(index.offsets[i] - from, index.offsets[i] - from + index.sizes[i]), parent);
        }
      },
      (e: Error) => {
        for (const i of run) this.inFlight.delete(this.key(mi, i));
        m.view.fail(`${m.view.entry.id}: ${e.message}`);
        this.onChange();
      },
    );
  }

  // Copies the tiles that entered the cache into their layers and rewrites the indirections.
  private upload(): void {
    const atlas = this.atlas!, data = atlas.image.data as Uint16Array, values = this.stride * this.stride * 4;
    let shown = 0, changedAtlas = false;
    this.materials.forEach((m, mi) => {
      const slots = this.cache!.slots(mi), up = m.uploaded;
      let changed = false;
      for (let i = 0; i < slots.length; ++i) {
        const s = slots[i];
        if (s >= 0 && up[i] === s) {
          ++shown;
          continue;
        }
        const tile = s >= 0 ? this.store.get(this.key(mi, i)) : undefined;
        if (!tile) {
          if (up[i] !== -1) (up[i] = -1), (changed = true);
          continue;
        }
        data.set(tile, s * values);
        atlas.addLayerUpdate(s);
        up[i] = s;
        changed = changedAtlas = true;
        ++shown;
      }
      if (changed) m.view.setIndirection(up);
    });
    if (changedAtlas) atlas.needsUpdate = true;
    this.state.shown = shown;
  }

  dispose(): void {
    this.target?.dispose();
    this.atlas?.dispose();
  }
}
