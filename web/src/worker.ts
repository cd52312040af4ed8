// SPDX-License-Identifier: MIT
// The decoding worker: parses one material's package bytes as they arrive, checks and
// decompresses each section, decodes the factors and packs them into texture layers, so that the
// page only copies finished layers into textures and its frame loop never waits on decoding.

import {
  FactorModel,
  UnsupportedMaterial,
  blockIndex,
  columnBytes,
  columnHalfBits,
  evalBlockOf,
  groupRows,
  makeLayout,
  mipChain,
  readFactorHeader,
  storedRows,
  upsampleLevel,
  type FactorInfo,
  type Layout,
} from "./factor";
import { MlvqDecoder, readMlvqHeader } from "./mlvq";
import { decodeTile, layoutOf, predictChild, readBsvtfHeader, readTileIndex, type BsvtfInfo } from "./bsvtf";
import type { TileLayout } from "./cache";
import { floatToHalf, halfToFloat } from "./half";
import { lookup, readTablesSection, uniformEnvironmentWeights, type InterpTables } from "./interp";
import { PackageStream, loadChecksum, type Checksum, type DecodedSection, type PackageHeader } from "./package";
import { TABLE_WIDTH, type FromWorker, type InterpUniforms, type ToWorker } from "./protocol";

const ctx = self as unknown as {
  postMessage(message: FromWorker, transfer?: Transferable[]): void;
  onmessage: ((event: MessageEvent<ToWorker>) => void) | null;
};

let name = "material";
let stream: PackageStream | null = null;
let info: FactorInfo | null = null;
let layout: Layout | null = null;
let model: FactorModel | null = null;
let tables: { views: InterpTables; lights: InterpTables } | null = null;
/** Environment weight per light (normalized to sum 1 for log models). */
let envWeights: Float64Array | null = null;
let aLayers: Float32Array[] = [];
let bLayers: (Float32Array | Uint16Array)[] = [];
/** Per eval block: aBase, layers holding loaded components, bBase, means layer (Layout "Blocks"). */
let blockTable: Int32Array = new Int32Array(0);
let failed = false;
/** BSVTF packages: the tile fields and layout (null for fmf packages). */
let bsvtf: BsvtfInfo | null = null;
let tileLayout: TileLayout | null = null;
let header: PackageHeader | null = null;
/** mlvq packages: the codec module that decodes them (null for the factor codecs). */
let mlvq: MlvqDecoder | null = null;

// The checksum's WebAssembly module is instantiated once, when the worker starts; messages that
// arrive before it is ready wait in `pending` and are then handled in order.
let xxh64: Checksum | null = null;
let checksumError = "";
let pending: ToWorker[] | null = [];

function post(message: FromWorker, transfer: Transferable[] = []): void {
  ctx.postMessage(message, transfer);
}

function fail(e: unknown): void {
  if (failed) return;
  failed = true;
  const err = e as Error;
  const message = err && err.message ? err.message : String(e);
  post({ type: "error", message: message.startsWith(name) ? message : `${name}: ${message}`, unsupported: e instanceof UnsupportedMaterial });
}

