// SPDX-License-Identifier: MIT
// The viewer's BSVTF mode in headless Chromium against `btf serve` of a BSVTF package (btf
// bsvtf), behind a 2 Mbit/s link that lets the tile and U-packet requests through one at a time,
// each once the page has drawn what the one before brought: the tile cache fills from the
// coarsest tiles down as the feedback pass asks for them, every frame nearer to the final one,
// and the settled frame matches `btf render` of the fmf package it was made from. Pictures go to
// web/test-artifacts/bsvtf/.

import { test, before, after } from "node:test";
import assert from "node:assert/strict";
import { mkdirSync, readFileSync, rmSync, writeFileSync } from "node:fs";
import path from "node:path";
import { PATIENCE_MS, launchBrowser, meanDiff, openPage, pixels, render, snapshot, state, timeline, writePpm } from "./browser.mjs";
import { ARTIFACTS, buildViewer, makeFixtures, run } from "./fixtures.mjs";
import { decompress } from "fzstd";
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

/**
 * How many U packets and tiles a byte-range request of a BSVTF package brings: those whose
 * stored bytes lie inside the range { from, to } (to exclusive, null for the file's end).
 */
function itemsOfPackage(file) {
  const bytes = readFileSync(file);
  const h = bytes.readUInt32LE(12);
  const header = JSON.parse(bytes.subarray(24, 24 + h).toString("utf8"));
  const base = 24 + h;
  const section = (name) => header.sections.find((x) => x.name === name);
  const index = section("tiles.index"), tiles = section("tiles");
  let data = bytes.subarray(base + index.offset, base + index.offset + index.size);
  if (index.coding === "zstd") data = Buffer.from(decompress(data));
  else assert.equal(index.coding, "raw");
  const items = header.sections.filter((x) => /^u\d+$/.test(x.name)).map((x) => [base + x.offset, base + x.offset + x.size]);
  for (let t = 0; t < data.length / 16; ++t) {
    const at = base + tiles.offset + Number(data.readBigUInt64LE(16 * t + 8));
    items.push([at, at + data.readUInt32LE(16 * t + 4)]);
  }
  // An empty payload could not be told apart from its neighbours' ranges.
  assert.ok(items.every(([a, b]) => b > a), "a tile without payload bytes");
  return (range) => items.filter(([a, b]) => a >= range.from && b <= (range.to ?? bytes.length)).length;
}

const sleep = (ms) => new Promise((r) => setTimeout(r, ms));

test("BSVTF mode: the tile cache refines the frames as tiles arrive and settles on btf render's picture", async () => {
  const link = await startThrottle(new URL(serve.url).port, 2e6);
  // The first range (the header and the tile index) passes; every later one (a U packet or a run
  // of tiles) waits at the link until released below.
  link.queue((r) => r.path === "/materials/woven_fabric.btfpkg" && r.range !== null && r.range.from > 0);
  const itemsOf = itemsOfPackage(fx.packages.bsvtf);
  const view = scene("woven_fabric.bsvtf");
  const { page, problems } = await openPage(browser, link.url, `scene=${encodeURIComponent(JSON.stringify(view))}&deterministic=1&hud=0&snapshots=1&cache=256`);
  try {
    // One response at a time, the earliest in the file first, each once the page has drawn a frame
    // with everything released before (its requests minus those in flight count the packets and
    // tiles it has) and all it asked for waits at the link (or six of its requests do: Chromium's
    // connections to one server). What each frame shows is then set by the bytes let through.
    const releases = [];
    let released = 0;
    const deadline = Date.now() + PATIENCE_MS; // a hang guard only
    for (;;) {
      const s = await state(page);
      if (s.error || s.complete) break;
      const b = s.bsvtf, waiting = link.waiting;
      const held = waiting.reduce((n, w) => n + itemsOf(w.request.range), 0);
      if (waiting.length > 0 && b.requests - b.inFlight === released && (b.inFlight === held || waiting.length >= 6)) {
        const next = [...waiting].sort((x, y) => x.request.range.from - y.request.range.from)[0];
        const n = itemsOf(next.request.range);
        assert.ok(n > 0, `a request of no packet or tile: ${JSON.stringify(next.request)}`);
        releases.push(`bytes ${next.request.range.from}-${next.request.range.to - 1}: ${n} packets or tiles`);
        released += n;
        next.release();
        continue;
      }
      assert.ok(Date.now() < deadline, `the page did not settle: ${JSON.stringify({ bsvtf: b, released, waiting: waiting.map((w) => w.request.range) })}`);
      await sleep(10);
    }
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

    assert.equal(released, b.requests, "the packets and tiles the link let through differ from those the page asked for");

    // Refinement: frames with more tiles or components, each nearer to the final frame.
    const stages = (await timeline(page)).filter((e) => e.tiles > 0 && e.components > 0);
    const final = await pixels(page);
    const frames = stages.map((e) => snapshot(e, SIZE, SIZE));
    const d = frames.map((f) => meanDiff(f, final));
    const summary = stages.map((e, i) => `${e.components} components, ${e.tiles} tiles, ${e.bytes} B: ${d[i].toFixed(2)}`);
    writeFileSync(path.join(OUT, "timeline.json"), JSON.stringify({ releases, stages: summary }, null, 1));
    writePpm(path.join(OUT, "first.ppm"), frames[0]);
    const story = `${summary.join("\n")}\nreleased:\n${releases.join("\n")}`;
    assert.ok(stages.length >= 3, `only ${stages.length} stages:\n${story}`);
    assert.ok(stages[0].tiles < b.shown, story);
    for (let k = 1; k < stages.length; ++k) {
      const [p, q] = [stages[k - 1], stages[k]];
      // Each stage shows more: more tiles or components, or the settled state. (The bytes count
      // a run of tiles when it reaches the decoder; its tiles may show over several frames.)
      assert.ok(q.components >= p.components && q.tiles >= p.tiles && q.bytes >= p.bytes, story);
      assert.ok(q.tiles > p.tiles || q.components > p.components || (q.complete && !p.complete), story);
      assert.ok(d[k] <= d[k - 1] + 0.05, `the difference to the final frame grew:\n${story}`);
    }
    assert.ok(d[0] > 0.5, `no visible refinement:\n${summary.join("\n")}`);

    // The settled frame against the C++ renderer on the fmf package the BSVTF was made from.
    const sceneFile = path.join(OUT, "scene.json");
    writeFileSync(sceneFile, JSON.stringify(scene(fx.packages.woven_fabric), null, 1));
    const cpp = path.join(OUT, "cpp.exr");
    run(fx.bin, ["-q", "render", sceneFile, "--spp", "64", "--filter", "deterministic", "-o", cpp]);
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
    await page.waitForFunction(() => window.btfViewer.state.complete || window.btfViewer.state.error, null, { timeout: PATIENCE_MS });
    await render(page);
    const s = await state(page);
    assert.equal(s.error, null);
    assert.deepEqual(s.objects.map((o) => [o.material, o.visible]), [["woven_fabric", true], ["woven_lossless", true]]);
    const b = s.bsvtf;
    assert.equal(b.capacity, 16);
    assert.ok(b.settled && b.resident <= 16 && b.shown === b.resident, JSON.stringify(b));
    // Full, with tiles the frame votes for left out: the cache had to choose. Whether it got there
    // by swaps depends on the order the tiles arrived in (the unit test replays the swaps).
    assert.ok(b.resident === b.capacity && b.unmet > 0, `the cache never had to choose: ${JSON.stringify(b)}`);
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
    await page.waitForFunction(() => window.btfViewer.state.error, null, { timeout: PATIENCE_MS });
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
