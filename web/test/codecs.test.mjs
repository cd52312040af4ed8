// SPDX-License-Identifier: MIT
// Every codec in the browser against the C++ renderer, in headless Chromium: for each codec a
// scene of one of its packages, the viewer's settled frame against `btf render --integrator
// direct` of the same scene file (mean ΔE00 at most 1, the 95th percentile recorded), and the
// progressive order of pca-views (a first picture once every view group's first component is in,
// then nearer to the final frame with each round). Each stage is set by bytes held back by the
// test server, never by time. Pictures and numbers go to web/test-artifacts/codecs/.

import { test, before, after } from "node:test";
import assert from "node:assert/strict";
import { mkdirSync, readFileSync, rmSync, writeFileSync } from "node:fs";
import path from "node:path";
import { PATIENCE_MS, launchBrowser, meanDiff, openPage, pixels, render, state, writePpm } from "./browser.mjs";
import { ARTIFACTS, listEntry, makeFixtures, makeSite, run } from "./fixtures.mjs";
import { startServer } from "./server.mjs";

const OUT = path.join(ARTIFACTS, "codecs");
/** codec (or codec-coded: its coded storage) → the fixture package that shows it. */
export const CODEC_FIXTURES = {
  fmf: "woven_fabric",
  "fmf-coded": "woven_coded",
  "pca-views": "woven_pca",
  lpca: "woven_lpca",
  perceptual: "woven_perceptual",
  mlvq: "woven_mlvq",
};

let fx, server, browser;

before(async () => {
  fx = makeFixtures();
  rmSync(OUT, { recursive: true, force: true });
  mkdirSync(OUT, { recursive: true });
  const site = makeSite("codecs-site", fx.packages, [...Object.values(CODEC_FIXTURES), "leather_mlvq"]);
  server = await startServer(site);
  browser = await launchBrowser();
});

after(async () => {
  await browser?.close();
  await server?.close();
});

/** The scene of the comparison: a sphere of the material under a directional light. */
function sceneOf(id) {
  return {
    camera: { position: [0, 0.6, 3.2], look_at: [0, 0, 0], up: [0, 1, 0], fov: 40, width: 160, height: 160 },
    render: { integrator: "direct", exposure: 0 },
    objects: [{ shape: "sphere", uv_scale: 2, material: { type: "btf", file: fx.packages[id] } }],
    lights: [{ type: "directional", direction: [-0.5, 0.8, 0.7], irradiance: 2.5 }],
  };
}

/**
 * Frames of successive stages get nearer to the last one (mean absolute difference in 8-bit
 * levels, written to OUT/<name>-progressive.json; 0.05 levels of slack for rounding), and the
 * first differs visibly from it.
 */
function assertRefines(frames, name) {
  const d = frames.map((f) => meanDiff(f, frames[frames.length - 1]));
  writeFileSync(path.join(OUT, `${name}-progressive.json`), JSON.stringify({ meanAbsDiffToFinal: d }, null, 1));
  for (let k = 1; k < d.length; ++k) assert.ok(d[k] <= d[k - 1] + 0.05, `${name}: difference to the final frame grew: ${d.map((x) => x.toFixed(3))}`);
  assert.ok(d[0] > 0.2, `${name}: no visible refinement: ${d.map((x) => x.toFixed(3))}`);
}

