// SPDX-License-Identifier: MIT
// GLSL ES 3.00 of the BTF surface. The fragment shader is one shared part — the shading frame of
// scene.cpp, the lights, shading like the C++ path tracer's next-event estimation
// (src/btf/render/integrator.cpp: radiance = f · E / π per delta light, plus a uniform
// environment), tone mapping like quality::tone_map (exposure, the ACES fit, then sRGB) — and one
// codec part, which declares its own uniforms and textures and defines
//
//   void codecEvaluate(vec2 uv, vec2 sx, vec2 sy, vec3 wo, vec3 wi[MAX_LIGHTS], bool lit[MAX_LIGHTS],
//                      int lightCount, bool env, out vec3 value[MAX_LIGHTS], out vec3 ambient);
//
// the material's value (linear RGB, before clamping) at mapped uv for the view direction wo and
// each lit light direction wi[i] (local frame), and with env the uniform environment's value
// ((1/π) ∫ f dωi); sx and sy are the pixel's footprint in level-0 texels, for codecs that filter.
// The part may use MAX_LIGHTS, PI, tableTexel (index → texel of a TABLE_WIDTH-wide table) and
// wrapLerp (wrap_lerp of btf_lookup.h). A codec added later only needs its decoder module and
// such a part: factorPart here (fmf, pca-views, lpca, perceptual; bsvtf with BSVTF defined), and
// mlvqFragment in mlvq.ts.

export const MAX_LIGHTS = 4;

export const vertexShader = /* glsl */ `
precision highp float;
precision highp int;

uniform mat4 modelViewMatrix;
uniform mat4 projectionMatrix;

in vec3 position;
in vec3 normal;
in vec3 btfTangent;
in vec2 uv;

out vec3 vPosition;
out vec3 vNormal;
out vec3 vTangent;
out vec2 vUv;

void main() {
  // Meshes are built in world space (the C++ renderer transforms its meshes the same way), so
  // the model matrix is the identity and positions, normals and tangents pass through.
  vPosition = position;
  vNormal = normal;
  vTangent = btfTangent;
  vUv = uv;
  gl_Position = projectionMatrix * modelViewMatrix * vec4(position, 1.0);
}
`;

export const wrapLerpFunction = /* glsl */ `
// wrap_lerp of btf_lookup.h: the two texels and the weight of the second.
void wrapLerp(float c, int size, out int i0, out int i1, out float t) {
  float n = float(size);
  float x = c * n - 0.5;
  if (isnan(x) || isinf(x)) x = -0.5;
  if (!(x >= 0.0 && x < n)) x -= n * floor(x / n);
  if (!(x >= 0.0 && x < n)) x = 0.0;
  i0 = int(x);
  t = x - float(i0);
  i1 = i0 + 1 == size ? 0 : i0 + 1;
}
`;

/** The most tile levels a BSVTF material may have (textures up to 2^(MAX_TILE_LEVELS − 1) tiles). */
export const MAX_TILE_LEVELS = 16;


// The object's uv mapping, uv' = R(rotation) · (u · su, v · sv) (scene.cpp), and the screen
// footprint of one pixel in level-0 texels of the mapped uv (uSize), scaled by footprintScale.
const mapUvFunction = /* glsl */ `
void mapUv(vec2 uv, vec2 dudx, vec2 dudy, float footprintScale, out vec2 uvm, out vec2 sx, out vec2 sy) {
  mat2 uvRotation = mat2(uUvRotation.x, uUvRotation.y, -uUvRotation.y, uUvRotation.x);
  uvm = uvRotation * (uv * uUvScale);
  sx = uvRotation * (dudx * uUvScale) * vec2(uSize) * footprintScale;
  sy = uvRotation * (dudy * uUvScale) * vec2(uSize) * footprintScale;
}
`;

// Shared by the BSVTF surface and the feedback shaders: the tile level a footprint needs.
const tileLevelFunction = /* glsl */ `
// Equation 1: the level whose texels are as large as the pixel's footprint (level 0 with
// mip-mapping off), as the feedback pass requests it and the surface shows it.
int tileLevel(vec2 sx, vec2 sy) {
  if (uMip == 0) return 0;
  float rho = max(length(sx), length(sy));
  return rho > 1.0 ? min(int(floor(log2(rho))), uLevels - 1) : 0;
}
`;

