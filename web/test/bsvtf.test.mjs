// The viewer's BSVTF mode in headless Chromium against `btf serve` of a BSVTF package (btf
// bsvtf), behind a 2 Mbit/s link: the tile cache fills from the coarsest tiles down as the
// feedback pass asks for them, every frame nearer to the final one, and the settled frame matches
// `btf render` of the fmf package it was made from. Pictures go to web/test-artifacts/bsvtf/.

import { test, before, after } from "node:test";
import assert from "node:assert/strict";
import { mkdirSync, readFileSync, rmSync, writeFileSync } from "node:fs";
import path from "node:path";
import { launchBrowser, meanDiff, openPage, pixels, render, snapshot, state, timeline, writePpm } from "./browser.mjs";
import { ARTIFACTS, buildViewer, makeFixtures, run } from "./fixtures.mjs";
import { startBtfServe } from "./processes.mjs";
import { startThrottle } from "./throttle.mjs";

const OUT = path.join(ARTIFACTS, "bsvtf");
const SIZE = 192;

let fx, browser, serve;
const closers = [];

before(async () => {
  fx = makeFixtures();
  rmSync(OUT, { recursive: true, force: true });
  mkdirSync(OUT, { recursive: true });
  const viewer = buildViewer(path.join(OUT, "viewer"));
  serve = await startBtfServe(fx.bin, [fx.packages.bsvtf, fx.packages.bsvtfLossless, "--web", viewer]);
  closers.push(() => serve.close());
  browser = await launchBrowser();
  closers.push(() => browser.close());
});

after(async () => {
  for (const close of closers.reverse()) await close();
});

// A sphere with the 32² material repeated twice: magnified everywhere, so the settled frame needs
// the finest tiles and equals the full factorization (up to the tile codec's 1 %).
const scene = (file) => ({
  camera: { position: [0, 0.6, 3.2], look_at: [0, 0, 0], up: [0, 1, 0], fov: 40, width: SIZE, height: SIZE },
  render: { integrator: "direct", exposure: 0 },
  objects: [{ shape: "sphere", uv_scale: 2, material: { type: "btf", file } }],
  lights: [{ type: "directional", direction: [-0.5, 0.8, 0.7], irradiance: 2.5 }],
});

test("BSVTF mode: the tile cache refines the frames as tiles arrive and settles on btf render's picture", async () => {
  const link = await startThrottle(new URL(serve.url).port, 2e6);
  const view = scene("woven_fabric.bsvtf");
  const { page, problems } = await openPage(browser, link.url, `scene=${encodeURIComponent(JSON.stringify(view))}&deterministic=1&hud=0&snapshots=1&cache=256`);
  try {
    await page.waitForFunction(() => window.btfViewer.state.complete || window.btfViewer.state.error, null, { timeout: 90000 });
    await render(page);
    const s = await state(page);
    assert.equal(s.error, null);
    assert.equal(s.materials[0].codec, "bsvtf");
    assert.equal(s.components, 8, "both U packets arrived");
    const b = s.bsvtf;
    // cache=256 holds (256 / 16)² = 256 tiles: room for all 42, so it ends with every tile the
    // sphere shows at level 0 (both groups), and never asked for a tile twice.
    assert.equal(b.capacity, 256);
    assert.ok(b.settled && b.inFlight === 0, JSON.stringify(b));
    assert.equal(b.shown, b.resident, JSON.stringify(b));
    assert.ok(b.resident >= 2 * 16 && b.resident <= 42, JSON.stringify(b));
    assert.ok(b.tileBytes > 0 && b.packetBytes > 0, JSON.stringify(b));

    // Refinement: frames with more tiles or components, each nearer to the final frame.
    const stages = (await timeline(page)).filter((e) => e.tiles > 0 && e.components > 0);
    const final = await pixels(page);
    const frames = stages.map((e) => snapshot(e, SIZE, SIZE));
    const d = frames.map((f) => meanDiff(f, final));
    const summary = stages.map((e, i) => `${e.components} components, ${e.tiles} tiles, ${e.bytes} B at ${e.t.toFixed(0)} ms: ${d[i].toFixed(2)}`);
    writeFileSync(path.join(OUT, "timeline.json"), JSON.stringify(summary, null, 1));
    writePpm(path.join(OUT, "first.ppm"), frames[0]);
    assert.ok(stages.length >= 3, `only ${stages.length} stages:\n${summary.join("\n")}`);
    assert.ok(stages[0].tiles < b.shown, summary.join("\n"));
    for (let k = 1; k < stages.length; ++k) assert.ok(d[k] <= d[k - 1] + 0.05, `the difference to the final frame grew:\n${summary.join("\n")}`);
    assert.ok(d[0] > 0.5, `no visible refinement:\n${summary.join("\n")}`);

    // The settled frame against the C++ renderer on the fmf package the BSVTF was made from.
    const sceneFile = path.join(OUT, "scene.json");
    writeFileSync(sceneFile, JSON.stringify(scene(fx.packages.woven_fabric), null, 1));
    const cpp = path.join(OUT, "cpp.exr");
    run(fx.bin, ["-q", "render", sceneFile, "--spp", "64", "-o", cpp]);
    const viewer = path.join(OUT, "viewer.ppm");
    writePpm(viewer, final);
    const metrics = JSON.parse(run(fx.bin, ["image-diff", viewer, cpp, "--json", "-o", path.join(OUT, "viewer-vs-cpp.png")]));
    writeFileSync(path.join(OUT, "viewer-vs-cpp.json"), JSON.stringify(metrics, null, 1));
    assert.ok(metrics.de2000_mean <= 1, `mean ΔE00 ${metrics.de2000_mean} between the BSVTF viewer and btf render`);
    assert.ok(metrics.ssim > 0.9, JSON.stringify(metrics));
    assert.deepEqual(problems, []);
    await page.locator("canvas").screenshot({ path: path.join(OUT, "final.png") });
  } finally {
    await page.close();
    await link.close();
  }
});

