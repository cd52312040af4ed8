// SPDX-License-Identifier: MIT
// The BSVTF tile cache of the viewer's BSVTF mode: a port of src/btf/bsvtf/cache.{h,cpp} (tile
// layout, votes of equation 9, add and swap, the decision rule of §5.2). The decisions must be the
// C++ ones exactly — same candidates, same arithmetic, same order and tie-breaking — and a unit
// test replays the C++ decisions recorded in web/test/data/cache-trace.json. Levels count from the
// finest (0); the paper's l is L − j.

import { wrapLerp } from "./factor";

export interface TileId {
  group: number;
  level: number;
  x: number;
  y: number;
}

export interface TileKey extends TileId {
  material: number;
}

export interface Group {
  plane: number;
  first: number;
  count: number;
}

/** TileLayout of pyramid.h: levels, tiles per level, and the dense tile numbering. */
export class TileLayout {
  readonly levels: number;
  readonly tilesPerGroup: number;
  readonly levelBase: number[] = [];

  constructor(
    readonly width: number,
    readonly height: number,
    readonly tile: number,
    readonly pad: number,
    readonly groups: Group[],
  ) {
    if (tile < 8 || pad < 2 || (tile + 2 * pad) % 8 !== 0) throw new Error(`tile size ${tile} with padding ${pad} cannot be used`);
    let levels = 1;
    while (Math.max(width >> (levels - 1), height >> (levels - 1)) > tile) ++levels;
    const divisor = 1 << (levels - 1);
    if (width % divisor !== 0 || height % divisor !== 0)
      throw new Error(`${width} × ${height} texels are not divisible by ${divisor} (${levels} levels of tiles of ${tile})`);
    this.levels = levels;
    let n = 0;
    for (let level = 0; level < levels; ++level) {
      this.levelBase.push(n);
      n += this.tilesX(level) * this.tilesY(level);
    }
    this.tilesPerGroup = n;
  }

  get stride(): number {
    return this.tile + 2 * this.pad;
  }
  /** Half floats of one tile: stride² texels × 4 channels. */
  get values(): number {
    return this.stride * this.stride * 4;
  }
  get tileCount(): number {
    return this.tilesPerGroup * this.groups.length;
  }
  levelWidth(level: number): number {
    return this.width >> level;
  }
  levelHeight(level: number): number {
    return this.height >> level;
  }
  tilesX(level: number): number {
    return Math.ceil(this.levelWidth(level) / this.tile);
  }
  tilesY(level: number): number {
    return Math.ceil(this.levelHeight(level) / this.tile);
  }
  index(t: TileId): number {
    return t.group * this.tilesPerGroup + this.levelBase[t.level] + t.y * this.tilesX(t.level) + t.x;
  }
  id(index: number): TileId {
    const group = Math.floor(index / this.tilesPerGroup);
    let rest = index % this.tilesPerGroup;
    let level = 0;
    while (level + 1 < this.levels && rest >= this.levelBase[level + 1]) ++level;
    rest -= this.levelBase[level];
    const tx = this.tilesX(level);
    return { group, level, x: rest % tx, y: Math.floor(rest / tx) };
  }
  hasParent(t: TileId): boolean {
    return t.level + 1 < this.levels;
  }
  parent(t: TileId): TileId {
    return { group: t.group, level: t.level + 1, x: t.x >> 1, y: t.y >> 1 };
  }
}

/** TileKey's order in C++ (material, group, level, x, y). */
export function compareKeys(a: TileKey, b: TileKey): number {
  return a.material - b.material || a.group - b.group || a.level - b.level || a.x - b.x || a.y - b.y;
}

const sameKey = (a: TileKey, b: TileKey) => compareKeys(a, b) === 0;

/** Feedback votes of one frame, per material and tile position (shared by the groups). */
export class Votes {
  private readonly votes: Uint32Array[];

  constructor(private readonly layouts: TileLayout[]) {
    this.votes = layouts.map((l) => new Uint32Array(l.tilesPerGroup));
  }

