// SPDX-License-Identifier: MIT
// Unit tests of the viewer's modules in node (node --test test/): the package reader against the
// CLI's packages, the fmf decoder and CPU evaluator against `btf eval`, the interpolation tables,
// the meshes' conventions and the URL parameters.

import { test, before } from "node:test";
import assert from "node:assert/strict";
import { execFileSync } from "node:child_process";
import { mkdirSync, readFileSync, writeFileSync } from "node:fs";
import path from "node:path";
import { ARTIFACTS, FIXTURES, WEB, bundleModules, makeFixtures } from "./fixtures.mjs";

let M; // the bundled modules
let xxh64; // the package checksum (xxhash-wasm, loaded once)
let fx; // fixtures

before(async () => {
  fx = makeFixtures();
  const out = path.join(ARTIFACTS, "unit", "modules.mjs");
  M = await bundleModules(["half", "package", "interp", "factor", "meshes", "scene", "reference", "cache", "bsvtf", "coded", "rangecoder"], out);
  xxh64 = await M.loadChecksum();
});

const bytesOf = (file) => new Uint8Array(readFileSync(file));

/** Reads a whole package through PackageStream in chunks of the given sizes (cycled). */
function readAll(bytes, sizes = [bytes.length]) {
  const sections = [];
  let header = null;
  const s = new M.PackageStream("x.btfpkg", { header: (h) => (header = h), section: (x) => sections.push(x) }, xxh64);
  for (let at = 0, i = 0; at < bytes.length; ++i) {
    const n = sizes[i % sizes.length];
    s.push(bytes.subarray(at, at + n));
    at += n;
  }
  const complete = s.end();
  return { header, sections, complete };
}

test("the package checksum (xxhash-wasm) gives the known XXH64 digests as 16 hex digits", async () => {
  const enc = (t) => new TextEncoder().encode(t);
  assert.equal(xxh64(enc("")), "ef46db3751d8e999");
  assert.equal(xxh64(enc("a")), "d24ec4f1a98c6e5b");
  assert.equal(xxh64(enc("abc")), "44bc2cf5ad770999");
  // the 202-byte example package of docs/formats.md: its header digest
  const header = '{"codec":"test","format":"btfpkg","sections":[{"coding":"raw","name":"data","offset":0,"raw_size":4,"size":4,"xxh64":"542620e3a2a92ed1"}],"version":1,"writer":"btfkit 0.2.0"}';
  assert.equal(xxh64(enc(header)), "c37368fbe4082e31");
  assert.equal(xxh64(new Uint8Array([1, 2, 3, 4])), "542620e3a2a92ed1");
  // leading zero digits are kept
  assert.equal(xxh64(enc("14754")), "000245515fa5fc5d");
  // a view into a larger buffer hashes only its own bytes
  const padded = enc("xxabcxx");
  assert.equal(xxh64(padded.subarray(2, 5)), "44bc2cf5ad770999");
  // the module is instantiated once
  assert.equal(await M.loadChecksum(), xxh64);
});

test("half floats round-trip every finite bit pattern and round to nearest even", () => {
  for (let h = 0; h < 65536; ++h) {
    const f = M.halfToFloat(h);
    if (Number.isNaN(f)) continue;
    assert.equal(M.floatToHalf(f), h, `pattern ${h.toString(16)}`);
  }
  assert.equal(M.floatToHalf(1 + 2 ** -11), 0x3c00); // tie → even
  assert.equal(M.floatToHalf(1 + 3 * 2 ** -11), 0x3c02); // tie → even (up)
  assert.equal(M.floatToHalf(65520), 0x7c00); // rounds to infinity
  assert.equal(M.floatToHalf(2 ** -25), 0); // tie between 0 and the smallest subnormal → 0
  assert.equal(M.floatToHalf(3 * 2 ** -25), 2);
});

test("the package reader gives the same sections for any chunking, and checks them", () => {
  const bytes = bytesOf(fx.packages.woven_fabric);
  const whole = readAll(bytes);
  assert.ok(whole.complete);
  assert.equal(whole.header.totalBytes, bytes.length);
  assert.deepEqual(whole.sections.map((s) => s.entry.name), ["tables", "means", ...Array.from({ length: 8 }, (_, k) => `b0.k${k}`)]);
  for (const s of whole.sections) assert.equal(s.data.length, s.entry.raw_size);
  for (const sizes of [[1], [7, 3, 1000], [65536]]) {
    const r = readAll(bytes, sizes);
    assert.equal(r.sections.length, whole.sections.length);
    r.sections.forEach((s, i) => assert.deepEqual(s.data, whole.sections[i].data));
  }
  // raw sections (zstd level 0)
  const raw = readAll(bytesOf(fx.packages.woven_perchannel));
  assert.ok(raw.complete && raw.sections.every((s) => s.entry.coding === "raw"));
});

