// SPDX-License-Identifier: MIT
// The viewer with every codec (issue 19), in headless Chromium (WebGL2 on the CPU through
// SwiftShader): one material (btf synth --preset woven_fabric, ubo81 sampling: 81 views × 81
// lights) compressed by each codec at its defaults and at parameters that give about the same
// package size (--target, 2 MB; found by a few trial compressions of the real material, kept
// within ±25 %), then for each package:
//
//  - package bytes and the wall time of its compression;
//  - the stream held at the end of each component section (P6 level section for mlvq;
//    test/server.mjs), released one stage at a time: the bytes through which the material first
//    draws (state.materials[0].ready), and the frame of each stage compared with the final frame
//    by `btf image-diff` over the sphere's bounding box (SSIM, ΔE00; the black background would
//    lift any frame's SSIM): the bytes through the first stage with SSIM ≥ 0.95. With more stages
//    than --max-stages (--max-stages-target for the packages of about --target bytes), only that
//    many are drawn (evenly spaced, always the first drawable one and the last): the bytes are
//    then those of the first *drawn* stage reaching 0.95, an upper bound;
//  - the GPU memory of the material's textures (state.materials[0].gpuBytes) once complete;
//  - the frame time at the scene's size: median of --frames synchronous renders
//    (btfViewer.render(): upload, draw and a 1-pixel read-back that waits for the GPU), next to
//    that of an empty frame (the material held before its first section);
//  - the final frame against `btf render` of the same scene file (direct lighting, --spp):
//    mean and 95th-percentile ΔE00.
// A codec the viewer refuses gets "not rendered: <message>" in its row.
//
// The scene: the viewer's demo sphere and default camera (position 0,1,4, fov 40), uv scale 1,
// the default directional light (towards 1,1.5,1, irradiance π), exposure 0, mip off.
//
// Packages and the material are cached in OUT/packages keyed by their arguments, so reruns only
// measure. Results: OUT/codecs-bench.json and OUT/table.md (also printed).
//
// Usage: node web/bench/codecs.mjs [--btf build/release/btf] [--size 256] [--out DIR]
//          [--codecs fmf,pca-views,lpca,perceptual,mlvq] [--target 2000000] [--max-stages 8]
//          [--max-stages-target N] [--frames 5] [--spp 64] [--width 1280 --height 720] [--shots DIR]
// --shots DIR: the final frame of each codec's default package as DIR/<codec>.png (halved to
// 640 × 360 with ImageMagick when the full frame's PNG is over 300 KB).

import { execFileSync } from "node:child_process";
import { existsSync, mkdirSync, readFileSync, renameSync, rmSync, statSync, writeFileSync } from "node:fs";
import os from "node:os";
import path from "node:path";
import { parseArgs } from "node:util";
import { CHROMIUM, launchBrowser, openPage, pixels, render, state, writePpm } from "../test/browser.mjs";
import { ARTIFACTS, REPO, listEntry, makeSite, run } from "../test/fixtures.mjs";
import { startServer } from "../test/server.mjs";

const ALL_CODECS = ["fmf", "pca-views", "lpca", "perceptual", "mlvq"];
const { values: opt } = parseArgs({
  options: {
    btf: { type: "string", default: path.join(REPO, "build/release/btf") },
    size: { type: "string", default: "256" },
    out: { type: "string", default: path.join(ARTIFACTS, "bench-codecs") },
    codecs: { type: "string", default: ALL_CODECS.join(",") },
    target: { type: "string", default: "2000000" },
    "max-stages": { type: "string", default: "8" },
    "max-stages-target": { type: "string" },
    frames: { type: "string", default: "5" },
    spp: { type: "string", default: "64" },
    width: { type: "string", default: "1280" },
    height: { type: "string", default: "720" },
    shots: { type: "string" },
  },
});
const SIZE = Number(opt.size);
const TARGET = Number(opt.target);
const TOLERANCE = 0.25;
const MAX_STAGES = Math.max(2, Number(opt["max-stages"]));
const MAX_STAGES_TARGET = Math.max(2, Number(opt["max-stages-target"] ?? MAX_STAGES));
const FRAMES = Number(opt.frames);
const W = Number(opt.width), H = Number(opt.height);
const CODECS = opt.codecs.split(",").filter(Boolean);
for (const c of CODECS) if (!ALL_CODECS.includes(c)) throw new Error(`unknown codec '${c}' (known: ${ALL_CODECS.join(", ")})`);
const OUT = path.resolve(opt.out);
const PACKAGES = path.join(OUT, "packages");
const FRAMES_DIR = path.join(OUT, "frames");
const T0 = Date.now();

