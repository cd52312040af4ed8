// SPDX-License-Identifier: MIT
// Unit tests of the viewer's mlvq module (src/mlvq.ts) in node (node --test test/mlvq.test.mjs):
// the CPU reference against `btf eval` for both colour models and for packages of shared
// code-books, prefixes of the stream, damaged sections, the header reader's refusals, and the
// shader (mlvqFragment) in headless Chromium (WebGL2 through SwiftShader) against the CPU
// reference. Packages are made with the CLI (btf synth, btf convert, btf compress) under
// web/test-artifacts/mlvq/ and reused while their arguments stay the same.

import { test, before, after } from "node:test";
import assert from "node:assert/strict";
import { execFile, execFileSync } from "node:child_process";
import { existsSync, mkdirSync, readFileSync, rmSync, writeFileSync } from "node:fs";
import path from "node:path";
import { ARTIFACTS, btfBinary, bundleModules, run } from "./fixtures.mjs";
import { launchBrowser } from "./browser.mjs";

const DIR = path.join(ARTIFACTS, "mlvq");
let M; // the bundled modules
let xxh64;
let bin;
const pkg = {}; // id → package file

// Small grids keep compression to seconds; two grids so that nothing depends on one shape (an
// even n_alpha has no slice through the normal, an odd n_phi_v no opposite azimuth).
const GRID_A = ["-p", "n-alpha=7", "-p", "n-beta=7", "-p", "n-theta-v=4", "-p", "n-phi-v=8"];
const GRID_B = ["-p", "n-alpha=6", "-p", "n-beta=5", "-p", "n-theta-v=3", "-p", "n-phi-v=5"];
const PACKAGES = {
  // LDR source (a UTIA PNG image set): colour=auto is YCbCr, 8-bit P2 scales
  ldr: [["woven_png"], GRID_B],
  // HDR source (btf synth writes HDR): colour=auto is LogLuv, 16-bit P2 scales
  hdr: [["woven.h5"], GRID_A],
  // YCbCr on the HDR source (16-bit P2 scales with YCbCr)
  hdr_ycbcr: [["woven.h5"], [...GRID_B, "-p", "colour=ycbcr"]],
  // two materials sharing the code-books (32² and 16²: 4 and 3 P6 levels, interleaved)
  shared: [["woven.h5", "leather.h5"], GRID_B],
  // isotropic (n-phi-v=1)
  iso: [["woven.h5"], ["-p", "n-alpha=5", "-p", "n-beta=5", "-p", "n-theta-v=3", "-p", "n-phi-v=1"]],
};

function makeMlvqFixtures() {
  mkdirSync(DIR, { recursive: true });
  const sources = {
    "woven.h5": () => run(bin, ["-q", "synth", "--preset", "woven_fabric", "--size", "32", "-o", path.join(DIR, "woven.h5")]),
    "leather.h5": () => run(bin, ["-q", "synth", "--preset", "leather", "--size", "16", "-o", path.join(DIR, "leather.h5")]),
    woven_png: () => run(bin, ["-q", "convert", path.join(DIR, "woven.h5"), path.join(DIR, "woven_png"), "--format", "png"]),
  };
  for (const [name, make] of Object.entries(sources)) if (!existsSync(path.join(DIR, name))) make();
  for (const [id, [inputs, params]] of Object.entries(PACKAGES)) {
    const file = path.join(DIR, `${id}.btfpkg`);
    const args = ["-q", "--threads", "2", "compress", ...inputs.map((i) => path.join(DIR, i)), "--codec", "mlvq", ...params, "--no-error", "-o", file];
    const stamp = file + ".args";
    if (!existsSync(file) || !existsSync(stamp) || readFileSync(stamp, "utf8") !== JSON.stringify(args)) {
      rmSync(file, { force: true });
      run(bin, args);
      writeFileSync(stamp, JSON.stringify(args));
    }
    pkg[id] = file;
  }
}

before(async () => {
  bin = btfBinary();
  makeMlvqFixtures();
  const out = path.join(DIR, "modules.mjs");
  M = await bundleModules(["half", "package", "mlvq", "shader"], out);
  xxh64 = await M.loadChecksum();
});

// ---- helpers ------------------------------------------------------------------------------------

const bytesOf = (file) => new Uint8Array(readFileSync(file));

/** The package's header and decoded sections (through the viewer's reader). */
function readPackage(bytes, name = "x.btfpkg") {
  const sections = [];
  let header = null;
  const s = new M.PackageStream(name, { header: (h) => (header = h), section: (x) => sections.push(x) }, xxh64);
  s.push(bytes);
  const complete = s.end();
  return { header, sections, complete };
}

/** A decoder fed with every section of a package (or prefix); collects the errors it throws. */
function decode(bytes, name) {
  const { header, sections, complete } = readPackage(bytes, name);
  const decoder = new M.MlvqDecoder(M.readMlvqHeader(name, header.json));
  const errors = [];
  for (const s of sections) {
    try {
      decoder.addSection(s.entry.name, s.data);
    } catch (e) {
      errors.push(e);
    }
  }
  return { decoder, header, sections, complete, errors };
}

