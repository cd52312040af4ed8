// SPDX-License-Identifier: MIT
// Streaming benchmarks of the viewer for docs/benchmarks.md, in headless Chromium (WebGL2 on the
// CPU through SwiftShader):
//
//  1. Time to first frame and to full quality: a fresh page loads the viewer and the built-in demo
//     material from `btf serve` through a throttled link (test/throttle.mjs) at each rate; the
//     viewer's own files come over the same link. Read from the page's timeline (the frame
//     submitted with the first component; the frame with every component). Median of --runs.
//  2. Screenshots of the page (HUD and controls) mid-stream and converged, for docs/viewer.md
//     (--shots DIR).
//  3. Quality against bytes: the package held back after each component (test/server.mjs), the
//     frame of each stage compared with the final frame by `btf image-diff` (SSIM, ΔE00); the
//     bytes needed to reach SSIM 0.95.
//
// Usage: node bench/stream.mjs [--btf build/release/btf] [--size 512] [--runs 3]
//                              [--rates 10mbit,100mbit] [--out DIR] [--shots DIR]

import { mkdirSync, rmSync, writeFileSync } from "node:fs";
import os from "node:os";
import path from "node:path";
import { parseArgs } from "node:util";
import { launchBrowser, openPage, pixels, render, state, timeline, writePpm } from "../test/browser.mjs";
import { ARTIFACTS, REPO, listEntry, makeSite, run } from "../test/fixtures.mjs";
import { startBtfServe } from "../test/processes.mjs";
import { startServer } from "../test/server.mjs";
import { parseRate, startThrottle } from "../test/throttle.mjs";

const { values: opt } = parseArgs({
  options: {
    btf: { type: "string", default: path.join(REPO, "build/release/btf") },
    size: { type: "string", default: "512" },
    runs: { type: "string", default: "3" },
    rates: { type: "string", default: "10mbit,100mbit" },
    out: { type: "string", default: path.join(ARTIFACTS, "bench") },
    shots: { type: "string" },
  },
});
const SIZE = Number(opt.size);
const RUNS = Number(opt.runs);
const median = (v) => [...v].sort((a, b) => a - b)[Math.floor(v.length / 2)];
const kib = (b) => `${(b / 1024).toFixed(0)} KiB`;

/** Where `btf serve` keeps the demo material (cmd_serve.cpp: cache_folder()). */
function demoPackage() {
  const env = process.env;
  const root = env.BTF_CACHE_DIR || (env.XDG_CACHE_HOME?.startsWith("/") ? path.join(env.XDG_CACHE_HOME, "btfkit") : path.join(os.homedir(), ".cache", "btfkit"));
  return path.join(root, "demo", "woven_fabric.btfpkg");
}

async function timeToFrames(browser, serve) {
  const rows = [];
  for (const rateText of opt.rates.split(",")) {
    const rate = parseRate(rateText);
    const runs = [];
    let total = 0, components = 0;
    for (let r = 0; r < RUNS; ++r) {
      const link = await startThrottle(new URL(serve.url).port, rate);
      const { page, problems } = await openPage(browser, link.url, `material=woven_fabric&size=${SIZE}x${SIZE}&hud=0`);
      try {
        await page.waitForFunction(() => window.btfViewer.state.complete && window.btfViewer.timeline().some((e) => e.complete), null, { timeout: 600000 });
        const s = await state(page);
        if (s.error || problems.length) throw new Error(`${s.error} ${problems.join(" ")}`);
        const tl = await timeline(page);
        const t = s.materials[0].times;
        const f = tl.find((e) => e.components > 0);
        const c = tl.find((e) => e.complete && e.components === s.totalComponents);
        runs.push({ stream_start: t.start, ready: t.ready, first_frame: f.t, first_frame_bytes: f.bytes, received: t.received, decoded: t.decoded, full_quality: c.t });
        total = s.total;
        components = s.totalComponents;
      } finally {
        await page.close();
        await link.close();
      }
    }
    const m = (k) => median(runs.map((x) => x[k]));
    const row = {
      rate: rateText,
      package_bytes: total,
      components,
      median: Object.fromEntries(Object.keys(runs[0]).map((k) => [k, m(k)])),
      runs,
    };
    const ms = (k) => `${row.median[k].toFixed(0)} ms`;
    console.log(`${rateText} (medians of ${RUNS}): stream opened ${ms("stream_start")}, first component decoded ${ms("ready")}, first frame ${ms("first_frame")} (drawn with ${kib(row.median.first_frame_bytes)} received), last byte ${ms("received")}, decoded ${ms("decoded")}, full-quality frame ${ms("full_quality")}`);
    rows.push(row);
  }
  return rows;
}