test("BSVTF mode: two materials share a cache too small for both and it never overflows", async () => {
  // cache=64 holds (64 / 16)² = 16 tiles: the two materials' coarsest tiles (4) and some of the
  // 2 × 32 finest tiles the spheres show, so the decision rule has to swap.
  const view = scene("woven_fabric.bsvtf");
  view.camera.position = [0, 0.6, 4.5];
  view.objects = [
    { shape: "sphere", uv_scale: 2, position: [-0.8, 0, 0], scale: 0.7, material: { type: "btf", id: "woven_fabric" } },
    { shape: "sphere", uv_scale: 2, position: [0.8, 0, 0], scale: 0.7, material: { type: "btf", id: "woven_lossless" } },
  ];
  const { page, problems } = await openPage(browser, serve.url, `scene=${encodeURIComponent(JSON.stringify(view))}&deterministic=1&hud=0&cache=64`);
  try {
    await page.waitForFunction(() => window.btfViewer.state.complete || window.btfViewer.state.error, null, { timeout: 90000 });
    await render(page);
    const s = await state(page);
    assert.equal(s.error, null);
    assert.deepEqual(s.objects.map((o) => [o.material, o.visible]), [["woven_fabric", true], ["woven_lossless", true]]);
    const b = s.bsvtf;
    assert.equal(b.capacity, 16);
    assert.ok(b.settled && b.resident <= 16 && b.shown === b.resident, JSON.stringify(b));
    assert.ok(b.swaps > 0, `the cache never had to choose: ${JSON.stringify(b)}`);
    const frame = await pixels(page);
    writePpm(path.join(OUT, "two-materials.ppm"), frame);
    await page.locator("canvas").screenshot({ path: path.join(OUT, "two-materials.png") });
    // Both spheres are drawn (not the background): the centre row crosses both.
    const row = SIZE / 2, lit = (x) => frame.data.subarray((row * SIZE + x) * 4, (row * SIZE + x) * 4 + 3).some((v) => v > 20);
    assert.ok(lit(Math.round(SIZE * 0.3)) && lit(Math.round(SIZE * 0.7)));
    assert.deepEqual(problems, []);
  } finally {
    await page.close();
  }
});

test("BSVTF mode: a damaged tile fails its material with a message naming it, and the page does not hang", async () => {
  // The first payload of section 'tiles' (a coarsest tile, the first one asked for) with an
  // unknown format byte. Tiles carry no checksum of their own; the decoder refuses them.
  const bytes = Buffer.from(readFileSync(fx.packages.bsvtf));
  const h = bytes.readUInt32LE(12);
  const header = JSON.parse(bytes.subarray(24, 24 + h).toString("utf8"));
  const tiles = header.sections.find((x) => x.name === "tiles");
  bytes[24 + h + tiles.offset] = 7;
  const damaged = path.join(OUT, "woven_damaged.bsvtf");
  writeFileSync(damaged, bytes);
  const server = await startBtfServe(fx.bin, [damaged, "--web", path.join(OUT, "viewer")]);
  const { page, problems } = await openPage(browser, server.url, `deterministic=1&hud=0&size=96x96`);
  try {
    await page.waitForFunction(() => window.btfViewer.state.error, null, { timeout: 60000 });
    const s = await state(page);
    assert.match(s.error, /^woven_damaged: tile \d+: tile: unknown format 7$/);
    assert.equal(s.done, true);
    assert.match(await page.locator("#message").innerText(), /woven_damaged: tile \d+: tile: unknown format 7/);
    assert.deepEqual(problems, []);
  } finally {
    await page.close();
    await server.close();
  }
});