const decodeFile = (file) => decode(bytesOf(file), path.basename(file));

/** Writes a package from a header (codec fields) and sections { name, data } (stored raw). */
function writePackage(file, fields, sections) {
  const json = { ...fields };
  delete json.sections;
  let offset = 0;
  json.sections = sections.map((s) => {
    const e = { name: s.name, offset, size: s.data.length, raw_size: s.data.length, coding: "raw", xxh64: xxh64(s.data) };
    offset += s.data.length;
    return e;
  });
  const header = new TextEncoder().encode(JSON.stringify(json));
  const pre = Buffer.alloc(24);
  Buffer.from([0x89, 0x42, 0x54, 0x46, 0x50, 0x4b, 0x47, 0x0a]).copy(pre);
  pre.writeUInt32LE(1, 8);
  pre.writeUInt32LE(header.length, 12);
  pre.writeBigUInt64LE(BigInt("0x" + xxh64(header)), 16);
  writeFileSync(file, Buffer.concat([pre, header, ...sections.map((s) => s.data)]));
  return file;
}

/** `btf eval --queries -` of many queries in one process: the RGB of each, or { error } for all. */
async function cliEvalAll(file, queries) {
  const input = queries.map((q) => `${q.uv.join(",")} ${q.light.join(",")} ${q.view.join(",")}`).join("\n");
  return new Promise((resolve) => {
    const child = execFile(bin, ["-q", "eval", path.basename(file), "--queries", "-"], { cwd: path.dirname(file), maxBuffer: 1 << 26 }, (err, stdout, stderr) => {
      if (err) resolve(queries.map(() => ({ error: stderr.toString().trim().replace(/^btf: error: /, "") || err.message })));
      else resolve(stdout.toString().trim().split("\n").map((l) => l.trim().split(/\s+/).map(Number)));
    });
    child.stdin.end(input);
  });
}

const cliError = (file) => {
  try {
    const args = ["-q", "eval", path.basename(file), "--uv", "0.3,0.6", "--light", "30,40", "--view", "20,200"];
    execFileSync(bin, args, { cwd: path.dirname(file), stdio: ["ignore", "pipe", "pipe"] });
  } catch (e) {
    if (e.stderr === null || e.stderr === undefined) throw e;
    return e.stderr.toString().trim().replace(/^btf: error: /, "");
  }
  return null;
};

/** Direction::from_degrees(θ, φ).vector() as the CLI computes it. */
function dirVec(thetaDeg, phiDeg) {
  let phi = phiDeg % 360;
  if (phi < 0) phi += 360;
  const t = thetaDeg * (Math.PI / 180), p = phi * (Math.PI / 180);
  const s = Math.sin(t);
  return [s * Math.cos(p), s * Math.sin(p), Math.cos(t)];
}

/** A small seeded generator (mulberry32). */
function random(seed) {
  let a = seed >>> 0;
  return () => {
    a = (a + 0x6d2b79f5) >>> 0;
    let t = a;
    t = Math.imul(t ^ (t >>> 15), t | 1);
    t ^= t + Math.imul(t ^ (t >>> 7), t | 61);
    return ((t ^ (t >>> 14)) >>> 0) / 4294967296;
  };
}

/**
 * Random queries over the upper hemisphere: θ uniform in solid angle, with grazing (θ = 90°
 * exactly), normal (θ = 0) and near-grazing directions; uv inside and outside [0, 1), texel
 * centres and seams; azimuths beyond ±360°.
 */
function queries(n, seed) {
  const r = random(seed);
  const angle = () => {
    const k = r();
    const theta = k < 0.12 ? 90 : k < 0.17 ? 0 : k < 0.25 ? 89 + r() : (Math.acos(1 - r()) * 180) / Math.PI;
    return [theta, r() < 0.1 ? r() * 1440 - 720 : r() * 360];
  };
  const coord = () => {
    const k = r();
    return k < 0.1 ? (Math.floor(r() * 32) + 0.5) / 32 : k < 0.15 ? Math.floor(r() * 8) - 3 : r() * 5 - 2;
  };
  return Array.from({ length: n }, () => ({ uv: [coord(), coord()], light: angle(), view: angle() }));
}

/** Largest relative error (|Δ| − abs) / |want| of got against want; asserts the tolerance. */
function compare(got, want, rel, abs, what) {
  let worst = 0;
  for (let c = 0; c < 3; ++c) {
    const d = Math.abs(got[c] - want[c]);
    assert.ok(d <= rel * Math.abs(want[c]) + abs, `${what}: got ${got.join(" ")}, want ${want.join(" ")}`);
    if (Math.abs(want[c]) > 1e-3) worst = Math.max(worst, d / Math.abs(want[c]));
  }
  return worst;
}

async function evalAgainstCli(t, file, decoder, n, seed) {
  const qs = queries(n, seed);
  const want = await cliEvalAll(file, qs);
  let worst = 0;
  qs.forEach((q, k) => {
    assert.ok(!want[k].error, `btf eval ${JSON.stringify(q)}: ${want[k].error}`);
    const got = decoder.eval(q.uv[0], q.uv[1], dirVec(...q.light), dirVec(...q.view));
    worst = Math.max(worst, compare(got, want[k], 1e-4, 1e-6, `${path.basename(file)} ${JSON.stringify(q)}`));
  });
  t.diagnostic(`${path.basename(file)}: ${n} queries, max relative error ${worst.toExponential(2)} (btf eval prints 6 digits)`);
  return worst;
}

