// SPDX-License-Identifier: MIT
// The viewer against real servers, in headless Chromium: `btf serve` (the WebSocket stream) and a
// `btf bundle` folder served by Debian's nginx (HTTP with byte ranges), each behind a 2 Mbit/s
// link (test/throttle.mjs) that holds the package at the end of each component until the page has
// drawn a frame with it, so that the test sees a frame of every stage in between whatever the
// machine's load; then the final frame against `btf render` of the same scene, the proof that the
// shader and the C++ evaluator agree. Pictures go to web/test-artifacts/servers/.

import { test, before, after } from "node:test";
import assert from "node:assert/strict";
import { mkdirSync, rmSync, writeFileSync } from "node:fs";
import path from "node:path";
import { PATIENCE_MS, launchBrowser, meanDiff, openPage, pixels, render, snapshot, state, timeline, writePpm } from "./browser.mjs";
import { ARTIFACTS, buildViewer, listEntry, makeFixtures, run } from "./fixtures.mjs";
import { startBtfServe, startNginx } from "./processes.mjs";
import { startThrottle } from "./throttle.mjs";

const OUT = path.join(ARTIFACTS, "servers");
const RATE = 2e6;
const SIZE = 160;

let fx, browser, serve, nginx;
const closers = [];

before(async () => {
  fx = makeFixtures();
  rmSync(OUT, { recursive: true, force: true });
  mkdirSync(OUT, { recursive: true });
  const viewer = buildViewer(path.join(OUT, "viewer"));
  const packages = ["woven_fabric", "woven_declog"].map((id) => fx.packages[id]);
  serve = await startBtfServe(fx.bin, [...packages, "--web", viewer]);
  closers.push(() => serve.close());
  const site = path.join(OUT, "site");
  run(fx.bin, ["-q", "bundle", ...packages, "-o", site, "--web", viewer]);
  nginx = await startNginx(site, path.join(OUT, "nginx"));
  closers.push(() => nginx.close());
  browser = await launchBrowser();
  closers.push(() => browser.close());
});

after(async () => {
  for (const close of closers.reverse()) await close();
});

/**
 * Opens the demo view through a slow link to `base` that stops the package at the end of each
 * component but the last until the page has drawn a frame with that component, and checks the
 * progressive refinement from the page's timeline: a frame with the first component drawn from a
 * prefix of well under half the package, then a frame per component, each from the bytes up to
 * that component's end and each nearer to the final frame. The stages are set by the bytes the
 * link lets through, not by how fast the page draws. Returns the final frame.
 */
async function streamThroughSlowLink(base, label, transport) {
  const link = await startThrottle(new URL(base).port, RATE);
  const entry = listEntry("woven_fabric", fx.packages.woven_fabric, false);
  const ends = entry.sections.filter((x) => /^b0\.k\d+$/.test(x.name)).map((x) => x.offset + x.size);
  assert.equal(ends.length, 8);
  // The package's bytes whichever way they come: the HTTP body, or the WebSocket's messages.
  link.hold(/^\/(materials\/woven_fabric\.btfpkg|stream\/woven_fabric)$/, ends.slice(0, -1));
  const { page, problems } = await openPage(browser, link.url, `material=woven_fabric&size=${SIZE}x${SIZE}&deterministic=1&mip=0&hud=0&snapshots=1`);
  try {
    for (let k = 1; k < ends.length; ++k) {
      // The link waits at the end of component k; the page draws a frame with it.
      await page.waitForFunction((n) => window.btfViewer.state.error || window.btfViewer.timeline().some((e) => e.components === n), k, { timeout: PATIENCE_MS });
      link.release();
    }
    await page.waitForFunction(() => window.btfViewer.state.complete || window.btfViewer.state.error, null, { timeout: PATIENCE_MS });
    await render(page);
    const s = await state(page);
    assert.equal(s.error, null);
    assert.equal(s.materials[0].transport, transport);
    assert.equal(s.components, 8);
    assert.equal(s.bytes, s.total);
    const stages = (await timeline(page)).filter((e) => e.components > 0);
    const final = await pixels(page);
    const frames = stages.map((e) => snapshot(e, SIZE, SIZE));
    writePpm(path.join(OUT, `${label}-first.ppm`), frames[0]);
    writePpm(path.join(OUT, `${label}-final.ppm`), final);
    const d = frames.map((f) => meanDiff(f, final));
    const summary = stages.map((e, i) => `${e.components} components, ${e.bytes} B${e.complete ? ", complete" : ""}: ${d[i].toFixed(2)}`);
    writeFileSync(path.join(OUT, `${label}-timeline.json`), JSON.stringify(summary, null, 1));
    // A frame per component, each drawn from exactly the bytes up to that component's end (the
    // last one from the whole package), the first while most of the package was still to come.
    const perComponent = ends.map((_, k) => stages.find((e) => e.components === k + 1));
    assert.ok(perComponent.every((e) => e), `a component without its own frame:\n${summary.join("\n")}`);
    assert.deepEqual(perComponent.slice(0, -1).map((e) => e.bytes), ends.slice(0, -1), summary.join("\n"));
    assert.ok(!stages[0].complete && stages[0].components === 1 && stages[0].bytes < s.total / 2, summary.join("\n"));
    assert.ok(stages[stages.length - 1].complete, summary.join("\n"));
    for (let k = 1; k < stages.length; ++k) {
      assert.ok(stages[k].components >= stages[k - 1].components && stages[k].bytes >= stages[k - 1].bytes, summary.join("\n"));
      assert.ok(d[k] <= d[k - 1] + 0.05, `the difference to the final frame grew:\n${summary.join("\n")}`);
    }
    assert.ok(d[0] > 0.5, `no visible refinement:\n${summary.join("\n")}`);
    assert.ok(link.connections >= 1);
    assert.ok(link.requests.some((r) => r.path === (transport === "websocket" ? "/stream/woven_fabric" : "/materials/woven_fabric.btfpkg")), "the package did not come through the link");
    assert.deepEqual(problems, []);
    await page.locator("canvas").screenshot({ path: path.join(OUT, `${label}-final.png`) });
    return final;
  } finally {
    await page.close();
    await link.close();
  }
}

