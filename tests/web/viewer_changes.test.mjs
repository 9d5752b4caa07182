// End-to-end test of the viewer's changes in the building, in headless Debian chromium driven by playwright-core:
// the real wmd with --token on a free loopback port and a fresh database, a plan whose only object is a solid
// wall drawn across the Intel lab corridor the robot drives down (so the laser sees through it), 50 real scans,
// then the page: the change is listed by GET /api/v1/changes as wall_missing, the page lists and draws every
// change the API lists, errors (409, 401) show in the panel, Accept takes the wall out of the plan and Undo puts
// it back, each checked against the REST API. Saves a screenshot as the test's artefact.
//
// Environment: as viewer.test.mjs (WM_WMD_PATH, WM_ARTIFACT_DIR, WM_CHROMIUM, WM_SCAN_COUNT, WM_CARMEN_LOG).

import assert from 'node:assert/strict';
import fs from 'node:fs';
import os from 'node:os';
import path from 'node:path';
import { after, before, test } from 'node:test';
import { fileURLToPath } from 'node:url';

import { chromium } from 'playwright-core';

import { readFlaserScans, scanRequest } from './lib/carmen.mjs';
import { getJson, request, startWmd } from './lib/wmd.mjs';

const here = path.dirname(fileURLToPath(import.meta.url));
const repo = path.resolve(here, '..', '..');
const wmdPath = process.env.WM_WMD_PATH || path.join(repo, 'build', 'bin', 'wmd');
const artifactDir = process.env.WM_ARTIFACT_DIR || path.join(repo, 'build', 'web-test');
const chromiumPath = process.env.WM_CHROMIUM || '/usr/bin/chromium';
const logPath = [process.env.WM_CARMEN_LOG,
  path.resolve(repo, '..', 'shared', 'data', 'carmen', 'intel-corrected.log.gz'),
  path.join(repo, 'tests', 'data', 'carmen', 'intel-corrected-excerpt.log.gz')]
  .find((file) => file && fs.existsSync(file));
// The excerpt holds 35 scans; the wall is placed where scans 28..34 drive.
const scanCount = Number(process.env.WM_SCAN_COUNT || (logPath && logPath.includes('excerpt') ? 35 : 50));
const token = 'viewer-changes-test-token';
const auth = { authorization: `Bearer ${token}` };

const ctx = {};

const putAuth = async (route, body) => (await request(ctx.base, 'PUT', route, body, auth)).json();
const postAuth = async (route, body) => (await request(ctx.base, 'POST', route, body, auth)).json();

/**
 * A wall 0.8 m long across the corridor the robot drives along between scans 28 and 34 of the Intel log (south
 * down x ≈ 13 m), centred between the two poses and square to the drive: the beams of the scans before and after
 * pass through it.
 */
// A wall across the robot's drive, 0.7 m long and centred on its path where the log's returns leave it clear: no
// return of any scan within 0.4 m of it, so every part of it is crossed by beams and none ends on it (a wall the
// grid sees through everywhere: wall_missing, not a missing stretch beside clutter).
function wallAcrossTheDrive(scans, half = 0.35) {
  const returns = [];
  for (const s of scans) {
    const n = s.ranges.length;
    const increment = n % 2 === 0 ? Math.PI / n : Math.PI / (n - 1);
    s.ranges.forEach((r, i) => {
      if (!(r > 0.05 && r < 50)) return;
      const a = s.pose.theta - Math.PI / 2 + i * increment;
      returns.push([s.pose.x + r * Math.cos(a), s.pose.y + r * Math.sin(a)]);
    });
  }
  const distance = (p, [a, b]) => {
    const d = [b[0] - a[0], b[1] - a[1]];
    const t = Math.max(0, Math.min(1, ((p[0] - a[0]) * d[0] + (p[1] - a[1]) * d[1]) / (d[0] * d[0] + d[1] * d[1])));
    return Math.hypot(p[0] - a[0] - t * d[0], p[1] - a[1] - t * d[1]);
  };
  const across = (k) => {
    const a = scans[k].pose, b = scans[k + 6].pose;
    const mid = [(a.x + b.x) / 2, (a.y + b.y) / 2];
    const length = Math.hypot(b.x - a.x, b.y - a.y);
    if (length < 0.2) return null;
    const u = [(b.x - a.x) / length, (b.y - a.y) / length];
    return [[mid[0] - u[1] * half, mid[1] + u[0] * half], [mid[0] + u[1] * half, mid[1] - u[0] * half]];
  };
  for (let k = 28; k + 6 < scans.length; ++k) {
    const wall = across(k);
    if (wall && returns.every((p) => distance(p, wall) > 0.4)) return wall;
  }
  for (let k = 27; k >= 6; --k) {
    const wall = across(k);
    if (wall && returns.every((p) => distance(p, wall) > 0.4)) return wall;
  }
  return across(28);
}