// ---- the CPU reference against btf eval ---------------------------------------------------------

test("the CPU reference matches `btf eval` for YCbCr (LDR) and LogLuv (HDR) packages and for shared code-books", async (t) => {
  for (const [id, colour, hdr] of [["ldr", "ycbcr", false], ["hdr", "logluv", true], ["hdr_ycbcr", "ycbcr", true], ["shared", "logluv", true], ["iso", "logluv", true]]) {
    const { decoder, errors, complete } = decodeFile(pkg[id]);
    assert.deepEqual(errors, []);
    assert.ok(complete && decoder.ready);
    assert.equal(decoder.info.colour, colour, id);
    assert.equal(decoder.info.quantization.P2.bits, hdr ? 16 : 8, id);
    assert.deepEqual(decoder.progress(), { present: 4, total: 4, unit: "P6 levels" });
    await evalAgainstCli(t, pkg[id], decoder, id === "hdr_ycbcr" || id === "iso" ? 100 : 220, 17 + id.length);
  }
});

test("several materials sharing code-books: the first is shown, as `btf eval` shows it; the others' sections are checked and dropped", () => {
  const { decoder, sections } = decodeFile(pkg.shared);
  assert.deepEqual(
    sections.map((s) => s.entry.name),
    ["codebooks", "m0.P6.3", "m1.P6.2", "m0.P6.2", "m1.P6.1", "m0.P6.1", "m1.P6.0", "m0.P6.0"],
  );
  assert.deepEqual(
    decoder.info.materials.map((m) => [path.basename(m.name), m.prefix, m.width, m.levels]),
    [["woven.h5", "m0.", 32, 4], ["leather.h5", "m1.", 16, 3]],
  );
  assert.equal(decoder.info.width, 32);
  assert.deepEqual(decoder.uniforms().uMlvqExtent, [32, 32]);
  // a damaged section of the material not shown is an error all the same (the C++ reads it)
  const { header } = readPackage(bytesOf(pkg.shared));
  const bad = sections.map((s) => ({ name: s.entry.name, data: s.entry.name === "m1.P6.1" ? s.data.subarray(0, s.data.length - 1) : s.data }));
  const file = writePackage(path.join(DIR, "shared_bad.btfpkg"), header.json, bad);
  const r = decodeFile(file);
  assert.equal(r.errors.length, 1);
  assert.equal(r.errors[0].message, cliError(file));
  assert.match(r.errors[0].message, /section 'm1\.P6\.1' is too short$/);
});

test("albedo is the (1/π)-scaled quadrature of eval over the grid's light directions (the CLI has no albedo query)", (t) => {
  // `btf render --aov` writes Material::albedo only as a half-float EXR averaged over each
  // pixel's samples, not at a given (uv, wo): no CLI value to compare with at 1e-4. The C++
  // computes albedo as this quadrature (YCbCr: of the planes, exact; LogLuv: of eval at the grid
  // directions), which the test reproduces with the CPU eval (checked against btf eval above).
  // At the pole rows (the horizon ends of every slice) the direction is approached along the
  // slice: at the pole itself α is undefined and the C++'s eval picks a slice by rounding.
  for (const id of ["ldr", "hdr"]) {
    const { decoder } = decodeFile(pkg[id]);
    const g = decoder.info.grid;
    let worst = 0;
    for (const q of queries(40, 5)) {
      const wo = dirVec(...q.view);
      const a = decoder.albedo(q.uv[0], q.uv[1], wo);
      const frame = M.lookup(g, [0, 0, 1], wo);
      const sum = [0, 0, 0];
      for (let i = 0; i < g.nAlpha; ++i)
        for (let j = 0; j < g.nBeta; ++j) {
          const u = -1 + (2 * j) / (g.nBeta - 1) + (j === 0 ? 1e-9 : j === g.nBeta - 1 ? -1e-9 : 0);
          const wi = M.onionDirection(-Math.PI / 2 + (Math.PI * i) / (g.nAlpha - 1), u, frame.c, frame.s);
          const v = decoder.eval(q.uv[0], q.uv[1], wi, wo);
          for (let c = 0; c < 3; ++c) sum[c] += (M.lightWeight(g, i, j) * v[c]) / Math.PI;
        }
      worst = Math.max(worst, compare(a, sum, 1e-5, 1e-7, `${id} albedo ${JSON.stringify(q)}`));
    }
    t.diagnostic(`${id}: albedo vs quadrature of eval, max relative error ${worst.toExponential(2)}`);
  }
});


// ---- prefixes -------------------------------------------------------------------------------------

