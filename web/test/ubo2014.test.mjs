// SPDX-License-Identifier: MIT
// UBO2014 files as they are, in the viewer (node --test test/ubo2014.test.mjs; no browser): a DFMF
// file on the 151-direction "UBO dome 1" sampling (made with the repository's writer: btf synth
// --sampling dome151, then btf convert to .btf), converted with `btf convert X.btf X.btfpkg`
// (its own factors, no refactorization). The viewer's CPU evaluator (FactorModel over the package
// read by PackageStream, directions through the package's "tables" section) must give what
// `btf eval` gives for the package and for the .btf file itself, and the tables must interpolate
// the 151 directions exactly.

import { test, before } from "node:test";
import assert from "node:assert/strict";
import { execFileSync } from "node:child_process";
import { existsSync, mkdirSync, readFileSync, writeFileSync } from "node:fs";
import path from "node:path";
import { ARTIFACTS, btfBinary, bundleModules, run } from "./fixtures.mjs";

const DIR = path.join(ARTIFACTS, "ubo2014");
// The two files: colour model 11 in half floats, colour model 0 (per-channel RGB) in float32.
const FILES = {
  model11: ["--components", "6", "--colour", "model11", "--half"],
  rgb: ["--components", "6", "--colour", "rgb"],
};

let M; // the bundled modules
let xxh64; // the package checksum
let bin; // the btf binary
const files = {}; // id → { btf, pkg }

before(async () => {
  mkdirSync(DIR, { recursive: true });
  const out = path.join(DIR, "modules.mjs");
  M = await bundleModules(["half", "package", "interp", "factor"], out);
  xxh64 = await M.loadChecksum();

  // 16² texels × 151 × 151 directions: a few seconds to make, kept while present.
  bin = btfBinary();
  const h5 = path.join(DIR, "leather151.h5");
  if (!existsSync(h5)) run(bin, ["-q", "synth", "--preset", "leather", "--size", "16", "--sampling", "dome151", "--seed", "2", "-o", h5]);
  for (const [id, args] of Object.entries(FILES)) {
    const btf = path.join(DIR, `${id}.btf`), pkg = path.join(DIR, `${id}.btfpkg`);
    const stamp = pkg + ".args", wanted = JSON.stringify(args);
    if (!existsSync(pkg) || !existsSync(stamp) || readFileSync(stamp, "utf8") !== wanted) {
      run(bin, ["-q", "convert", h5, btf, ...args]);
      run(bin, ["-q", "convert", btf, pkg]);
      writeFileSync(stamp, wanted);
    }
    files[id] = { btf, pkg };
  }
});

/** The package read through PackageStream (in uneven chunks) into the viewer's model and tables. */
function decode(file) {
  const bytes = new Uint8Array(readFileSync(file));
  let header = null;
  const sections = [];
  const stream = new M.PackageStream(path.basename(file), { header: (h) => (header = h), section: (s) => sections.push(s) }, xxh64);
  for (let at = 0, i = 0; at < bytes.length; ++i) {
    const n = [4093, 65536, 17][i % 3];
    stream.push(bytes.subarray(at, at + n));
    at += n;
  }
  assert.ok(stream.end(), `${file}: the whole package arrived`);
  const { info, model, tables } = M.decodeFactorSections(path.basename(file), header.json, sections);
  assert.ok(tables, `${file}: a tables section`);
  return { info, model, tables, header: header.json };
}

const dirVec = (thetaDeg, phiDeg) => {
  const t = (thetaDeg * Math.PI) / 180, p = (phiDeg * Math.PI) / 180;
  return [Math.sin(t) * Math.cos(p), Math.sin(t) * Math.sin(p), Math.cos(t)];
};

/**
 * n random queries as `btf eval --queries` lines and as numbers (the same rounded values): uv in
 * [-1, 2)² (the material wraps), directions with cos θ uniform, every fourth light and every
 * fifth view grazing (θ in [85°, 90°]).
 */
function randomQueries(n, seed) {
  let x = seed >>> 0;
  const next = () => (x = (Math.imul(x, 1664525) + 1013904223) >>> 0) / 2 ** 32;
  const theta = (grazing) => (grazing ? 85 + 5 * next() : (Math.acos(next()) * 180) / Math.PI);
  return Array.from({ length: n }, (_, i) => {
    const f = [next() * 3 - 1, next() * 3 - 1, theta(i % 4 === 0), next() * 360, theta(i % 5 === 0), next() * 360].map((v) => v.toFixed(6));
    return { line: `${f[0]},${f[1]} ${f[2]},${f[3]} ${f[4]},${f[5]}`, uv: [Number(f[0]), Number(f[1])], light: [Number(f[2]), Number(f[3])], view: [Number(f[4]), Number(f[5])] };
  });
}

