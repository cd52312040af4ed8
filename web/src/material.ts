// SPDX-License-Identifier: MIT
// One material on the page: its stream, its decoding worker, and the textures and uniforms its
// objects' shaders read. Worker results queue up here and are applied from the frame loop a few
// at a time, so a burst of arriving components never stalls a frame.

import * as THREE from "three";
import type { BsvtfInfo, TileIndex } from "./bsvtf";
import { TileLayout } from "./cache";
import { FACTOR_CODECS, type FactorInfo, type Layout } from "./factor";
import type { FromWorker, InterpUniforms, ToWorker } from "./protocol";
import { TABLE_WIDTH } from "./protocol";
import { MAX_TILE_LEVELS, factorPart } from "./shader";
import { mlvqFragment, type TextureSpec } from "./mlvq";
import { fetchRange, openStream, type MaterialEntry } from "./stream";

export interface MaterialState {
  id: string;
  bytes: number;
  total: number;
  /** Parts present and in all, counted in `unit` (components; P6 levels for mlvq). */
  components: number;
  totalComponents: number;
  unit: string;
  /** Bytes of the textures this material uploads (the page's shared tile cache not included). */
  gpuBytes: number;
  /** Tables and at least one component (or the whole stream) are on the GPU: objects render. */
  ready: boolean;
  /** The stream ended (completely or at a section boundary). */
  done: boolean;
  complete: boolean;
  error: string | null;
  unsupported: boolean;
  transport: string;
  codec: string | null;
  /** Sections decoded by the worker. */
  sections: number;
  /** Component sections applied to the textures, in order of arrival. */
  applied: string[];
  /** performance.now() when the stream was opened, when the first component was decoded (the
   * material can be drawn), when the last byte arrived, and when the last section was decoded;
   * null until then. */
  times: { start: number; ready: number | null; received: number | null; decoded: number | null };
}

export interface GpuLimits {
  maxTextureSize: number;
  maxArrayLayers: number;
}

/** THREE's format and type of each sized format a codec module's texture may have. */
const TEXTURE_FORMATS: Record<TextureSpec["format"], [THREE.PixelFormat, THREE.TextureDataType]> = {
  R32F: [THREE.RedFormat, THREE.FloatType],
  RG32F: [THREE.RGFormat, THREE.FloatType],
  RGBA32F: [THREE.RGBAFormat, THREE.FloatType],
  R16F: [THREE.RedFormat, THREE.HalfFloatType],
  RGBA16F: [THREE.RGBAFormat, THREE.HalfFloatType],
  R32I: [THREE.RedIntegerFormat, THREE.IntType],
  RG32I: [THREE.RGIntegerFormat, THREE.IntType],
  RGBA32I: [THREE.RGBAIntegerFormat, THREE.IntType],
  R32UI: [THREE.RedIntegerFormat, THREE.UnsignedIntType],
  RGBA32UI: [THREE.RGBAIntegerFormat, THREE.UnsignedIntType],
  R8UI: [THREE.RedIntegerFormat, THREE.UnsignedByteType],
  RGBA8UI: [THREE.RGBAIntegerFormat, THREE.UnsignedByteType],
  R8: [THREE.RedFormat, THREE.UnsignedByteType],
  RGBA8: [THREE.RGBAFormat, THREE.UnsignedByteType],
};

/** The codecs whose packages the viewer renders. */
export const VIEWER_CODECS: string[] = [...FACTOR_CODECS, "mlvq", "bsvtf"];

const emptyInterp = (): InterpUniforms => ({ R: 1, N: 1, T: 0, lifted: 0, triBase: 0, offBase: 0, cellBase: 0, invBase: 0 });