test("prefixes of the stream evaluate like `btf eval` of the same prefix file (coarse P6 levels copied to finer texels)", async (t) => {
  for (const id of ["hdr", "shared"]) {
    const bytes = bytesOf(pkg[id]);
    const { sections } = readPackage(bytes);
    // after the code-books only: not a material yet, for the viewer as for the CLI
    const cuts = id === "hdr" ? [1, 2, 3] : [1, 2, 4];
    for (const n of [0, ...cuts]) {
      const last = sections[n];
      const file = path.join(DIR, `${id}.prefix${n + 1}.btfpkg`);
      writeFileSync(file, bytes.subarray(0, last.fileOffset + last.entry.size));
      const { decoder, errors, complete } = decodeFile(file);
      assert.deepEqual(errors, []);
      assert.equal(complete, false);
      const own = sections.slice(1, n + 1).filter((s) => !s.entry.name.startsWith("m1.")).length;
      assert.deepEqual(decoder.progress(), { present: own, total: 4, unit: "P6 levels" });
      if (n === 0) {
        assert.equal(decoder.ready, false);
        assert.equal(cliError(file), `${path.basename(file)}: package (mlvq): section '${id === "hdr" ? "" : "m0."}P6.3' is missing`);
        continue;
      }
      assert.ok(decoder.ready);
      await evalAgainstCli(t, file, decoder, 40, 100 + n);
    }
  }
});

test("the P6 texture after each level is the coarse-to-fine copy the C++ reader makes", () => {
  const { sections } = readPackage(bytesOf(pkg.hdr));
  const { decoder } = decodeFile(pkg.hdr);
  const full = decoder.textures().find((x) => x.uniform === "uMlvqP6").data.slice();
  const info = M.readMlvqHeader("hdr", readPackage(bytesOf(pkg.hdr)).header.json);
  const d = new M.MlvqDecoder(info);
  d.addSection("codebooks", sections[0].data);
  for (let n = 1; n <= 4; ++n) {
    d.addSection(sections[n].entry.name, sections[n].data);
    const finest = 4 - n, mask = ~((1 << finest) - 1);
    const p6 = d.textures().find((x) => x.uniform === "uMlvqP6").data;
    for (let y = 0; y < 32; ++y)
      for (let x = 0; x < 32; ++x) {
        const t = y * 32 + x, from = (y & mask) * 32 + (x & mask);
        assert.equal(p6[2 * t], full[2 * from]);
        assert.equal(p6[2 * t + 1], full[2 * from + 1]);
      }
  }
});

// ---- damage -----------------------------------------------------------------------------------------

test("damaged sections give one error naming the section, with the C++ reader's message", () => {
  const file = pkg.hdr;
  const bytes = bytesOf(file);
  const { header, sections } = readPackage(bytes);
  const json = header.json;

  // A flipped byte in a P6 section: the package reader's checksum names it; the stream stops.
  const p61 = sections.find((s) => s.entry.name === "P6.1");
  const flipped = Uint8Array.from(bytes);
  flipped[p61.fileOffset + 3] ^= 0x10;
  const flippedFile = path.join(DIR, "flipped.btfpkg");
  writeFileSync(flippedFile, flipped);
  const thrown = [];
  const stream = new M.PackageStream("flipped.btfpkg", { section: () => {} }, xxh64);
  for (let at = 0; at < flipped.length; at += 1000) {
    try {
      stream.push(flipped.subarray(at, at + 1000));
    } catch (e) {
      thrown.push(e);
    }
  }
  assert.equal(thrown.length, 1);
  assert.match(thrown[0].message, /^flipped\.btfpkg: checksum mismatch in section 'P6\.1' \(bytes \d+\.\.\d+\): stored [0-9a-f]{16}, computed [0-9a-f]{16}$/);
  assert.match(cliError(flippedFile), /checksum mismatch in section 'P6\.1'/);

  // A file cut inside the code-books: the package reader names the section when the stream ends.
  const cb = sections[0];
  const cutFile = path.join(DIR, "cut.btfpkg");
  writeFileSync(cutFile, bytes.subarray(0, cb.fileOffset + Math.floor(cb.entry.size / 2)));
  const got = [];
  const cutStream = new M.PackageStream("cut.btfpkg", { section: (x) => got.push(x) }, xxh64);
  cutStream.push(bytesOf(cutFile));
  assert.throws(() => cutStream.end(), { message: cliError(cutFile) }); // "… section 'codebooks' is truncated: …"
  assert.match(cliError(cutFile), /^cut\.btfpkg: section 'codebooks' is truncated: \d+ of \d+ bytes present \(from byte \d+\)$/);
  assert.equal(got.length, 0);

  // Sections with valid checksums but damaged contents: the decoder's checks.
  // an index of all ones is out of range unless P4 has a power-of-two size
  const s4 = json.codebooks.P4;
  assert.ok(2 ** M.indexBits(s4) - 1 >= s4 && M.indexBits(s4) <= 8, `P4 has ${s4} entries`);
  const rewrite = (name, change) => sections.map((s) => ({ name: s.entry.name, data: s.entry.name === name ? change(Uint8Array.from(s.data)) : s.data }));
  const cases = [
    // the first texel of level 1, (2, 0): its P4 index (the low bits of the first byte) all ones
    ["p6_index", rewrite("P6.1", (d) => ((d[0] |= (1 << M.indexBits(s4)) - 1), d)), /^section 'P6\.1': P6 of texel \(2, 0\) points to P4 \d+ of \d+$/],
    ["p6_short", rewrite("P6.0", (d) => d.subarray(0, d.length - 1)), /^section 'P6\.0' is too short$/],
    ["p6_long", rewrite("P6.2", (d) => Uint8Array.from([...d, 0])), /^section 'P6\.2' holds \d+ bytes, expected \d+$/],
    ["p6_coarsest_short", rewrite("P6.3", (d) => d.subarray(0, 10)), /^section 'P6\.3' is too short for the 16 entries of P6 level 3 its header declares$/],
    // truncated inside a code-book (P2 of 737 entries at 16 + 12 bits starts after P1's bytes)
    ["codebooks_short", rewrite("codebooks", (d) => d.subarray(0, 20000)), /^section 'codebooks' is too short for the \d+ entries of P2 its header declares$/],
    ["codebooks_long", rewrite("codebooks", (d) => Uint8Array.from([...d, 7])), /^section 'codebooks' holds \d+ bytes, expected \d+$/],
  ];
  for (const [id, parts, message] of cases) {
    const damaged = writePackage(path.join(DIR, `damaged_${id}.btfpkg`), json, parts);
    const { decoder, errors } = decodeFile(damaged);
    assert.equal(errors.length, 1, `${id}: ${errors.map((e) => e.message).join(" | ")}`);
    const text = errors[0].message;
    assert.ok(!text.includes("\n"));
    const prefix = `damaged_${id}.btfpkg: package (mlvq): `;
    assert.ok(text.startsWith(prefix), text);
    assert.match(text.slice(prefix.length), message);
    // the C++ reader says the same (without naming the section where it does not)
    const cpp = cliError(damaged);
    assert.equal(text.replace(/section 'P6\.\d': /, ""), cpp, id);
    assert.equal(decoder.error, errors[0]);
    // the sections before the damage still make a material when they did
    const before = parts.findIndex((p, k) => p.data !== sections[k].data);
    assert.equal(decoder.ready, before >= 2, id);
  }
});