const median = (v) => [...v].sort((a, b) => a - b)[Math.floor(v.length / 2)];
const mb = (b) => `${(b / 1e6).toFixed(2)} MB`;
const pct = (b, of) => `${((100 * b) / of).toFixed(0)} %`;
const log = (...a) => console.error(`[${((Date.now() - T0) / 1000).toFixed(0).padStart(5)} s]`, ...a);

// ---- the material and its packages -----------------------------------------------------------

/** Runs `make` unless `file` exists with the same `key`; returns the stamp ({ key, seconds, ... }). */
function cached(file, key, make) {
  const stampFile = file + ".json";
  if (existsSync(file) && existsSync(stampFile)) {
    const stamp = JSON.parse(readFileSync(stampFile, "utf8"));
    if (JSON.stringify(stamp.key) === JSON.stringify(key)) return { ...stamp, cached: true };
  }
  rmSync(file, { recursive: true, force: true });
  const t = Date.now();
  const tmp = path.join(path.dirname(file), `.tmp-${path.basename(file)}`); // same extension
  make(tmp);
  renameSync(tmp, file);
  const stamp = { key, seconds: (Date.now() - t) / 1000 };
  writeFileSync(stampFile, JSON.stringify(stamp));
  return { ...stamp, cached: false };
}

function material() {
  const file = path.join(PACKAGES, `woven${SIZE}.h5`);
  const args = ["synth", "--preset", "woven_fabric", "--size", String(SIZE), "--sampling", "ubo81"];
  const s = cached(file, args, (tmp) => run(opt.btf, ["-q", ...args, "-o", tmp]));
  return { file, args, seconds: s.seconds };
}

/** Compresses the material with `args` (after --codec); cached by its arguments. */
function compress(h5, codec, args) {
  const key = ["compress", path.basename(h5), "--codec", codec, ...args, "--no-error"];
  const name = `${codec}-${args.filter((a) => a !== "-p").join("-").replace(/[^A-Za-z0-9.-]+/g, "-") || "default"}`;
  const file = path.join(PACKAGES, `${name}.btfpkg`);
  const s = cached(file, key, (tmp) => {
    log(`btf compress --codec ${codec} ${args.join(" ")}`);
    run(opt.btf, ["-q", "compress", h5, "--codec", codec, ...args, "--no-error", "-o", tmp]);
  });
  return { file, codec, args, bytes: statSync(file).size, compress_seconds: s.seconds, cached: s.cached };
}

/**
 * How each codec is brought to about TARGET bytes: one parameter (`knob`) varied, the others
 * fixed. Integer knobs (components) scale the size about linearly; mlvq's threshold about as a
 * power (a larger threshold, fewer code-book entries).
 */
const KNOBS = {
  fmf: { fixed: [], knob: "components", int: true, default: 32 },
  // The default (one view per group, 81 groups × 8 components) is far above 2 MB at 256²: each
  // group's component carries one weight per texel. Groups of 27 views (3 groups) instead.
  "pca-views": { fixed: ["-p", "views-per-group=27"], knob: "components", int: true, default: null, first: 4 },
  lpca: { fixed: [], knob: "components", int: true, default: 5 },
  perceptual: { fixed: [], knob: "components", int: true, default: 32 },
  mlvq: { fixed: [], knob: "threshold", int: false, default: 3e-5 },
};
const knobArgs = (k, v) => [...k.fixed, "-p", `${k.knob}=${k.int ? v : Number(v.toPrecision(3))}`];
const near = (bytes) => Math.abs(bytes / TARGET - 1) <= TOLERANCE;

