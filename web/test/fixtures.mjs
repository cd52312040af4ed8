// SPDX-License-Identifier: MIT
// Test inputs made with the project's CLI (btf synth, btf compress) and the viewer's bundle, in
// web/test-artifacts/. The btf binary is $BTF_BIN, else build/web/btf of the checkout, built
// with the documented cmake/ninja commands when it is missing.

import { execFileSync } from "node:child_process";
import { existsSync, mkdirSync, readFileSync, renameSync, rmSync, writeFileSync, copyFileSync } from "node:fs";
import path from "node:path";
import { fileURLToPath, pathToFileURL } from "node:url";
import { build } from "esbuild";

export const WEB = path.resolve(path.dirname(fileURLToPath(import.meta.url)), "..");
export const REPO = path.resolve(WEB, "..");
export const ARTIFACTS = path.join(WEB, "test-artifacts");
export const FIXTURES = path.join(ARTIFACTS, "fixtures");

/** Runs a program; returns its stdout as text ("" when stdout is not piped, as with "inherit"). */
export const run = (cmd, args, opts = {}) => {
  const out = execFileSync(cmd, args, { stdio: ["ignore", "pipe", "pipe"], ...opts });
  return out === null ? "" : out.toString();
};

/**
 * The btf binary: $BTF_BIN, else build/web/btf of the checkout, configured and built with the
 * documented cmake and ninja commands when missing (their output on stderr, where the test runner
 * shows it). `env` and `repo` are for the test of this first run.
 */
export function btfBinary({ env = process.env, repo = REPO } = {}) {
  if (env.BTF_BIN) return env.BTF_BIN;
  const dir = path.join(repo, "build/web");
  const bin = path.join(dir, "btf");
  if (!existsSync(bin)) {
    console.error("# building build/web/btf (first run only)");
    const steps = [
      ["cmake", ["-S", repo, "-B", dir, "-G", "Ninja", "-DCMAKE_BUILD_TYPE=Release", "-DBTF_BUILD_BENCH=OFF", "-DBTF_BUILD_TESTS=OFF"]],
      ["ninja", ["-C", dir, "btf"]],
    ];
    for (const [cmd, args] of steps) {
      try {
        run(cmd, args, { stdio: ["ignore", 2, 2], env });
      } catch (e) {
        const why = e.code === "ENOENT" ? `${cmd} is not installed (apt-get install -y cmake ninja-build)` : `${cmd} ${args.join(" ")} failed (exit ${e.status ?? e.signal})`;
        throw new Error(`building ${bin}: ${why}; or set BTF_BIN to a btf binary`);
      }
    }
    if (!existsSync(bin)) throw new Error(`ninja -C ${dir} btf finished without making ${bin}`);
  }
  return bin;
}

/** The packages the tests use: id → { file, codec, ... }. Made once, reused while present. */
export const PACKAGES = {
  // the progressive-refinement material: fmf, rgb colour, f16 factors (the defaults), 8 components
  woven_fabric: ["--codec", "fmf", "--components", "8"],
  // decorrelated colour, log, u8 factors, row means
  woven_declog: ["--codec", "fmf", "--components", "6", "-p", "colour=decorrelated", "-p", "log=true", "-p", "mean=true", "--quantize", "u8"],
  // per-channel colour, f32 factors, stored raw (no zstd)
  woven_perchannel: ["--codec", "fmf", "--components", "6", "-p", "colour=per-channel", "--quantize", "f32", "--zstd", "0"],
  // pca-views: groups of 9 neighbouring views, rgb, f16
  woven_pca: ["--codec", "pca-views", "--components", "3", "-p", "views-per-group=9"],
  // pca-views: decorrelated colour, log, u8
  woven_pca_declog: ["--codec", "pca-views", "--components", "2", "-p", "views-per-group=20", "-p", "colour=decorrelated", "-p", "log=true", "--quantize", "u8"],
  // lpca: 4 texel clusters, rgb, f16
  woven_lpca: ["--codec", "lpca", "--components", "3", "-p", "clusters=4"],
  // lpca: decorrelated colour, f32
  woven_lpca_dec: ["--codec", "lpca", "--components", "2", "-p", "clusters=3", "-p", "colour=decorrelated", "--quantize", "f32"],
  // perceptual: CIELab planes with spatial and angular levels (high-frequency omission), f16
  woven_perceptual: ["--codec", "perceptual", "--components", "10", "-p", "base-quality=0.6"],
  // perceptual: one level, row means, u8
  woven_perceptual_u8: ["--codec", "perceptual", "--components", "6", "-p", "mean=true", "--quantize", "u8"],
  // the third quantization of each factor codec (CPU reference only)
  woven_pca_f32: ["--codec", "pca-views", "--components", "2", "-p", "views-per-group=27", "--quantize", "f32"],
  woven_lpca_u8: ["--codec", "lpca", "--components", "2", "-p", "clusters=2", "-p", "log=true", "--quantize", "u8"],
  woven_perceptual_f32: ["--codec", "perceptual", "--components", "6", "-p", "base-quality=0.5", "--quantize", "f32"],
  // coded storage (DCT-coded eigen-textures): fmf; lpca (cluster-scattered texels, coded plain);
  // perceptual (coarse grids and angular levels)
  woven_coded: ["--codec", "fmf", "--components", "8", "--quantize", "coded", "-p", "quality=40"],
  woven_lpca_coded: ["--codec", "lpca", "--components", "3", "-p", "clusters=4", "--quantize", "coded"],
  woven_perceptual_coded: ["--codec", "perceptual", "--components", "10", "-p", "base-quality=0.6", "--quantize", "coded", "-p", "quality=40"],
  // mlvq: LogLuv colour (the default for btf synth's HDR source), P6 in 4 levels
  woven_mlvq: ["--codec", "mlvq"],
  // mlvq: YCbCr colour
  woven_mlvq_ycbcr: ["--codec", "mlvq", "-p", "colour=ycbcr"],
};