function onHeader(h: PackageHeader): void {
  header = h;
  if (h.json.codec === "mlvq") {
    mlvq = new MlvqDecoder(readMlvqHeader(name, h.json));
    const p = mlvq.progress();
    post({
      type: "codecHeader",
      codec: "mlvq",
      width: mlvq.info.materials[0].width,
      height: mlvq.info.materials[0].height,
      totalBytes: h.totalBytes,
      sections: h.sections.map((s) => ({ name: s.name, offset: h.headerBytes + s.offset, size: s.size })),
      present: p.present,
      total: p.total,
      unit: p.unit,
    });
    return;
  }
  if (h.json.codec === "bsvtf") {
    // A BSVTF package (docs/bsvtf.md): the fmf header of its source describes the angular part;
    // the eigen-textures come as tiles (requested by the page), the angular factors as U packets.
    try {
      bsvtf = readBsvtfHeader(h.json);
      tileLayout = layoutOf(bsvtf);
    } catch (e) {
      throw new Error(`${name}: package (bsvtf): ${(e as Error).message}`);
    }
    const source = h.json.source;
    if (!source || typeof source !== "object") throw new Error(`${name}: package (bsvtf): header field 'source' is missing`);
    info = readFactorHeader(name, source as Record<string, unknown>);
  } else {
    info = readFactorHeader(name, h.json);
  }
  layout = makeLayout(info);
  model = new FactorModel(info);
  const L = layout;
  if (bsvtf) {
    if (info.groups.length > 1 || info.clusters > 1 || info.levels > 1 || info.angularLevels.length > 0)
      throw new UnsupportedMaterial(`${name}: a BSVTF package of a ${info.codec} model with view groups, clusters or levels is not supported by the viewer`);
    // The shader reads group g's four components from a-layer g.
    bsvtf.groups.forEach((g, gi) => {
      if (L.layerBase[g.plane] + (g.first >> 2) !== gi || g.first % 4 !== 0)
        throw new UnsupportedMaterial(`${name}: component group ${gi} (plane ${g.plane}, components ${g.first}…) does not match the viewer's layers`);
    });
  }
  const aSize = L.aWidth * L.aHeight * 4;
  const bSize = bsvtf ? 0 : L.atlasWidth * L.atlasHeight * 4;
  aLayers = Array.from({ length: L.aLayers }, () => new Float32Array(aSize));
  bLayers = Array.from({ length: bsvtf ? 0 : L.bLayers }, () => (L.half ? new Uint16Array(bSize) : new Float32Array(bSize)));
  blockTable = new Int32Array(4 * L.evalBlocks);
  for (let e = 0; e < L.evalBlocks; ++e) {
    const pg = Math.floor(e / info.clusters);
    blockTable.set([L.aBase[e], bsvtf ? L.aCapacity[e] : 0, bsvtf ? L.aBase[e] : L.bBase[pg], Math.floor(pg / info.groups.length) * info.clusters + (e % info.clusters)], 4 * e);
  }
  post({
    type: "header",
    info,
    layout: L,
    blocks: blockTable.slice(),
    totalBytes: h.totalBytes,
    sections: h.sections.map((s) => ({ name: s.name, offset: h.headerBytes + s.offset, size: s.size })),
    bsvtf,
  });
}

// Writes component k of block `block` (its a column at every row of its group) into its a-layer
// lane, with the environment column; returns the layer and the lane.
function packA(block: number, k: number, a: Float32Array): { layer: number; lane: number } {
  const i = info!, L = layout!;
  const b = i.blocks[block];
  const e = evalBlockOf(i, b), index = L.laneOffset[block] + k;
  const layer = L.aBase[e] + (index >> 2), lane = index & 3;
  const C = i.channels, nL = i.nL, W = L.aWidth;
  const aLayer = aLayers[layer];
  for (const v of i.groups[b.group]) {
    const slot = i.slotOfView[v];
    for (let ch = 0; ch < C; ++ch) {
      let env = 0;
      for (let l = 0; l < nL; ++l) {
        const x = a[(slot * nL + l) * C + ch];
        aLayer[(v * W + l * C + ch) * 4 + lane] = x;
        env += envWeights![l] * x;
      }
      aLayer[(v * W + nL * C + ch) * 4 + lane] = env;
    }
  }
  blockTable[4 * e + 1] = Math.max(blockTable[4 * e + 1], (index >> 2) + 1);
  return { layer, lane };
}

let packetsLoaded = 0;