export class MaterialView {
  readonly state: MaterialState;
  /** Shared by the ShaderMaterials of every object showing this material. */
  readonly uniforms: Record<string, THREE.IUniform>;
  info: FactorInfo | null = null;
  layout: Layout | null = null;
  /** The codec part of the surface's fragment shader (shader.ts). */
  readonly codecPart: string;
  /** Packages decoded by a codec module (mlvq): its textures by sampler uniform. */
  private moduleTextures = new Map<string, THREE.DataTexture | THREE.DataArrayTexture>();
  private moduleHeader = false;
  /** Called when something changed that a new frame would show. */
  onChange: () => void = () => {};
  /** Called when bytes arrived (for the HUD; nothing to draw yet). */
  onProgress: () => void = () => {};

  /** null for a material the list already marks as another codec. */
  private worker: Worker | null = null;
  private pending: FromWorker[] = [];
  private stop: (() => void) | null = null;
  private a: THREE.DataArrayTexture | null = null;
  private b: THREE.DataArrayTexture | null = null;
  private means: THREE.DataArrayTexture | null = null;
  private tabF: THREE.DataTexture | null = null;
  private tabI: THREE.DataTexture | null = null;
  private blocks: THREE.DataTexture | null = null;
  private viewGroup: THREE.DataTexture | null = null;
  private texelCluster: THREE.DataTexture | null = null;
  private haveTables = false;
  /** BSVTF packages: the tile fields, layout and index (docs/bsvtf.md); null for fmf. */
  bsvtf: { info: BsvtfInfo; layout: TileLayout; index: TileIndex | null; indirection: THREE.DataTexture } | null = null;
  /** BSVTF: called with each tile the worker decoded (data null and an error when it failed). */
  onTile: (index: number, data: Uint16Array | null, error: string | null) => void = () => {};
  /** BSVTF: called when the tile index arrived. */
  onTileIndex: () => void = () => {};
  private evalId = 0;
  private evalWaiting = new Map<number, (v: Float64Array) => void>();

  constructor(
    readonly entry: MaterialEntry,
    workerUrl: string,
    base: string,
    transport: "auto" | "websocket" | "http",
    private readonly limits: GpuLimits,
  ) {
    this.codecPart = entry.codec === "mlvq" ? mlvqFragment : factorPart;
    this.state = {
      id: entry.id,
      bytes: 0,
      total: entry.bytes ?? 0,
      components: 0,
      totalComponents: 0,
      unit: "components",
      gpuBytes: 0,
      times: { start: performance.now(), ready: null, received: null, decoded: null },
      ready: false,
      done: false,
      complete: false,
      error: null,
      unsupported: false,
      transport: "",
      codec: entry.codec ?? null,
      sections: 0,
      applied: [],
    };
    this.uniforms = {
      uA: { value: null },
      uB: { value: null },
      uMean: { value: null },
      uTabF: { value: null },
      uTabI: { value: null },
      uViews: { value: emptyInterp() },
      uLights: { value: emptyInterp() },
      uPlanes: { value: 1 },
      uChannels: { value: 3 },
      uNL: { value: 1 },
      uBlocks: { value: null },
      uViewGroup: { value: null },
      uTexelCluster: { value: null },
      uGroups: { value: 1 },
      uClusters: { value: 1 },
      uColour: { value: 0 },
      uLog: { value: 0 },
      uLogEps: { value: 0.001 },
      uSize: { value: [1, 1] },
      uMipLevels: { value: 1 },
      uEnvScale: { value: 1 },
    };
    // A codec module's uniforms, declared up front: the objects' shader materials copy this
    // record's entries when they are made.
    for (const m of this.codecPart.matchAll(/^uniform\s+(?:(?:lowp|mediump|highp)\s+)?(\w+)\s+(\w+)\s*;/gm)) {
      const [, type, name] = m;
      const size = { vec2: 2, ivec2: 2, vec3: 3, ivec3: 3, vec4: 4, ivec4: 4 }[type as "vec2"];
      this.uniforms[name] ??= { value: type.includes("sampler") ? null : size ? new Array(size).fill(0) : 0 };
    }
    if (entry.codec === "bsvtf")
      Object.assign(this.uniforms, {
        uIndir: { value: null },
        uAtlas: { value: null },
        uTile: { value: 64 },
        uPad: { value: 4 },
        uLevels: { value: 1 },
        uTilesPerGroup: { value: 1 },
        uLevelBase: { value: new Array(MAX_TILE_LEVELS).fill(0) },
        uTilesX: { value: new Array(MAX_TILE_LEVELS).fill(1) },
      });
    if (entry.codec && !VIEWER_CODECS.includes(entry.codec)) {
      // The list says so already: no need to download the package to refuse it.
      this.state.unsupported = true;
      this.state.error = `${entry.id}: codec '${entry.codec}' is not supported by the viewer (it renders ${VIEWER_CODECS.join(", ")} packages)`;
      this.state.done = true;
      return;
    }
    const worker = new Worker(workerUrl);
    this.worker = worker;
    worker.onmessage = (e: MessageEvent<FromWorker>) => this.receive(e.data);
    worker.onerror = (e: ErrorEvent) => this.setError(`${entry.id}: the decoding worker failed: ${e.message}`, false);
    this.send({ type: "start", name: entry.id });
    if (entry.codec === "bsvtf") {
      this.openPrefix(base);
      return;
    }
    this.stop = openStream(
      entry,
      base,
      {
        total: (n) => {
          this.state.total = n;
        },
        chunk: (data) => {
          this.state.bytes += data.length;
          if (this.state.total > 0 && this.state.bytes >= this.state.total) this.state.times.received ??= performance.now();
          // A copy the worker owns: the stream's buffers may be reused.
          const copy = data.slice();
          this.send({ type: "chunk", data: copy.buffer }, [copy.buffer]);
          this.onProgress();
        },
        end: () => this.send({ type: "end" }),
        error: (message) => this.setError(`${entry.id}: ${message}`, false),
        transport: (kind) => {
          this.state.transport = kind;
        },
      },
      { transport },
    );
  }