/** The package of about TARGET bytes: up to 4 trial compressions; every trial is recorded. */
function sizedPackage(h5, codec, dflt) {
  const k = KNOBS[codec];
  const trials = [];
  const points = []; // [value, bytes]
  if (k.default !== null && k.fixed.length === 0) {
    points.push([k.default, dflt.bytes]);
    if (near(dflt.bytes)) return { pkg: dflt, trials, same_as_default: true };
  }
  let guess;
  if (points.length === 0) guess = k.first;
  else if (k.int) guess = Math.max(1, Math.round((k.default * TARGET) / dflt.bytes));
  else guess = Number((k.default * (dflt.bytes / TARGET) ** (1 / 0.55)).toPrecision(3)); // at first bytes ∝ threshold^-0.55 (seen at 64²)
  let best = null;
  for (let i = 0; i < 4; ++i) {
    const p = compress(h5, codec, knobArgs(k, guess));
    trials.push({ [k.knob]: guess, bytes: p.bytes, compress_seconds: p.compress_seconds });
    log(`  ${codec} ${k.knob}=${guess}: ${mb(p.bytes)}`);
    points.push([guess, p.bytes]);
    if (!best || Math.abs(Math.log(p.bytes / TARGET)) < Math.abs(Math.log(best.bytes / TARGET))) best = p;
    if (near(p.bytes)) break;
    // the next guess from the two trials nearest the target
    const [a, b] = [...points].sort((x, y) => Math.abs(Math.log(x[1] / TARGET)) - Math.abs(Math.log(y[1] / TARGET)));
    let next;
    if (k.int) {
      if (!b || a[0] === b[0]) next = Math.round((a[0] * TARGET) / a[1]);
      else next = Math.round(a[0] + ((TARGET - a[1]) * (b[0] - a[0])) / (b[1] - a[1]));
      next = Math.max(1, Math.round(a[0] / 4), Math.min(4 * a[0], next));
    } else {
      // log(bytes) linear in log(threshold)
      let e = -0.5;
      if (b && a[0] !== b[0] && a[1] !== b[1]) e = Math.log(b[1] / a[1]) / Math.log(b[0] / a[0]);
      e = Number.isFinite(e) ? Math.min(-0.2, Math.max(-2, e)) : -0.5;
      next = a[0] * Math.min(30, Math.max(1 / 30, (TARGET / a[1]) ** (1 / e)));
    }
    if (!k.int) next = Number(next.toPrecision(3));
    if (points.some(([v]) => v === next || (!k.int && Math.abs(Math.log(v / next)) < 0.02))) break;
    guess = next;
  }
  return { pkg: best, trials, same_as_default: false };
}

// ---- the scene -------------------------------------------------------------------------------

/** The scene in the `btf render` format; the viewer takes it as `scene=` (material by id). */
function sceneOf(material) {
  return {
    camera: { position: [0, 1, 4], look_at: [0, 0, 0], up: [0, 1, 0], fov: 40, width: W, height: H },
    render: { integrator: "direct", exposure: 0 },
    objects: [{ shape: "sphere", uv_scale: 1, material: { type: "btf", ...material } }],
    lights: [{ type: "directional", direction: [1, 1.5, 1], irradiance: Math.PI }],
  };
}
const pageQuery = (id) => `scene=${encodeURIComponent(JSON.stringify(sceneOf({ id })))}&deterministic=1&mip=0&hud=0`;

// ---- the viewer ------------------------------------------------------------------------------

const PATIENCE = 1800000; // a frame with hundreds of components may take minutes on SwiftShader
const WAIT = { timeout: PATIENCE, polling: 100 };

/** The parts a stage ends with: component sections (factor codecs) or P6 level sections (mlvq). */
const isPart = (name) => /^b\d+\.k\d+$/.test(name) || /(^|\.)P6\.\d+$/.test(name);

/** Waits until the page has applied stage k (its parts decoded and on the GPU) or failed. */
async function waitStage(page, entry, parts, k) {
  const last = k === parts.length;
  const index = entry.sections.findIndex((s) => s.name === parts[k - 1].name);
  await page.waitForFunction(
    ({ index, k, last }) => {
      const m = window.btfViewer.state.materials?.[0];
      if (!m) return !!window.btfViewer.state.error;
      if (m.error) return true;
      if (last) return m.complete || m.done;
      return m.sections >= index + 1 && m.components >= k;
    },
    { index, k, last },
    WAIT,
  );
  // A last render applies whatever the worker handed over meanwhile.
  const s = await state(page);
  return { s, m: s.materials[0] ?? null };
}

/** The stages drawn: from the first drawable one, at most MAX_STAGES, evenly spaced, the last included. */
function sampleStages(first, n, max) {
  const count = n - first + 1;
  if (count <= max) return { stages: Array.from({ length: count }, (_, i) => first + i), step: 1 };
  const step = Math.ceil((count - 1) / (max - 1));
  const out = [];
  for (let k = first; k < n; k += step) out.push(k);
  out.push(n);
  return { stages: out, step };
}