/** `btf eval FILE --queries LIST`: one RGB triple per query. */
function cliEval(file, queries) {
  const list = path.join(DIR, "queries.txt");
  writeFileSync(list, queries.map((q) => q.line).join("\n") + "\n");
  const out = execFileSync(bin, ["-q", "eval", file, "--queries", list]).toString().trim().split("\n");
  assert.equal(out.length, queries.length);
  return out.map((l) => l.trim().split(/\s+/).map(Number));
}

const close = (got, want) => Math.abs(got - want) <= 1e-4 * Math.abs(want) + 1e-6;

test("the packages of UBO2014 files keep the 151-direction dome and the file's factors", () => {
  for (const [id, args] of Object.entries(FILES)) {
    const { info, header } = decode(files[id].pkg);
    assert.equal(header.codec, "fmf");
    assert.equal(info.nV, 151);
    assert.equal(info.nL, 151);
    assert.equal(info.width, 16);
    assert.equal(info.colour, id === "model11" ? "model11" : "per-channel");
    assert.equal(info.quantization, args.includes("--half") ? "f16" : "f32");
    // UBO dome 1 (FORMATS.md item 9): ring θ and counts.
    const rings = new Map();
    for (const t of info.lights.theta) {
      const deg = Math.round(((t * 180) / Math.PI) * 10) / 10;
      rings.set(deg, (rings.get(deg) ?? 0) + 1);
    }
    assert.deepEqual([...rings.entries()].sort((a, b) => a[0] - b[0]), [[0, 1], [11, 6], [23.5, 12], [30, 12], [37.5, 12], [45, 18], [52.5, 18], [60, 24], [67.5, 24], [75, 24]]);
  }
});

test("the interpolation tables of the 151-direction dome: weight 1 at every sampled direction, a partition of unity elsewhere", () => {
  const { info, tables } = decode(files.model11.pkg);
  for (const [name, set, t] of [["views", info.views, tables.views], ["lights", info.lights, tables.lights]]) {
    assert.equal(t.N, 151, name);
    for (let i = 0; i < 151; ++i) {
      const w = M.lookup(t, ...dirVec((set.theta[i] * 180) / Math.PI, (set.phi[i] * 180) / Math.PI));
      const k = w.weight.indexOf(Math.max(...w.weight));
      assert.equal(w.index[k], i, `${name} ${i}`);
      assert.ok(w.weight[k] > 1 - 1e-5, `${name} ${i}: weight ${w.weight[k]}`);
    }
    let seed = 3;
    const rand = () => (seed = (seed * 16807) % 2147483647) / 2147483647;
    for (let n = 0; n < 3000; ++n) {
      // the whole sphere: below the outermost ring (75°) and below the horizon too
      const d = [rand() * 2 - 1, rand() * 2 - 1, rand() * 2 - 1];
      const w = M.lookup(t, ...d);
      const sum = w.weight.reduce((a, b) => a + b, 0);
      assert.ok(Math.abs(sum - 1) < 1e-6 && w.weight.every((x) => x >= 0), `${name}: ${JSON.stringify(w)} at ${d}`);
      w.index.forEach((x, j) => assert.ok(w.weight[j] === 0 || (x >= 0 && x < 151), `${name}: index ${x}`));
    }
  }
});

test("the viewer's CPU evaluator matches `btf eval` of the package and of the .btf file (model 11 and model 0)", (t) => {
  for (const id of Object.keys(FILES)) {
    const { model, tables } = decode(files[id].pkg);
    const queries = randomQueries(240, id === "model11" ? 5 : 6);
    const ofPackage = cliEval(files[id].pkg, queries);
    const ofFile = cliEval(files[id].btf, queries);
    let worst = 0;
    queries.forEach((q, i) => {
      const got = model.evalWeights(q.uv[0], q.uv[1], M.lookup(tables.views, ...dirVec(...q.view)), M.lookup(tables.lights, ...dirVec(...q.light)));
      for (let c = 0; c < 3; ++c) {
        const p = ofPackage[i][c], f = ofFile[i][c];
        assert.ok(close(got[c], p), `${id} ${q.line}: viewer ${got} vs btf eval of the package ${ofPackage[i]}`);
        assert.ok(close(got[c], f), `${id} ${q.line}: viewer ${got} vs btf eval of the file ${ofFile[i]}`);
        assert.ok(close(f, p), `${id} ${q.line}: file ${ofFile[i]} vs package ${ofPackage[i]}`);
        worst = Math.max(worst, Math.abs(got[c] - p) / (Math.abs(p) + 1e-2), Math.abs(got[c] - f) / (Math.abs(f) + 1e-2));
      }
    });
    t.diagnostic(`${id}: largest relative difference ${worst.toExponential(2)}`);
  }
});
