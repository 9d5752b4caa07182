// Starts the real wmd on a free loopback port with a fresh database, and talks HTTP to it.
import { spawn } from 'node:child_process';
import fs from 'node:fs';
import path from 'node:path';

/**
 * Starts `wmdPath --db <dir>/wm.db --port 0 --rules <repo>/rules/prolog --web <repo>/clients/web` and resolves
 * when it prints "listening on http://ADDR:PORT/": {url, child, output(), stop()}.
 * @throws Error with wmd's output when it exits or stays silent for `timeoutMs`.
 */
export async function startWmd({ wmdPath, repo, dir, timeoutMs = 30000, extraArgs = [] }) {
  if (!fs.existsSync(wmdPath)) throw new Error(`no wmd at ${wmdPath} (build it, or set WM_WMD_PATH)`);
  const args = ['--db', path.join(dir, 'wm.db'), '--port', '0', '--rules', path.join(repo, 'rules', 'prolog'),
    '--web', path.join(repo, 'clients', 'web'), ...extraArgs];
  const child = spawn(wmdPath, args, { stdio: ['ignore', 'pipe', 'pipe'] });
  let out = '';
  child.stdout.setEncoding('utf8');
  child.stderr.setEncoding('utf8');
  child.stderr.on('data', (d) => { out += d; });
  const url = await new Promise((resolve, reject) => {
    const timer = setTimeout(() => reject(new Error(`wmd printed no address within ${timeoutMs} ms:\n${out}`)), timeoutMs);
    child.stdout.on('data', (d) => {
      out += d;
      const m = /listening on (http:\/\/[^\s/]+)\//.exec(out);
      if (m) {
        clearTimeout(timer);
        resolve(m[1]);
      }
    });
    child.on('exit', (code, signal) => {
      clearTimeout(timer);
      reject(new Error(`wmd exited (${code ?? signal}) before listening:\n${out}`));
    });
  });
  const exited = new Promise((resolve) => child.on('exit', (code, signal) => resolve({ code, signal })));
  return {
    url,
    child,
    output: () => out,
    /** SIGTERM, then SIGKILL after `graceMs`; resolves with {code, signal}. */
    async stop(graceMs = 10000) {
      if (child.exitCode !== null || child.signalCode !== null) return exited;
      child.kill('SIGTERM');
      const timer = setTimeout(() => child.kill('SIGKILL'), graceMs);
      const result = await exited;
      clearTimeout(timer);
      return result;
    },
  };
}

/** fetch() that throws on a non-2xx answer, with the server's error text. */
export async function request(base, method, route, body, headers = {}) {
  const init = { method, headers: { ...headers } };
  if (body !== undefined) {
    init.body = typeof body === 'string' ? body : JSON.stringify(body);
    init.headers['content-type'] ??= 'application/json';
  }
  const res = await fetch(base + route, init);
  if (!res.ok) throw new Error(`${method} ${route}: ${res.status} ${await res.text()}`);
  return res;
}

export const getJson = async (base, route) => (await request(base, 'GET', route)).json();
export const postJson = async (base, route, body) => (await request(base, 'POST', route, body)).json();
export const putJson = async (base, route, body) => (await request(base, 'PUT', route, body)).json();