test("the package reader accepts clean prefixes and reports damage like the C++ reader", () => {
  const bytes = bytesOf(fx.packages.woven_fabric);
  const { header, sections } = readAll(bytes);
  const cut = sections[3].fileOffset + sections[3].entry.size; // after b0.k1
  const prefix = readAll(bytes.subarray(0, cut));
  assert.equal(prefix.complete, false);
  assert.equal(prefix.sections.length, 4);
  const err = (data) => {
    try {
      readAll(data);
    } catch (e) {
      assert.ok(e instanceof M.PackageError, e.message);
      return e.message;
    }
    assert.fail("no error");
  };
  assert.match(err(bytes.subarray(0, cut + 100)), /^x\.btfpkg: section 'b0\.k2' is truncated: 100 of \d+ bytes present \(from byte \d+\)$/);
  assert.match(err(bytes.subarray(0, 17)), /truncated in the header: 17 of the 24 preamble bytes present/);
  assert.match(err(bytes.subarray(0, 34)), /truncated in the header: 10 of its \d+ JSON bytes present \(from byte 24\)/);
  const bad = Uint8Array.from(bytes);
  bad[0] = 0x88;
  assert.match(err(bad), /not a btfkit package \(bad magic\)/);
  const damaged = bytesOf(fx.packages.woven_broken);
  assert.match(err(damaged), /checksum mismatch in section 'b0\.k2' \(bytes \d+\.\.\d+\): stored [0-9a-f]{16}, computed [0-9a-f]{16}/);
  const headerDamage = Uint8Array.from(bytes);
  headerDamage[30] ^= 1;
  assert.match(err(headerDamage), /header checksum mismatch/);
  const trailing = new Uint8Array(bytes.length + 3);
  trailing.set(bytes);
  assert.match(err(trailing), /trailing bytes after the last section \(from byte \d+\)/);
  const version = Uint8Array.from(bytes);
  version[8] = 2;
  assert.match(err(version), /unsupported package version 2/);
  assert.equal(header.headerBytes, sections[0].fileOffset);
  assert.throws(() => M.checkHeader("y", { format: "btfpkg", version: 1, sections: [{ name: "a", offset: 0, size: 1, raw_size: 1, coding: "raw", xxh64: "0123456789abcdef", extra: 1 }] }, 30), /y: header: section 0 has an unknown field 'extra'/);
  assert.throws(() => M.checkHeader("y", { format: "btfpkg", version: 1, sections: [{ name: "a", offset: 0, size: 1, raw_size: 1, coding: "lz4", xxh64: "0123456789abcdef" }] }, 30), /coding "lz4", expected "raw" or "zstd"/);
  assert.throws(() => M.checkHeader("y", { format: "btfpkg", version: 1, sections: [{ name: "a", offset: 1, size: 1, raw_size: 1, coding: "raw", xxh64: "0123456789abcdef" }] }, 30), /starts at offset 1 but the section before it ends at 0/);
});

function decode(file) {
  const bytes = bytesOf(file);
  const { header, sections } = readAll(bytes);
  const { info, model, tables } = M.decodeFactorSections(path.basename(file), header.json, sections);
  return { info, model, tables, bytes, sections };
}

const dirVec = (thetaDeg, phiDeg) => {
  const t = (thetaDeg * Math.PI) / 180, p = (phiDeg * Math.PI) / 180;
  return [Math.sin(t) * Math.cos(p), Math.sin(t) * Math.sin(p), Math.cos(t)];
};

function cliEval(file, uv, light, view) {
  return cliEvalMany(file, [{ uv, light, view }])[0];
}

/** `btf eval --queries -` of many queries in one process: one RGB per query. */
function cliEvalMany(file, queries) {
  const input = queries.map((q) => `${q.uv.join(",")} ${q.light.join(",")} ${q.view.join(",")}`).join("\n");
  const lines = execFileSync(fx.bin, ["-q", "eval", file, "--queries", "-"], { input }).toString().trim().split("\n");
  assert.equal(lines.length, queries.length);
  return lines.map((l) => l.trim().split(/\s+/).map(Number));
}