/**
 * The codec part of the factorization codecs (src/btf/codecs/factor/material.cpp): bilinear in
 * space with wrapping and texel centres at (i + 0.5) / W, barycentric over ≤ 3 views × ≤ 3 lights
 * found through the AngularInterpolator grid of docs/interpolation.md, interpolation on the plane
 * values, then the inverse colour transform. View groups, texel clusters and levels as in
 * factor.ts "texture layouts"; with BSVTF defined, the eigen-textures come from the page's tile
 * cache instead (docs/bsvtf.md).
 */
export const factorPart = /* glsl */ `
precision highp sampler2DArray;
precision highp isampler2D;

struct Interp {
  int R;
  int N;
  int T;
  int lifted;
  int triBase;
  int offBase;
  int cellBase;
  int invBase;
};

uniform highp sampler2DArray uA;     // angular factors, 4 components per texel
uniform highp sampler2DArray uB;     // eigen-texture atlases (level 0 + mip chain)
uniform highp sampler2DArray uMean;  // row means, a layer per (plane, cluster)
uniform highp sampler2D uTabF;       // inverse matrices of both direction sets
uniform highp isampler2D uTabI;      // triangles, cell offsets, cell triangles
uniform highp isampler2D uBlocks;    // per (plane, group, cluster): aBase, layers loaded, bBase, means layer
uniform highp isampler2D uViewGroup; // view group of each view
uniform highp isampler2D uTexelCluster; // texel cluster of each texel (1 × 1 with one cluster)
uniform Interp uViews;
uniform Interp uLights;

uniform int uPlanes;                 // 1 (rgb) or 3
uniform int uChannels;               // 3 (rgb) or 1
uniform int uNL;                     // lights of the sampling (column uNL = environment)
uniform int uGroups;                 // view groups
uniform int uClusters;               // texel clusters
uniform int uColour;                 // 0 rgb, 1 decorrelated, 2 per-channel, 3 model11, 4 lab
uniform int uLog;
uniform float uLogEps;
uniform int uMipLevels;
#ifdef BSVTF
uniform highp sampler2DArray uAtlas; // the tile cache, one tile per layer
uniform highp isampler2D uIndir;     // per tile index: its layer, or −1
uniform int uTile;                   // tile size T and padding
uniform int uPad;
uniform int uLevels;
uniform int uTilesPerGroup;
uniform int uLevelBase[MAX_TILE_LEVELS];
uniform int uTilesX[MAX_TILE_LEVELS];
${tileLevelFunction}
#endif

int tableInt(int base, int k) { return texelFetch(uTabI, tableTexel(base + (k >> 2)), 0)[k & 3]; }

// atan on [-1, 1] (Abramowitz & Stegun 4.4.49): the polynomial the C++ grid uses to find a cell.
float approxAtan(float t) {
  float t2 = t * t;
  return t * (0.9998660 + t2 * (-0.3302995 + t2 * (0.1801410 + t2 * (-0.0851330 + t2 * 0.0208351))));
}

struct Weights {
  ivec3 index;
  vec3 weight;
};

Weights finishWeights(Interp s, int t, vec3 l) {
  ivec3 v = texelFetch(uTabI, tableTexel(s.triBase + t), 0).xyz;
  vec3 w = max(l, 0.0) * vec3(lessThan(v, ivec3(s.N)));
  float sum = w.x + w.y + w.z;
  Weights r;
  r.index = v;
  r.weight = sum > 0.0 ? w / sum : vec3(1.0, 0.0, 0.0);
  return r;
}

vec3 barycentric(Interp s, int t, vec3 d) {
  int o = s.invBase + 3 * t;
  return vec3(dot(texelFetch(uTabF, tableTexel(o), 0).xyz, d),
              dot(texelFetch(uTabF, tableTexel(o + 1), 0).xyz, d),
              dot(texelFetch(uTabF, tableTexel(o + 2), 0).xyz, d));
}

// AngularInterpolator::weights (docs/interpolation.md), for a direction in the local frame.
Weights lookupWeights(Interp s, vec3 d) {
  d.z = max(d.z, 0.0);
  if (s.lifted == 1) {
    float r = length(d.xy);
    d = r > 0.0 ? vec3(d.xy / r * 0.70710678, 0.70710678) : vec3(0.70710678, 0.0, 0.70710678);
  }
  if (!(dot(d, d) > 0.0)) d = vec3(1.0, 0.0, 0.0);
  d = normalize(d);
  // hemisphere -> square: Lambert (r = sqrt(1 - z)), then the inverse concentric map
  float r = sqrt(max(1.0 - d.z, 0.0));
  bool xMajor = abs(d.x) >= abs(d.y);
  float major = xMajor ? d.x : d.y;
  float minor = xMajor ? d.y : d.x;
  float along = major < 0.0 ? -r : r;
  float across = along * (4.0 / PI) * approxAtan(minor / (major != 0.0 ? major : 1.0));
  vec2 ab = xMajor ? vec2(along, across) : vec2(across, along);
  float half_ = 0.5 * float(s.R);
  ivec2 c = min(ivec2((ab + 1.0) * half_), ivec2(s.R - 1));
  int cell = c.y * s.R + c.x;
  int first = tableInt(s.offBase, cell), last = tableInt(s.offBase, cell + 1);
  for (int k = first; k < last; ++k) {
    int t = tableInt(s.cellBase, k);
    vec3 l = barycentric(s, t, d);
    if (min(l.x, min(l.y, l.z)) >= -1e-6 * (l.x + l.y + l.z)) return finishWeights(s, t, l);
  }
  // No candidate contains the query (float rounding on an edge): the best triangle of all, as
  // weights_brute_force does.
  int best = 0;
  float bestScore = -1e30;
  vec3 bestL = vec3(1.0, 0.0, 0.0);
  for (int t = 0; t < s.T; ++t) {
    ivec3 v = texelFetch(uTabI, tableTexel(s.triBase + t), 0).xyz;
    if (v.x >= s.N) continue;
    vec3 l = barycentric(s, t, d);
    float sum = l.x + l.y + l.z;
    if (!(sum > 0.0)) continue;
    float score = min(l.x, min(l.y, l.z)) / sum;
    if (score > bestScore) { bestScore = score; best = t; bestL = l; }
  }
  return finishWeights(s, best, bestL);
}

// One mip level's bilinear footprint in the atlas.
struct Footprint {
  ivec2 p00, p10, p01, p11;
  vec4 w;
};

Footprint footprint(vec2 uv, int level) {
  int w = max(1, uSize.x >> level), h = max(1, uSize.y >> level);
  ivec2 origin = ivec2(0);
  if (level > 0) {
    origin.x = uSize.x;
    for (int m = 1; m < level; ++m) origin.y += max(1, uSize.y >> m);
  }
  int x0, x1, y0, y1;
  float tx, ty;
  wrapLerp(uv.x, w, x0, x1, tx);
  wrapLerp(uv.y, h, y0, y1, ty);
  Footprint f;
  f.p00 = origin + ivec2(x0, y0);
  f.p10 = origin + ivec2(x1, y0);
  f.p01 = origin + ivec2(x0, y1);
  f.p11 = origin + ivec2(x1, y1);
  f.w = vec4((1.0 - tx) * (1.0 - ty), tx * (1.0 - ty), (1.0 - tx) * ty, tx * ty);
  return f;
}

vec4 sampleB(Footprint f, int layer) {
  return f.w.x * texelFetch(uB, ivec3(f.p00, layer), 0) + f.w.y * texelFetch(uB, ivec3(f.p10, layer), 0) +
         f.w.z * texelFetch(uB, ivec3(f.p01, layer), 0) + f.w.w * texelFetch(uB, ivec3(f.p11, layer), 0);
}

// The bilinear footprint restricted to the texels of one cluster (mask: 1 for its texels).
vec4 sampleB(Footprint f, int layer, vec4 mask) {
  vec4 w = f.w * mask;
  return w.x * texelFetch(uB, ivec3(f.p00, layer), 0) + w.y * texelFetch(uB, ivec3(f.p10, layer), 0) +
         w.z * texelFetch(uB, ivec3(f.p01, layer), 0) + w.w * texelFetch(uB, ivec3(f.p11, layer), 0);
}

#ifdef BSVTF
// BSVTF mode (docs/bsvtf.md): the eigen-textures are tiles in a cache shared by every material,
// one tile per layer of uAtlas; uIndir maps this material's tile index (TileLayout::index) to
// its layer, or −1 when the tile is not resident or its data has not arrived. The lookup is
// sample_cached of src/btf/bsvtf/cache.h.
int tileSlot(int g, int level, int tx, int ty) {
  int i = g * uTilesPerGroup + uLevelBase[level] + ty * uTilesX[level] + tx;
  return texelFetch(uIndir, tableTexel(i), 0).r;
}

// TileCache::lookup and texel_from_tile: texel (x, y) of a level of group g from the tile the
// cache shows there — its own, a coarser one (bilinear at the texel's centre) or finer ones (the
// average of the texels below it). False when no tile with data covers it.
bool cachedTexel(int g, int level, int x, int y, out vec4 texel) {
  texel = vec4(0.0);
  int tl = level, tx = x / uTile, ty = y / uTile;
  int slot = tileSlot(g, tl, tx, ty);
  while (slot < 0 && tl + 1 < uLevels) {
    ++tl;
    tx >>= 1;
    ty >>= 1;
    slot = tileSlot(g, tl, tx, ty);
  }
  if (slot < 0) {
    for (int k = level - 1; k >= 0; --k) {
      tx = (x << (level - k)) / uTile;
      ty = (y << (level - k)) / uTile;
      slot = tileSlot(g, k, tx, ty);
      if (slot >= 0) {
        tl = k;
        break;
      }
    }
    if (slot < 0) return false;
  }
  ivec2 origin = ivec2(tx, ty) * uTile - uPad;
  if (tl == level) {
    texel = texelFetch(uAtlas, ivec3(ivec2(x, y) - origin, slot), 0);
    return true;
  }
  if (tl > level) {
    float scale = 1.0 / float(1 << (tl - level));
    vec2 p = (vec2(x, y) + 0.5) * scale - 0.5;
    ivec2 i = ivec2(floor(p));
    vec2 t = p - vec2(i);
    ivec2 l = i - origin;
    texel = texelFetch(uAtlas, ivec3(l, slot), 0) * (1.0 - t.x) * (1.0 - t.y) +
            texelFetch(uAtlas, ivec3(l + ivec2(1, 0), slot), 0) * t.x * (1.0 - t.y) +
            texelFetch(uAtlas, ivec3(l + ivec2(0, 1), slot), 0) * (1.0 - t.x) * t.y +
            texelFetch(uAtlas, ivec3(l + ivec2(1, 1), slot), 0) * t.x * t.y;
    return true;
  }
  int n = 1 << (level - tl);
  ivec2 first = (ivec2(x, y) << (level - tl)) - origin;
  int count = 0;
  for (int ly = first.y; ly < first.y + n; ++ly)
    for (int lx = first.x; lx < first.x + n; ++lx) {
      if (lx < uPad || ly < uPad || lx >= uPad + uTile || ly >= uPad + uTile) continue;
      ++count;
      texel += texelFetch(uAtlas, ivec3(lx, ly, slot), 0);
    }
  if (count == 0) return false;
  texel /= float(count);
  return true;
}

// sample_cached: the group's four channels at uv on a level, bilinear from the cached texels;
// nothing (0) when a texel has no data yet, as the C++ leaves such a group out.
vec4 sampleCached(vec2 uv, int level, int g) {
  int x0, x1, y0, y1;
  float tx, ty;
  wrapLerp(uv.x, max(1, uSize.x >> level), x0, x1, tx);
  wrapLerp(uv.y, max(1, uSize.y >> level), y0, y1, ty);
  vec4 t00, t10, t01, t11;
  if (!cachedTexel(g, level, x0, y0, t00) || !cachedTexel(g, level, x1, y0, t10) ||
      !cachedTexel(g, level, x0, y1, t01) || !cachedTexel(g, level, x1, y1, t11))
    return vec4(0.0);
  return (1.0 - tx) * (1.0 - ty) * t00 + tx * (1.0 - ty) * t10 + (1.0 - tx) * ty * t01 + tx * ty * t11;
}
#endif

vec3 inverseColour(vec3 p) {
  if (uColour == 3) {
    // UBO2014 colour model 11 (log Y, U/Y, V/Y), eps 1e-5: ubo_model11_to_rgb.
    const float eps = 1e-5;
    float y = exp(p.x) - eps, u = p.y * (y + eps), w = p.z * (y + eps);
    return vec3(y + 1.13983 * w, y - 0.39465 * u - 0.58060 * w, y + 2.03211 * u);
  }
  if (uColour == 4) {
    // CIELab (D65, Y = 1) → XYZ → linear RGB: lab_to_xyz and xyz_to_rgb of core/color.cpp.
    const float epsilon = 216.0 / 24389.0, kappa = 24389.0 / 27.0;
    float fy = (p.x + 16.0) / 116.0, fx = fy + p.y / 500.0, fz = fy - p.z / 200.0;
    float x = fx * fx * fx > epsilon ? fx * fx * fx : (116.0 * fx - 16.0) / kappa;
    float y = p.x > kappa * epsilon ? fy * fy * fy : p.x / kappa;
    float z = fz * fz * fz > epsilon ? fz * fz * fz : (116.0 * fz - 16.0) / kappa;
    vec3 xyz = vec3(x * 0.95047, y, z * 1.08883);
    return vec3(dot(vec3(3.2404542, -1.5371385, -0.4985314), xyz), dot(vec3(-0.9692660, 1.8760108, 0.0415560), xyz),
                dot(vec3(0.0556434, -0.2040259, 1.0572252), xyz));
  }
  vec3 v = p;
  if (uColour == 1) {
    const float a = 0.57735026919, b = 0.70710678118, c = 0.40824829046;
    v = vec3(a * p.x + b * p.y + c * p.z, a * p.x - b * p.y + c * p.z, a * p.x - 2.0 * c * p.z);
  }
  if (uLog == 1) v = exp(v) - uLogEps;
  return v;
}

// One row's value for column col (light · C + channel) of a view: the row mean times the
// cluster's spatial weight (layer < 0; b = that weight), or a(row, 4 components of the layer) · b.
float rowValue(int col, int view, int meanLayer, int layer, vec4 b) {
  if (layer < 0) return texelFetch(uMean, ivec3(col, view, meanLayer), 0).r * b.x;
  return dot(texelFetch(uA, ivec3(col, view, layer), 0), b);
}

void codecEvaluate(vec2 uvm, vec2 sx, vec2 sy, vec3 wo, vec3 wi[MAX_LIGHTS], bool lit[MAX_LIGHTS], int lightCount, bool env,
                   out vec3 direct[MAX_LIGHTS], out vec3 ambient) {
  Weights lw[MAX_LIGHTS];
  for (int i = 0; i < MAX_LIGHTS; ++i) {
    direct[i] = vec3(0.0);
    lw[i].index = ivec3(0);
    lw[i].weight = vec3(0.0);
    if (i < lightCount && lit[i]) lw[i] = lookupWeights(uLights, wi[i]);
  }
  ambient = vec3(0.0);
  Weights vw = lookupWeights(uViews, wo);

  // Mip level from the screen footprint in level-0 texels; at or below 0 (magnification) the
  // lookup is exactly the C++ bilinear one. Clustered models have no mip chain.
#ifdef BSVTF
  // The level the feedback pass asks for (equation 1), without blending between levels.
  int level = tileLevel(sx, sy);
#else
  float lod = 0.0;
  if (uMip == 1 && uMipLevels > 1) {
    float rho = max(length(sx), length(sy));
    lod = rho > 1.0 ? min(log2(rho), float(uMipLevels - 1)) : 0.0;
  }
  int level0 = int(floor(lod));
  float levelBlend = lod - float(level0);
  int level1 = min(level0 + 1, uMipLevels - 1);
  Footprint f0 = footprint(uvm, level0);
  Footprint f1 = footprint(uvm, level1);
#endif

  // The clusters of the lookup's four texels (material.cpp: each texel is evaluated with its own
  // cluster's blocks) and the groups of its views.
  ivec4 texelCluster = ivec4(0);
#ifndef BSVTF
  if (uClusters > 1)
    texelCluster = ivec4(texelFetch(uTexelCluster, f0.p00, 0).r, texelFetch(uTexelCluster, f0.p10, 0).r,
                         texelFetch(uTexelCluster, f0.p01, 0).r, texelFetch(uTexelCluster, f0.p11, 0).r);
#endif
  ivec3 viewGroup = ivec3(-1);
  for (int vi = 0; vi < 3; ++vi)
    if (vw.weight[vi] > 0.0) viewGroup[vi] = uGroups == 1 ? 0 : texelFetch(uViewGroup, tableTexel(vw.index[vi]), 0).r;

  int C = uChannels;
  for (int p = 0; p < uPlanes; ++p)
    for (int gi = 0; gi < 3; ++gi) {
      int g = viewGroup[gi];
      if (g < 0 || (gi > 0 && g == viewGroup[0]) || (gi > 1 && g == viewGroup[1])) continue;
      for (int ci = 0; ci < 4; ++ci) {
        int c = texelCluster[ci];
        if ((ci > 0 && c == texelCluster[0]) || (ci > 1 && c == texelCluster[1]) || (ci > 2 && c == texelCluster[2])) continue;
        vec4 mask = vec4(equal(texelCluster, ivec4(c)));
        ivec4 block = texelFetch(uBlocks, tableTexel((p * uGroups + g) * uClusters + c), 0);
        // j = -1: the row means (texel-independent: weighted by the cluster's share of the
        // bilinear weights, 1 with one cluster); then each layer of four components, a(row) · b(texel).
        for (int j = -1; j < block.y; ++j) {
          vec4 b;
          if (j < 0) {
#ifdef BSVTF
            b = vec4(1.0);
#else
            b = vec4(dot(f0.w, mask));
#endif
          } else {
#ifdef BSVTF
            b = sampleCached(uvm, level, block.z + j);
#else
            b = sampleB(f0, block.z + j, mask);
            if (levelBlend > 0.0) b = mix(b, sampleB(f1, block.z + j, mask), levelBlend);
#endif
          }
          int layer = j < 0 ? -1 : block.x + j;
          for (int vi = 0; vi < 3; ++vi) {
            if (viewGroup[vi] != g) continue;
            float wv = vw.weight[vi];
            int view = vw.index[vi];
            for (int i = 0; i < lightCount; ++i) {
              if (!lit[i]) continue;
              for (int li = 0; li < 3; ++li) {
                float w = wv * lw[i].weight[li];
                if (w <= 0.0) continue;
                int light = lw[i].index[li];
                for (int ch = 0; ch < C; ++ch) direct[i][p + ch] += w * rowValue(light * C + ch, view, block.w, layer, b);
              }
            }
            if (env)
              for (int ch = 0; ch < C; ++ch) ambient[p + ch] += wv * rowValue(uNL * C + ch, view, block.w, layer, b);
          }
        }
      }
    }
  for (int i = 0; i < MAX_LIGHTS; ++i) direct[i] = inverseColour(direct[i]);
  ambient = inverseColour(ambient);
}
`;