// ---- the header ----------------------------------------------------------------------------------

test("the header reader refuses what the C++ reader refuses, with its messages", () => {
  const { header, sections } = readPackage(bytesOf(pkg.hdr));
  const base = header.json;
  const parts = sections.map((s) => ({ name: s.entry.name, data: s.data }));
  const clone = () => JSON.parse(JSON.stringify(base));
  const mutations = {
    phi2: (h) => (h.grid.n_phi_v = 2),
    alpha2: (h) => (h.grid.n_alpha = 2),
    grid_key: (h) => (h.grid.n_gamma = 3),
    grid_big: (h) => Object.assign(h.grid, { n_alpha: 1024, n_beta: 1024, n_theta_v: 100 }),
    colour: (h) => (h.colour = "rgb"),
    size_fraction: (h) => (h.codebooks.M = 1.5),
    size_key: (h) => (h.codebooks.P5 = 1),
    bits: (h) => (h.quantization.P2.bits = 12),
    range: (h) => Object.assign(h.quantization.P1, { lo: 1, hi: 0.5 }),
    no_materials: (h) => (h.materials = []),
    width: (h) => (h.width = 33),
    levels: (h) => (h.materials[0].P6_levels = 3),
    p6_bits: (h) => (h.materials[0].P6.bits = 9),
    theta: (h) => (h.views.theta[3] = h.materials[0].views.theta[3] = 2),
  };
  for (const [id, mutate] of Object.entries(mutations)) {
    const h = clone();
    mutate(h);
    const file = writePackage(path.join(DIR, `header_${id}.btfpkg`), h, parts);
    const cpp = cliError(file);
    assert.ok(cpp, `${id}: btf eval accepted it`);
    assert.throws(
      () => M.readMlvqHeader(`header_${id}.btfpkg`, h),
      (e) => !(e instanceof M.UnsupportedMaterial) && e.message === cpp,
      `${id}: ${cpp}`,
    );
  }
  // an extra section is refused when it arrives
  const extra = writePackage(path.join(DIR, "header_extra.btfpkg"), base, [...parts, { name: "P6.9", data: new Uint8Array(4) }]);
  const r = decodeFile(extra);
  assert.equal(r.errors.length, 1);
  assert.equal(r.errors[0].message, cliError(extra));
  // n_phi_v = 2 is refused (it cannot tell φ from −φ), as by the C++ reader
  const two = clone();
  two.grid.n_phi_v = 2;
  assert.throws(() => M.readMlvqHeader("x", two), /n_phi_v = 2 cannot tell view azimuths/);
  // other codecs, and code-books beyond the viewer's textures: valid, not shown
  assert.throws(() => M.readMlvqHeader("x", { ...base, codec: "fmf" }), (e) => e instanceof M.UnsupportedMaterial && /codec 'fmf'/.test(e.message));
  const huge = clone();
  huge.codebooks.M = 2 ** 30;
  assert.throws(
    () => M.readMlvqHeader("x", huge),
    (e) => e instanceof M.UnsupportedMaterial && /^x: the decoded M entries .* more than the viewer's limit/.test(e.message),
  );
  // missing fields name the field
  const missing = clone();
  delete missing.quantization.P3;
  assert.throws(() => M.readMlvqHeader("x", missing), { message: "x: package (mlvq): header field 'quantization.P3' is missing" });
});