// A small fixed set of queries: texel centres, seams, between directions, below the outer ring.
const QUERIES = [
  { uv: [0.3, 0.7], light: [30, 40], view: [20, 200] },
  { uv: [0, 0], light: [0, 0], view: [45, 90] },
  { uv: [1.25, -0.4], light: [80, 300], view: [10, 10] },
  { uv: [0.015625, 0.984375], light: [60, 15], view: [75, 345] },
  { uv: [0.51, 0.49], light: [88, 170], view: [52, 33] },
];

/** n random queries (uv anywhere, both directions over the hemisphere, grazing included) from a seed. */
function randomQueries(n, seed) {
  let x = seed >>> 0;
  const next = () => ((x = (Math.imul(x, 1664525) + 1013904223) >>> 0) / 2 ** 32);
  return Array.from({ length: n }, () => ({
    uv: [next() * 3 - 1, next() * 3 - 1],
    light: [Math.acos(next()) * (180 / Math.PI), next() * 360],
    view: [Math.acos(next()) * (180 / Math.PI), next() * 360],
  }));
}

test("the CPU evaluator matches `btf eval` for every factor codec and colour, log and quantization variant", () => {
  const ids = ["woven_fabric", "woven_declog", "woven_perchannel", "woven_model11", "woven_pca", "woven_pca_declog", "woven_lpca", "woven_lpca_dec", "woven_perceptual", "woven_perceptual_u8", "woven_pca_f32", "woven_lpca_u8", "woven_perceptual_f32", "woven_coded", "woven_lpca_coded", "woven_perceptual_coded"];
  ids.forEach((id, i) => {
    const { model, tables } = decode(fx.packages[id]);
    const queries = [...QUERIES, ...randomQueries(200, 17 + i)];
    const values = cliEvalMany(fx.packages[id], queries);
    queries.forEach((q, k) => {
      const wi = dirVec(...q.light), wo = dirVec(...q.view);
      const got = model.evalWeights(q.uv[0], q.uv[1], M.lookup(tables.views, ...wo), M.lookup(tables.lights, ...wi));
      const want = values[k];
      for (let c = 0; c < 3; ++c)
        assert.ok(Math.abs(got[c] - want[c]) <= 2e-5 + 1e-4 * Math.abs(want[c]), `${id} ${JSON.stringify(q)}: ${got} vs ${want}`);
    });
  });
});

test("a prefix of a package evaluates like the C++ reader's prefix (components present only)", () => {
  const { bytes, sections } = decode(fx.packages.woven_declog);
  const cut = sections[4].fileOffset + sections[4].entry.size; // tables, means and 3 components
  const file = path.join(FIXTURES, "woven_declog.prefix.btfpkg");
  writeFileSync(file, bytes.subarray(0, cut));
  const { model, tables } = decode(file);
  assert.equal(model.loadedComponents, 3);
  for (const q of QUERIES.slice(0, 3)) {
    const got = model.evalWeights(q.uv[0], q.uv[1], M.lookup(tables.views, ...dirVec(...q.view)), M.lookup(tables.lights, ...dirVec(...q.light)));
    const want = cliEval(file, q.uv, q.light, q.view);
    for (let c = 0; c < 3; ++c) assert.ok(Math.abs(got[c] - want[c]) <= 2e-5 + 1e-4 * Math.abs(want[c]), `${got} vs ${want}`);
  }
});

test("the fixtures cover every model layout: view groups, clusters, spatial and angular levels, lab colour", () => {
  const info = (id) => decode(fx.packages[id]).info;
  assert.equal(info("woven_pca").codec, "pca-views");
  assert.ok(info("woven_pca").groups.length > 1);
  assert.ok(info("woven_lpca").clusters > 1);
  const perceptual = info("woven_perceptual");
  assert.equal(perceptual.colour, "lab");
  assert.ok(perceptual.levels > 1, "spatial levels");
  assert.ok(perceptual.angularLevels.length > 0, "angular levels");
  assert.ok(perceptual.blocks.some((b) => b.level > 0 && b.components > 0), "components at a reduced spatial level");
  assert.ok(perceptual.blocks.some((b) => b.angular > 0 && b.components > 0), "components at a reduced angular level");
});