test("each codec's settled frame matches btf render of the same scene within a mean ΔE00 of 1", async () => {
  const summary = {};
  for (const [codec, id] of Object.entries(CODEC_FIXTURES)) {
    const scene = sceneOf(id);
    const sceneFile = path.join(OUT, `${codec}.scene.json`);
    writeFileSync(sceneFile, JSON.stringify(scene, null, 1));
    const cpp = path.join(OUT, `${codec}.cpp.exr`);
    run(fx.bin, ["-q", "render", sceneFile, "--spp", "64", "--filter", "deterministic", "-o", cpp]);
    const { page, problems } = await openPage(browser, server.url, `scene=${encodeURIComponent(JSON.stringify(scene))}&deterministic=1&mip=0&hud=0`);
    try {
      await page.waitForFunction(() => window.btfViewer.state.complete, null, { timeout: PATIENCE_MS });
      await render(page);
      const s = await state(page);
      assert.deepEqual(s.objects, [{ shape: "sphere", material: id, visible: true }]);
      assert.equal(s.materials[0].codec, codec.replace(/-coded$/, ""));
      assert.equal(s.materials[0].components, s.materials[0].totalComponents);
      const viewer = path.join(OUT, `${codec}.viewer.ppm`);
      writePpm(viewer, await pixels(page));
      await page.locator("canvas").screenshot({ path: path.join(OUT, `${codec}.png`) });
      const metrics = JSON.parse(run(fx.bin, ["image-diff", viewer, cpp, "--json", "-o", path.join(OUT, `${codec}.viewer-vs-cpp.png`)]));
      summary[codec] = { package: id, de2000_mean: metrics.de2000_mean, de2000_p95: metrics.de2000_p95, ssim: metrics.ssim };
      assert.deepEqual(problems, []);
    } finally {
      await page.close();
    }
  }
  writeFileSync(path.join(OUT, "viewer-vs-cpp.json"), JSON.stringify(summary, null, 1));
  // One picture of all codecs side by side (docs/viewer.md), each sphere its codec's package.
  const ids = Object.entries(CODEC_FIXTURES)
    .filter(([codec]) => !codec.endsWith("-coded"))
    .map(([, id]) => id);
  const objects = ids.map((id, i) => `sphere:${id}@${(i - (ids.length - 1) / 2) * 2.2},0,0`).join(";");
  const { page, problems } = await openPage(browser, server.url, `objects=${objects}&camera=0,0.8,4.8&size=880x200&light=0.1,0.6,1&deterministic=1&hud=0`);
  try {
    await page.waitForFunction(() => window.btfViewer.state.complete, null, { timeout: PATIENCE_MS });
    await render(page);
    assert.deepEqual((await state(page)).objects.map((o) => o.visible), ids.map(() => true));
    await page.locator("canvas").screenshot({ path: path.join(OUT, "codecs.png") });
    assert.deepEqual(problems, []);
  } finally {
    await page.close();
  }
  for (const [codec, m] of Object.entries(summary)) {
    assert.ok(m.de2000_mean <= 1, `${codec}: mean ΔE00 ${m.de2000_mean} between the viewer and btf render`);
    // Not an empty picture: the sphere covers a good part of the frame.
    assert.ok(m.ssim > 0.9, `${codec}: ${JSON.stringify(m)}`);
  }
});

test("pca-views: a first picture once every view group's first component is in, then sharper with each round", async () => {
  const id = CODEC_FIXTURES["pca-views"];
  const entry = listEntry(id, fx.packages[id], false);
  const bytes = readFileSync(fx.packages[id]);
  const groups = JSON.parse(bytes.subarray(24, 24 + bytes.readUInt32LE(12)).toString("utf8")).model.groups.length;
  const components = entry.sections.filter((s) => /^b\d+\.k\d+$/.test(s.name));
  // The package's rounds: every block's k-th component before any (k+1)-th.
  const rounds = [];
  for (const s of components) {
    const k = Number(s.name.split(".k")[1]);
    (rounds[k] ??= []).push(s);
  }
  assert.ok(groups > 1 && rounds.length >= 2, `${groups} groups, ${rounds.length} rounds`);
  assert.ok(rounds.every((r) => r.length === groups), "one component of every group per round");
  assert.deepEqual(components, rounds.flat(), "components come round by round");
  // Hold the body halfway through the first round, then at the end of each round.
  const half = rounds[0][Math.floor(groups / 2)];
  const ends = rounds.map((r) => r[r.length - 1].offset + r[r.length - 1].size);
  server.hold(id, [half.offset + half.size, ...ends.slice(0, -1)]);
  const { page, problems } = await openPage(browser, server.url, `material=${id}&size=128x128&deterministic=1&mip=0&hud=0`);
  try {
    // Halfway through the first round: components have arrived, but no picture yet.
    await page.waitForFunction((n) => window.btfViewer.state.materials[0]?.components === n, Math.floor(groups / 2) + 1, { timeout: PATIENCE_MS });
    const early = await state(page);
    assert.equal(early.materials[0].ready, false, "a picture before every group had its first component");
    assert.equal(early.objects[0].visible, false);
    const frames = [];
    for (let r = 0; r < rounds.length; ++r) {
      server.release(id);
      await page.waitForFunction((n) => window.btfViewer.state.materials[0]?.components === n, groups * (r + 1), { timeout: PATIENCE_MS });
      const s = await render(page);
      assert.equal(s.components, groups * (r + 1));
      assert.ok((await state(page)).objects[0].visible);
      frames.push(await pixels(page));
      await page.locator("canvas").screenshot({ path: path.join(OUT, `pca-views-round-${r + 1}.png`) });
    }
    await page.waitForFunction(() => window.btfViewer.state.complete, null, { timeout: PATIENCE_MS });
    assertRefines(frames, "pca-views");
    assert.deepEqual(problems, []);
  } finally {
    server.releaseAll(id);
    await page.close();
  }
});