let serveFinal;

test("btf serve: the WebSocket stream draws early, refines with each component and completes", async () => {
  serveFinal = await streamThroughSlowLink(serve.url, "serve", "websocket");
});

test("a btf bundle served by nginx: the same stream over HTTP ends at the same frame", async () => {
  const final = await streamThroughSlowLink(nginx.url, "nginx", "http");
  assert.ok(serveFinal, "the btf serve test ran first");
  assert.equal(meanDiff(final, serveFinal), 0);
});

test("the final frame matches btf render of the same scene within a mean ΔE00 of 1", async () => {
  const scene = {
    camera: { position: [0, 0.6, 3.2], look_at: [0, 0, 0], up: [0, 1, 0], fov: 40, width: 192, height: 192 },
    render: { integrator: "direct", exposure: 0 },
    objects: [{ shape: "sphere", uv_scale: 2, material: { type: "btf", file: fx.packages.woven_declog } }],
    lights: [{ type: "directional", direction: [-0.5, 0.8, 0.7], irradiance: 2.5 }],
  };
  const sceneFile = path.join(OUT, "scene.json");
  writeFileSync(sceneFile, JSON.stringify(scene, null, 1));
  const cpp = path.join(OUT, "cpp.exr");
  run(fx.bin, ["-q", "render", sceneFile, "--spp", "64", "--filter", "deterministic", "-o", cpp]);

  const { page, problems } = await openPage(browser, serve.url, `scene=${encodeURIComponent(JSON.stringify(scene))}&deterministic=1&mip=0&hud=0`);
  try {
    await page.waitForFunction(() => window.btfViewer.state.complete, null, { timeout: PATIENCE_MS });
    await render(page);
    const s = await state(page);
    assert.deepEqual(s.objects, [{ shape: "sphere", material: "woven_declog", visible: true }]);
    const viewer = path.join(OUT, "viewer.ppm");
    writePpm(viewer, await pixels(page));
    const metrics = JSON.parse(run(fx.bin, ["image-diff", viewer, cpp, "--json", "-o", path.join(OUT, "viewer-vs-cpp.png")]));
    writeFileSync(path.join(OUT, "viewer-vs-cpp.json"), JSON.stringify(metrics, null, 1));
    assert.ok(metrics.de2000_mean <= 1, `mean ΔE00 ${metrics.de2000_mean} between the viewer and btf render`);
    // Not an empty picture: the sphere covers a good part of the frame.
    assert.ok(metrics.ssim > 0.9, JSON.stringify(metrics));
    assert.deepEqual(problems, []);
  } finally {
    await page.close();
  }
});