test("other codecs are refused as unsupported; malformed model fields are errors", () => {
  const fmf = readAll(bytesOf(fx.packages.woven_fabric)).header.json;
  const other = structuredClone(fmf);
  other.codec = "neural";
  assert.throws(() => M.readFactorHeader("m", other), (e) => e instanceof M.UnsupportedMaterial && /codec 'neural' is not supported by the viewer/.test(e.message));
  const clustered = structuredClone(fmf);
  clustered.model.clusters = 4;
  assert.throws(() => M.readFactorHeader("m", clustered), /m: package \(fmf\): 1 blocks for 1 planes × 1 groups × 4 clusters/);
  const twice = structuredClone(readAll(bytesOf(fx.packages.woven_pca)).header.json);
  twice.model.groups[1][0] = twice.model.groups[0][0];
  assert.throws(() => M.readFactorHeader("m", twice), /view \d+ is in two view groups/);
  const lablog = structuredClone(readAll(bytesOf(fx.packages.woven_perceptual)).header.json);
  lablog.model.log = true;
  assert.throws(() => M.readFactorHeader("m", lablog), /log with lab colour/);
});

test("damaged model sections give one clear error naming the section", () => {
  const { info, sections } = decode(fx.packages.woven_lpca);
  const model = new M.FactorModel(info);
  const clusters = sections.find((s) => s.entry.name === "clusters").data.slice();
  new DataView(clusters.buffer).setInt32(4 * 5, 99, true);
  assert.throws(() => model.setClusters(clusters), /section 'clusters': texel 5 is in cluster 99 of 4/);
  assert.throws(() => model.addComponent("b0.k0", new Uint8Array(10)), /section 'b0.k0' arrives before section 'clusters'/);
  const p = decode(fx.packages.woven_perceptual);
  const angular = p.sections.find((s) => s.entry.name === "angular").data;
  assert.throws(() => new M.FactorModel(p.info).setAngular(angular.subarray(0, angular.length - 4)), /section 'angular' holds \d+ bytes, expected \d+/);
  const first = p.sections.find((s) => /^b\d+\.k0$/.test(s.entry.name) && p.info.blocks[Number(s.entry.name.slice(1, s.entry.name.indexOf(".")))].angular > 0);
  const block = Number(first.entry.name.slice(1, first.entry.name.indexOf(".")));
  const fresh = new M.FactorModel(p.info);
  assert.throws(() => fresh.addComponent(`b${block}.k0`, first.data), /needs section 'angular'/);
});

