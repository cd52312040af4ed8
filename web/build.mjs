// SPDX-License-Identifier: MIT
// Bundles the viewer: node build.mjs [OUT] (default web/dist). Writes OUT/index.html,
// OUT/viewer.js (the page, an ES module) and OUT/worker.js (the decoding worker, its own bundle).
import { build } from "esbuild";
import { copyFile, mkdir } from "node:fs/promises";
import path from "node:path";
import { fileURLToPath } from "node:url";

const here = path.dirname(fileURLToPath(import.meta.url));
const out = path.resolve(process.argv[2] ?? path.join(here, "dist"));
const minify = !process.argv.includes("--no-minify");

await mkdir(out, { recursive: true });
const common = { bundle: true, minify, sourcemap: true, target: "es2022", logLevel: "warning", legalComments: "linked" };
await build({ ...common, entryPoints: [path.join(here, "src/viewer.ts")], format: "esm", outfile: path.join(out, "viewer.js") });
await build({ ...common, entryPoints: [path.join(here, "src/worker.ts")], format: "iife", outfile: path.join(out, "worker.js") });
await copyFile(path.join(here, "index.html"), path.join(out, "index.html"));
console.log(`viewer built in ${out}`);