async function until(what, probe, timeoutMs = 20000) {
  const end = Date.now() + timeoutMs;
  let last;
  while (Date.now() < end) {
    last = await probe();
    if (last.ok) return last;
    await new Promise((resolve) => setTimeout(resolve, 250));
  }
  assert.fail(`${what}: ${JSON.stringify(last?.detail ?? last)}`);
}

before(async () => {
  if (!fs.existsSync(chromiumPath)) {
    throw new Error(`missing ${chromiumPath}: Debian chromium (apt-get install -y chromium), or set WM_CHROMIUM`);
  }
  if (!logPath) throw new Error('no Intel lab log found: set WM_CARMEN_LOG');
  ctx.dir = fs.mkdtempSync(path.join(os.tmpdir(), 'wm-web-changes-'));
  ctx.wmd = await startWmd({ wmdPath, repo, dir: ctx.dir, extraArgs: ['--token', token] });
  ctx.base = ctx.wmd.url;

  const scans = readFlaserScans(logPath, scanCount);
  assert.equal(scans.length, scanCount, `the log has ${scanCount} FLASER scans`);
  ctx.wall = wallAcrossTheDrive(scans);
  await putAuth('/api/v1/floorplan', {
    name: 'a wall across the Intel lab corridor, for the changes test', units: 'm',
    objects: [{ id: 'wall-gone', kind: 'wall', attributes: ['solid'], pose: { x: 0, y: 0, theta: 0 }, segments: [ctx.wall] }],
  });
  for (const scan of scans) await postAuth('/api/v1/scans', scanRequest(scan));

  ctx.profile = fs.mkdtempSync(path.join(os.tmpdir(), 'wm-web-chromium-'));
  ctx.browser = await chromium.launchPersistentContext(ctx.profile, {
    executablePath: chromiumPath,
    headless: true,
    viewport: { width: 1400, height: 900 },
    args: ['--no-sandbox', '--disable-gpu', '--disable-quic', '--no-first-run', '--disable-background-networking',
      '--disable-component-update', '--disable-sync'],
  });
  ctx.page = ctx.browser.pages()[0] || await ctx.browser.newPage();
  ctx.pageErrors = [];
  ctx.consoleErrors = [];
  ctx.page.on('pageerror', (error) => ctx.pageErrors.push(String(error)));
  ctx.page.on('console', (message) => {
    if (message.type() === 'error') ctx.consoleErrors.push(message.text());
  });
  ctx.page.setDefaultTimeout(20000);
});

after(async () => {
  if (ctx.page && !ctx.screenshotSaved) await saveScreenshot('viewer-changes-failure.png').catch(() => {});
  if (ctx.browser) await ctx.browser.close().catch(() => {});
  if (ctx.wmd) {
    const { code, signal } = await ctx.wmd.stop();
    if (code !== 0) console.error(`wmd stopped with ${code ?? signal}:\n${ctx.wmd.output()}`);
  }
  for (const dir of [ctx.dir, ctx.profile]) if (dir) fs.rmSync(dir, { recursive: true, force: true });
});

async function saveScreenshot(name) {
  fs.mkdirSync(artifactDir, { recursive: true });
  const file = path.join(artifactDir, name);
  await ctx.page.screenshot({ path: file });
  return file;
}

/** What the page holds and drew of the changes, as plain JSON. */
const pageChanges = () => ctx.page.evaluate(() => {
  const v = window.worldmodelViewer;
  const rows = [...document.querySelectorAll('#changes-list li.change')].map((li) => ({ id: li.dataset.id, kind: li.dataset.kind }));
  return { changes: v.changes, drawn: v.drawn.changes, drawnKinds: v.drawn.changeKinds, rows, mapVersion: v.mapVersion };
});

/**
 * Waits until the page lists (panel rows and its model) and draws exactly the changes GET /api/v1/changes lists
 * (read again while waiting: the evidence is refreshed after a plan edit); returns that answer.
 */