  clear(): void {
    for (const v of this.votes) v.fill(0);
  }

  /** One feedback pixel: `material` seen at `level` (clamped) at texture coordinates (u, v). */
  add(material: number, level: number, u: number, v: number): void {
    const l = this.layouts[material];
    level = Math.min(Math.max(level, 0), l.levels - 1);
    const x = wrapLerp(u, l.levelWidth(level)), y = wrapLerp(v, l.levelHeight(level));
    this.addTile(material, level, Math.floor(x.i0 / l.tile), Math.floor(y.i0 / l.tile));
  }

  /** A vote for tile (x, y) of `level` and each of its ancestors. */
  addTile(material: number, level: number, x: number, y: number): void {
    const l = this.layouts[material];
    const votes = this.votes[material];
    let t: TileId = { group: 0, level, x, y };
    for (;;) {
      ++votes[l.index(t)];
      if (!l.hasParent(t)) break;
      t = l.parent(t);
    }
  }

  get(material: number, t: TileId): number {
    return this.votes[material][this.layouts[material].index({ group: 0, level: t.level, x: t.x, y: t.y })];
  }
}

export interface Operation {
  kind: "add" | "swap";
  /** Added, or the ancestor coming in. */
  tile: TileKey;
  out?: [TileKey, TileKey];
  /** P of the add, or c of the swap. */
  value: number;
}

export interface Decision {
  operations: Operation[];
  /** A swap's ancestor to ask for (see TileCache::Decision). */
  wanted: TileKey | null;
}

interface MaterialSlots {
  layout: TileLayout;
  weights: ArrayLike<number>;
  slot: Int32Array;
}

/** TileCache of cache.h: fixed slots shared by every material, filled by add and swap. */
export class TileCache {
  private readonly materials: MaterialSlots[];
  private readonly free: number[] = [];
  private count = 0;

  constructor(layouts: TileLayout[], weights: ArrayLike<number>[], readonly capacity: number) {
    if (layouts.length !== weights.length) throw new Error("TileCache: one weight list per layout");
    let coarsest = 0;
    this.materials = layouts.map((l, i) => {
      if (weights[i].length !== l.tileCount) throw new Error("TileCache: the weights do not match the layout");
      coarsest += l.groups.length * l.tilesX(l.levels - 1) * l.tilesY(l.levels - 1);
      return { layout: l, weights: weights[i], slot: new Int32Array(l.tileCount).fill(-1) };
    });
    if (coarsest > capacity) throw new Error(`a cache of ${capacity} tiles cannot hold the coarsest level of every material (${coarsest} tiles)`);
    for (let s = capacity - 1; s >= 0; --s) this.free.push(s);
    this.materials.forEach((m, mi) => {
      const l = m.layout, top = l.levels - 1;
      for (let g = 0; g < l.groups.length; ++g)
        for (let y = 0; y < l.tilesY(top); ++y) for (let x = 0; x < l.tilesX(top); ++x) this.insert({ material: mi, group: g, level: top, x, y });
    });
  }

  get size(): number {
    return this.count;
  }

  layout(material: number): TileLayout {
    return this.materials[material].layout;
  }

  /** The slot per tile index of a material (−1: not resident), for the indirection texture. */
  slots(material: number): Int32Array {
    return this.materials[material].slot;
  }

  slot(t: TileKey): number {
    const m = this.materials[t.material];
    return m.slot[m.layout.index(t)];
  }

  resident(t: TileKey): boolean {
    return this.slot(t) >= 0;
  }

  tiles(): TileKey[] {
    const out: TileKey[] = [];
    this.materials.forEach((m, mi) => {
      for (let i = 0; i < m.slot.length; ++i) if (m.slot[i] >= 0) out.push({ material: mi, ...m.layout.id(i) });
    });
    return out;
  }

  private weight(t: TileKey): number {
    const m = this.materials[t.material];
    return m.weights[m.layout.index(t)];
  }

  priority(t: TileKey, votes: Votes): number {
    return this.weight(t) * votes.get(t.material, t);
  }

