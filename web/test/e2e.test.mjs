// SPDX-License-Identifier: MIT
// End-to-end test of the viewer in headless Chromium (Debian's chromium, WebGL2 on SwiftShader):
// a bundle folder served by test/server.mjs, a package held back section by section so the test
// sees each stage of the progressive refinement, the WebSocket stream and its HTTP fallback,
// the CPU reference at chosen pixels, several objects, and the error messages of the page.
// Screenshots go to web/test-artifacts/e2e/.

import { test, before, after } from "node:test";
import assert from "node:assert/strict";
import { mkdirSync, readFileSync, statSync, writeFileSync } from "node:fs";
import path from "node:path";
import { PATIENCE_MS, freePort, launchBrowser, meanDiff, openPage as open, pixels, render, state } from "./browser.mjs";
import { ARTIFACTS, listEntry, makeFixtures, makeSite } from "./fixtures.mjs";
import { startServer } from "./server.mjs";

const SHOTS = path.join(ARTIFACTS, "e2e");
const IDS = [
  "woven_fabric",
  "woven_declog",
  "woven_perchannel",
  "woven_model11",
  "woven_pca",
  "woven_pca_declog",
  "woven_lpca",
  "woven_lpca_dec",
  "woven_perceptual",
  "woven_mlvq",
  "woven_mlvq_ycbcr",
  "woven_broken",
  "woven_lpca_broken",
  "woven_perceptual_broken",
  "woven_pca_broken",
  "woven_mlvq_broken",
];

let fx, site, server, browser;

before(async () => {
  fx = makeFixtures();
  site = makeSite("site", fx.packages, IDS);
  // A list entry of a codec the viewer does not know: refused from the list alone.
  const list = JSON.parse(readFileSync(path.join(site, "api", "materials"), "utf8"));
  list.materials.push({ ...list.materials[0], id: "woven_other", name: "woven_other", codec: "neural" });
  writeFileSync(path.join(site, "api", "materials"), JSON.stringify(list, null, 1));
  // A second list naming the WebSocket streams (what btf serve answers).
  writeFileSync(
    path.join(site, "api", "materials-ws"),
    JSON.stringify({ protocol: 1, materials: IDS.map((id) => listEntry(id, fx.packages[id], true)) }),
  );
  mkdirSync(SHOTS, { recursive: true });
  server = await startServer(site);
  browser = await launchBrowser();
});

after(async () => {
  await browser?.close();
  await server?.close();
});

const openPage = (query, options) => open(browser, server.url, query, options);

/**
 * Checks the frame against the CPU reference at a grid of pixels. The rasterizer snaps vertices
 * to a sub-pixel grid, so a pixel may show the surface a few hundredths of a pixel away from the
 * ray through its centre; where the texture changes fast that is a few 8-bit levels. Each pixel
 * must therefore lie within the range of the reference over ±0.06 px around its centre (± 1 level
 * of rounding); pixels where that neighbourhood leaves the object (silhouettes) are skipped.
 */
async function checkReference(page, frame, label) {
  const D = 0.06;
  const offsets = [[0, 0], [D, 0], [-D, 0], [0, D], [0, -D]];
  const centres = [];
  for (let y = 6; y < frame.height; y += 10) for (let x = 6; x < frame.width; x += 10) centres.push([x, y]);
  const points = centres.flatMap(([x, y]) => offsets.map(([dx, dy]) => [x + dx, y + dy]));
  const ref = await page.evaluate((p) => window.btfViewer.reference(p), points);
  const objects = await page.evaluate((p) => window.btfViewer.trace(p).map((h) => (h ? h.object : -1)), points);
  let hits = 0, worst = 0;
  const bad = [];
  centres.forEach(([x, y], i) => {
    const group = offsets.map((_, k) => i * offsets.length + k);
    if (group.some((j) => !ref[j] || objects[j] !== objects[group[0]])) return;
    const o = (y * frame.width + x) * 4;
    const got = [frame.data[o], frame.data[o + 1], frame.data[o + 2]];
    hits += 1;
    for (let c = 0; c < 3; ++c) {
      const values = group.map((j) => ref[j][c] * 255);
      const lo = Math.min(...values) - 1, hi = Math.max(...values) + 1;
      const err = Math.max(0, lo - got[c], got[c] - hi);
      worst = Math.max(worst, err);
      if (err > 0) bad.push(`(${x}, ${y}) channel ${c}: got ${got[c]}, reference ${lo + 1}..${hi - 1}`);
    }
  });
  assert.deepEqual(bad, [], `${label}: pixels differ from the CPU reference`);
  assert.ok(hits >= 20, `${label}: only ${hits} reference pixels lie inside an object`);
  return { hits, worst };
}