async function expectPageShowsApiChanges(what) {
  const result = await until(`${what}: the page shows what GET /api/v1/changes lists`, async () => {
    const api = await getJson(ctx.base, '/api/v1/changes');
    const got = await pageChanges();
    const want = api.changes.map((c) => c.id).sort();
    const kinds = {};
    for (const c of api.changes) kinds[c.kind] = (kinds[c.kind] || 0) + 1;
    const ok = JSON.stringify([...got.changes.ids].sort()) === JSON.stringify(want) &&
      JSON.stringify(got.rows.map((r) => r.id).sort()) === JSON.stringify(want) &&
      got.drawn === api.changes.length && JSON.stringify(got.drawnKinds) === JSON.stringify(
        Object.fromEntries(Object.keys(got.drawnKinds).map((k) => [k, kinds[k]]))) &&
      Object.keys(kinds).length === Object.keys(got.drawnKinds).length;
    return { ok, api, detail: { api: { count: api.changes.length, kinds, version: api.version }, page: got } };
  });
  return result.api;
}

/** Waits until the page has drawn the objects and edges GET /api/v1/map holds, at its version; returns that map. */
async function expectDrawnMap(what) {
  const result = await until(`${what}: the page draws the plan GET /api/v1/map has`, async () => {
    const map = await getJson(ctx.base, '/api/v1/map');
    const want = { version: map.version, objects: map.objects.length, edges: map.objects.reduce((n, o) => n + o.edges.length, 0) };
    const got = await ctx.page.evaluate(() => {
      const v = window.worldmodelViewer;
      return { version: v.mapVersion, objects: v.drawn.objects, edges: v.drawn.edges, counts: v.counts };
    });
    const ok = got.version === want.version && got.objects === want.objects && got.edges === want.edges;
    return { ok, map, detail: { want, got } };
  });
  return result.map;
}

const planHasWall = (plan) => plan.objects.some((o) => o.id === 'wall-gone' && (o.segments || []).length > 0);