export function makeFixtures() {
  mkdirSync(FIXTURES, { recursive: true });
  const bin = btfBinary();
  const h5 = path.join(FIXTURES, "woven.h5");
  if (!existsSync(h5)) run(bin, ["-q", "synth", "--preset", "woven_fabric", "--size", "32", "-o", h5]);
  const out = {};
  for (const [id, args] of Object.entries(PACKAGES)) {
    const file = path.join(FIXTURES, `${id}.btfpkg`);
    const stamp = file + ".args";
    const wanted = JSON.stringify(args);
    if (!existsSync(file) || !existsSync(stamp) || readFileSync(stamp, "utf8") !== wanted) {
      rmSync(file, { force: true });
      run(bin, ["-q", "compress", h5, ...args, "--no-error", "-o", file]);
      writeFileSync(stamp, wanted);
    }
    out[id] = file;
  }
  // mlvq's progressive P6 of a material whose spatial structure its coarse levels resolve: the
  // leather preset (woven_fabric's weave at 32² is finer than P6 levels 3 and 2 sample it, so
  // those levels alias; see docs/viewer.md).
  const leather = path.join(FIXTURES, "leather.h5");
  if (!existsSync(leather)) run(bin, ["-q", "synth", "--preset", "leather", "--size", "32", "-o", leather]);
  out.leather_mlvq = path.join(FIXTURES, "leather_mlvq.btfpkg");
  if (!existsSync(out.leather_mlvq)) run(bin, ["-q", "compress", leather, "--codec", "mlvq", "--no-error", "-o", out.leather_mlvq]);
  // BSVTF packages of the first (btf bsvtf): tiles of 8 texels plus 4 of padding, so that the
  // 32² material has three levels; lossy (the default 1 % tile error) and lossless.
  for (const [name, extra] of [["woven_fabric.bsvtf", []], ["woven_lossless.bsvtf", ["--lossless"]]]) {
    const file = path.join(FIXTURES, name);
    const args = ["-q", "bsvtf", out.woven_fabric, "--tile", "8", "--pad", "4", ...extra, "-o", file];
    const stamp = file + ".args";
    if (!existsSync(file) || !existsSync(stamp) || readFileSync(stamp, "utf8") !== JSON.stringify(args)) {
      run(bin, args);
      writeFileSync(stamp, JSON.stringify(args));
    }
  }
  // A UBO2014 DFMF file in colour model 11 (the repository's writer) and its own factors as an
  // fmf package (`btf convert X.btf X.btfpkg`, no refactorization).
  const dfmf = path.join(FIXTURES, "woven_model11.btf");
  const model11 = path.join(FIXTURES, "woven_model11.btfpkg");
  if (!existsSync(model11)) {
    run(bin, ["-q", "convert", h5, dfmf, "--components", "6", "--colour", "model11"]);
    run(bin, ["-q", "convert", dfmf, model11]);
  }
  out.woven_model11 = model11;
  out.bsvtf = path.join(FIXTURES, "woven_fabric.bsvtf");
  out.bsvtfLossless = path.join(FIXTURES, "woven_lossless.bsvtf");
  // Packages damaged in one section: the header and the sections before it read fine, then the
  // checksum of that section fails. fmf in its third component; the other codecs in a section of
  // their own model (clusters, angular up-sampling, a component of the second view group).
  const damage = (id, from, section) => {
    const file = path.join(FIXTURES, `${id}.btfpkg`);
    const bytes = readFileSync(out[from]);
    const h = bytes.readUInt32LE(12);
    const header = JSON.parse(bytes.subarray(24, 24 + h).toString("utf8"));
    const s = header.sections.find((x) => x.name === section);
    const damaged = Buffer.from(bytes);
    damaged[24 + h + s.offset + Math.floor(s.size / 2)] ^= 0x5a;
    // Written only when it changed, and whole (a rename): test files running at once read it.
    if (!existsSync(file) || !readFileSync(file).equals(damaged)) {
      writeFileSync(`${file}.${process.pid}.tmp`, damaged);
      renameSync(`${file}.${process.pid}.tmp`, file);
    }
    out[id] = file;
  };
  damage("woven_broken", "woven_fabric", "b0.k2");
  damage("woven_lpca_broken", "woven_lpca", "clusters");
  damage("woven_perceptual_broken", "woven_perceptual", "angular");
  damage("woven_pca_broken", "woven_pca", "b1.k0");
  damage("woven_mlvq_broken", "woven_mlvq", "P6.1");
  return { bin, h5, packages: out };
}