test("the page draws before the stream completes and refines with each component", async () => {
  const entry = listEntry("woven_fabric", fx.packages.woven_fabric, false);
  const components = entry.sections.filter((s) => /^b0\.k\d+$/.test(s.name));
  assert.equal(components.length, 8);
  // Hold the body after each component but the last: the first stop comes once the header, the
  // tables, the means and b0.k0 are through.
  server.hold("woven_fabric", components.slice(0, -1).map((s) => s.offset + s.size));
  const { page, problems } = await openPage("material=woven_fabric&size=160x160&deterministic=1&mip=0&hud=0");
  try {
    await page.waitForFunction(() => window.btfViewer.state.components === 1 && window.btfViewer.state.ready && window.btfViewer.state.frames > 0, null, { timeout: PATIENCE_MS });
    const first = await state(page);
    assert.equal(first.done, false, "the stream must still be running");
    assert.ok(first.bytes < first.total, `${first.bytes} of ${first.total} bytes`);
    assert.deepEqual(first.objects, [{ shape: "sphere", material: "woven_fabric", visible: true }]);
    const frames = [];
    for (let k = 1; k <= 8; ++k) {
      if (k > 1) {
        server.release("woven_fabric");
        await page.waitForFunction((n) => window.btfViewer.state.components === n, k, { timeout: PATIENCE_MS });
      }
      const r = await render(page);
      assert.equal(r.components, k);
      frames.push(await pixels(page));
      await page.locator("canvas").screenshot({ path: path.join(SHOTS, `progressive-${k}-of-8.png`) });
    }
    await page.waitForFunction(() => window.btfViewer.state.complete, null, { timeout: PATIENCE_MS });
    const final = await state(page);
    assert.equal(final.bytes, final.total);
    assert.deepEqual(final.materials[0].applied, components.map((s) => s.name));
    assert.equal(final.materials[0].transport, "http");
    // The difference to the final frame shrinks as components arrive (decreasing energy).
    const d = frames.map((f) => meanDiff(f, frames[7]));
    for (let k = 1; k < 8; ++k) assert.ok(d[k] <= d[k - 1] + 0.05, `difference to the final frame grew: ${d.map((x) => x.toFixed(3))}`);
    assert.ok(d[0] > 0.5 && d[0] > 4 * d[6], `no visible refinement: ${d.map((x) => x.toFixed(3))}`);
    assert.equal(d[7], 0);
    // Every stage matches the CPU evaluator of the components received.
    await checkReference(page, frames[7], "final frame");
    writeFileSync(path.join(SHOTS, "progressive-differences.json"), JSON.stringify({ meanAbsDiffToFinal: d }, null, 1));
    assert.deepEqual(problems, []);
  } finally {
    server.releaseAll("woven_fabric");
    await page.close();
  }
});

test("the animated page keeps drawing while components arrive, and its HUD says how far it is", async () => {
  const entry = listEntry("woven_fabric", fx.packages.woven_fabric, false);
  const components = entry.sections.filter((s) => /^b0\.k\d+$/.test(s.name));
  // The HUD's total: the package's size as the viewer prints it (KiB with one decimal).
  const total = (statSync(fx.packages.woven_fabric).size / 1024).toFixed(1).replace(".", "\\.");
  server.hold("woven_fabric", components.slice(0, -1).map((s) => s.offset + s.size));
  const { page, problems } = await openPage("material=woven_fabric&size=120x120");
  try {
    await page.waitForFunction(() => window.btfViewer.state.components === 1 && window.btfViewer.state.frames > 0, null, { timeout: PATIENCE_MS });
    // The frame loop runs on while the stream waits: frames are drawn between two components.
    const f0 = (await state(page)).frames;
    await page.waitForFunction((n) => window.btfViewer.state.frames >= n + 3, f0, { timeout: PATIENCE_MS });
    assert.equal((await state(page)).components, 1);
    assert.match(await page.locator("#hud").innerText(), new RegExp(`woven_fabric \\(fmf\\): [\\d.]+ KiB / ${total} KiB · 1/8 components · http · refining`));
    server.releaseAll("woven_fabric");
    await page.waitForFunction(() => window.btfViewer.state.complete && window.btfViewer.state.components === 8, null, { timeout: PATIENCE_MS });
    const f1 = (await state(page)).frames;
    await page.waitForFunction((n) => window.btfViewer.state.frames >= n + 2, f1, { timeout: PATIENCE_MS });
    const hud = await page.locator("#hud").innerText();
    assert.match(hud, new RegExp(`woven_fabric \\(fmf\\): ${total} KiB / ${total} KiB · 8/8 components · http · complete`));
    assert.match(hud, /frame [\d.]+ ms \(\d+ fps\) · submit [\d.]+ ms/);
    await page.screenshot({ path: path.join(SHOTS, "animated-page.png") });
    assert.deepEqual(problems, []);
  } finally {
    server.releaseAll("woven_fabric");
    await page.close();
  }
});