  // A BSVTF package: only its prefix up to the tile index comes at once (header, tables, means,
  // tiles.index); U packets and tiles are fetched by byte range as the cache asks for them.
  private openPrefix(base: string): void {
    const entry = this.entry;
    const index = entry.sections?.find((s) => s.name === "tiles.index");
    if (!index) {
      this.setError(`${entry.id}: the material list gives no section 'tiles.index' for this BSVTF package`, false);
      return;
    }
    const abort = new AbortController();
    this.stop = () => abort.abort();
    this.state.transport = "http ranges";
    fetchRange(entry, base, 0, index.offset + index.size, abort.signal).then(
      (data) => {
        this.state.bytes += data.length;
        this.send({ type: "chunk", data: data.buffer as ArrayBuffer }, [data.buffer as ArrayBuffer]);
        this.onProgress();
      },
      (e: Error) => this.setError(`${entry.id}: ${e.message}`, false),
    );
  }

  /** BSVTF: hands a U packet's stored bytes to the worker (it answers with a component). */
  decodePacket(name: string, stored: Uint8Array): void {
    this.state.bytes += stored.length;
    const copy = stored.slice();
    this.send({ type: "packet", name, stored: copy.buffer }, [copy.buffer]);
  }

  /** BSVTF: hands a tile's payload and its parent's data to the worker (it answers onTile). */
  decodeTile(index: number, payload: Uint8Array, parent: Uint16Array | null): void {
    this.state.bytes += payload.length;
    const copy = payload.slice();
    this.send({ type: "tile", index, payload: copy.buffer, parent }, [copy.buffer]);
  }

  private send(message: ToWorker, transfer: Transferable[] = []): void {
    this.worker?.postMessage(message, transfer);
  }

  /** Marks the material as failed (the message names it and the problem). */
  fail(message: string): void {
    this.setError(message, false);
  }

  private setError(message: string, unsupported: boolean): void {
    if (this.state.error) return;
    this.state.error = message;
    this.state.unsupported = unsupported;
    this.state.done = true;
    this.stop?.();
    this.onChange();
  }