/** The surface's fragment shader with a codec part (see the top of this file). */
export function fragmentShader(codecPart: string): string {
  return /* glsl */ `
precision highp float;
precision highp int;
precision highp sampler2D;

#define MAX_LIGHTS ${MAX_LIGHTS}
#define TABLE_WIDTH 1024
#define PI 3.14159265358979
#define MAX_TILE_LEVELS ${MAX_TILE_LEVELS}

uniform vec3 cameraPosition;

uniform ivec2 uSize;                 // material width, height
uniform int uMip;                    // 1: mip-mapped minification, 0: level 0 only (the C++ lookup)

uniform vec2 uUvScale;
uniform vec2 uUvRotation;            // cos, sin of the uv rotation
uniform int uUvTurnsTangent;         // rotation != 0 or scale_u != scale_v (scene.cpp)

uniform int uLightCount;
uniform int uLightType[MAX_LIGHTS];  // 0 directional, 1 point
uniform vec3 uLightVec[MAX_LIGHTS];  // direction towards the light, or its position
uniform vec3 uLightPower[MAX_LIGHTS];// irradiance E, or intensity I
uniform vec3 uEnvRadiance;           // uniform environment radiance (0: off)
uniform float uEnvScale;

uniform float uExposure;
uniform int uDebug;                  // 0 shading; 1 uv, 2 normal, 3 tangent, 4 view dir, 5 light dir

in vec3 vPosition;
in vec3 vNormal;
in vec3 vTangent;
in vec2 vUv;

out vec4 fragColor;

ivec2 tableTexel(int i) { return ivec2(i % TABLE_WIDTH, i / TABLE_WIDTH); }
${wrapLerpFunction}
${mapUvFunction}
${codecPart}
// quality::tone_map (exposure, Narkowicz's ACES fit, clamp), then the sRGB transfer.
vec3 toneMap(vec3 linear) {
  vec3 x = max(linear * exp2(uExposure), 0.0);
  vec3 y = clamp((x * (2.51 * x + 0.03)) / (x * (2.43 * x + 0.59) + 0.14), 0.0, 1.0);
  return mix(1.055 * pow(y, vec3(1.0 / 2.4)) - 0.055, 12.92 * y, vec3(lessThanEqual(y, vec3(0.0031308))));
}

// Duff et al. 2017, as render::orthonormal_basis.
vec3 anyTangent(vec3 n) {
  float s = n.z >= 0.0 ? 1.0 : -1.0;
  float a = -1.0 / (s + n.z);
  float b = n.x * n.y * a;
  return vec3(1.0 + s * n.x * n.x * a, s * b, -s * n.x);
}

void main() {
  // Derivatives first, in uniform control flow.
  vec3 dpdx = dFdx(vPosition), dpdy = dFdy(vPosition);
  vec2 dudx = dFdx(vUv), dudy = dFdy(vUv);
  vec2 uvm, sx, sy;
  mapUv(vUv, dudx, dudy, 1.0, uvm, sx, sy);

  // The shading frame of Scene::intersect: interpolated normal, flipped when seen from behind
  // (two-sided surfaces); interpolated tangent made orthogonal to it; bitangent = n × t.
  vec3 n = normalize(vNormal);
  if (!gl_FrontFacing) n = -n;
  vec3 toCamera = cameraPosition - vPosition;
  vec3 ng = normalize(cross(dpdx, dpdy));
  if (dot(ng, toCamera) < 0.0) ng = -ng;  // the geometric normal, facing the camera
  vec3 t = vTangent - n * dot(vTangent, n);
  t = length(t) < 1e-8 ? anyTangent(n) : normalize(t);
  vec3 bt = cross(n, t);

  // The object's uv mapping: uv' = R(rotation) · (u · su, v · sv), with the tangent turned to the
  // direction of growth of u' (dP/du and dP/dv from the triangle, as scene.cpp takes them).
  if (uUvTurnsTangent == 1) {
    float det = dudx.x * dudy.y - dudy.x * dudx.y;
    float lenU = 1.0, lenV = 1.0;
    vec3 alongV = bt;
    if (abs(det) > 1e-20) {
      vec3 dPdu = (dpdx * dudy.y - dpdy * dudx.y) / det;
      vec3 dPdv = (dpdy * dudx.x - dpdx * dudy.x) / det;
      lenU = length(dPdu);
      lenV = length(dPdv);
      if (dot(dPdv, bt) < 0.0) alongV = -bt;
    }
    t = normalize(t * (uUvRotation.x * lenU / uUvScale.x) - alongV * (uUvRotation.y * lenV / uUvScale.y));
    bt = cross(n, t);
  }
  mat3 toLocal = transpose(mat3(t, bt, n));

  vec3 wo = toLocal * normalize(toCamera);
  if (wo.z < 1e-4) wo = normalize(vec3(wo.xy, 1e-4));  // silhouettes (integrator.cpp)

  // Lights: direction, irradiance, and whether it reaches the surface.
  vec3 wi[MAX_LIGHTS];
  vec3 irradiance[MAX_LIGHTS];
  bool lit[MAX_LIGHTS];
  for (int i = 0; i < MAX_LIGHTS; ++i) {
    lit[i] = false;
    irradiance[i] = vec3(0.0);
    wi[i] = vec3(0.0, 0.0, 1.0);
    if (i >= uLightCount) continue;
    vec3 wiWorld;
    if (uLightType[i] == 1) {
      vec3 d = uLightVec[i] - vPosition;
      float d2 = dot(d, d);
      wiWorld = d / sqrt(d2);
      irradiance[i] = uLightPower[i] / d2;
    } else {
      wiWorld = normalize(uLightVec[i]);
      irradiance[i] = uLightPower[i];
    }
    wi[i] = toLocal * wiWorld;
    if (dot(wiWorld, ng) <= 0.0 || wi[i].z <= 0.0) continue;
    lit[i] = true;
  }

  if (uDebug != 0) {
    vec3 c = uDebug == 1 ? vec3(fract(uvm), 0.0)
           : uDebug == 2 ? n * 0.5 + 0.5
           : uDebug == 3 ? t * 0.5 + 0.5
           : uDebug == 4 ? wo * 0.5 + 0.5
           : (uLightCount > 0 ? wi[0] : vec3(0.0)) * 0.5 + 0.5;
    fragColor = vec4(c, 1.0);
    return;
  }

  bool env = uEnvRadiance.x > 0.0 || uEnvRadiance.y > 0.0 || uEnvRadiance.z > 0.0;
  vec3 direct[MAX_LIGHTS];
  vec3 ambient;
  codecEvaluate(uvm, sx, sy, wo, wi, lit, uLightCount, env, direct, ambient);

  // BtfSurface::eval clamps negative values (a truncated factorization rings); each delta light
  // adds f · E / π.
  vec3 radiance = vec3(0.0);
  for (int i = 0; i < uLightCount; ++i)
    if (lit[i]) radiance += max(direct[i], 0.0) * irradiance[i] / PI;
  if (env) radiance += max(ambient, 0.0) * uEnvScale * uEnvRadiance;
  fragColor = vec4(toneMap(radiance), 1.0);
}
`;
}