// ---- textures -----------------------------------------------------------------------------------

test("textures and uniforms: shapes within WebGL2 limits, data sizes, and the memory of the test packages", (t) => {
  const channels = { RG32I: 2, R32UI: 1, RGBA32F: 4 };
  for (const id of ["ldr", "hdr", "shared"]) {
    const { decoder } = decodeFile(pkg[id]);
    const info = decoder.info, g = info.grid, s = info.sizes;
    const tex = decoder.textures();
    assert.deepEqual(tex.map((x) => x.uniform), ["uMlvqP6", "uMlvqViews", "uMlvqEntries", "uMlvqAlbedo"]);
    let bytes = 0;
    for (const x of tex) {
      assert.equal(x.kind, "2d-array");
      assert.ok(x.width <= 1024 && x.height <= 4096 && x.depth <= 256);
      assert.equal(x.data.length, x.width * x.height * x.depth * channels[x.format], x.uniform);
      bytes += x.data.byteLength;
    }
    const [p6, views, entries, albedo] = tex;
    assert.ok(p6.width * p6.height >= 32 * 32);
    assert.ok(views.width * views.height >= s.P4 * g.nPhiV * g.nThetaV);
    assert.ok(entries.width * entries.height >= s.M * g.nAlpha * g.nBeta);
    assert.ok(albedo.width * albedo.height >= (info.colour === "ycbcr" ? s.M : 1));
    const u = decoder.uniforms();
    assert.deepEqual(u.uMlvqGrid, [g.nAlpha, g.nBeta, g.nThetaV, g.nPhiV]);
    assert.deepEqual(u.uMlvqRows, tex.map((x) => x.height));
    assert.equal(u.uMlvqColour, info.colour === "ycbcr" ? 0 : 1);
    const shapes = tex.map((x) => `${x.uniform} ${x.width}×${x.height}×${x.depth} ${x.format}`).join(", ");
    t.diagnostic(
      `${id}: ${info.colour}, grid ${u.uMlvqGrid.join("×")}, M ${s.M}, P4 ${s.P4}: textures ${shapes} = ${bytes} bytes (${(bytes / 1024).toFixed(1)} KiB)`,
    );
  }
  // tables beyond 4096 rows take layers, their rows spread evenly over them
  for (const n of [0, 1, 1023, 1024, 1025, 4096 * 1024, 4096 * 1024 + 1, 3 * 4096 * 1024 + 5, 64 * 4096 * 1024]) {
    const { width, height, depth } = M.tableShape(n);
    const rows = Math.max(1, Math.ceil(n / 1024));
    assert.ok(width * height * depth >= n && width <= 1024 && height <= 4096, `${n}`);
    assert.equal(depth, Math.ceil(rows / 4096), `${n}`);
    assert.ok(height * depth - rows < depth, `${n}: ${height}×${depth} rows for ${rows}`);
  }
  // before anything arrives: zeros of the right shapes
  const fresh = new M.MlvqDecoder(M.readMlvqHeader("hdr", readPackage(bytesOf(pkg.hdr)).header.json));
  assert.equal(fresh.ready, false);
  assert.ok(fresh.textures().every((x) => x.data.every((v) => v === 0)));
  assert.deepEqual(fresh.eval(0.5, 0.5, [0, 0, 1], [0, 0, 1]), [0, 0, 0]);
});

// ---- the shader in WebGL2 -------------------------------------------------------------------------

// The shared fragment shader's definitions that mlvqFragment relies on (shader.ts).
const prelude = () => `#version 300 es
precision highp float;
precision highp int;
#define MAX_LIGHTS 4
#define PI 3.14159265358979
${M.wrapLerpFunction}
ivec2 tableTexel(int i) { return ivec2(i % 1024, i / 1024); }
`;

// One query per column: texels (u, v, lightCount, env), (wo, lit mask), wi[0..3]; rows 0–3 of
// the output are value[0..3], row 4 the ambient term.
const MAIN = `
uniform highp sampler2D uQueries;
out vec4 fragColor;
void main() {
  int q = int(gl_FragCoord.x), row = int(gl_FragCoord.y);
  vec4 a = texelFetch(uQueries, ivec2(0, q), 0), b = texelFetch(uQueries, ivec2(1, q), 0);
  vec3 wi[MAX_LIGHTS];
  bool lit[MAX_LIGHTS];
  int mask = int(b.w);
  for (int l = 0; l < MAX_LIGHTS; ++l) {
    wi[l] = texelFetch(uQueries, ivec2(2 + l, q), 0).xyz;
    lit[l] = ((mask >> l) & 1) == 1;
  }
  vec3 value[MAX_LIGHTS];
  vec3 ambient;
  codecEvaluate(a.xy, vec2(1.0), vec2(1.0), b.xyz, wi, lit, int(a.z), a.w > 0.5, value, ambient);
  vec3 outv = ambient;
  for (int l = 0; l < MAX_LIGHTS; ++l) if (l == row) outv = value[l];
  fragColor = vec4(outv, 1.0);
}
`;