test("damaged coded components give the C++ reader's errors, naming the section", () => {
  const { info, sections } = decode(fx.packages.woven_coded);
  const k0 = sections.find((s) => s.entry.name === "b0.k0").data;
  assert.equal(k0[0], 2, "the fixture's first component is range-coded (format 2), as the messages below assume");
  const add = (bytes) => () => new M.FactorModel(info).addComponent("b0.k0", bytes);
  assert.doesNotThrow(add(k0));
  assert.throws(add(k0.subarray(0, 5)), /^Error: section 'b0\.k0': 5 bytes, shorter than a coded component's head$/);
  assert.throws(add(k0.subarray(0, k0.length - 1)), /^Error: section 'b0\.k0': the coded factors end early$/);
  const longer = new Uint8Array(k0.length + 1);
  longer.set(k0);
  assert.throws(add(longer), /^Error: section 'b0\.k0': 1 bytes after the coded factors$/);
  for (const [at, value, message] of [
    [0, 9, "unknown coded format 9"],
    [1, 65, "prediction distance 65"],
    [2, 7, "unknown texel coding 7"],
  ]) {
    const bad = k0.slice();
    bad[at] = value;
    assert.throws(add(bad), new RegExp(`^Error: section 'b0\\.k0': ${message}$`));
  }
});

// The C++ tests' worked examples (range_coder_test.cpp, coded_test.cpp), read by the viewer.
test("the range decoder and format 1 read the C++ tests' worked examples", () => {
  const coder = new M.RangeDecoder(new Uint8Array([0x00, 0x7f, 0xff, 0xfc, 0x00]), 0, "x");
  const probs = new Uint16Array([1024]);
  assert.equal(coder.bit(probs, 0), 1);
  assert.equal(probs[0], 1024 - 32);
  assert.equal(coder.remaining, 0);
  // Format 1: a = (1, 1.5, 2.5, 3) with step 0.5 as the varints 4, 2, 4, 2; one 8 × 8 block with DC 34.
  const head = new Uint8Array(12);
  head.set([1, 1, 1, 0]);
  const view = new DataView(head.buffer);
  view.setFloat32(4, 0.5, true);
  view.setFloat32(8, Math.fround(1 / Math.sqrt(4.625)), true);
  const bytes = new Uint8Array(12 + 5 + 63);
  bytes.set(head);
  bytes.set([4, 2, 4, 2, 0x44], 12);
  const { a, b } = M.decodeCodedComponent(bytes, 4, 64, { width: 8, height: 8 }, "b0.k0");
  assert.deepEqual(Array.from(a), [1, 1.5, 2.5, 3]);
  const dc = (34 * Math.fround(1 / Math.sqrt(4.625))) / 8;
  for (const v of b) assert.ok(Math.abs(v - dc) <= dc * 2 ** -11);
  // Channel prediction is format 2's only.
  bytes[1] = 0;
  assert.throws(() => M.decodeCodedComponent(bytes, 4, 64, { width: 8, height: 8 }, "b0.k0"), /^Error: section 'b0\.k0': prediction distance 0$/);
});

// coded_test.cpp's worked example of the prediction by neighbouring directions (floor of the mean).
test("the viewer reads the prediction by neighbouring directions as the C++ reader does", () => {
  const bytes = new Uint8Array([
    0x02, 0x80, 0x00, 0x01, 0x00, 0x00, 0x00, 0x3f, 0x00, 0x00, 0x80, 0x3e, 0x00, 0xd4, 0xac, 0x12, 0x69, 0x81, 0xa0, 0x40, 0x00,
  ]);
  const { a, b } = M.decodeCodedComponent(bytes, 6, 1, null, "b0.k0", { lights: 3, channels: 1 });
  assert.deepEqual(Array.from(a), [-0.5, 0.5, 2, -1, 2.5, 3]);
  assert.deepEqual(Array.from(b), [0.75]);
  const layoutError = /^Error: section 'b0\.k0': prediction by neighbouring directions, but the factor's rows are not laid out by directions$/;
  assert.throws(() => M.decodeCodedComponent(bytes, 6, 1, null, "b0.k0"), layoutError);
  assert.throws(() => M.decodeCodedComponent(bytes, 6, 1, null, "b0.k0", { lights: 4, channels: 1 }), layoutError);
  const format1 = bytes.slice();
  format1[0] = 1;
  assert.throws(
    () => M.decodeCodedComponent(format1, 6, 1, null, "b0.k0", { lights: 3, channels: 1 }),
    /^Error: section 'b0\.k0': prediction by neighbouring directions in format 1$/,
  );
});

// coded_test.cpp's worked example of a as images of directions (prediction 129).
test("the viewer reads a as images of directions as the C++ reader does", () => {
  const bytes = new Uint8Array([
    0x02, 0x81, 0x00, 0x01, 0x00, 0x00, 0x00, 0x3f, 0x00, 0x00, 0x80, 0x3e,
    0x00, 0xb7, 0xff, 0xfc, 0x00, 0x00, 0x00, 0x00, 0x39, 0x91, 0xd8, 0x00, 0x01, 0x18, 0xba, 0x4f, 0x00, 0xf0, 0x20, 0xf0, 0x00,
  ]);
  const layout = { lights: 8, channels: 3 };
  const { a, b } = M.decodeCodedComponent(bytes, 192, 1, null, "b0.k0", layout);
  assert.deepEqual(Array.from(a), Array.from({ length: 64 }, () => [0.75, 0.5, 0]).flat());
  assert.deepEqual(Array.from(b), [0.75]);
  assert.throws(
    () => M.decodeCodedComponent(bytes, 192, 1, null, "b0.k0"),
    /^Error: section 'b0\.k0': a as images of directions, but the factor's rows are not laid out by directions$/,
  );
  const format1 = bytes.slice();
  format1[0] = 1;
  assert.throws(
    () => M.decodeCodedComponent(format1, 192, 1, null, "b0.k0", layout),
    /^Error: section 'b0\.k0': a as images of directions in format 1$/,
  );
});

test("the interpolation tables give weight 1 at the sampled directions and a partition of unity", () => {
  const { info, tables } = decode(fx.packages.woven_fabric);
  for (let i = 0; i < info.nL; ++i) {
    const t = info.lights.theta[i], p = info.lights.phi[i];
    const w = M.lookup(tables.lights, Math.sin(t) * Math.cos(p), Math.sin(t) * Math.sin(p), Math.cos(t));
    const k = w.weight.indexOf(Math.max(...w.weight));
    assert.equal(w.index[k], i);
    assert.ok(w.weight[k] > 1 - 1e-5);
  }
  let seed = 1;
  const rand = () => ((seed = (seed * 16807) % 2147483647) / 2147483647);
  for (let n = 0; n < 2000; ++n) {
    const d = [rand() * 2 - 1, rand() * 2 - 1, rand() * 2 - 1.2];
    const w = M.lookup(tables.views, ...d);
    const sum = w.weight.reduce((a, b) => a + b, 0);
    assert.ok(Math.abs(sum - 1) < 1e-6 && w.weight.every((x) => x >= 0));
    w.index.forEach((x, j) => assert.ok(w.weight[j] === 0 || (x >= 0 && x < info.nV)));
  }
  // a uniform environment's weights integrate the hemisphere: Σ c_l = (1/π) · 2π
  const c = M.uniformEnvironmentWeights(tables.lights, 64);
  assert.ok(Math.abs(c.reduce((a, b) => a + b, 0) - 2) < 1e-6);
});

test("the meshes follow mesh.h: outward winding, tangents along +u, orientation-preserving uv", () => {
  for (const shape of M.SHAPES) {
    const mesh = M.transformMesh(M.makeShape({ shape, segments: 24 }), M.objectTransform([0.5, -1, 2], [10, 20, 30], [1, 1.5, 1]));
    const P = mesh.positions, N = mesh.normals, T = mesh.tangents, UV = mesh.uvs, I = mesh.indices;
    const v = (a, i) => [a[3 * i], a[3 * i + 1], a[3 * i + 2]];
    const sub = (a, b) => a.map((x, k) => x - b[k]);
    const cross = (a, b) => [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]];
    const dot = (a, b) => a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
    for (let t = 0; t < I.length; t += 3) {
      const [a, b, c] = [I[t], I[t + 1], I[t + 2]];
      const e1 = sub(v(P, b), v(P, a)), e2 = sub(v(P, c), v(P, a));
      const ng = cross(e1, e2);
      if (Math.hypot(...ng) < 1e-9) continue;
      assert.ok(dot(ng, v(N, a)) > 0, `${shape}: triangle ${t / 3} winds inward`);
      // dP/du and dP/dv from the triangle; their cross product points outward
      const du1 = UV[2 * b] - UV[2 * a], dv1 = UV[2 * b + 1] - UV[2 * a + 1];
      const du2 = UV[2 * c] - UV[2 * a], dv2 = UV[2 * c + 1] - UV[2 * a + 1];
      const det = du1 * dv2 - du2 * dv1;
      if (Math.abs(det) < 1e-12) continue;
      const dpdu = e1.map((x, k) => (x * dv2 - e2[k] * dv1) / det);
      const dpdv = e2.map((x, k) => (x * du1 - e1[k] * du2) / det);
      assert.ok(dot(cross(dpdu, dpdv), ng) > 0, `${shape}: uv mirrored at triangle ${t / 3}`);
      assert.ok(dot(dpdu, v(T, a)) > 0, `${shape}: tangent against +u at triangle ${t / 3}`);
    }
    for (let i = 0; i < P.length / 3; ++i) assert.ok(Math.abs(dot(v(N, i), v(T, i))) < 1e-5);
  }
  const sphere = M.makeSphere(1, 8);
  assert.equal(sphere.positions.length / 3, 9 * 3 + 2 * 8);
  assert.equal(sphere.indices.length / 3, 2 * 8 + 2 * 8 * 2);
});

