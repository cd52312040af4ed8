// Messages between the page and the decoding worker (one worker per material).

import type { FmfInfo, Layout } from "./fmf";

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
  | { type: "eval"; id: number; queries: Float64Array; environment: boolean };

export type FromWorker =
  | { type: "header"; info: FmfInfo; layout: Layout; totalBytes: number; sections: { name: string; offset: number; size: number }[] }
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
  | {
      type: "component";
      name: string;
      plane: number;
      k: number;
      layer: number;
      aLayer: Float32Array;
      bLayer: Float32Array | Uint16Array;
      loaded: number;
    }
  | { type: "section"; name: string; index: number; end: number }
  | { type: "done"; complete: boolean; sections: number; declared: number }
  | { type: "error"; message: string; unsupported: boolean }
  /** values: per query linear RGB (before clamping), NaN when the model cannot evaluate yet. */
  | { type: "evalResult"; id: number; values: Float64Array };