// A U packet u<g>: the a columns of group g's components (file.h), f16 or f32.
function onPacket(packetName: string, stored: Uint8Array): void {
  const b = bsvtf!, i = info!;
  const m = /^u(\d+)$/.exec(packetName);
  const entry = header!.sections.find((s) => s.name === packetName);
  if (!m || !entry || Number(m[1]) >= b.groups.length) throw new Error(`package (bsvtf): no U packet '${packetName}'`);
  if (!envWeights) throw new Error(`section '${packetName}' arrives before section 'tables' (the viewer needs the tables first)`);
  const data = stream!.decodeSection(entry, stored, header!.headerBytes + entry.offset);
  const g = b.groups[Number(m[1])];
  const rows = groupRows(i, 0), size = b.uFormat === "f16" ? 2 : 4;
  if (data.length !== rows * g.count * size) throw new Error(`section '${packetName}' holds ${data.length} bytes, expected ${rows * g.count * size}`);
  const view = new DataView(data.buffer, data.byteOffset, data.byteLength);
  let layer = 0;
  for (let c = 0; c < g.count; ++c) {
    const a = new Float32Array(rows);
    for (let r = 0; r < rows; ++r) {
      const at = (c * rows + r) * size;
      a[r] = size === 2 ? halfToFloat(view.getUint16(at, true)) : view.getFloat32(at, true);
    }
    layer = packA(blockIndex(i, g.plane, 0, 0), g.first + c, a).layer;
  }
  packetsLoaded += g.count;
  const aCopy = aLayers[layer].slice();
  const blocks = blockTable.slice();
  post({ type: "component", name: packetName, aIndex: layer, aLayer: aCopy, bIndex: -1, bLayer: null, blocks, loaded: packetsLoaded }, [aCopy.buffer, blocks.buffer]);
}

async function onTile(index: number, payload: Uint8Array, parent: Uint16Array | null): Promise<void> {
  const L = tileLayout!;
  try {
    const id = L.id(index);
    if (L.hasParent(id) !== (parent !== null)) throw new Error("tile: the parent's data is missing");
    const prediction = parent ? predictChild(parent, L, id) : null;
    const data = await decodeTile(payload, prediction, L);
    post({ type: "tile", index, data, error: null }, [data.buffer]);
  } catch (e) {
    post({ type: "tile", index, data: null, error: `${name}: tile ${index}: ${(e as Error).message}` });
  }
}

// Packs both direction sets into one float texture (inverse rows) and one int texture
// (triangles, cell offsets, cell triangles), 4 values per texel.
function packTables(views: InterpTables, lights: InterpTables): FromWorker & { type: "tables" } {
  let fTexels = 0, iTexels = 0;
  const place = (t: InterpTables): InterpUniforms => {
    const u: InterpUniforms = {
      R: t.R,
      N: t.N,
      T: t.T,
      lifted: t.lifted ? 1 : 0,
      invBase: fTexels,
      triBase: iTexels,
      offBase: iTexels + t.T,
      cellBase: iTexels + t.T + Math.ceil((t.R * t.R + 1) / 4),
    };
    fTexels += 3 * t.T;
    iTexels = u.cellBase + Math.ceil(t.M / 4);
    return u;
  };
  const vu = place(views), lu = place(lights);
  const tabFHeight = Math.ceil(fTexels / TABLE_WIDTH), tabIHeight = Math.ceil(iTexels / TABLE_WIDTH);
  const tabF = new Float32Array(TABLE_WIDTH * tabFHeight * 4);
  const tabI = new Int32Array(TABLE_WIDTH * tabIHeight * 4);
  const fill = (t: InterpTables, u: InterpUniforms) => {
    for (let i = 0; i < t.T; ++i)
      for (let r = 0; r < 3; ++r)
        for (let c = 0; c < 3; ++c) tabF[(u.invBase + 3 * i + r) * 4 + c] = t.inverse[9 * i + 3 * r + c];
    for (let i = 0; i < t.T; ++i) for (let c = 0; c < 3; ++c) tabI[(u.triBase + i) * 4 + c] = t.triangles[3 * i + c];
    tabI.set(t.cellOffsets, u.offBase * 4);
    tabI.set(t.cellTriangles, u.cellBase * 4);
  };
  fill(views, vu);
  fill(lights, lu);
  const c = envWeights!;
  let total = 0;
  for (const x of c) total += x;
  return { type: "tables", tabF, tabFHeight, tabI, tabIHeight, views: vu, lights: lu, envScale: info!.log ? total : 1 };
}