/**
 * The whole page (HUD, controls): the package held after its 4th component, then complete
 * (test/server.mjs holds the body at section boundaries).
 */
async function screenshots(browser, server, parts, dir) {
  mkdirSync(dir, { recursive: true });
  server.hold("woven_fabric", [parts[3].offset + parts[3].size]);
  const page = await browser.newPage({ viewport: { width: 1100, height: 640 } });
  try {
    await page.goto(`${server.url}index.html?material=woven_fabric&uvscale=4,2&camera=-1.4,0.9,2.6&light=-1,1.4,1.2`);
    await page.waitForFunction(() => window.btfViewer.state.components === 4, null, { timeout: 600000 });
    const frames = (await state(page)).frames;
    await page.waitForFunction((n) => window.btfViewer.state.frames >= n + 2, frames, { timeout: 600000 });
    await page.screenshot({ path: path.join(dir, "viewer-streaming.png") });
    server.releaseAll("woven_fabric");
    await page.waitForFunction(() => window.btfViewer.state.complete, null, { timeout: 600000 });
    const done = (await state(page)).frames;
    await page.waitForFunction((n) => window.btfViewer.state.frames >= n + 2, done, { timeout: 600000 });
    await page.screenshot({ path: path.join(dir, "viewer-complete.png") });
    console.log(`screenshots in ${dir}: at 4/${parts.length} components, and complete`);
  } finally {
    server.releaseAll("woven_fabric");
    await page.close();
  }
}

async function qualityAgainstBytes(browser, server, entry, parts, out) {
  server.hold("woven_fabric", parts.slice(0, -1).map((s) => s.offset + s.size));
  const { page } = await openPage(browser, server.url, `material=woven_fabric&size=${SIZE}x${SIZE}&deterministic=1&mip=0&hud=0`);
  const stages = [];
  try {
    for (let k = 1; k <= parts.length; ++k) {
      if (k > 1) server.release("woven_fabric");
      await page.waitForFunction((n) => window.btfViewer.state.components === n, k, { timeout: 120000 });
      await render(page);
      const file = path.join(out, `stage-${String(k).padStart(2, "0")}.ppm`);
      writePpm(file, await pixels(page));
      if (k === 1 || k === 4 || k === parts.length) await page.locator("canvas").screenshot({ path: path.join(out, `stage-${k}.png`) });
      stages.push({ components: k, bytes: parts[k - 1].offset + parts[k - 1].size, file });
    }
  } finally {
    server.releaseAll("woven_fabric");
    await page.close();
  }
  const final = stages[stages.length - 1].file;
  for (const s of stages) {
    const m = JSON.parse(run(opt.btf, ["image-diff", s.file, final, "--json"]));
    s.ssim = m.ssim;
    s.de2000_mean = m.de2000_mean;
  }
  const reach = stages.find((s) => s.ssim >= 0.95);
  console.log(`quality against bytes (${stages.length} components, ${kib(entry.bytes)}):`);
  for (const s of stages) console.log(`  ${s.components} components, ${kib(s.bytes)}: SSIM ${s.ssim.toFixed(4)}, mean ΔE00 ${s.de2000_mean.toFixed(3)}`);
  console.log(`SSIM 0.95 reached with ${reach.components} components, ${reach.bytes} bytes (${((100 * reach.bytes) / entry.bytes).toFixed(1)} % of the package)`);
  return { stages: stages.map(({ file, ...rest }) => rest), reach: { components: reach.components, bytes: reach.bytes }, package_bytes: entry.bytes };
}

const out = opt.out;
rmSync(out, { recursive: true, force: true });
mkdirSync(out, { recursive: true });
console.log(`# ${new Date().toISOString()}, ${os.cpus().length} cores, ${os.cpus()[0].model}; viewer ${SIZE}² in headless chromium (SwiftShader)`);
const serve = await startBtfServe(opt.btf, []);
const browser = await launchBrowser();
try {
  const times = await timeToFrames(browser, serve);
  const pkg = demoPackage();
  const site = await startServer(makeSite("bench-site", { woven_fabric: pkg }, ["woven_fabric"]));
  const entry = listEntry("woven_fabric", pkg, false);
  const parts = entry.sections.filter((s) => /^b0\.k\d+$/.test(s.name));
  let quality;
  try {
    if (opt.shots) await screenshots(browser, site, parts, opt.shots);
    quality = await qualityAgainstBytes(browser, site, entry, parts, out);
  } finally {
    await site.close();
  }
  writeFileSync(path.join(out, "stream-bench.json"), JSON.stringify({ size: SIZE, runs: RUNS, times, quality }, null, 1));
} finally {
  await browser.close();
  await serve.close();
}