async function emptyFrame(browser, server, id, entry) {
  server.hold(id, [entry.header_bytes]);
  const { page } = await openPage(browser, server.url, pageQuery(id));
  try {
    await page.waitForFunction(() => window.btfViewer.state.materials?.[0]?.codec, null, WAIT);
    const ms = [];
    for (let i = 0; i < FRAMES; ++i) ms.push((await render(page)).ms);
    return median(ms);
  } finally {
    server.releaseAll(id);
    await page.close();
  }
}

/** A binary PPM (as writePpm writes them) as { width, height, data: RGBA }. */
function readPpm(file) {
  const bytes = readFileSync(file);
  const m = /^P6\s+(\d+)\s+(\d+)\s+255\s/.exec(bytes.subarray(0, 64).toString("latin1"));
  const width = Number(m[1]), height = Number(m[2]);
  const rgb = bytes.subarray(m[0].length);
  const data = Buffer.alloc(width * height * 4);
  for (let i = 0, j = 0; j < rgb.length; i += 4, j += 3) {
    data[i] = rgb[j];
    data[i + 1] = rgb[j + 1];
    data[i + 2] = rgb[j + 2];
    data[i + 3] = 255;
  }
  return { width, height, data };
}

/** The bounding box of the frame's non-black pixels, 4 pixels wider; `lit`: how many there are. */
function sphereBox(f) {
  let x0 = f.width, y0 = f.height, x1 = -1, y1 = -1, lit = 0;
  for (let y = 0; y < f.height; ++y)
    for (let x = 0; x < f.width; ++x) {
      const i = 4 * (y * f.width + x);
      if (f.data[i] || f.data[i + 1] || f.data[i + 2]) {
        ++lit;
        x0 = Math.min(x0, x);
        x1 = Math.max(x1, x);
        y0 = Math.min(y0, y);
        y1 = Math.max(y1, y);
      }
    }
  if (lit === 0) return { x: 0, y: 0, width: f.width, height: f.height, lit };
  x0 = Math.max(0, x0 - 4);
  y0 = Math.max(0, y0 - 4);
  x1 = Math.min(f.width - 1, x1 + 4);
  y1 = Math.min(f.height - 1, y1 + 4);
  return { x: x0, y: y0, width: x1 - x0 + 1, height: y1 - y0 + 1, lit };
}

function crop(f, b) {
  const data = Buffer.alloc(b.width * b.height * 4);
  for (let y = 0; y < b.height; ++y) f.data.copy(data, y * b.width * 4, ((b.y + y) * f.width + b.x) * 4, ((b.y + y) * f.width + b.x + b.width) * 4);
  return { width: b.width, height: b.height, data };
}