function onSection(s: DecodedSection): void {
  post({ type: "section", name: s.entry.name, index: s.index, end: s.fileOffset + s.entry.size });
  if (mlvq) {
    mlvq.addSection(s.entry.name, s.data);
    // Copies: the decoder keeps its arrays and fills them further with later sections.
    const textures = mlvq.textures().map((t) => ({ ...t, data: t.data.slice() }));
    post({ type: "codecUpdate", textures, uniforms: mlvq.uniforms(), ready: mlvq.ready, present: mlvq.progress().present }, textures.map((t) => t.data.buffer));
    return;
  }
  const i = info!, L = layout!, m = model!;
  const sectionName = s.entry.name;
  if (sectionName === "tables") {
    tables = readTablesSection(s.data, i.nV, i.nL);
    envWeights = uniformEnvironmentWeights(tables.lights);
    if (i.log) {
      // Log models interpolate log values: the environment term averages them with normalized
      // weights and scales the decoded value by Σ c_l instead (a geometric-mean approximation).
      let total = 0;
      for (const x of envWeights) total += x;
      for (let l = 0; l < envWeights.length; ++l) envWeights[l] /= total;
    }
    const msg = packTables(tables.views, tables.lights);
    post(msg, [msg.tabF.buffer, msg.tabI.buffer]);
    return;
  }
  if (sectionName === "angular") {
    m.setAngular(s.data);
    return;
  }
  if (sectionName === "clusters") {
    m.setClusters(s.data);
    const clusters = m.cluster!.slice();
    post({ type: "clusters", data: clusters }, [clusters.buffer]);
    return;
  }
  if (sectionName === "means") {
    if (!envWeights) throw new Error("section 'means' arrives before section 'tables' (the viewer needs the tables first)");
    m.setMeans(s.data);
    // Each eval block's means layer holds the sum of its blocks' means (every level's bilinear
    // weights sum to one, so their means add).
    const C = i.channels, nL = i.nL, W = L.aWidth;
    const data = new Float32Array(W * L.aHeight * L.meanLayers);
    i.blocks.forEach((b, bi) => {
      const mean = m.means[bi];
      if (!mean) return;
      const layer = b.plane * i.clusters + b.cluster;
      for (const v of i.groups[b.group]) {
        const slot = i.slotOfView[v];
        for (let ch = 0; ch < C; ++ch) {
          let env = 0;
          for (let l = 0; l < nL; ++l) {
            const x = mean[(slot * nL + l) * C + ch];
            data[(layer * L.aHeight + v) * W + l * C + ch] += x;
            env += envWeights![l] * x;
          }
          data[(layer * L.aHeight + v) * W + nL * C + ch] += env;
        }
      }
    });
    post({ type: "means", data }, [data.buffer]);
    return;
  }
  if (sectionName === "tiles.index" && bsvtf) {
    const tiles = header!.sections.find((x) => x.name === "tiles");
    if (!tiles || tiles.coding !== "raw") throw new Error("package (bsvtf): section 'tiles' is missing or not stored raw (its tiles are fetched by byte range)");
    const index = readTileIndex(s.data, bsvtf.tiles, tiles.size);
    post({ type: "tileIndex", ...index }, [index.weights.buffer, index.sizes.buffer, index.offsets.buffer]);
    return;
  }
  if (!/^b\d+\.k\d+$/.test(sectionName)) return; // sections of no concern to the viewer
  if (!envWeights) throw new Error(`section '${sectionName}' arrives before section 'tables' (the viewer needs the tables first)`);
  const { block, k } = m.addComponent(sectionName, s.data);
  const b = i.blocks[block];
  const { layer, lane } = packA(block, k, m.a[block][k]);
  const bIndex = L.bBase[b.plane * i.groups.length + b.group] + (layer - L.aBase[evalBlockOf(i, b)]);
  const bLayer = bLayers[bIndex];
  const stored = m.b[block][k];
  if (i.clusters > 1) {
    // Each texel of the block's cluster gets its own value; the other texels keep their clusters'.
    const cluster = m.cluster!, local = m.local!;
    for (let t = 0; t < cluster.length; ++t) {
      if (cluster[t] !== b.cluster) continue;
      const at = t * 4 + lane; // no mip chain: the atlas is W × H
      bLayer[at] = L.half ? floatToHalf(stored[local[t]]) : stored[local[t]];
    }
  } else {
    const full = b.level > 0 ? upsampleLevel(i, stored, b.level) : stored;
    const mips = mipChain(L, full);
    // f16 packages: level 0 of a full-resolution block keeps the stored half bits (exact); the
    // averaged and up-sampled levels are rounded.
    const level0Bits = i.quantization === "f16" && b.level === 0 ? columnHalfBits(s.data, columnBytes("f16", storedRows(i, b)), i.width * i.height) : null;
    mips.forEach((level, mi) => {
      const r = L.mips[mi];
      for (let y = 0; y < r.h; ++y)
        for (let x = 0; x < r.w; ++x) {
          const at = ((r.y + y) * L.atlasWidth + r.x + x) * 4 + lane;
          const src = y * r.w + x;
          if (level0Bits && mi === 0) bLayer[at] = level0Bits[src];
          else bLayer[at] = L.half ? floatToHalf(level[src]) : level[src];
        }
    });
  }
  const aCopy = aLayers[layer].slice(), bCopy = bLayer.slice(), blocks = blockTable.slice();
  post({ type: "component", name: sectionName, aIndex: layer, aLayer: aCopy, bIndex, bLayer: bCopy, blocks, loaded: m.loadedComponents }, [
    aCopy.buffer,
    bCopy.buffer,
    blocks.buffer,
  ]);
}