  private receive(msg: FromWorker): void {
    switch (msg.type) {
      case "evalResult": {
        const resolve = this.evalWaiting.get(msg.id);
        this.evalWaiting.delete(msg.id);
        resolve?.(msg.values);
        return;
      }
      case "error":
        this.setError(msg.message, msg.unsupported);
        return;
      case "section":
        this.state.sections = msg.index + 1;
        return;
      case "tile":
        this.onTile(msg.index, msg.data, msg.error);
        return;
      default:
        this.pending.push(msg);
        this.onChange();
    }
  }

  /** Whether results wait to be applied. */
  get hasPending(): boolean {
    return this.pending.length > 0;
  }

  /**
   * Applies queued worker results to the textures until `budgetMs` is spent (Infinity: all).
   * Returns whether anything changed.
   */
  applyPending(budgetMs: number): boolean {
    const start = performance.now();
    let changed = false;
    // Results that arrived before an error were checked and still show (a stream cut or damaged
    // after some components renders with those).
    while (this.pending.length > 0) {
      this.apply(this.pending.shift()!);
      changed = true;
      if (performance.now() - start >= budgetMs) break;
    }
    if (changed) this.state.gpuBytes = this.textures().reduce((n, t) => n + (t.image.data as ArrayBufferView).byteLength, 0);
    return changed;
  }

  private apply(msg: FromWorker): void {
    // A header the GPU cannot hold leaves no textures: nothing after it can be applied.
    if (msg.type !== "header" && msg.type !== "codecHeader" && !this.info && !this.moduleHeader) return;
    switch (msg.type) {
      case "codecHeader": {
        this.moduleHeader = true;
        this.state.total = msg.totalBytes;
        this.state.codec = msg.codec;
        this.state.unit = msg.unit;
        this.state.components = msg.present;
        this.state.totalComponents = msg.total;
        this.uniforms.uSize.value = [msg.width, msg.height];
        return;
      }
      case "codecUpdate": {
        for (const spec of msg.textures) if (!this.uploadModuleTexture(spec)) return;
        for (const [name, value] of Object.entries(msg.uniforms)) {
          if (!this.uniforms[name]) throw new Error(`the codec module set uniform '${name}', which its shader part does not declare`);
          this.uniforms[name].value = value;
        }
        this.state.components = msg.present;
        if (msg.ready) this.markReady();
        return;
      }
      case "header":
        return this.applyHeader(msg.info, msg.layout, msg.blocks, msg.totalBytes, msg.bsvtf);
      case "tables": {
        this.tabF = new THREE.DataTexture(msg.tabF, TABLE_WIDTH, msg.tabFHeight, THREE.RGBAFormat, THREE.FloatType);
        this.tabI = new THREE.DataTexture(msg.tabI, TABLE_WIDTH, msg.tabIHeight, THREE.RGBAIntegerFormat, THREE.IntType);
        this.tabI.internalFormat = "RGBA32I";
        for (const t of [this.tabF, this.tabI]) {
          t.minFilter = t.magFilter = THREE.NearestFilter;
          t.generateMipmaps = false;
          t.needsUpdate = true;
        }
        this.uniforms.uTabF.value = this.tabF;
        this.uniforms.uTabI.value = this.tabI;
        this.uniforms.uViews.value = msg.views;
        this.uniforms.uLights.value = msg.lights;
        this.uniforms.uEnvScale.value = msg.envScale;
        this.haveTables = true;
        return;
      }
      case "means": {
        const tex = this.means!;
        (tex.image.data as Float32Array).set(msg.data);
        tex.needsUpdate = true;
        return;
      }
      case "clusters": {
        const tex = this.texelCluster!;
        (tex.image.data as Int32Array).set(msg.data);
        tex.needsUpdate = true;
        return;
      }
      case "component": {
        const L = this.layout!;
        const aSize = L.aWidth * L.aHeight * 4, bSize = L.atlasWidth * L.atlasHeight * 4;
        (this.a!.image.data as Float32Array).set(msg.aLayer, msg.aIndex * aSize);
        this.a!.addLayerUpdate(msg.aIndex);
        this.a!.needsUpdate = true;
        if (msg.bLayer) {
          (this.b!.image.data as Float32Array | Uint16Array).set(msg.bLayer, msg.bIndex * bSize);
          this.b!.addLayerUpdate(msg.bIndex);
          this.b!.needsUpdate = true;
        }
        (this.blocks!.image.data as Int32Array).set(msg.blocks);
        this.blocks!.needsUpdate = true;
        this.state.components = msg.loaded;
        this.state.applied.push(msg.name);
        if (this.haveTables && !this.bsvtf && this.firstPicture(msg.blocks)) this.markReady();
        return;
      }
      case "tileIndex": {
        const b = this.bsvtf!;
        b.index = { weights: msg.weights, sizes: msg.sizes, offsets: msg.offsets };
        if (this.haveTables) this.markReady();
        this.onTileIndex();
        return;
      }
      case "done":
        this.state.done = true;
        this.state.complete = msg.complete;
        if (msg.complete) this.state.times.decoded ??= performance.now();
        if (this.haveTables && this.info) this.markReady();
        return;
    }
  }

