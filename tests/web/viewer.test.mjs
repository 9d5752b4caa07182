// End-to-end test of the web viewer in headless Debian chromium, driven by playwright-core:
// the real wmd on a free loopback port with a fresh database, a floor plan, 50 real laser scans of the Intel
// lab log, then the page, checked against the REST API: the grid image, what was drawn, a live decision,
// a click with its history, the layer switch. Saves a screenshot as the test's artefact.
//
// Environment: WM_WMD_PATH (default <repo>/build/bin/wmd), WM_ARTIFACT_DIR (default <repo>/build/web-test),
// WM_CHROMIUM (default /usr/bin/chromium), WM_SCAN_COUNT (default 50), WM_CARMEN_LOG (default: the Intel log of
// ../shared/data/carmen, else the excerpt in tests/data/carmen).

import assert from 'node:assert/strict';
import fs from 'node:fs';
import os from 'node:os';
import path from 'node:path';
import { after, before, test } from 'node:test';
import { fileURLToPath } from 'node:url';

import { chromium } from 'playwright-core';

import { fnv1a } from '../../clients/web/js/grid_layers.js';
import { parsePgm, pgmToRgba } from '../../clients/web/js/pgm.js';
import { readFlaserScans, scanRequest } from './lib/carmen.mjs';
import { getJson, postJson, putJson, request, startWmd } from './lib/wmd.mjs';

const here = path.dirname(fileURLToPath(import.meta.url));
const repo = path.resolve(here, '..', '..');
const wmdPath = process.env.WM_WMD_PATH || path.join(repo, 'build', 'bin', 'wmd');
const artifactDir = process.env.WM_ARTIFACT_DIR || path.join(repo, 'build', 'web-test');
const chromiumPath = process.env.WM_CHROMIUM || '/usr/bin/chromium';
// The whole Intel log beside the checkout when it is there, else the excerpt shipped in tests/data.
const logPath = [process.env.WM_CARMEN_LOG,
  path.resolve(repo, '..', 'shared', 'data', 'carmen', 'intel-corrected.log.gz'),
  path.join(repo, 'tests', 'data', 'carmen', 'intel-corrected-excerpt.log.gz')]
  .find((file) => file && fs.existsSync(file));
// The excerpt holds 35 scans.
const scanCount = Number(process.env.WM_SCAN_COUNT || (logPath && logPath.includes('excerpt') ? 30 : 50));

const ctx = {};