function evaluate(id: number, q: Float64Array, environment: boolean): void {
  const n = Math.floor(q.length / 8);
  const values = new Float64Array(3 * n).fill(NaN);
  if (mlvq && mlvq.ready && !failed) {
    for (let j = 0; j < n; ++j) {
      const o = 8 * j;
      const wo: [number, number, number] = [q[o + 5], q[o + 6], q[o + 7]];
      values.set(environment ? mlvq.albedo(q[o], q[o + 1], wo) : mlvq.eval(q[o], q[o + 1], [q[o + 2], q[o + 3], q[o + 4]], wo), 3 * j);
    }
  } else if (model && tables && envWeights && !failed) {
    for (let j = 0; j < n; ++j) {
      const o = 8 * j;
      const vw = lookup(tables.views, q[o + 5], q[o + 6], q[o + 7]);
      if (environment) {
        values.set(model.evalEnvironment(q[o], q[o + 1], vw, envWeights), 3 * j);
      } else {
        const lw = lookup(tables.lights, q[o + 2], q[o + 3], q[o + 4]);
        values.set(model.evalWeights(q[o], q[o + 1], vw, lw), 3 * j);
      }
    }
  }
  post({ type: "evalResult", id, values }, [values.buffer]);
}

function handle(msg: ToWorker): void {
  try {
    switch (msg.type) {
      case "start":
        name = msg.name;
        if (!xxh64) throw new Error(`cannot check the package: the XXH64 WebAssembly module (xxhash-wasm) did not load: ${checksumError}`);
        stream = new PackageStream(name, { header: onHeader, section: onSection }, xxh64);
        return;
      case "chunk":
        if (!failed && stream) stream.push(new Uint8Array(msg.data));
        return;
      case "end":
        if (!failed && stream) {
          const complete = stream.end();
          post({ type: "done", complete, sections: stream.sectionsDone, declared: stream.header?.sections.length ?? 0 });
        }
        return;
      case "eval":
        evaluate(msg.id, msg.queries, msg.environment);
        return;
      case "packet":
        if (!failed && bsvtf) onPacket(msg.name, new Uint8Array(msg.stored));
        return;
      case "tile":
        // Always answered, so that the page never waits for a tile of a failed material.
        if (failed || !tileLayout) post({ type: "tile", index: msg.index, data: null, error: `${name}: tile ${msg.index}: the material failed before it` });
        else void onTile(msg.index, new Uint8Array(msg.payload), msg.parent);
        return;
    }
  } catch (e) {
    fail(e);
  }
}

function drainPending(): void {
  const queued = pending ?? [];
  pending = null;
  for (const msg of queued) handle(msg);
}

loadChecksum().then(
  (c) => {
    xxh64 = c;
    drainPending();
  },
  (e: unknown) => {
    checksumError = e instanceof Error ? e.message : String(e);
    drainPending();
  },
);

ctx.onmessage = (event: MessageEvent<ToWorker>) => {
  if (pending) pending.push(event.data);
  else handle(event.data);
};