  // Whether the components so far make a first picture: any component, and with several view
  // groups (pca-views, the thesis' progressive order) the first component of every group's
  // blocks, so that no view shows its mean alone.
  private firstPicture(blocks: Int32Array): boolean {
    const info = this.info!, layout = this.layout!;
    if (info.groups.length === 1) return true;
    for (let e = 0; e < layout.evalBlocks; ++e) if (layout.aCapacity[e] > 0 && blocks[4 * e + 1] === 0) return false;
    return true;
  }

  private markReady(): void {
    this.state.ready = true;
    this.state.times.ready ??= performance.now();
  }

  private applyHeader(info: FactorInfo, layout: Layout, blocks: Int32Array, totalBytes: number, bsvtf: BsvtfInfo | null): void {
    const { maxTextureSize, maxArrayLayers } = this.limits;
    // A BSVTF material has no eigen-texture atlas: the page's tile cache holds its tiles.
    const atlas = bsvtf ? 0 : Math.max(layout.atlasWidth, layout.atlasHeight);
    if (atlas > maxTextureSize || layout.aWidth > maxTextureSize || layout.aHeight > maxTextureSize)
      return this.setError(
        `${info.name}: ${info.width}×${info.height} texels with ${info.nV} views × ${info.nL} lights need textures larger than this GPU's ${maxTextureSize} texels`,
        true,
      );
    const layers = Math.max(layout.aLayers, layout.bLayers, layout.meanLayers);
    if (layers > maxArrayLayers)
      return this.setError(`${info.name}: ${info.totalComponents} components need ${layers} texture layers, more than this GPU's ${maxArrayLayers}`, true);
    if (bsvtf && !this.applyTileHeader(info, bsvtf)) return;
    this.info = info;
    this.layout = layout;
    this.state.total = bsvtf ? (this.entry.bytes ?? totalBytes) : totalBytes;
    this.state.totalComponents = info.totalComponents;
    this.state.codec = bsvtf ? "bsvtf" : info.codec;
    const make = (data: Float32Array | Uint16Array, w: number, h: number, d: number, format: THREE.PixelFormat, type: THREE.TextureDataType) => {
      const t = new THREE.DataArrayTexture(data, w, h, d);
      t.format = format;
      t.type = type;
      t.minFilter = t.magFilter = THREE.NearestFilter;
      t.generateMipmaps = false;
      t.unpackAlignment = 1;
      t.needsUpdate = true;
      return t;
    };
    this.a = make(new Float32Array(layout.aWidth * layout.aHeight * 4 * layout.aLayers), layout.aWidth, layout.aHeight, layout.aLayers, THREE.RGBAFormat, THREE.FloatType);
    if (!bsvtf) {
      const bSize = layout.atlasWidth * layout.atlasHeight * 4 * layout.bLayers;
      this.b = layout.half
        ? make(new Uint16Array(bSize), layout.atlasWidth, layout.atlasHeight, layout.bLayers, THREE.RGBAFormat, THREE.HalfFloatType)
        : make(new Float32Array(bSize), layout.atlasWidth, layout.atlasHeight, layout.bLayers, THREE.RGBAFormat, THREE.FloatType);
    }
    this.means = make(new Float32Array(layout.aWidth * layout.aHeight * layout.meanLayers), layout.aWidth, layout.aHeight, layout.meanLayers, THREE.RedFormat, THREE.FloatType);
    // Integer lookup tables: the block table, each view's group, each texel's cluster.
    const table = (data: Int32Array, w: number, h: number, rgba: boolean) => {
      const t = new THREE.DataTexture(data, w, h, rgba ? THREE.RGBAIntegerFormat : THREE.RedIntegerFormat, THREE.IntType);
      t.internalFormat = rgba ? "RGBA32I" : "R32I";
      t.minFilter = t.magFilter = THREE.NearestFilter;
      t.generateMipmaps = false;
      t.unpackAlignment = 1;
      t.needsUpdate = true;
      return t;
    };
    const rows = (n: number) => Math.max(1, Math.ceil(n / TABLE_WIDTH));
    const blockData = new Int32Array(TABLE_WIDTH * rows(layout.evalBlocks) * 4);
    blockData.set(blocks);
    this.blocks = table(blockData, TABLE_WIDTH, rows(layout.evalBlocks), true);
    const groupData = new Int32Array(TABLE_WIDTH * rows(info.nV));
    groupData.set(info.groupOfView);
    this.viewGroup = table(groupData, TABLE_WIDTH, rows(info.nV), false);
    this.texelCluster = info.clusters > 1 ? table(new Int32Array(info.width * info.height), info.width, info.height, false) : table(new Int32Array(1), 1, 1, false);
    const u = this.uniforms;
    u.uA.value = this.a;
    u.uB.value = this.b;
    u.uMean.value = this.means;
    u.uPlanes.value = info.planes;
    u.uChannels.value = info.channels;
    u.uNL.value = info.nL;
    u.uBlocks.value = this.blocks;
    u.uViewGroup.value = this.viewGroup;
    u.uTexelCluster.value = this.texelCluster;
    u.uGroups.value = info.groups.length;
    u.uClusters.value = info.clusters;
    u.uColour.value = { rgb: 0, decorrelated: 1, "per-channel": 2, model11: 3, lab: 4 }[info.colour];
    u.uLog.value = info.log ? 1 : 0;
    u.uLogEps.value = info.logEps;
    u.uSize.value = [info.width, info.height];
    u.uMipLevels.value = layout.mipLevels;
  }

