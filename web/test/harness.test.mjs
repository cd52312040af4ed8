// Tests of the test harness itself, in node without a browser or a btf binary: the first-run
// build of build/web/btf (test/fixtures.mjs) with stand-ins for cmake and ninja.

import { test } from "node:test";
import assert from "node:assert/strict";
import { chmodSync, existsSync, mkdirSync, mkdtempSync, readFileSync, rmSync, writeFileSync } from "node:fs";
import os from "node:os";
import path from "node:path";
import { btfBinary } from "./fixtures.mjs";

test("without BTF_BIN the first run configures and builds build/web/btf with the documented commands, once", () => {
  const root = mkdtempSync(path.join(os.tmpdir(), "btf-first-run-"));
  try {
    // Stand-ins for cmake and ninja that log their arguments; ninja makes the binary, as the real
    // build would. Both print, as the real ones do (the output must not break the run).
    const bin = path.join(root, "bin"), repo = path.join(root, "repo"), log = path.join(root, "log");
    mkdirSync(bin);
    mkdirSync(repo);
    const tool = (name, body) => {
      writeFileSync(path.join(bin, name), `#!/bin/sh\necho "${name} $*" >> "${log}"\necho "${name} says hello"\n${body}\n`);
      chmodSync(path.join(bin, name), 0o755);
    };
    tool("cmake", 'mkdir -p "$4"');
    tool("ninja", 'touch "$2/$3"');
    const env = { PATH: `${bin}:${process.env.PATH}` };
    const out = btfBinary({ env, repo });
    assert.equal(out, path.join(repo, "build/web/btf"));
    assert.ok(existsSync(out));
    const dir = path.join(repo, "build/web");
    assert.deepEqual(readFileSync(log, "utf8").trim().split("\n"), [
      `cmake -S ${repo} -B ${dir} -G Ninja -DCMAKE_BUILD_TYPE=Release -DBTF_BUILD_BENCH=OFF -DBTF_BUILD_TESTS=OFF`,
      `ninja -C ${dir} btf`,
    ]);
    // The second run finds it; BTF_BIN wins over it.
    assert.equal(btfBinary({ env, repo }), out);
    assert.equal(readFileSync(log, "utf8").trim().split("\n").length, 2);
    assert.equal(btfBinary({ env: { ...env, BTF_BIN: "/somewhere/btf" }, repo }), "/somewhere/btf");
    // A failed build says what failed and what to do.
    rmSync(out);
    tool("ninja", "exit 3");
    assert.throws(() => btfBinary({ env, repo }), /building .*build\/web\/btf: ninja -C .* btf failed \(exit 3\); or set BTF_BIN/);
    tool("ninja", "true");
    assert.throws(() => btfBinary({ env, repo }), /ninja -C .* btf finished without making/);
    assert.throws(() => btfBinary({ env: { PATH: "/nonexistent" }, repo }), /cmake is not installed/);
  } finally {
    rmSync(root, { recursive: true, force: true });
  }
});