test("URL parameters and scene JSON fix the scene", () => {
  const s = M.sceneFromParams(new URLSearchParams("material=m&object=torus&camera=1,2,3&target=0,0.5,0&fov=30&size=320x200&light=0,1,0&irradiance=2&env=0.25&exposure=-1&mip=0&deterministic=1&uvscale=2,3&uvrot=15"));
  assert.equal(s.objects[0].shape, "torus");
  assert.equal(s.objects[0].material, "m");
  assert.deepEqual(s.camera.position, [1, 2, 3]);
  assert.deepEqual([s.camera.width, s.camera.height], [320, 200]);
  assert.deepEqual(s.lights, [{ type: "directional", vector: [0, 1, 0], power: [2, 2, 2] }]);
  assert.deepEqual(s.environment, [0.25, 0.25, 0.25]);
  assert.deepEqual(s.objects[0].uv_scale, [2, 3]);
  assert.equal(s.objects[0].uv_rotation, 15);
  assert.ok(s.deterministic && !s.mip);
  const scene = {
    camera: { position: [0, 1.2, 4], look_at: [0, 0.4, 0], fov: 35, width: 64, height: 48 },
    render: { exposure: 0.5 },
    objects: [{ shape: "cylinder", radius: 0.5, uv_scale: 4, material: { type: "btf", file: "dir/cloth.btfpkg" } }],
    lights: [{ type: "point", position: [0, 4, 1], intensity: 12 }],
  };
  const j = M.sceneFromParams(new URLSearchParams({ scene: JSON.stringify(scene) }));
  assert.equal(j.objects[0].material, "cloth");
  assert.deepEqual(j.objects[0].uv_scale, [4, 4]);
  assert.equal(j.objects[0].radius, 0.5);
  assert.deepEqual(j.lights[0], { type: "point", vector: [0, 4, 1], power: [12, 12, 12] });
  assert.equal(j.exposure, 0.5);
  assert.throws(() => M.sceneFromParams(new URLSearchParams("object=cube")), /unknown shape 'cube'/);
  assert.throws(() => M.sceneFromParams(new URLSearchParams("camera=1,2")), /expected 3 comma-separated numbers/);
});