test('the viewer lists and draws the changes in the building, and a person accepts and undoes one', async (t) => {
  const { page, base } = ctx;

  await t.test('GET /api/v1/changes lists the wall the scans saw through as wall_missing', async () => {
    const found = await until('the wall is listed missing', async () => {
      const answer = await getJson(base, '/api/v1/changes');
      const change = answer.changes.find((c) => c.object === 'wall-gone');
      return { ok: change?.kind === 'wall_missing', change, detail: answer.changes.map((c) => `${c.kind} ${c.key}`) };
    });
    ctx.change = found.change;
    assert.equal(ctx.change.key, 'missing:wall-gone/0');
    assert.match(ctx.change.id, /^c[0-9a-f]{12}$/);
    assert.ok(ctx.change.evidence.beams_through > 0, `beams passed through it: ${JSON.stringify(ctx.change.evidence)}`);
  });

  await t.test('the page lists and draws every change the API lists', async () => {
    const res = await page.goto(`${base}/?token=${encodeURIComponent(token)}`);
    assert.equal(res.status(), 200);
    await page.waitForFunction(() => window.worldmodelViewer?.ready && window.worldmodelViewer.connection === 'open');
    const api = await expectPageShowsApiChanges('after load');
    assert.ok(api.changes.some((c) => c.id === ctx.change.id));
    const row = page.locator(`#changes-list li.change[data-id="${ctx.change.id}"][data-kind="wall_missing"]`);
    await row.waitFor();
    assert.equal(await row.getAttribute('title'), ctx.change.explanation, 'the explanation on hover');
    assert.match(await row.locator('.numbers').textContent(), /0\.70 m · confidence \d+ %/);
    await row.locator('summary').click();
    assert.equal(await row.locator('.explanation').textContent(), ctx.change.explanation, 'and under "why"');
    assert.match(await row.locator('.evidence').textContent(), /beams through \d+/);
    assert.equal(await page.locator('#legend li[data-kind="wall_missing"]').count(), 1, 'a legend entry');

    // The stretch is drawn in its colour (#ff2d2d) around its middle.
    const mid = [(ctx.change.p0[0] + ctx.change.p1[0]) / 2, (ctx.change.p0[1] + ctx.change.p1[1]) / 2];
    const red = async () => page.evaluate(([x, y]) => {
      const v = window.worldmodelViewer;
      const c = document.getElementById('map-canvas');
      const r = c.getBoundingClientRect();
      const at = v.toClient(x, y);
      const dpr = window.devicePixelRatio || 1;
      const size = Math.round(16 * dpr);
      const data = c.getContext('2d').getImageData(Math.round((at.x - r.left) * dpr) - size / 2,
        Math.round((at.y - r.top) * dpr) - size / 2, size, size).data;
      let n = 0;
      for (let i = 0; i < data.length; i += 4) if (data[i] > 200 && data[i + 1] < 90 && data[i + 2] < 90) ++n;
      return n;
    }, mid);
    assert.ok(await red() > 0, 'red pixels on the missing wall');

    // The layer toggle hides them and shows them again.
    await page.uncheck('#toggle-changes');
    await page.waitForFunction(() => window.worldmodelViewer.drawn.changes === 0);
    assert.equal(await red(), 0, 'no red pixels with the layer off');
    await page.check('#toggle-changes');
    await page.waitForFunction((n) => window.worldmodelViewer.drawn.changes === n, api.changes.length);
  });

  await t.test('errors show in the panel: nothing to undo (409), a wrong token (401)', async () => {
    await page.click('#changes-undo');
    await page.waitForSelector('#changes-error[data-status="409"]:not([hidden])');
    assert.match(await page.textContent('#changes-error'), /^undo: 409 /);

    await page.fill('#changes-token', 'not-the-token');
    await page.click(`#changes-list li.change[data-id="${ctx.change.id}"] button.accept`);
    await page.waitForSelector('#changes-error[data-status="401"]:not([hidden])');
    assert.match(await page.textContent('#changes-error'), new RegExp(`^accept ${ctx.change.id}: 401 not authorised`));
    assert.equal(await page.evaluate(() => sessionStorage.getItem('worldmodel.token')), 'not-the-token', 'kept for the tab');
    const plan = await getJson(base, '/api/v1/floorplan');
    assert.ok(planHasWall(plan), 'a refused accept changes nothing');
    await page.fill('#changes-token', token);
  });

  await t.test('Accept takes the wall out of the plan; the panel and the map follow', async () => {
    const versionBefore = (await getJson(base, '/api/v1/map')).version;
    await page.click(`#changes-list li.change[data-id="${ctx.change.id}"] button.accept`);
    await page.waitForFunction((id) => {
      const o = window.worldmodelViewer.changes.lastOutcome;
      return o?.verdict === 'accept' && o.change === id;
    }, ctx.change.id);
    assert.equal(await page.isHidden('#changes-error'), true, 'the error is gone');
    assert.match(await page.textContent('#changes-message'), new RegExp(`^accepted ${ctx.change.id}: decision #\\d+`));

    const plan = await getJson(base, '/api/v1/floorplan');
    assert.ok(!planHasWall(plan), `the plan has no wall-gone: ${JSON.stringify(plan.objects.map((o) => o.id))}`);
    const decisions = await getJson(base, '/api/v1/decisions?since=0&limit=10000');
    assert.ok(decisions.decisions.some((d) => d.action === 'accept' && d.rule === 'change_accepted'), 'an accept decision');

    const api = await expectPageShowsApiChanges('after accept');
    assert.ok(!api.changes.some((c) => c.id === ctx.change.id), 'no longer listed');
    assert.equal(await page.locator(`#changes-list li.change[data-id="${ctx.change.id}"]`).count(), 0);
    const map = await expectDrawnMap('after accept');
    assert.ok(map.version > versionBefore);
    assert.ok(!map.objects.some((o) => o.id === 'wall-gone'), 'the map has no wall-gone');
  });

  await t.test('Undo puts the wall back and lists the change again', async () => {
    await page.click('#changes-undo');
    await page.waitForFunction(() => window.worldmodelViewer.changes.lastOutcome?.verdict === 'undo');
    assert.match(await page.textContent('#changes-message'), new RegExp(`^undid ${ctx.change.id}`));
    const plan = await getJson(base, '/api/v1/floorplan');
    assert.ok(planHasWall(plan), 'the wall is back in the plan');
    await until('the change is listed again', async () => {
      const answer = await getJson(base, '/api/v1/changes');
      return { ok: answer.changes.some((c) => c.id === ctx.change.id), detail: answer.changes.map((c) => c.key) };
    });
    await expectPageShowsApiChanges('after undo');
    await page.locator(`#changes-list li.change[data-id="${ctx.change.id}"]`).waitFor();
    const map = await expectDrawnMap('after undo');
    assert.ok(map.objects.some((o) => o.id === 'wall-gone'), 'the map has wall-gone again');
  });

  await t.test('the screenshot is saved, centred on the change', async () => {
    await page.click(`#changes-list li.change[data-id="${ctx.change.id}"] button.key`);
    await page.focus('#map-canvas');
    for (let i = 0; i < 4; ++i) await page.keyboard.press('+');
    const file = await saveScreenshot('viewer-changes.png');
    ctx.screenshotSaved = true;
    assert.ok(fs.statSync(file).size > 10000, `screenshot ${file}`);
    console.log(`screenshot: ${file}`);
  });

  assert.deepEqual(ctx.pageErrors, [], 'no uncaught error in the page');
  // The 409 and 401 above were asked for: the browser logs each refused request as a console error.
  const unexpected = ctx.consoleErrors.filter((m) => !/status of (401|409)/.test(m));
  assert.deepEqual(unexpected, [], 'no other error on the console');
});