// Runs in the page: compiles, uploads, renders, reads back. Plain WebGL2, no three.js.
function renderInPage({ source, textures, uniforms, queries: qdata, count }) {
  const canvas = document.createElement("canvas");
  const gl = canvas.getContext("webgl2");
  if (!gl) return { error: "no WebGL2" };
  if (!gl.getExtension("EXT_color_buffer_float")) return { error: "no EXT_color_buffer_float" };
  const shader = (type, text) => {
    const s = gl.createShader(type);
    gl.shaderSource(s, text);
    gl.compileShader(s);
    if (!gl.getShaderParameter(s, gl.COMPILE_STATUS)) throw new Error(gl.getShaderInfoLog(s));
    return s;
  };
  const program = gl.createProgram();
  try {
    // one triangle covering the viewport
    const vertex = "#version 300 es\nvoid main() { gl_Position = vec4(vec2(gl_VertexID & 1, gl_VertexID >> 1) * 4.0 - 1.0, 0.0, 1.0); }";
    gl.attachShader(program, shader(gl.VERTEX_SHADER, vertex));
    gl.attachShader(program, shader(gl.FRAGMENT_SHADER, source));
  } catch (e) {
    return { error: `compile: ${e.message}` };
  }
  gl.linkProgram(program);
  if (!gl.getProgramParameter(program, gl.LINK_STATUS)) return { error: `link: ${gl.getProgramInfoLog(program)}` };
  gl.useProgram(program);
  const formats = {
    RG32I: [gl.RG32I, gl.RG_INTEGER, gl.INT, Int32Array],
    R32UI: [gl.R32UI, gl.RED_INTEGER, gl.UNSIGNED_INT, Uint32Array],
    RGBA32F: [gl.RGBA32F, gl.RGBA, gl.FLOAT, Float32Array],
  };
  let unit = 0;
  for (const t of textures) {
    const [internal, format, type, TypedArray] = formats[t.format];
    gl.activeTexture(gl.TEXTURE0 + unit);
    const tex = gl.createTexture();
    gl.bindTexture(gl.TEXTURE_2D_ARRAY, tex);
    gl.texParameteri(gl.TEXTURE_2D_ARRAY, gl.TEXTURE_MIN_FILTER, gl.NEAREST);
    gl.texParameteri(gl.TEXTURE_2D_ARRAY, gl.TEXTURE_MAG_FILTER, gl.NEAREST);
    gl.texImage3D(gl.TEXTURE_2D_ARRAY, 0, internal, t.width, t.height, t.depth, 0, format, type, new TypedArray(t.data));
    gl.uniform1i(gl.getUniformLocation(program, t.uniform), unit++);
  }
  // uniforms by the types the program declares
  for (let i = 0; i < gl.getProgramParameter(program, gl.ACTIVE_UNIFORMS); ++i) {
    const { name, type } = gl.getActiveUniform(program, i);
    if (!(name in uniforms)) continue;
    const v = [].concat(uniforms[name]);
    const loc = gl.getUniformLocation(program, name);
    const setter = {
      [gl.INT]: "uniform1iv",
      [gl.INT_VEC2]: "uniform2iv",
      [gl.INT_VEC4]: "uniform4iv",
      [gl.FLOAT]: "uniform1fv",
      [gl.FLOAT_VEC4]: "uniform4fv",
    }[type];
    if (!setter) return { error: `uniform ${name} of type ${type}` };
    gl[setter](loc, setter.endsWith("iv") ? new Int32Array(v) : new Float32Array(v));
  }
  gl.activeTexture(gl.TEXTURE0 + unit);
  const q = gl.createTexture();
  gl.bindTexture(gl.TEXTURE_2D, q);
  gl.texParameteri(gl.TEXTURE_2D, gl.TEXTURE_MIN_FILTER, gl.NEAREST);
  gl.texParameteri(gl.TEXTURE_2D, gl.TEXTURE_MAG_FILTER, gl.NEAREST);
  gl.texImage2D(gl.TEXTURE_2D, 0, gl.RGBA32F, 6, count, 0, gl.RGBA, gl.FLOAT, new Float32Array(qdata));
  gl.uniform1i(gl.getUniformLocation(program, "uQueries"), unit);
  const target = gl.createTexture();
  gl.activeTexture(gl.TEXTURE0 + unit + 1);
  gl.bindTexture(gl.TEXTURE_2D, target);
  gl.texStorage2D(gl.TEXTURE_2D, 1, gl.RGBA32F, count, 5);
  const fb = gl.createFramebuffer();
  gl.bindFramebuffer(gl.FRAMEBUFFER, fb);
  gl.framebufferTexture2D(gl.FRAMEBUFFER, gl.COLOR_ATTACHMENT0, gl.TEXTURE_2D, target, 0);
  if (gl.checkFramebufferStatus(gl.FRAMEBUFFER) !== gl.FRAMEBUFFER_COMPLETE) return { error: "framebuffer incomplete" };
  gl.viewport(0, 0, count, 5);
  gl.drawArrays(gl.TRIANGLES, 0, 3);
  const out = new Float32Array(count * 5 * 4);
  gl.readPixels(0, 0, count, 5, gl.RGBA, gl.FLOAT, out);
  const error = gl.getError();
  if (error) return { error: `GL error ${error}` };
  return { pixels: Array.from(out) };
}

