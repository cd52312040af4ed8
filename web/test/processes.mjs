// SPDX-License-Identifier: MIT
// Real servers for the viewer's tests and benchmarks: `btf serve` and Debian's nginx serving a
// `btf bundle` folder, each started on a free loopback port and stopped with the test.

import { spawn } from "node:child_process";
import { existsSync, mkdirSync, readFileSync, writeFileSync } from "node:fs";
import path from "node:path";
import { PATIENCE_MS, freePort } from "./browser.mjs";

export const NGINX = process.env.NGINX ?? "/usr/sbin/nginx";

/** Waits for `child` to exit (resolves with its code) or kills it after `ms`. */
function exited(child, ms) {
  return new Promise((resolve) => {
    if (child.exitCode !== null) return resolve(child.exitCode);
    const timer = setTimeout(() => child.kill("SIGKILL"), ms);
    child.once("exit", (code, signal) => {
      clearTimeout(timer);
      resolve(code ?? signal);
    });
  });
}

/**
 * Starts `btf serve ARGS --port 0` and resolves once it prints its address. Returns
 * { url, child, stderr(), close() }; close() sends SIGTERM and resolves with the exit code.
 */
export function startBtfServe(bin, args, { env } = {}) {
  const child = spawn(bin, ["serve", ...args, "--port", "0"], { stdio: ["ignore", "pipe", "pipe"], env: { ...process.env, ...env } });
  let out = "", err = "";
  child.stderr.on("data", (d) => (err += d));
  return new Promise((resolve, reject) => {
    const fail = (why) => reject(new Error(`btf serve ${args.join(" ")}: ${why}\n${err}`));
    child.once("exit", (code) => fail(`exited with ${code} before serving`));
    child.stdout.on("data", (d) => {
      out += d;
      const m = /serving \d+ materials? at (http:\/\/\S+)/.exec(out);
      if (!m) return;
      child.removeAllListeners("exit");
      resolve({
        url: m[1],
        child,
        stderr: () => err,
        close: async () => {
          child.kill("SIGTERM");
          return exited(child, 10000);
        },
      });
    });
  });
}

/**
 * Serves the folder `site` with nginx on a free loopback port (its own configuration, logs and
 * temporary files in `work`, no daemon). Returns { url, close() }.
 */
export async function startNginx(site, work) {
  if (!existsSync(NGINX)) throw new Error(`${NGINX} is missing: apt-get install -y nginx (or set NGINX)`);
  mkdirSync(work, { recursive: true });
  const port = await freePort();
  const conf = path.join(work, "nginx.conf");
  const temp = (name) => `${name}_temp_path ${path.join(work, name)};`;
  writeFileSync(
    conf,
    [
      "daemon off;",
      "worker_processes 1;",
      // Workers run as the user starting the test (root's workers would otherwise be 'nobody',
      // who may not read the checkout).
      process.getuid?.() === 0 ? "user root;" : "",
      `pid ${path.join(work, "nginx.pid")};`,
      `error_log ${path.join(work, "error.log")} warn;`,
      "events { worker_connections 256; }",
      "http {",
      "  include /etc/nginx/mime.types;",
      "  default_type application/octet-stream;",
      "  types { application/octet-stream btfpkg; }",
      "  access_log off;",
      "  sendfile on;",
      `  ${temp("client_body")} ${temp("proxy")} ${temp("fastcgi")} ${temp("uwsgi")} ${temp("scgi")}`,
      `  server { listen 127.0.0.1:${port}; root ${site}; location / { try_files $uri $uri/ =404; } }`,
      "}",
      "",
    ].join("\n"),
  );
  const child = spawn(NGINX, ["-p", work, "-e", path.join(work, "error.log"), "-c", conf], { stdio: ["ignore", "pipe", "pipe"] });
  let err = "";
  child.stderr.on("data", (d) => (err += d));
  const url = `http://127.0.0.1:${port}/`;
  const deadline = Date.now() + PATIENCE_MS;
  for (;;) {
    if (child.exitCode !== null) {
      const log = existsSync(path.join(work, "error.log")) ? readFileSync(path.join(work, "error.log"), "utf8") : "";
      throw new Error(`nginx exited with ${child.exitCode}: ${err}${log}`);
    }
    try {
      const r = await fetch(`${url}index.html`);
      if (r.ok) break;
    } catch {
      // not listening yet
    }
    if (Date.now() > deadline) {
      child.kill("SIGKILL");
      throw new Error(`nginx did not answer on ${url} within ${PATIENCE_MS / 1000} s: ${err}`);
    }
    await new Promise((r) => setTimeout(r, 50));
  }
  return {
    url,
    close: async () => {
      child.kill("SIGQUIT");
      return exited(child, 10000);
    },
  };
}