test("the TypeScript sources type-check (tsc --noEmit)", () => {
  execFileSync(process.execPath, [path.join(WEB, "node_modules/typescript/bin/tsc"), "--noEmit", "-p", WEB], { stdio: "pipe" });
});

// ---- the BSVTF tile cache -------------------------------------------------------------------

test("the tile cache takes the C++ decisions on the recorded votes (data/cache-trace.json)", () => {
  // src/btf/bsvtf/cache_test.cpp records TileCache::decide frame by frame and keeps the file in
  // step with the C++; here the port replays the same pixels and must decide identically.
  const trace = JSON.parse(readFileSync(path.join(WEB, "test/data/cache-trace.json"), "utf8"));
  const layouts = trace.materials.map((m) => new M.TileLayout(m.width, m.height, m.tile, m.pad, m.groups.map(([plane, first, count]) => ({ plane, first, count }))));
  const cache = new M.TileCache(layouts, trace.materials.map((m) => Float32Array.from(m.weights)), trace.capacity);
  const votes = new M.Votes(layouts);
  const key = (t) => [t.material, t.group, t.level, t.x, t.y];
  let operations = 0, swaps = 0, waits = 0;
  trace.frames.forEach((f, frame) => {
    votes.clear();
    for (const [m, level, u, v] of f.pixels) votes.add(m, level, u, v);
    const missing = new Set(f.unavailable.map(([m, i]) => `${m}/${i}`));
    const d = cache.decide(votes, (t) => !missing.has(`${t.material}/${layouts[t.material].index(t)}`), trace.max_operations);
    const got = d.operations.map((op) => {
      const o = { kind: op.kind, tile: key(op.tile), value: op.value };
      if (op.out) o.out = op.out.map(key);
      return o;
    });
    assert.deepEqual(got, f.operations, `frame ${frame}: operations`);
    assert.deepEqual(d.wanted ? key(d.wanted) : null, f.wanted, `frame ${frame}: wanted`);
    assert.deepEqual(cache.tiles().map(key), f.resident, `frame ${frame}: resident tiles`);
    operations += got.length;
    swaps += got.filter((o) => o.kind === "swap").length;
    waits += d.wanted ? 1 : 0;
  });
  assert.ok(operations > 100 && swaps > 10 && waits > 0, `${operations} operations, ${swaps} swaps, ${waits} waits`);
});

test("tile layout numbering and votes follow pyramid.h and cache.cpp", () => {
  const l = new M.TileLayout(512, 256, 64, 4, [{ plane: 0, first: 0, count: 4 }, { plane: 0, first: 4, count: 2 }]);
  assert.equal(l.levels, 4);
  assert.equal(l.tilesPerGroup, 8 * 4 + 4 * 2 + 2 + 1);
  for (let i = 0; i < l.tileCount; ++i) assert.equal(l.index(l.id(i)), i);
  assert.deepEqual(l.id(l.tilesPerGroup + 8 * 4 + 5), { group: 1, level: 1, x: 1, y: 1 });
  const votes = new M.Votes([l]);
  votes.add(0, 0, (300 + 0.5) / 512, (70 + 0.5) / 256); // level-0 texel (300, 70): tile (4, 1)
  assert.equal(votes.get(0, { group: 1, level: 0, x: 4, y: 1 }), 1);
  assert.equal(votes.get(0, { group: 0, level: 1, x: 2, y: 0 }), 1);
  assert.equal(votes.get(0, { group: 0, level: 3, x: 0, y: 0 }), 1);
  assert.equal(votes.get(0, { group: 0, level: 0, x: 3, y: 1 }), 0);
});

