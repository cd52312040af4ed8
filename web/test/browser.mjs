// SPDX-License-Identifier: MIT
// Headless Chromium for the viewer's browser tests and benchmarks (Debian's chromium; WebGL2 on
// the CPU through SwiftShader), and what they read from a page.

import { existsSync, writeFileSync } from "node:fs";
import { createServer } from "node:net";
import { chromium } from "playwright-core";

export const CHROMIUM = process.env.CHROMIUM ?? "/usr/bin/chromium";

/**
 * How long a test waits for the page (or a server) before calling it hung, in ms. Only a guard
 * against hangs, so generous: a loaded machine may run many times slower. No test asserts on how
 * long anything takes; they wait for bytes, counts and states.
 */
export const PATIENCE_MS = 180000;

export async function launchBrowser() {
  if (!existsSync(CHROMIUM)) throw new Error(`${CHROMIUM} is missing: apt-get install -y chromium (or set CHROMIUM)`);
  return chromium.launch({
    executablePath: CHROMIUM,
    args: ["--headless=new", "--use-angle=swiftshader", "--enable-unsafe-swiftshader", "--ignore-gpu-blocklist", "--no-sandbox"],
  });
}

/** Opens `${base}index.html?${query}`; `problems` collects uncaught page errors. */
export async function openPage(browser, base, query, { init } = {}) {
  const page = await browser.newPage();
  page.setDefaultTimeout(PATIENCE_MS);
  page.setDefaultNavigationTimeout(PATIENCE_MS);
  const problems = [];
  page.on("pageerror", (e) => problems.push(e.message));
  if (init) await page.addInitScript(init);
  await page.goto(`${base}index.html?${query}`);
  return { page, problems };
}

export const state = (page) => page.evaluate(() => window.btfViewer.state);
export const render = (page) => page.evaluate(() => window.btfViewer.render());
export const timeline = (page) => page.evaluate(() => window.btfViewer.timeline());

/** The page's frame: { width, height, data: RGBA bytes, top row first }. */
export async function pixels(page) {
  const p = await page.evaluate(() => window.btfViewer.pixels());
  return { width: p.width, height: p.height, data: Buffer.from(p.data, "base64") };
}

/** A timeline entry's snapshot as a frame. */
export const snapshot = (entry, width, height) => ({ width, height, data: Buffer.from(entry.pixels, "base64") });

/** Mean absolute difference of two frames over the RGB channels, in 8-bit levels. */
export function meanDiff(a, b) {
  let sum = 0;
  for (let i = 0; i < a.data.length; i += 4) sum += Math.abs(a.data[i] - b.data[i]) + Math.abs(a.data[i + 1] - b.data[i + 1]) + Math.abs(a.data[i + 2] - b.data[i + 2]);
  return sum / ((a.data.length / 4) * 3);
}

/** Writes a frame as a binary PPM (8-bit sRGB), which `btf image-diff` reads. */
export function writePpm(file, frame) {
  const rgb = Buffer.alloc(frame.width * frame.height * 3);
  for (let i = 0, j = 0; i < frame.data.length; i += 4, j += 3) {
    rgb[j] = frame.data[i];
    rgb[j + 1] = frame.data[i + 1];
    rgb[j + 2] = frame.data[i + 2];
  }
  writeFileSync(file, Buffer.concat([Buffer.from(`P6\n${frame.width} ${frame.height}\n255\n`), rgb]));
}

/** A TCP port nobody listens on at the moment of asking. */
export async function freePort() {
  const probe = createServer();
  await new Promise((r) => probe.listen(0, "127.0.0.1", r));
  const port = probe.address().port;
  await new Promise((r) => probe.close(r));
  return port;
}