  // A BSVTF package's tile layout, its indirection texture (tile index → cache layer) and the
  // uniforms the shader's cache lookup reads; false (and the material's error) when the viewer
  // cannot show it.
  private applyTileHeader(info: FactorInfo, b: BsvtfInfo): boolean {
    const tiles = new TileLayout(b.width, b.height, b.tile, b.pad, b.groups);
    if (tiles.levels > MAX_TILE_LEVELS) {
      this.setError(`${info.name}: ${tiles.levels} tile levels, more than the viewer's ${MAX_TILE_LEVELS}`, true);
      return false;
    }
    if (tiles.tilesX(0) > 255 || tiles.tilesY(0) > 255) {
      this.setError(`${info.name}: ${tiles.tilesX(0)} × ${tiles.tilesY(0)} tiles per level, more than the feedback pass can name (255)`, true);
      return false;
    }
    const width = Math.min(tiles.tileCount, TABLE_WIDTH), height = Math.ceil(tiles.tileCount / TABLE_WIDTH);
    const indirection = new THREE.DataTexture(new Int32Array(width * height).fill(-1), width, height, THREE.RedIntegerFormat, THREE.IntType);
    indirection.internalFormat = "R32I";
    indirection.minFilter = indirection.magFilter = THREE.NearestFilter;
    indirection.generateMipmaps = false;
    indirection.needsUpdate = true;
    this.bsvtf = { info: b, layout: tiles, index: null, indirection };
    const u = this.uniforms;
    u.uIndir.value = indirection;
    u.uTile.value = b.tile;
    u.uPad.value = b.pad;
    u.uLevels.value = tiles.levels;
    u.uTilesPerGroup.value = tiles.tilesPerGroup;
    u.uLevelBase.value = Array.from({ length: MAX_TILE_LEVELS }, (_, l) => tiles.levelBase[l] ?? 0);
    u.uTilesX.value = Array.from({ length: MAX_TILE_LEVELS }, (_, l) => (l < tiles.levels ? tiles.tilesX(l) : 1));
    return true;
  }