  private children(m: MaterialSlots, t: TileId): TileId[] {
    const out: TileId[] = [];
    if (t.level === 0) return out;
    const l = m.layout;
    for (let dy = 0; dy < 2; ++dy)
      for (let dx = 0; dx < 2; ++dx) {
        const c = { group: t.group, level: t.level - 1, x: 2 * t.x + dx, y: 2 * t.y + dy };
        if (c.x < l.tilesX(c.level) && c.y < l.tilesY(c.level)) out.push(c);
      }
    return out;
  }

  private coveredBelow(m: MaterialSlots, t: TileId): boolean {
    const kids = this.children(m, t);
    if (kids.length === 0) return false;
    return kids.every((c) => m.slot[m.layout.index(c)] >= 0 || this.coveredBelow(m, c));
  }

  /** Calls fn(tile, P) for every add candidate with P > 0, in the C++ order. */
  forEachAddCandidate(votes: Votes, fn: (t: TileKey, p: number) => void): void {
    this.materials.forEach((m, mi) => {
      for (let i = 0; i < m.slot.length; ++i) {
        if (m.slot[i] < 0) continue;
        for (const c of this.children(m, m.layout.id(i))) {
          if (m.slot[m.layout.index(c)] >= 0 || this.coveredBelow(m, c)) continue;
          const key = { material: mi, ...c };
          const p = this.priority(key, votes);
          if (p > 0) fn(key, p);
        }
      }
    });
  }

  bestAdd(votes: Votes, skip: (t: TileKey) => boolean = () => false): Operation | null {
    let best: Operation | null = null;
    this.forEachAddCandidate(votes, (key, p) => {
      if (!skip(key) && (!best || p > best.value)) best = { kind: "add", tile: key, value: p };
    });
    return best;
  }

  cheapestSwap(votes: Votes): Operation | null {
    interface Two {
      ancestor: TileKey;
      cost: [number, number];
      tile: [TileKey | null, TileKey | null];
    }
    const below = new Map<string, Two>();
    this.materials.forEach((m, mi) => {
      const l = m.layout;
      for (let i = 0; i < m.slot.length; ++i) {
        if (m.slot[i] < 0) continue;
        const t: TileKey = { material: mi, ...l.id(i) };
        let sum = 0;
        const v = votes.get(mi, t);
        for (let s: TileId = t; l.hasParent(s); ) {
          sum += this.weight({ material: mi, ...s });
          s = l.parent(s);
          const cost = v * sum;
          const k = `${mi}/${l.index(s)}`;
          let two = below.get(k);
          if (!two) {
            two = { ancestor: { material: mi, ...s }, cost: [Infinity, Infinity], tile: [null, null] };
            below.set(k, two);
          }
          if (cost < two.cost[0]) {
            two.cost[1] = two.cost[0];
            two.tile[1] = two.tile[0];
            two.cost[0] = cost;
            two.tile[0] = t;
          } else if (cost < two.cost[1]) {
            two.cost[1] = cost;
            two.tile[1] = t;
          }
        }
      }
    });
    // std::map order: by (material, group, level, x, y).
    const ordered = [...below.values()].sort((a, b) => compareKeys(a.ancestor, b.ancestor));
    let best: Operation | null = null;
    for (const two of ordered) {
      if (!Number.isFinite(two.cost[1])) continue;
      const c = two.cost[0] + two.cost[1];
      if (!best || c < best.value || (c === best.value && two.ancestor.level < best.tile.level))
        best = { kind: "swap", tile: two.ancestor, out: [two.tile[0]!, two.tile[1]!], value: c };
    }
    return best;
  }

  private insert(t: TileKey): void {
    const m = this.materials[t.material];
    const i = m.layout.index(t);
    if (m.slot[i] >= 0) return;
    const s = this.free.pop();
    if (s === undefined) throw new Error("bsvtf: the tile cache is full");
    m.slot[i] = s;
    ++this.count;
  }