let browser = null;
after(async () => {
  if (browser) await browser.close();
});

test("mlvqFragment compiles in WebGL2 and decodes like the CPU reference (Chromium, SwiftShader)", async (t) => {
  browser = await launchBrowser();
  const page = await browser.newPage();
  const f = Math.fround;
  const unit = (v) => {
    const l = Math.hypot(...v);
    return v.map((x) => f(x / l));
  };
  for (const [id, prefixSections] of [["ldr", 0], ["hdr", 0], ["shared", 0], ["hdr", 3]]) {
    const bytes = bytesOf(pkg[id]);
    const { header, sections } = readPackage(bytes);
    const decoder = new M.MlvqDecoder(M.readMlvqHeader(id, header.json));
    for (const s of prefixSections ? sections.slice(0, prefixSections) : sections) decoder.addSection(s.entry.name, s.data);
    assert.ok(decoder.ready);
    const qs = queries(256, 900 + prefixSections);
    const r = random(4);
    const data = [], expected = [];
    for (const q of qs) {
      const uv = q.uv.map(f), wo = dirVec(...q.view).map(f);
      // four lights: the query's, two random ones (one of them maybe off), one grazing
      const wi = [dirVec(...q.light), dirVec(r() * 90, r() * 360), unit([r() - 0.5, r() - 0.5, r() * 0.2]), dirVec(90, r() * 360)].map((v) => v.map(f));
      const count = 1 + Math.floor(r() * 4), mask = Math.floor(r() * 16) | 1, env = r() < 0.75;
      data.push(uv[0], uv[1], count, env ? 1 : 0, ...wo, mask);
      for (const w of wi) data.push(...w, 0);
      const rows = [0, 1, 2, 3].map((l) => (l < count && (mask >> l) & 1 ? decoder.eval(uv[0], uv[1], wi[l], wo) : [0, 0, 0]));
      rows.push(env ? decoder.albedo(uv[0], uv[1], wo) : [0, 0, 0]);
      expected.push(rows);
    }
    const textures = decoder.textures().map((x) => ({ ...x, data: Array.from(x.data) }));
    const source = prelude() + M.mlvqFragment + MAIN;
    const result = await page.evaluate(renderInPage, { source, textures, uniforms: decoder.uniforms(), queries: data, count: qs.length });
    assert.ok(!result.error, result.error);
    let worstEval = 0, worstAlbedo = 0;
    const failures = [];
    qs.forEach((q, k) => {
      for (let row = 0; row < 5; ++row) {
        const at = (row * qs.length + k) * 4;
        const got = result.pixels.slice(at, at + 3);
        try {
          const worst = compare(got, expected[k][row], 1e-3, 1e-6, `query ${k} ${row < 4 ? `light ${row}` : "ambient"} ${JSON.stringify(q)}`);
          if (row < 4) worstEval = Math.max(worstEval, worst);
          else worstAlbedo = Math.max(worstAlbedo, worst);
        } catch (e) {
          failures.push(e.message);
        }
      }
    });
    assert.equal(failures.length, 0, `${id}: ${failures.length} of ${qs.length * 5} GPU values differ from the CPU's:\n${failures.slice(0, 6).join("\n")}`);
    const what = `${id}${prefixSections ? ` (prefix of ${prefixSections} sections)` : ""}`;
    t.diagnostic(
      `${what}: GPU vs CPU over ${qs.length} queries, max relative error eval ${worstEval.toExponential(2)}, albedo ${worstAlbedo.toExponential(2)}`,
    );
  }

  // Addressing of a table of several layers (the test packages' tables have one): entry i of an
  // R32UI table of 1024 × 3 rows × 4 layers holds i.
  const count = 2400;
  const entries = { uniform: "uMlvqEntries", kind: "2d-array", width: 1024, height: 3, depth: 4, format: "R32UI" };
  entries.data = Array.from({ length: 1024 * 3 * 4 }, (_, i) => i);
  const addressing = `
uniform highp sampler2D uQueries;
out vec4 fragColor;
void main() {
  int i = int(gl_FragCoord.y) * ${count} + int(gl_FragCoord.x);
  fragColor = vec4(float(texelFetch(uMlvqEntries, mlvqAt(i, uMlvqRows.z), 0).r), float(i), 0.0, 1.0);
}
`;
  const result = await page.evaluate(renderInPage, {
    source: prelude() + M.mlvqFragment + addressing,
    textures: [entries],
    uniforms: { uMlvqRows: [1, 1, 3, 1] },
    queries: new Array(6 * count * 4).fill(0),
    count,
  });
  assert.ok(!result.error, result.error);
  for (let i = 0; i < 5 * count; ++i) assert.equal(result.pixels[4 * i], result.pixels[4 * i + 1], `entry ${i}`);
  assert.equal(result.pixels[4 * (5 * count - 1)], 5 * count - 1);
  await page.close();
});