/** Streams one package stage by stage; returns the row's viewer measurements. */
async function measure(browser, server, p, variant) {
  const id = p.id;
  const entry = listEntry(id, p.file, false);
  const parts = entry.sections.filter((s) => isPart(s.name));
  const ends = parts.map((s) => s.offset + s.size);
  ends[ends.length - 1] = entry.bytes;
  const n = parts.length;
  server.hold(id, ends.slice(0, -1));
  const dir = path.join(FRAMES_DIR, id);
  mkdirSync(dir, { recursive: true });
  const { page, problems } = await openPage(browser, server.url, pageQuery(id));
  page.setDefaultTimeout(PATIENCE);
  const row = { stages_total: n, stages: [] };
  try {
    let firstReady = null, plan = null;
    for (let k = 1; ; ) {
      const { s, m } = await waitStage(page, entry, parts, k);
      if (!m || m.error) {
        row.not_rendered = `not rendered: ${m?.error ?? s.error}`;
        return row;
      }
      if (firstReady === null && m.ready) {
        firstReady = k;
        plan = sampleStages(k, n, variant === "default" ? MAX_STAGES : MAX_STAGES_TARGET);
        row.first_frame = { stage: k, bytes: ends[k - 1], received: m.bytes, components: m.components };
        row.stage_step = plan.step;
        log(`  ${id}: first frame at stage ${k}/${n}, ${mb(ends[k - 1])}; drawing ${plan.stages.length} stages (every ${plan.step})`);
      }
      if (plan?.stages.includes(k)) {
        const r = await render(page);
        const file = path.join(dir, `stage-${String(k).padStart(4, "0")}.ppm`);
        writePpm(file, await pixels(page));
        row.stages.push({ stage: k, bytes: ends[k - 1], components: r.components, render_ms: r.ms, file });
      }
      if (k === n) break;
      const next = plan ? plan.stages.find((x) => x > k) : k + 1;
      for (let j = k; j < next; ++j) server.release(id);
      k = next;
    }
    const s = await state(page);
    const m = s.materials[0];
    if (!m.ready) {
      row.not_rendered = `not rendered: the material never became drawable (${JSON.stringify({ complete: m.complete, components: m.components })})`;
      return row;
    }
    row.complete = m.complete;
    row.components = `${m.components}/${m.totalComponents} ${m.unit}`;
    row.gpu_bytes = m.gpuBytes;
    const ms = [];
    for (let i = 0; i < FRAMES; ++i) ms.push((await render(page)).ms);
    row.frame_ms = median(ms);
    row.frame_ms_min = Math.min(...ms);
    row.frame_ms_all = ms;
    if (opt.shots && variant === "default") row.shot = await shot(page, p.codec);
    if (problems.length) row.page_errors = problems;
  } finally {
    server.releaseAll(id);
    await page.close();
  }
  // Quality of each drawn stage against the final frame: over the whole frame, and over the
  // sphere's bounding box (the criterion: the black background, some 80 % of the frame, would
  // otherwise lift any frame's SSIM).
  const final = row.stages[row.stages.length - 1].file;
  const finalFrame = readPpm(final);
  const box = sphereBox(finalFrame);
  row.sphere = { box, coverage: box.lit / (finalFrame.width * finalFrame.height) };
  const finalCrop = path.join(dir, "final.box.ppm");
  writePpm(finalCrop, crop(finalFrame, box));
  for (const st of row.stages) {
    const d = JSON.parse(run(opt.btf, ["image-diff", st.file, final, "--json"]));
    st.frame = { ssim: d.ssim, de2000_mean: d.de2000_mean };
    const c = st.file.replace(/\.ppm$/, ".box.ppm");
    writePpm(c, crop(readPpm(st.file), box));
    const b = JSON.parse(run(opt.btf, ["image-diff", c, finalCrop, "--json"]));
    st.ssim = b.ssim;
    st.de2000_mean = b.de2000_mean;
    st.de2000_p95 = b.de2000_p95;
  }
  const reach = row.stages.find((st) => st.ssim >= 0.95);
  row.ssim95 = { stage: reach.stage, bytes: reach.bytes, components: reach.components, sampled: row.stage_step > 1 };
  // The final frame against the C++ renderer.
  const sceneFile = path.join(dir, "scene.json");
  writeFileSync(sceneFile, JSON.stringify(sceneOf({ file: p.file }), null, 1));
  const cpp = path.join(dir, "cpp.exr");
  const t = Date.now();
  run(opt.btf, ["-q", "render", sceneFile, "--spp", opt.spp, "-o", cpp]);
  row.cpp_render_seconds = (Date.now() - t) / 1000;
  const d = JSON.parse(run(opt.btf, ["image-diff", final, cpp, "--json", "-o", path.join(dir, "viewer-vs-cpp.png")]));
  row.vs_cpp = { de2000_mean: d.de2000_mean, de2000_p95: d.de2000_p95, ssim: d.ssim };
  for (const st of row.stages) st.file = path.relative(OUT, st.file);
  return row;
}

/** The canvas as DIR/<codec>.png; halved (ImageMagick) when over 300 KB. */
async function shot(page, codec) {
  mkdirSync(opt.shots, { recursive: true });
  const file = path.join(opt.shots, `${codec}.png`);
  await page.locator("canvas").screenshot({ path: file });
  let how = `${W}×${H} PNG`;
  if (statSync(file).size > 300000) {
    try {
      execFileSync("convert", [file, "-resize", "50%", "-strip", file]);
      how = `${W / 2}×${H / 2} PNG (halved with ImageMagick: the full frame's PNG was over 300 KB)`;
    } catch (e) {
      how += ` (over 300 KB; ImageMagick failed: ${e.message})`;
    }
  }
  return { file: path.relative(REPO, file), bytes: statSync(file).size, how };
}

// ---- the run ---------------------------------------------------------------------------------

mkdirSync(PACKAGES, { recursive: true });
rmSync(FRAMES_DIR, { recursive: true, force: true });
mkdirSync(FRAMES_DIR, { recursive: true });