  private erase(t: TileKey): void {
    const m = this.materials[t.material];
    const i = m.layout.index(t);
    if (m.slot[i] < 0) return;
    this.free.push(m.slot[i]);
    m.slot[i] = -1;
    --this.count;
  }

  private removeCoveredAncestors(t: TileKey): void {
    const m = this.materials[t.material];
    const l = m.layout;
    for (let a: TileId = t; l.hasParent(a); ) {
      a = l.parent(a);
      if (m.slot[l.index(a)] >= 0 && this.coveredBelow(m, a)) this.erase({ material: t.material, ...a });
    }
  }

  add(t: TileKey): void {
    const m = this.materials[t.material];
    const l = m.layout;
    if (this.resident(t)) throw new Error("bsvtf: add of a resident tile");
    if (!l.hasParent(t) || !this.resident({ material: t.material, ...l.parent(t) })) throw new Error("bsvtf: add of a tile whose parent is not resident");
    if (this.coveredBelow(m, t)) throw new Error("bsvtf: add of a tile that resident tiles below it cover already");
    this.insert(t);
    this.removeCoveredAncestors(t);
  }

  swap(ancestor: TileKey, t1: TileKey, t2: TileKey): void {
    const m = this.materials[ancestor.material];
    const l = m.layout;
    const below = (t: TileKey) => {
      if (t.material !== ancestor.material || t.group !== ancestor.group || t.level >= ancestor.level) return false;
      let s: TileId = t;
      while (s.level < ancestor.level) s = l.parent(s);
      return s.x === ancestor.x && s.y === ancestor.y;
    };
    if (sameKey(t1, t2) || !this.resident(t1) || !this.resident(t2) || !below(t1) || !below(t2))
      throw new Error("bsvtf: swap needs two resident tiles below the ancestor");
    this.erase(t1);
    this.erase(t2);
    if (!this.coveredBelow(m, ancestor)) this.insert(ancestor);
    this.removeCoveredAncestors(ancestor);
  }

  /** TileCache::decide: the decision rule of §5.2, applied (see cache.h). */
  decide(votes: Votes, available: (t: TileKey) => boolean, maxOperations: number): Decision {
    const d: Decision = { operations: [], wanted: null };
    for (let op = 0; op < maxOperations; ++op) {
      const add = this.bestAdd(votes, (t) => !available(t));
      if (!add) break;
      if (this.count < this.capacity) {
        this.add(add.tile);
        d.operations.push(add);
        continue;
      }
      const swap = this.cheapestSwap(votes);
      if (!swap || swap.value >= add.value) break;
      if (!this.resident(swap.tile) && !available(swap.tile)) {
        const l = this.materials[swap.tile.material].layout;
        let t: TileId = swap.tile;
        while (l.hasParent(t) && !available({ material: swap.tile.material, ...l.parent(t) })) t = l.parent(t);
        d.wanted = { material: swap.tile.material, group: t.group, level: t.level, x: t.x, y: t.y };
        break;
      }
      this.swap(swap.tile, swap.out![0], swap.out![1]);
      d.operations.push(swap);
    }
    return d;
  }

  /**
   * The resident tile of (material, group) that shows level-`level` texel (x, y): the tile at that
   * level or its nearest resident ancestor, else the coarsest resident tile below it.
   */
  lookup(material: number, group: number, level: number, x: number, y: number): TileKey {
    const m = this.materials[material];
    const l = m.layout;
    level = Math.min(Math.max(level, 0), l.levels - 1);
    let t: TileId = { group, level, x: Math.floor(x / l.tile), y: Math.floor(y / l.tile) };
    while (m.slot[l.index(t)] < 0 && l.hasParent(t)) t = l.parent(t);
    if (m.slot[l.index(t)] >= 0) return { material, ...t };
    for (let k = level - 1; k >= 0; --k) {
      t = { group, level: k, x: Math.floor((x << (level - k)) / l.tile), y: Math.floor((y << (level - k)) / l.tile) };
      if (m.slot[l.index(t)] >= 0) return { material, ...t };
    }
    throw new Error("bsvtf: a texel is not covered by the tile cache");
  }
}
