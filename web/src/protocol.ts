// SPDX-License-Identifier: MIT
// Messages between the page and the decoding worker (one worker per material).

import type { BsvtfInfo } from "./bsvtf";
import type { FactorInfo, Layout } from "./factor";
import type { TextureSpec } from "./mlvq";

/** Uniform values that locate one direction set's tables in the table textures. */
export interface InterpUniforms {
  R: number;
  N: number;
  T: number;
  lifted: number;
  /** Texel index in the int table texture of the first triangle (one texel per triangle). */
  triBase: number;
  /** Texel index in the int table texture where the cell offsets start (4 per texel). */
  offBase: number;
  /** Texel index in the int table texture where the cell triangles start (4 per texel). */
  cellBase: number;
  /** Texel index in the float table texture of the first inverse row (3 texels per triangle). */
  invBase: number;
}

/** Width of the table textures (texel i is at (i mod width, ⌊i / width⌋)). */
export const TABLE_WIDTH = 1024;

export type ToWorker =
  | { type: "start"; name: string }
  | { type: "chunk"; data: ArrayBuffer }
  | { type: "end" }
  /**
   * queries: per query u, v, wi (x, y, z), wo (x, y, z) in the local frame; with `environment`
   * the uniform environment's value at (u, v, wo) instead (wi unused).
   */
  | { type: "eval"; id: number; queries: Float64Array; environment: boolean }
  /** BSVTF: a section fetched on its own (a U packet "u<g>"), as stored in the file. */
  | { type: "packet"; name: string; stored: ArrayBuffer }
  /** BSVTF: a tile's payload and its parent's decoded half floats (null for a coarsest tile). */
  | { type: "tile"; index: number; payload: ArrayBuffer; parent: Uint16Array | null };

export type FromWorker =
  | {
      type: "header";
      info: FactorInfo;
      layout: Layout;
      /** Per eval block: aBase, layers holding loaded components, bBase, means layer. */
      blocks: Int32Array;
      totalBytes: number;
      sections: { name: string; offset: number; size: number }[];
      /** Set for a BSVTF package: the eigen-textures come as tiles, not in component sections. */
      bsvtf: BsvtfInfo | null;
    }
  /**
   * The header of a package decoded by a codec module (mlvq): what the page needs to know before
   * any texture arrives.
   */
  | {
      type: "codecHeader";
      codec: string;
      width: number;
      height: number;
      totalBytes: number;
      sections: { name: string; offset: number; size: number }[];
      present: number;
      total: number;
      unit: string;
    }
  /** A codec module's textures and uniforms after a section, and whether it can draw. */
  | { type: "codecUpdate"; textures: TextureSpec[]; uniforms: Record<string, number | number[]>; ready: boolean; present: number }
  /** BSVTF: the tiles.index section. */
  | { type: "tileIndex"; weights: Float32Array; sizes: Uint32Array; offsets: Float64Array }
  /** BSVTF: a decoded tile, or why it could not be decoded. */
  | { type: "tile"; index: number; data: Uint16Array | null; error: string | null }
  | {
      type: "tables";
      tabF: Float32Array;
      tabFHeight: number;
      tabI: Int32Array;
      tabIHeight: number;
      views: InterpUniforms;
      lights: InterpUniforms;
      /** Decoded environment value multiplier (Σ c_l for log models, 1 otherwise). */
      envScale: number;
    }
  | { type: "means"; data: Float32Array }
  /** The cluster of each texel (models with several texel clusters). */
  | { type: "clusters"; data: Int32Array }
  | {
      type: "component";
      name: string;
      /** The a-texture layer the component is in, and its content. */
      aIndex: number;
      aLayer: Float32Array;
      /** The b-texture layer and its content; −1 and null for a BSVTF U packet (the tiles hold b). */
      bIndex: number;
      bLayer: Float32Array | Uint16Array | null;
      /** The block table after this component. */
      blocks: Int32Array;
      loaded: number;
    }
  | { type: "section"; name: string; index: number; end: number }
  | { type: "done"; complete: boolean; sections: number; declared: number }
  | { type: "error"; message: string; unsupported: boolean }
  /** values: per query linear RGB (before clamping), NaN when the model cannot evaluate yet. */
  | { type: "evalResult"; id: number; values: Float64Array };
