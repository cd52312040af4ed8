// SPDX-License-Identifier: MIT
// The viewer's BSVTF mode against its fmf mode on the scene of bench/bsvtf_bench.sh (20 materials
// of 512² texels, 25 × 25 directions, 16 components), in headless Chromium (SwiftShader) on
// loopback:
//
//  - BSVTF: `btf serve` of the 20 .bsvtf packages; the page waits until the tile cache settles.
//    Bytes fetched (package prefixes, U packets, tiles), time, tiles resident, and the GPU memory
//    of the eigen-textures (the cache texture, whatever the number of materials).
//  - fmf: `btf serve` of the 20 .btfpkg packages; the page waits until every package is complete.
//    Bytes (the packages whole), time, the GPU memory of the eigen-texture atlases.
//  - The two settled frames compared by `btf image-diff` (SSIM, ΔE00).
//
// Usage: bash bench/bsvtf_bench.sh first (it makes out/bsvtf-bench), then
//   node web/bench/bsvtf.mjs [--btf build/release/btf] [--dir out/bsvtf-bench] [--cache 2048]
//                            [--size 480x270] [--out DIR]

import { mkdirSync, readFileSync, statSync, writeFileSync } from "node:fs";
import path from "node:path";
import { parseArgs } from "node:util";
import { launchBrowser, openPage, pixels, render, state, writePpm } from "../test/browser.mjs";
import { ARTIFACTS, REPO, buildViewer, run } from "../test/fixtures.mjs";
import { startBtfServe } from "../test/processes.mjs";

const { values: opt } = parseArgs({
  options: {
    btf: { type: "string", default: path.join(REPO, "build/release/btf") },
    dir: { type: "string", default: path.join(REPO, "out/bsvtf-bench") },
    cache: { type: "string", default: "2048" },
    size: { type: "string", default: "480x270" },
    out: { type: "string", default: path.join(ARTIFACTS, "bench-bsvtf") },
  },
});
const [W, H] = opt.size.split("x").map(Number);
mkdirSync(opt.out, { recursive: true });
const mib = (b) => `${(b / 1048576).toFixed(1)} MiB`;

// The simulator's scene without its floor (the viewer shows BTF objects only).
const simScene = JSON.parse(readFileSync(path.join(opt.dir, "scene.json"), "utf8"));
const objects = simScene.objects.filter((o) => o.material?.type === "btf");
const ids = objects.map((o) => path.basename(o.material.file).replace(/\.btfpkg$/, ""));
const scene = {
  camera: { ...simScene.camera, width: W, height: H },
  objects: objects.map((o, i) => ({ ...o, material: { type: "btf", id: ids[i] } })),
  lights: simScene.lights,
};
const viewer = buildViewer(path.join(opt.out, "viewer"));
const browser = await launchBrowser();

async function show(mode) {
  const files = ids.map((id) => path.join(opt.dir, `${id}.${mode === "bsvtf" ? "bsvtf" : "btfpkg"}`));
  const serve = await startBtfServe(opt.btf, [...files, "--web", viewer]);
  const { page, problems } = await openPage(browser, serve.url, `scene=${encodeURIComponent(JSON.stringify(scene))}&deterministic=1&hud=0&cache=${opt.cache}`);
  try {
    const t0 = Date.now();
    await page.waitForFunction(() => window.btfViewer.state.complete || window.btfViewer.state.error, null, { timeout: 900000, polling: 500 });
    const seconds = (Date.now() - t0) / 1000;
    await render(page);
    const s = await state(page);
    if (s.error || problems.length) throw new Error(`${mode}: ${s.error ?? problems.join("; ")}`);
    const frame = await pixels(page);
    const file = path.join(opt.out, `${mode}.ppm`);
    writePpm(file, frame);
    await page.locator("canvas").screenshot({ path: path.join(opt.out, `${mode}.png`) });
    const packages = files.reduce((n, f) => n + statSync(f).size, 0);
    return { seconds, bytes: s.bytes, packages, frames: s.frames, bsvtf: s.bsvtf, file };
  } finally {
    await page.close();
    await serve.close();
  }
}

const b = await show("bsvtf");
const f = await show("fmf");
const diff = JSON.parse(run(opt.btf, ["image-diff", b.file, f.file, "--json", "-o", path.join(opt.out, "bsvtf-vs-fmf.png")]));

// GPU memory of the eigen-textures: the cache (one 72² RGBA16F tile per layer) against the fmf
// atlases (level 0 and its mip chain, 1.5 W × H texels, RGBA16F, 4 layers for 16 components).
const header = (file) => {
  const bytes = readFileSync(file);
  return JSON.parse(bytes.subarray(24, 24 + bytes.readUInt32LE(12)).toString("utf8"));
};
const h = header(path.join(opt.dir, `${ids[0]}.bsvtf`)).bsvtf;
const stride = h.tile + 2 * h.pad;
const cacheBytes = b.bsvtf.capacity * stride * stride * 4 * 2;
const fmfBytes = ids.length * 1.5 * h.width * h.height * 4 * 2 * Math.ceil(16 / 4);

const lines = [
  `# ${new Date().toISOString().slice(0, 16)} UTC, ${ids.length} materials of ${h.width}² texels, ${W}×${H}, cache ${opt.cache}² texels (${b.bsvtf.capacity} tiles)`,
  "| mode | bytes fetched | of the packages | time to settle | frames | eigen-texture GPU memory |",
  "|---|---|---|---|---|---|",
  `| BSVTF | ${mib(b.bytes)} (tiles ${mib(b.bsvtf.tileBytes)}, U packets ${mib(b.bsvtf.packetBytes)}) | ${((100 * b.bytes) / b.packages).toFixed(1)} % of ${mib(b.packages)} | ${b.seconds.toFixed(1)} s | ${b.frames} | ${mib(cacheBytes)} (${b.bsvtf.resident} tiles resident) |`,
  `| fmf | ${mib(f.bytes)} | ${((100 * f.bytes) / f.packages).toFixed(1)} % of ${mib(f.packages)} | ${f.seconds.toFixed(1)} s | ${f.frames} | ${mib(fmfBytes)} |`,
  `settled BSVTF frame against the fmf frame: SSIM ${diff.ssim.toFixed(4)}, mean ΔE00 ${diff.de2000_mean.toFixed(2)}, 95th percentile ${diff.de2000_p95.toFixed(2)}, PSNR ${diff.psnr_db.toFixed(1)} dB`,
];
writeFileSync(path.join(opt.out, "result.md"), lines.join("\n") + "\n");
console.log(lines.join("\n"));
await browser.close();