test("mlvq: P6 streams coarse to fine, a first picture with the code-books and the coarsest level, then sharper with each level", async () => {
  const id = "leather_mlvq";
  const entry = listEntry(id, fx.packages[id], false);
  const levels = entry.sections.filter((s) => /^P6\.\d+$/.test(s.name));
  assert.deepEqual(
    levels.map((s) => s.name),
    levels.map((_, i) => `P6.${levels.length - 1 - i}`),
    "P6 levels from the coarsest to level 0",
  );
  assert.ok(levels.length >= 3, `${levels.length} P6 levels`);
  const codebooks = entry.sections.find((s) => s.name === "codebooks");
  // Hold the body after the code-books, then at the end of every level but the last.
  server.hold(id, [codebooks.offset + codebooks.size, ...levels.slice(0, -1).map((s) => s.offset + s.size)]);
  const { page, problems } = await openPage(browser, server.url, `material=${id}&size=128x128&deterministic=1&mip=0`);
  try {
    // The code-books alone are no picture (open_all needs the coarsest P6 level).
    await page.waitForFunction(() => window.btfViewer.state.materials[0]?.sections === 1, null, { timeout: PATIENCE_MS });
    const early = await state(page);
    assert.equal(early.materials[0].ready, false);
    assert.equal(early.materials[0].unit, "P6 levels");
    const frames = [];
    for (let l = 0; l < levels.length; ++l) {
      server.release(id);
      await page.waitForFunction((n) => window.btfViewer.state.materials[0]?.components === n, l + 1, { timeout: PATIENCE_MS });
      const s = await state(page);
      assert.equal(s.materials[0].bytes, levels[l].offset + levels[l].size, "frame drawn from exactly the bytes up to this level");
      assert.ok(s.materials[0].ready && s.objects[0].visible);
      await render(page);
      // The HUD names the codec and counts P6 levels.
      const hud = await page.locator("#hud").innerText();
      assert.match(hud, new RegExp(`leather_mlvq \\(mlvq\\): [\\d.]+ KiB / [\\d.]+ KiB · ${l + 1}/${levels.length} P6 levels · http · ${l + 1 < levels.length ? "refining" : "(refining|complete)"}`), hud);
      frames.push(await pixels(page));
      writePpm(path.join(OUT, `mlvq-level-${levels.length - 1 - l}.ppm`), frames[frames.length - 1]);
      await page.locator("canvas").screenshot({ path: path.join(OUT, `mlvq-level-${levels.length - 1 - l}.png`) });
    }
    await page.waitForFunction(() => window.btfViewer.state.complete, null, { timeout: PATIENCE_MS });
    assertRefines(frames, "mlvq");
    assert.deepEqual(problems, []);
  } finally {
    server.releaseAll(id);
    await page.close();
  }
});