test("the WebSocket stream renders the same frame, and a cut socket resumes over HTTP with Range", async () => {
  const query = "material=woven_fabric&size=160x160&deterministic=1&mip=0&hud=0";
  const frameOf = async (page) => {
    await page.waitForFunction(() => window.btfViewer.state.complete, null, { timeout: PATIENCE_MS });
    await render(page);
    return pixels(page);
  };
  const http = await openPage(query);
  const reference = await frameOf(http.page);
  await http.page.close();

  const before = server.requests.length;
  const ws = await openPage(`${query}&api=api/materials-ws`);
  const wsFrame = await frameOf(ws.page);
  const s = await state(ws.page);
  assert.equal(s.materials[0].transport, "websocket");
  assert.equal(meanDiff(wsFrame, reference), 0);
  const seen = server.requests.slice(before).map((r) => `${r.method} ${r.path}`);
  assert.ok(seen.includes("UPGRADE /stream/woven_fabric"), seen.join(", "));
  assert.ok(!seen.includes("GET /materials/woven_fabric.btfpkg"), "the package was fetched although the socket worked");
  await ws.page.close();

  // A server whose socket breaks off after 100000 bytes: the rest comes by a Range request.
  const cut = await startServer(site, { cutWebSocketAt: 100000 });
  try {
    const { page } = await open(browser, cut.url, `${query}&api=api/materials-ws`);
    const frame = await frameOf(page);
    assert.equal(meanDiff(frame, reference), 0);
    const ranges = cut.requests.filter((r) => r.path === "/materials/woven_fabric.btfpkg").map((r) => r.range);
    assert.deepEqual(ranges, ["bytes=100000-"]);
    assert.equal((await state(page)).materials[0].transport, "http");
    await page.close();
  } finally {
    await cut.close();
  }
});

test("every codec, colour variants (UBO2014 model 11 too), log, quantizations, the environment and several objects match the CPU reference", async () => {
  const cases = [
    // Each codec's own shader paths (view groups, clusters, levels and lab colour, the mlvq
    // decoder) with a colour variant and the environment; the colour, log and quantization
    // variants of the factor codecs share fmf's paths below and are checked on the CPU against
    // btf eval (unit.test.mjs).
    { name: "pca-views-declog-env", query: "material=woven_pca_declog&env=0.6" },
    { name: "lpca", query: "material=woven_lpca&light=-1,2,1.5" },
    { name: "lpca-decorrelated-env", query: "material=woven_lpca_dec&env=0.5&light=1,1,0.5" },
    { name: "perceptual-levels", query: "material=woven_perceptual&light=1,2,1.5&env=0.4" },
    { name: "mlvq-logluv-env", query: "material=woven_mlvq&env=0.6&light=-1,1,1" },
    { name: "mlvq-ycbcr", query: "material=woven_mlvq_ycbcr&light=-1,2,1.5" },
    { name: "declog-env", query: "material=woven_declog&env=0.6&exposure=0.5" },
    { name: "two-objects", query: "objects=sphere:woven_perchannel@-1.3,0,0;torus:woven_fabric@1.3,0,0&camera=0,2.5,5.5&light=-1,2,1.5" },
    { name: "ubo2014-model11", query: "material=woven_model11&light=1,2,1.5" },
    { name: "cylinder-uv", query: "material=woven_fabric&object=cylinder&uvscale=2,1&uvrot=30&lightpos=2,2,3&intensity=40&camera=0,0.5,5" },
  ];
  for (const c of cases) {
    const { page, problems } = await openPage(`${c.query}&size=160x128&deterministic=1&mip=0&hud=0`);
    try {
      await page.waitForFunction(() => window.btfViewer.state.complete, null, { timeout: PATIENCE_MS });
      await render(page);
      const frame = await pixels(page);
      await page.locator("canvas").screenshot({ path: path.join(SHOTS, `${c.name}.png`) });
      const s = await state(page);
      assert.ok(s.objects.every((o) => o.visible), JSON.stringify(s.objects));
      await checkReference(page, frame, c.name);
      assert.deepEqual(problems, []);
    } finally {
      await page.close();
    }
  }
});