/**
 * The feedback pass of the BSVTF mode, drawn at a fraction of the resolution: per pixel the
 * material (index + 1; 0 = nothing or an object without BSVTF material), the tile level it needs
 * (equation 1) and the tile of that level holding the lookup's first texel, as bytes. The page
 * reads it back and counts votes (equation 9) as Votes::add does.
 */
export const feedbackFragmentShader = /* glsl */ `
precision highp float;
precision highp int;

#define BSVTF 1

uniform vec2 uUvScale;
uniform vec2 uUvRotation;
uniform ivec2 uSize;
uniform int uMip;
uniform int uLevels;
uniform int uTile;
uniform int uMaterialIndex;          // −1: an occluder
uniform float uFootprintScale;       // full-resolution pixels per feedback pixel, inverted

in vec2 vUv;

out vec4 fragColor;
${wrapLerpFunction}
${mapUvFunction}
${tileLevelFunction}
void main() {
  vec2 dudx = dFdx(vUv), dudy = dFdy(vUv);
  if (uMaterialIndex < 0) {
    fragColor = vec4(0.0);
    return;
  }
  vec2 uvm, sx, sy;
  mapUv(vUv, dudx, dudy, uFootprintScale, uvm, sx, sy);
  int level = tileLevel(sx, sy);
  int x0, x1, y0, y1;
  float tx, ty;
  wrapLerp(uvm.x, max(1, uSize.x >> level), x0, x1, tx);
  wrapLerp(uvm.y, max(1, uSize.y >> level), y0, y1, ty);
  fragColor = vec4(float(uMaterialIndex + 1), float(level), float(x0 / uTile), float(y0 / uTile)) / 255.0;
}
`;