const command = `node ${path.relative(REPO, process.argv[1])} ${process.argv.slice(2).join(" ")}`.trim();
const lscpu = (() => {
  try {
    return run("lscpu", []);
  } catch {
    return "";
  }
})();
const cpuModel = /^Model name:\s*(.+)$/m.exec(lscpu)?.[1] ?? os.cpus()[0].model;

log(`material: btf synth --preset woven_fabric --size ${SIZE} (ubo81: 81 views × 81 lights)`);
const mat = material();

// Packages: each codec at its defaults and at about TARGET bytes.
const rows = [];
for (const codec of CODECS) {
  const dflt = compress(mat.file, codec, []);
  log(`${codec} default: ${mb(dflt.bytes)} (${dflt.compress_seconds.toFixed(0)} s${dflt.cached ? ", cached" : ""})`);
  rows.push({ codec, variant: "default", params: "defaults", pkg: dflt });
  const sized = sizedPackage(mat.file, codec, dflt);
  rows.push({
    codec,
    variant: "≈ target",
    params: sized.same_as_default ? "defaults (already within ±25 %)" : sized.pkg.args.join(" "),
    pkg: sized.pkg,
    trials: sized.trials,
    within_tolerance: near(sized.pkg.bytes),
  });
}
const ids = new Map(); // package file → id
for (const r of rows) {
  if (!ids.has(r.pkg.file)) ids.set(r.pkg.file, path.basename(r.pkg.file, ".btfpkg"));
  r.pkg.id = ids.get(r.pkg.file);
}
const files = Object.fromEntries([...ids].map(([file, id]) => [id, file]));
const site = await startServer(makeSite("bench-codecs-site", files, [...ids.values()]));
const browser = await launchBrowser();
let empty_frame_ms = null;
try {
  const firstId = [...ids.values()][0];
  empty_frame_ms = await emptyFrame(browser, site, firstId, listEntry(firstId, files[firstId], false));
  log(`empty frame: ${empty_frame_ms.toFixed(1)} ms`);
  const done = new Map(); // id → viewer measurements (a package shared by two rows is measured once)
  for (const r of rows) {
    if (!done.has(r.pkg.id)) {
      log(`${r.codec} ${r.variant}: ${r.pkg.id}, ${mb(r.pkg.bytes)}`);
      const t = Date.now();
      let v;
      try {
        v = await measure(browser, site, r.pkg, r.variant);
      } catch (e) {
        v = { not_rendered: `not rendered: ${e.message.split("\n")[0]}` };
      }
      v.seconds = (Date.now() - t) / 1000;
      done.set(r.pkg.id, v);
      log(`  ${v.not_rendered ?? `done in ${v.seconds.toFixed(0)} s: frame ${v.frame_ms.toFixed(0)} ms, ΔE00 ${v.vs_cpp.de2000_mean.toFixed(2)}`}`);
    }
    r.viewer = done.get(r.pkg.id);
  }
} finally {
  await browser.close();
  await site.close();
}

// ---- the report ------------------------------------------------------------------------------

const machine = {
  cpu: cpuModel,
  cores: os.cpus().length,
  chromium: (() => {
    try {
      return run(CHROMIUM, ["--version"]).trim();
    } catch {
      return "unknown";
    }
  })(),
  openblas_coretype: process.env.OPENBLAS_CORETYPE ?? null,
  node: process.version,
};
const machineLine = `${machine.cpu}, ${machine.cores} cores; ${machine.chromium}, WebGL2 through SwiftShader; node ${machine.node}; OPENBLAS_CORETYPE=${machine.openblas_coretype ?? "(unset)"}`;
const wall = (Date.now() - T0) / 1000;