/**
 * The viewer's modules `names` (web/src/<name>.ts) bundled for node into `out` and imported: what
 * the unit tests call.
 */
export async function bundleModules(names, out) {
  mkdirSync(path.dirname(out), { recursive: true });
  await build({
    stdin: { contents: names.map((m) => `export * from "./src/${m}";`).join("\n"), resolveDir: WEB, loader: "ts" },
    bundle: true,
    format: "esm",
    platform: "node",
    outfile: out,
    logLevel: "warning",
  });
  return import(pathToFileURL(out).href + `?t=${Date.now()}`);
}

/** The material list entry of a package (docs/protocol.md). */
export function listEntry(id, file, stream) {
  const bytes = readFileSync(file);
  const h = bytes.readUInt32LE(12);
  const header = JSON.parse(bytes.subarray(24, 24 + h).toString("utf8"));
  const base = 24 + h;
  return {
    id,
    name: id,
    codec: header.codec,
    width: header.width,
    height: header.height,
    views: header.views.theta.length,
    lights: header.lights.theta.length,
    bytes: bytes.length,
    header_bytes: base,
    sections: header.sections.map((x) => ({ name: x.name, offset: base + x.offset, size: x.size })),
    package: `materials/${id}.btfpkg`,
    stream: stream ? `stream/${id}` : null,
  };
}

/** Bundles the viewer (build.mjs) into `folder`. */
export function buildViewer(folder) {
  run(process.execPath, [path.join(WEB, "build.mjs"), folder]);
  return folder;
}

/**
 * A bundle folder: the viewer built into it, materials/<id>.btfpkg, api/materials listing `ids`
 * (with WebSocket streams when `streams`).
 */
export function makeSite(name, packages, ids, { streams = false, list = true } = {}) {
  const site = path.join(ARTIFACTS, name);
  rmSync(site, { recursive: true, force: true });
  mkdirSync(path.join(site, "materials"), { recursive: true });
  buildViewer(site);
  const materials = [];
  for (const id of ids) {
    copyFileSync(packages[id], path.join(site, "materials", `${id}.btfpkg`));
    materials.push(listEntry(id, packages[id], streams));
  }
  if (list) {
    mkdirSync(path.join(site, "api"), { recursive: true });
    writeFileSync(path.join(site, "api", "materials"), JSON.stringify({ protocol: 1, materials }, null, 1));
  }
  return site;
}

// `node test/fixtures.mjs`: makes the fixtures once, before test files that share them run at
// once (CMakeLists.txt: the WebViewer tests).
if (process.argv[1] && path.resolve(process.argv[1]) === fileURLToPath(import.meta.url)) makeFixtures();