before(async () => {
  if (!fs.existsSync(chromiumPath)) {
    throw new Error(`missing ${chromiumPath}: Debian chromium (apt-get install -y chromium), or set WM_CHROMIUM`);
  }
  if (!logPath) throw new Error('no Intel lab log: neither ../shared/data/carmen nor tests/data/carmen has one');
  ctx.dir = fs.mkdtempSync(path.join(os.tmpdir(), 'wm-web-test-'));
  ctx.wmd = await startWmd({ wmdPath, repo, dir: ctx.dir });
  const base = ctx.wmd.url;
  ctx.base = base;

  const plan = JSON.parse(fs.readFileSync(path.join(here, 'fixtures', 'plan.json'), 'utf8'));
  await putJson(base, '/api/v1/floorplan', plan);

  // Scans 0..count-2 before the page opens; the last one after, to see it arrive live.
  ctx.scans = readFlaserScans(logPath, scanCount);
  assert.equal(ctx.scans.length, scanCount, `the log has ${scanCount} FLASER scans`);
  for (const scan of ctx.scans.slice(0, -1)) await postJson(base, '/api/v1/scans', scanRequest(scan));

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
  if (ctx.page && !ctx.screenshotSaved) await saveScreenshot('viewer-failure.png').catch(() => {});
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

/** The page's read-only test hook, as plain JSON. */
const viewer = () => ctx.page.evaluate(() => {
  const v = window.worldmodelViewer;
  return {
    ready: v.ready, connection: v.connection, syncs: v.syncs, lastEventSeq: v.lastEventSeq, lastDecision: v.lastDecision,
    drawn: v.drawn, counts: v.counts, grid: v.grid, recentHighlights: v.recentHighlights, mapVersion: v.mapVersion,
    selection: v.selection, map: v.map,
  };
});

/** Waits until the page has drawn exactly what GET /api/v1/map holds; returns that map. */
async function expectDrawnEqualsApi(what) {
  const map = await getJson(ctx.base, '/api/v1/map');
  const want = {
    objects: map.objects.length,
    edges: map.objects.reduce((n, o) => n + o.edges.length, 0),
    elements: map.elements.length,
  };
  try {
    await ctx.page.waitForFunction((w) => {
      const v = window.worldmodelViewer;
      const d = v.drawn;
      return v.mapVersion >= 0 && d.objects === w.objects && d.edges === w.edges && d.elements === w.elements;
    }, want, { timeout: 15000 });
  } catch (error) {
    const got = await viewer();
    assert.fail(`${what}: the page drew ${JSON.stringify(got.drawn)} (map version ${got.mapVersion}), the API has ${JSON.stringify(want)} (version ${map.version})`);
  }
  return map;
}

test('the viewer shows the grid, the plan and the elements, follows live decisions and explains them', async (t) => {
  const { page, base } = ctx;

  await t.test('the page is served by wmd and syncs over REST and the WebSocket', async () => {
    const res = await page.goto(`${base}/`);
    assert.equal(res.status(), 200);
    await page.waitForFunction(() => window.worldmodelViewer?.ready && window.worldmodelViewer.connection === 'open');
    await page.waitForFunction(() => document.getElementById('status-health').dataset.value === 'ok');
    const rules = await page.$$eval('#status-rules li', (items) => items.map((li) => li.dataset.path));
    const health = await getJson(base, '/api/v1/health');
    assert.deepEqual(rules, health.rules.files.map((f) => f.path), 'rule files listed as the health answer has them');
    // The scans were posted before the page loaded: the robot comes from GET /api/v1/robots, with its track.
    const robots = await getJson(base, '/api/v1/robots');
    assert.equal(robots.robots.length, 1);
    assert.ok(robots.robots[0].track.length > 1, 'the robot has a track');
    await page.waitForFunction(() => window.worldmodelViewer.drawn.robots === 1);
  });

  await t.test('the grid image appears with the size and origin of the API grid', async () => {
    await page.waitForFunction(() => window.worldmodelViewer.grid.layers.bayes.width > 0 && window.worldmodelViewer.drawn.grid);
    const pgm = Buffer.from(await (await request(base, 'GET', '/api/v1/grid?layer=bayes&format=pgm')).arrayBuffer());
    const [, w, h] = /^P5\s+(?:#[^\n]*\n\s*)*(\d+)\s+(\d+)/.exec(pgm.toString('latin1', 0, 200)).map(Number);
    const yaml = await (await request(base, 'GET', '/api/v1/grid/map.yaml')).text();
    const origin = /origin:\s*\[([-0-9.e]+),\s*([-0-9.e]+)/.exec(yaml).slice(1).map(Number);
    const grid = (await viewer()).grid;
    assert.equal(grid.layers.bayes.width, w, 'grid width in cells');
    assert.equal(grid.layers.bayes.height, h, 'grid height in cells');
    assert.ok(Math.abs(grid.layers.bayes.origin[0] - origin[0]) < 1e-6 && Math.abs(grid.layers.bayes.origin[1] - origin[1]) < 1e-6,
      `grid origin ${grid.layers.bayes.origin} vs ${origin}`);
    // Read as tiles, the layer shows exactly the server's PGM of the same cells, pixel for pixel (when no scan
    // came in between: the log replay is over by now).
    const index = await getJson(base, '/api/v1/grid/tiles');
    assert.equal(grid.tileSize, index.tile_size_cells);
    const image = parsePgm(new Uint8Array(pgm));
    const drawn = await page.evaluate(() => window.worldmodelViewer.gridDigest('bayes'));
    assert.deepEqual(drawn, { width: image.width, height: image.height, digest: fnv1a(pgmToRgba(image.pixels, 'bayes')) });
    // Not a blank image: the canvas shows grey pixels lighter than unknown (205: free) and dark ones (occupied).
    const shades = await page.evaluate(() => {
      const c = document.getElementById('map-canvas');
      const data = c.getContext('2d').getImageData(0, 0, c.width, c.height).data;
      let free = 0, occupied = 0;
      for (let i = 0; i < data.length; i += 4) {
        if (data[i] !== data[i + 1] || data[i] !== data[i + 2]) continue;  // a coloured overlay
        if (data[i] > 212) ++free;
        if (data[i] < 100) ++occupied;
      }
      return { free, occupied };
    });
    assert.ok(shades.free > 1000 && shades.occupied > 50, `free and occupied cells visible: ${JSON.stringify(shades)}`);
  });

  await t.test('the page drew every CAD object, edge and element of the API', async () => {
    const map = await expectDrawnEqualsApi('after load');
    assert.ok(map.objects.length >= 9, 'the plan is loaded');
    assert.ok(map.elements.length > 0, 'the scans produced elements');
  });

  await t.test('a scan posted after load moves the robot and refreshes the grid region', async () => {
    const before = (await viewer()).grid.layers.bayes;
    const answer = await postJson(base, '/api/v1/scans', scanRequest(ctx.scans[ctx.scans.length - 1]));
    await page.waitForFunction((rev) => {
      const v = window.worldmodelViewer;
      return v.drawn.robots === 1 && v.drawn.scanPoints > 0 && v.grid.layers.bayes.revision >= rev;
    }, answer.grid_revision);
    const after = (await viewer()).grid.layers.bayes;
    assert.ok(after.fetches > before.fetches, 'the changed region was fetched');
    await expectDrawnEqualsApi('after a live scan');
  });

  await t.test('a decision made after load shows up without reload', async () => {
    const before = await viewer();
    const answer = await postJson(base, '/api/v1/primitives', {
      source: 'test', segments: [{ p0: [4.6, -8.2], p1: [5.7, -7.3] }],
    });
    assert.equal(answer.decisions.length, 1);
    const d = answer.decisions[0];
    ctx.decision = d;
    assert.ok(['add', 'merge'].includes(d.action), `a line in open space is added or merged, got ${d.action} (${d.rule})`);
    await page.waitForFunction((seq) => window.worldmodelViewer.lastDecision?.seq === seq, d.seq);
    const got = await viewer();
    assert.ok(got.lastEventSeq > before.lastEventSeq, 'an event arrived');
    assert.equal(got.syncs, before.syncs, 'no re-sync was needed');
    assert.ok(got.recentHighlights.some((h) => h.id === d.element && h.action === d.action && h.seq === d.seq),
      `highlighted ${d.element} (${d.action}): ${JSON.stringify(got.recentHighlights.slice(-3))}`);
    await page.waitForSelector(`#decision-feed li[data-seq="${d.seq}"][data-rule="${d.rule}"]`);
    await expectDrawnEqualsApi('after a live decision');
  });

  await t.test('clicking the element shows its details and decision history', async () => {
    const d = ctx.decision;
    const element = await getJson(base, `/api/v1/elements/${d.element}`);
    const mid = [(element.p0[0] + element.p1[0]) / 2, (element.p0[1] + element.p1[1]) / 2];
    const at = await page.evaluate(([x, y]) => window.worldmodelViewer.toClient(x, y), mid);
    await page.mouse.click(at.x, at.y);
    await page.waitForSelector(`#details[data-kind="element"][data-id="${d.element}"]`);
    await page.waitForSelector('#details-history[data-state="loaded"]');
    const history = await getJson(base, `/api/v1/elements/${d.element}/history`);
    const shown = await page.$$eval('#details-history li.decision', (items) => items.map((li) => ({
      seq: Number(li.dataset.seq), rule: li.querySelector('.rule').textContent, explanation: li.querySelector('.explanation').textContent,
    })));
    assert.equal(shown.length, history.decisions.length, 'every decision of the history is listed');
    for (const h of history.decisions) {
      const row = shown.find((s) => s.seq === h.seq);
      assert.ok(row, `decision ${h.seq} listed`);
      assert.equal(row.rule, h.rule);
      assert.equal(row.explanation, h.explanation);
    }
    assert.ok(await page.getByText(d.rule, { exact: true }).first().isVisible(), `rule ${d.rule} visible`);
  });

  await t.test('a rigid adjustment and a confirmed wall flash, and clicking the object shows its history', async () => {
    // One edge of table-1 seen 3 cm off (the demo's rigid_adjust primitive, moved to this plan's table), and
    // the north wall seen where it is drawn.
    const answer = await postJson(base, '/api/v1/primitives', {
      source: 'test',
      segments: [
        { p0: [5.7832, -11.5172], p1: [6.471, -11.3044], cov: [[1e-4, 0], [0, 1e-4]] },
        { p0: [-5.0, 6.5], p1: [0.0, 6.51] },
      ],
    });
    const [table, wall] = answer.decisions;
    assert.equal(table.action, 'rigid_adjust', `table edge: ${table.action} (${table.explanation})`);
    assert.equal(wall.action, 'delete', `wall: ${wall.action} (${wall.explanation})`);
    await page.waitForFunction((seq) => window.worldmodelViewer.lastDecision?.seq === seq, wall.seq);
    const got = await viewer();
    assert.ok(got.recentHighlights.some((h) => h.kind === 'object' && h.id === 'table-1' && h.action === 'rigid_adjust'),
      'the whole table flashes');
    assert.ok(got.recentHighlights.some((h) => h.kind === 'edge' && h.id === 'wall-north/0' && h.action === 'delete'),
      'the confirmed wall edge flashes');
    await expectDrawnEqualsApi('after a rigid adjustment');

    const object = await getJson(base, '/api/v1/objects/table-1');
    const e = object.edges[1];  // not the observed one, so the click lands on the table's moved drawing
    const at = await page.evaluate(([x, y]) => window.worldmodelViewer.toClient(x, y),
      [(e.p0[0] + e.p1[0]) / 2, (e.p0[1] + e.p1[1]) / 2]);
    await page.mouse.click(at.x, at.y);
    await page.waitForSelector('#details[data-kind="object"][data-id="table-1"]');
    await page.waitForSelector(`#details-history[data-state="loaded"] li.decision[data-seq="${table.seq}"][data-rule="${table.rule}"]`);
    const confirmed = await page.textContent('#details dd[data-key="confirmed"]');
    assert.match(confirmed, /adjusted 1×/);
  });

  await t.test('a new floor plan is reloaded live', async () => {
    const plan = JSON.parse(fs.readFileSync(path.join(here, 'fixtures', 'plan.json'), 'utf8'));
    plan.objects.push({ id: 'crate-1', kind: 'crate', attributes: ['not_deformable'], pose: { x: 2, y: -5, theta: 0 },
      polygon: [[-0.3, -0.3], [0.3, -0.3], [0.3, 0.3], [-0.3, 0.3]] });
    const deltaSyncsBefore = await page.evaluate(() => window.worldmodelViewer.deltaSyncs);
    await putJson(base, '/api/v1/floorplan', plan);
    await page.waitForFunction(() => window.worldmodelViewer.counts.objects === 10);
    await expectDrawnEqualsApi('after a new floor plan');
    // The reload fetched only what changed (GET /api/v1/map?since=), not the whole map.
    assert.ok(await page.evaluate(() => window.worldmodelViewer.deltaSyncs) > deltaSyncsBefore);
  });

  await t.test('the status shows the processing network: each executor\'s load and the queues', async () => {
    await page.waitForFunction(() => /world \d+%/.test(document.querySelector('#status-network').textContent), null,
      { timeout: 15000 });
    const text = await page.textContent('#status-network');
    for (const executor of ['world', 'storage', 'grids', 'lines']) assert.match(text, new RegExp(`${executor} \\d+%`));
    assert.match(await page.getAttribute('#status-network', 'title'), /store\.commit: \d+ ×/);
  });

  await t.test('a new placement of the plan moves it live and the status says where', async () => {
    const placed = await postJson(base, '/api/v1/floorplan/place', { x: 1.5, y: -0.5, theta_deg: 10 });
    assert.equal(placed.decision.action, 'place');
    await page.waitForFunction(() => document.querySelector('#status-placement').textContent.includes('10.00°'));
    assert.match(await page.textContent('#status-placement'), /x 1\.50 m, y -0\.50 m/);
    await expectDrawnEqualsApi('after a new placement');
    await postJson(base, '/api/v1/floorplan/undo', {});
    await page.waitForFunction(() => document.querySelector('#status-placement').textContent === 'as drawn');
    await expectDrawnEqualsApi('after the placement was undone');
  });

  await t.test('the layer switch shows each Dempster-Shafer, laser-only and sonar layer', async () => {
    for (const layer of ['ds_belief', 'ds_plausibility', 'ds_conflict', 'ds_decision', 'laser_bayes', 'sonar_bayes',
      'laser_sonar_conflict', 'bayes']) {
      await page.selectOption('#layer-select', layer);
      await page.waitForFunction((l) => {
        const v = window.worldmodelViewer;
        return v.grid.active === l && v.grid.layers[l].width > 0 && v.drawn.grid;
      }, layer);
    }
  });

  await t.test('the 95 % band toggle draws a band per element; the screenshot is saved', async () => {
    await page.check('#toggle-band');
    await page.waitForFunction(() => window.worldmodelViewer.drawn.bands === window.worldmodelViewer.counts.elements);
    const file = await saveScreenshot('viewer.png');
    ctx.screenshotSaved = true;
    assert.ok(fs.statSync(file).size > 10000, `screenshot ${file}`);
    console.log(`screenshot: ${file}`);
  });

  await t.test('the map picker lists the server\'s maps, shows the one the URL names and switches to another', async () => {
    await postJson(base, '/api/v1/maps', { id: 'floor2' });
    await postJson(base, '/api/v1/maps/floor2/primitives', {
      source: 'robot-2',
      segments: [{ p0: [0, 0], p1: [0, 4] }, { p0: [2, 0], p1: [5, 0] }],
    });
    await page.goto(`${base}/?map=floor2`);
    await page.waitForFunction(() => window.worldmodelViewer?.ready && window.worldmodelViewer.connection === 'open');
    await page.waitForFunction(() => window.worldmodelViewer.drawn.elements === 2);
    const shown = await viewer();
    assert.equal(shown.map, 'floor2');
    assert.equal(shown.drawn.objects, 0, 'floor2 has no plan: nothing of the default map\'s');
    await page.waitForFunction(() => document.querySelectorAll('#map-picker option').length === 2);
    assert.deepEqual(await page.$$eval('#map-picker option', (o) => o.map((x) => x.value)), ['default', 'floor2']);
    assert.equal(await page.$eval('#map-picker', (s) => s.value), 'floor2');
    // A decision on floor2 reaches the page through floor2's events.
    await postJson(base, '/api/v1/maps/floor2/primitives', { source: 'robot-2', segments: [{ p0: [9, 0], p1: [9, 3] }] });
    await page.waitForFunction(() => window.worldmodelViewer.drawn.elements === 3);
    await Promise.all([page.waitForNavigation(), page.selectOption('#map-picker', 'default')]);
    await page.waitForFunction(() => window.worldmodelViewer?.ready);
    assert.equal(new URL(page.url()).searchParams.get('map'), null);
    assert.equal((await viewer()).map, 'default');
    await expectDrawnEqualsApi('back on the default map');
  });

  assert.deepEqual(ctx.pageErrors, [], 'no uncaught error in the page');
  assert.deepEqual(ctx.consoleErrors, [], 'no error on the console');
});