  /** BSVTF: the indirection texture now shows `slots` (per tile index: a cache layer or −1). */
  setIndirection(slots: Int32Array): void {
    const tex = this.bsvtf!.indirection;
    (tex.image.data as Int32Array).set(slots);
    tex.needsUpdate = true;
  }

  /** The CPU evaluator's values (linear RGB per query; see ToWorker "eval"). */
  evaluate(queries: Float64Array, environment: boolean): Promise<Float64Array> {
    const id = ++this.evalId;
    return new Promise((resolve) => {
      if (!this.worker) return resolve(new Float64Array(3 * (queries.length / 8)).fill(NaN));
      this.evalWaiting.set(id, resolve);
      this.send({ type: "eval", id, queries, environment });
    });
  }

  // Creates or refills the texture of a codec module's sampler; false (and the material's error)
  // when the GPU cannot hold it.
  private uploadModuleTexture(spec: TextureSpec): boolean {
    const { maxTextureSize, maxArrayLayers } = this.limits;
    if (spec.width > maxTextureSize || spec.height > maxTextureSize || spec.depth > maxArrayLayers) {
      this.setError(`${this.entry.id}: texture ${spec.uniform} of ${spec.width} × ${spec.height} × ${spec.depth} texels exceeds this GPU's limits (${maxTextureSize} texels, ${maxArrayLayers} layers)`, true);
      return false;
    }
    let tex = this.moduleTextures.get(spec.uniform);
    if (tex && (tex.image.width !== spec.width || tex.image.height !== spec.height)) {
      tex.dispose();
      tex = undefined;
    }
    if (!tex) {
      const [format, type] = TEXTURE_FORMATS[spec.format];
      tex =
        spec.kind === "2d"
          ? new THREE.DataTexture(spec.data, spec.width, spec.height, format, type)
          : new THREE.DataArrayTexture(spec.data, spec.width, spec.height, spec.depth);
      tex.format = format;
      tex.type = type;
      tex.internalFormat = spec.format;
      tex.minFilter = tex.magFilter = THREE.NearestFilter;
      tex.generateMipmaps = false;
      tex.unpackAlignment = 1;
      this.moduleTextures.set(spec.uniform, tex);
      if (!this.uniforms[spec.uniform]) throw new Error(`the codec module made texture '${spec.uniform}', which its shader part does not declare`);
      this.uniforms[spec.uniform].value = tex;
    } else {
      tex.image.data = spec.data as never;
    }
    tex.needsUpdate = true;
    return true;
  }

  /** The textures this material owns. */
  private textures(): (THREE.DataTexture | THREE.DataArrayTexture)[] {
    const all = [this.a, this.b, this.means, this.tabF, this.tabI, this.blocks, this.viewGroup, this.texelCluster, this.bsvtf?.indirection, ...this.moduleTextures.values()];
    return all.filter((t): t is THREE.DataTexture | THREE.DataArrayTexture => !!t);
  }

  dispose(): void {
    this.stop?.();
    this.worker?.terminate();
    for (const t of this.textures()) t.dispose();
  }
}