const cell = (r) => {
  const v = r.viewer;
  const bytes = r.pkg.bytes;
  const head = [r.codec, r.variant === "default" ? "default" : `≈ ${mb(TARGET)}`, r.params.replace(/\|/g, "\\|"), mb(bytes), `${r.pkg.compress_seconds.toFixed(0)} s`];
  if (v.not_rendered) return [...head, v.not_rendered.replace(/\|/g, "\\|"), "", "", "", ""];
  const ff = v.first_frame;
  const reach = v.ssim95;
  const n = v.stages_total;
  return [
    ...head,
    `${mb(ff.bytes)} (${pct(ff.bytes, bytes)}; ${ff.stage}/${n})`,
    `${mb(reach.bytes)} (${pct(reach.bytes, bytes)}; ${reach.stage}/${n})${reach.sampled ? " ¹" : ""}`,
    `${(v.gpu_bytes / 1048576).toFixed(1)} MiB`,
    `${v.frame_ms.toFixed(0)} ms`,
    `${v.vs_cpp.de2000_mean.toFixed(2)} (p95 ${v.vs_cpp.de2000_p95.toFixed(2)})`,
  ];
};
const measured = [...new Map(rows.filter((r) => r.viewer.stages?.length).map((r) => [r.pkg.id, r])).values()];
const coverage = measured.length ? median(measured.map((r) => r.viewer.sphere.coverage)) : null;
const box = measured[0]?.viewer.sphere.box;
const lines = [
  `Material: \`btf synth --preset woven_fabric --size ${SIZE}\` (${SIZE}² texels; default sampling ubo81: 81 views × 81 lights). Scene: the viewer's demo sphere (uv scale 1), default camera, one directional light, ${W} × ${H}, \`deterministic=1&mip=0&hud=0\`.`,
  "",
  "| codec | package | parameters | package bytes | compression (wall) | bytes to first frame (stage) | bytes to SSIM 0.95 (stage) | GPU texture memory | frame time | mean ΔE00 vs `btf render` (p95) |",
  "|---|---|---|---|---|---|---|---|---|---|",
  ...rows.map((r) => `| ${cell(r).join(" | ")} |`),
  "",
  `- Stages: the package held at the end of each component section (each P6 level section for mlvq); stage k/n = k of them received. First frame: the first stage at which the material draws (\`state.materials[0].ready\`).`,
  `- SSIM 0.95: of the stage's frame against the package's own final frame (\`btf image-diff\`), over the sphere's bounding box${box ? ` (${box.width} × ${box.height} px)` : ""}: the black background${coverage !== null ? ` (the sphere lights ${(100 * coverage).toFixed(0)} % of the frame)` : ""} would lift any frame's SSIM. Whole-frame SSIM per stage in the JSON.`,
  `- GPU texture memory: \`state.materials[0].gpuBytes\` once complete. Frame time: median of ${FRAMES} \`btfViewer.render()\` at ${W} × ${H} (draw, then a 1-pixel read-back that waits for SwiftShader); an empty frame (material not yet drawable) takes ${empty_frame_ms?.toFixed(0) ?? "?"} ms. All runs in the JSON.`,
  `- ΔE00: the viewer's final frame against \`btf render --spp ${opt.spp}\` (direct lighting, EXR) of the same scene file at ${W} × ${H}, over the whole frame (the background is black in both pictures, so over the sphere alone the mean is roughly ${coverage ? (1 / coverage).toFixed(1) : "?"}× larger).`,
  `- Target ${mb(TARGET)} ± ${TOLERANCE * 100} %: one parameter per codec varied in a few trial compressions of this material (trials in the JSON); compression times are wall times on this machine (cached packages keep the time of their first compression).`,
];
if (rows.some((r) => r.viewer.ssim95?.sampled))
  lines.push(`- ¹ Stages sampled (at most ${MAX_STAGES} drawn for the defaults, ${MAX_STAGES_TARGET} for ≈ ${mb(TARGET)}, evenly spaced from the first drawable one, the last included): the bytes of the first *drawn* stage reaching SSIM 0.95, an upper bound. Drawn: ${measured.map((r) => `${r.pkg.id} ${r.viewer.stages.length}/${r.viewer.stages_total}`).join(", ")}.`);
lines.push("", `Machine: ${machineLine}.`, "", `Command: \`${command}\` (wall time ${(wall / 60).toFixed(1)} min).`);
const table = lines.join("\n") + "\n";
writeFileSync(path.join(OUT, "table.md"), table);
const result = {
  date: new Date().toISOString(),
  command,
  machine,
  wall_seconds: wall,
  material: { ...mat, size: SIZE, sampling: "ubo81 (81 views × 81 lights)" },
  scene: sceneOf({ id: "<package>" }),
  target_bytes: TARGET,
  tolerance: TOLERANCE,
  max_stages: MAX_STAGES,
  max_stages_target: MAX_STAGES_TARGET,
  empty_frame_ms,
  rows: rows.map((r) => ({ ...r, pkg: { ...r.pkg, file: path.relative(OUT, r.pkg.file) } })),
};
writeFileSync(path.join(OUT, "codecs-bench.json"), JSON.stringify(result, null, 1));
console.log(table);