test("mip-mapping changes only minified regions", async () => {
  const { page } = await openPage("material=woven_fabric&size=160x160&deterministic=1&hud=0&uvscale=4");
  try {
    await page.waitForFunction(() => window.btfViewer.state.complete, null, { timeout: PATIENCE_MS });
    await render(page);
    const mipped = await pixels(page);
    await page.locator("canvas").screenshot({ path: path.join(SHOTS, "mip-on.png") });
    await page.evaluate(() => window.btfViewer.setView({ mip: false }));
    await render(page);
    const plain = await pixels(page);
    await page.locator("canvas").screenshot({ path: path.join(SHOTS, "mip-off.png") });
    // uv × 4 on a 32-texel material: the sphere's limb and poles are minified, its centre not.
    const o = (80 * 160 + 80) * 4;
    assert.deepEqual([...mipped.data.subarray(o, o + 3)], [...plain.data.subarray(o, o + 3)]);
    assert.ok(meanDiff(mipped, plain) > 0.05, "mip-mapping changed nothing");
  } finally {
    await page.close();
  }
});

async function messageOf(query, options) {
  const { page } = await openPage(query, options);
  try {
    await page.waitForFunction(() => !document.getElementById("message").hidden, null, { timeout: PATIENCE_MS });
    return await page.locator("#message").innerText();
  } finally {
    await page.close();
  }
}

test("the page says clearly what went wrong", async () => {
  // A server that does not answer: a port nobody listens on.
  const port = await freePort();
  assert.match(await messageOf(`api=${encodeURIComponent(`http://127.0.0.1:${port}/api/materials`)}`), /The btfkit server does not answer: GET .*api\/materials failed/);
  assert.match(await messageOf("api=api/none"), /cannot list materials: GET api\/none answered HTTP 404/);
  // A package damaged in its third component section: the error, and the first two components
  // still on screen.
  const broken = await openPage("material=woven_broken&size=96x96&deterministic=1&hud=0");
  await broken.page.waitForFunction(() => !document.getElementById("message").hidden, null, { timeout: PATIENCE_MS });
  assert.match(await broken.page.locator("#message").innerText(), /Material failed to load: woven_broken: checksum mismatch in section 'b0\.k2'/);
  const s = await state(broken.page);
  assert.equal(s.components, 2);
  assert.ok(s.objects[0].visible);
  await broken.page.close();
  assert.match(await messageOf("material=woven_other"), /woven_other: codec 'neural' is not supported by the viewer/);
  // A damaged section of each codec's own model: one message naming the material and the section,
  // and the page keeps drawing the other object.
  for (const [id, section] of [
    ["woven_lpca_broken", "clusters"],
    ["woven_perceptual_broken", "angular"],
    ["woven_pca_broken", "b1.k0"],
    ["woven_mlvq_broken", "P6.1"],
  ]) {
    const { page, problems } = await openPage(`objects=sphere:${id}@-1.3,0,0;sphere:woven_fabric@1.3,0,0&camera=0,1,5&size=96x64&deterministic=1&hud=0`);
    try {
      await page.waitForFunction(() => !document.getElementById("message").hidden, null, { timeout: PATIENCE_MS });
      await page.waitForFunction(() => window.btfViewer.state.materials.find((m) => m.id === "woven_fabric").complete, null, { timeout: PATIENCE_MS });
      const message = await page.locator("#message").innerText();
      assert.match(message, new RegExp(`Material failed to load: ${id}: checksum mismatch in section '${section.replace(".", "\\.")}'`));
      assert.equal(message.split("\n").filter((l) => l.includes(id)).length, 1, message);
      await render(page);
      const s = await state(page);
      assert.ok(s.objects[1].visible, JSON.stringify(s.objects));
      assert.deepEqual(problems, []);
    } finally {
      await page.close();
    }
  }
  assert.match(await messageOf("material=nothing"), /material 'nothing' is not in the server's list/);
  assert.match(await messageOf("object=cube"), /unknown shape 'cube'/);
  // A browser without WebGL2.
  const noGl = `HTMLCanvasElement.prototype.getContext = (function (get) {
    return function (kind, ...rest) { return kind === "webgl2" ? null : get.call(this, kind, ...rest); };
  })(HTMLCanvasElement.prototype.getContext);`;
  assert.match(await messageOf("material=woven_fabric", { init: noGl }), /WebGL2 is not available/);
});