/** Every tile of a BSVTF package decoded, parents first, as the viewer decodes them. */
async function decodeAllTiles(file) {
  const { header, sections } = readAll(bytesOf(file));
  const info = M.readBsvtfHeader(header.json);
  const layout = M.layoutOf(info);
  const tilesSection = sections.find((x) => x.entry.name === "tiles");
  assert.equal(tilesSection.entry.coding, "raw", "the tiles section is stored raw (byte ranges)");
  const index = M.readTileIndex(sections.find((x) => x.entry.name === "tiles.index").data, info.tiles, tilesSection.data.length);
  const tiles = new Array(layout.tileCount);
  for (let level = layout.levels - 1; level >= 0; --level)
    for (let t = 0; t < layout.tileCount; ++t) {
      const id = layout.id(t);
      if (id.level !== level) continue;
      const payload = tilesSection.data.subarray(index.offsets[t], index.offsets[t] + index.sizes[t]);
      const prediction = layout.hasParent(id) ? M.predictChild(tiles[layout.index(layout.parent(id))], layout, id) : null;
      tiles[t] = await M.decodeTile(payload, prediction, layout);
    }
  return { info, layout, index, tiles };
}

test("BSVTF tiles decode to the eigen-textures: lossless exactly, lossy within the tile error", async () => {
  const lossless = await decodeAllTiles(fx.packages.bsvtfLossless);
  const lossy = await decodeAllTiles(fx.packages.bsvtf);
  const { layout, info } = lossless;
  assert.equal(layout.levels, 3);
  assert.equal(info.groups.length, 2);
  // The fmf package's eigen-texture columns b(·, k) (f16: the stored half bits).
  const fmf = decode(fx.packages.woven_fabric);
  const rows = M.groupRows(fmf.info, 0);
  const column = (k) => {
    const s = fmf.sections.find((x) => x.entry.name === `b0.k${k}`);
    return M.columnHalfBits(s.data, M.columnBytes("f16", rows), fmf.info.width * fmf.info.height);
  };
  const S = layout.stride, T = layout.tile, P = layout.pad, W = info.width, H = info.height;
  let sum = 0, err = 0, checked = 0;
  layout.groups.forEach((g, gi) => {
    const b = Array.from({ length: g.count }, (_, c) => column(g.first + c));
    for (let ty = 0; ty < layout.tilesY(0); ++ty)
      for (let tx = 0; tx < layout.tilesX(0); ++tx) {
        const t = layout.index({ group: gi, level: 0, x: tx, y: ty });
        for (let ly = 0; ly < S; ++ly)
          for (let lx = 0; lx < S; ++lx) {
            // padding wraps around the texture
            const x = (((tx * T + lx - P) % W) + W) % W, y = (((ty * T + ly - P) % H) + H) % H;
            for (let c = 0; c < 4; ++c) {
              const i = (ly * S + lx) * 4 + c;
              const want = c < g.count ? b[c][y * W + x] : 0;
              assert.equal(lossless.tiles[t][i], want, `group ${gi} tile (${tx}, ${ty}) texel (${lx}, ${ly}) channel ${c}`);
              ++checked;
              if (lx < P || ly < P || lx >= P + T || ly >= P + T) continue;
              const v = M.halfToFloat(want), d = M.halfToFloat(lossy.tiles[t][i]) - v;
              sum += v * v;
              err += d * d;
            }
          }
      }
  });
  assert.equal(checked, 2 * 16 * S * S * 4);
  const relative = Math.sqrt(err / sum);
  assert.ok(relative > 0 && relative <= lossy.info.relativeError, `relative RMS error ${relative} (bound ${lossy.info.relativeError})`);
  // The index's weights are equation 8's, as written.
  assert.ok(lossless.index.weights.every((w) => w >= 0) && lossless.index.weights.some((w) => w > 0));
  // A damaged payload is an error, not a wrong tile.
  const bad = new Uint8Array([1, 0, 0, 128, 63, 10, 0, 0, 0, 0xff, 0xff, 0xff]);
  await assert.rejects(M.decodeTile(bad, null, layout), /tile: /);
});
