// End-to-end test of wmd's Foxglove WebSocket (GET /foxglove, subprotocol foxglove.websocket.v1) with the real
// client of Foxglove's protocol (@foxglove/ws-protocol over the ws package): the real wmd on a free loopback port
// with a fresh database, the shipped Intel lab excerpt replayed by the real wmctl while a client subscribes to every
// channel. Every message is validated against Foxglove's published JSON schemas (@foxglove/schemas), the advertised
// schemas are checked against them, and once the replay is done every channel is checked against the REST API: the
// grid against GET /api/v1/grid and, bit for bit, the float32 tiles; the scenes' lines against GET /api/v1/map; the
// poses and transforms against GET /api/v1/robots; the log against GET /api/v1/decisions. A second wmd, with a token
// and a small per-client queue: refused upgrades, and a subscriber that stops reading does not hold up a replay,
// falls behind, and gets the current state when it reads again.
//
// Environment: WM_WMD_PATH, WM_WMCTL_PATH (default <repo>/build/bin/wmd, wmctl), WM_CARMEN_LOG (default: the
// excerpt in tests/data/carmen).

import assert from 'node:assert/strict';
import { spawn } from 'node:child_process';
import fs from 'node:fs';
import os from 'node:os';
import path from 'node:path';
import { after, before, describe, test } from 'node:test';
import { fileURLToPath } from 'node:url';

import foxglove from '@foxglove/ws-protocol';
import foxgloveSchemas from '@foxglove/schemas/jsonschema.js';
import Ajv from 'ajv';
import WebSocket from 'ws';

import { getJson, postJson, putJson, request, startWmd } from '../web/lib/wmd.mjs';

const { FoxgloveClient } = foxglove;
const here = path.dirname(fileURLToPath(import.meta.url));
const repo = path.resolve(here, '..', '..');
const wmdPath = process.env.WM_WMD_PATH || path.join(repo, 'build', 'bin', 'wmd');
const wmctlPath = process.env.WM_WMCTL_PATH || path.join(repo, 'build', 'bin', 'wmctl');
const logPath = process.env.WM_CARMEN_LOG || path.join(repo, 'tests', 'data', 'carmen', 'intel-corrected-excerpt.log.gz');
const planPath = path.join(repo, 'tests', 'web', 'fixtures', 'plan.json');

const kSubprotocol = 'foxglove.websocket.v1';
// The web viewer's colours (clients/web/js/map_view.js), which the scenes use too.
const kElementColors = { scan: '#ec6a00', grid: '#9c36b5', client: '#8d5524' };
const kObjectColors = { solid: '#2451a6', not_deformable: '#1e9e4a', other: '#c08a00' };

const ajv = new Ajv({ strict: false, allErrors: true });
const officialSchema = (schemaName) => foxgloveSchemas[schemaName.replace(/^foxglove\./, '')];
const validators = new Map();
function validatorFor(schemaName) {
  if (!validators.has(schemaName)) {
    const schema = officialSchema(schemaName);
    assert.ok(schema, `@foxglove/schemas has no ${schemaName}`);
    validators.set(schemaName, ajv.compile(schema));
  }
  return validators.get(schemaName);
}

/** Runs wmctl; resolves with {code, output, seconds}. */
function wmctl(args) {
  return new Promise((resolve, reject) => {
    const start = process.hrtime.bigint();
    const child = spawn(wmctlPath, args, { stdio: ['ignore', 'pipe', 'pipe'] });
    let output = '';
    child.stdout.on('data', (d) => { output += d; });
    child.stderr.on('data', (d) => { output += d; });
    child.on('error', reject);
    child.on('exit', (code) => resolve({ code, output, seconds: Number(process.hrtime.bigint() - start) / 1e9 }));
  });
}

async function replay(base, extra = [], token) {
  const args = ['--server', base, ...(token ? ['--token', token] : []), 'replay', logPath, ...extra];
  const result = await wmctl(args);
  assert.equal(result.code, 0, `wmctl ${args.join(' ')} failed:\n${result.output}`);
  return result;
}

async function waitFor(what, check, timeoutMs = 20000) {
  const deadline = Date.now() + timeoutMs;
  let problems = [];
  for (;;) {
    problems = await check();
    if (problems.length === 0) return;
    if (Date.now() > deadline) assert.fail(`${what}: still ${problems.length} differences after ${timeoutMs} ms:\n${problems.slice(0, 12).join('\n')}`);
    await new Promise((r) => setTimeout(r, 200));
  }
}

/**
 * An upgrade the server must refuse: resolves with its {status, body} (the JSON error); rejects if it opens, or if
 * the connection ends without an answer (with the client's error, so that it is never left pending).
 */
function refusal(url, protocols, headers) {
  return new Promise((resolve, reject) => {
    const ws = new WebSocket(url, protocols, { headers });
    let failure = null;
    ws.on('unexpected-response', (_req, res) => {
      let body = '';
      res.on('data', (d) => { body += d; });
      res.on('end', () => resolve({ status: res.statusCode, body: JSON.parse(body) }));
      res.on('error', (error) => reject(new Error(`${url}: the refusal's body did not arrive: ${error.message}`)));
    });
    ws.on('open', () => reject(new Error(`${url} opened`)));
    ws.on('error', (error) => {
      failure = error;
      reject(new Error(`${url}: no answer: ${error.message}`));
    });
    ws.on('close', () => reject(new Error(`${url}: closed without an answer${failure ? ` (${failure.message})` : ''}`)));
  });
}

const hexColor = (c) => '#' + [c.r, c.g, c.b].map((v) => Math.round(v * 255).toString(16).padStart(2, '0')).join('');
const yaw = (q) => 2 * Math.atan2(q.z, q.w);
const angleDiff = (a, b) => Math.abs(Math.atan2(Math.sin(a - b), Math.cos(a - b)));

/** A Grid message's cells: {x0, y0, resolution, width, height, fields: {name: Float32Array}}. */
function decodeGrid(grid) {
  const bytes = Buffer.from(grid.data, 'base64');
  const view = new DataView(bytes.buffer, bytes.byteOffset, bytes.byteLength);
  const width = grid.column_count;
  const height = bytes.byteLength / grid.row_stride;
  const fields = {};
  for (const f of grid.fields) {
    assert.equal(f.type, 7, `field ${f.name} is FLOAT32`);
    const values = new Float32Array(width * height);
    for (let i = 0; i < values.length; ++i) values[i] = view.getFloat32(i * grid.cell_stride + f.offset, true);
    fields[f.name] = values;
  }
  return { x0: grid.pose.position.x, y0: grid.pose.position.y, resolution: grid.cell_size.x, width, height, fields };
}

/**
 * One Foxglove client with what it was sent: the latest message of each topic, the scenes (entities by id, deletions
 * applied), the transforms by child frame, the log, the status messages, and every message checked against
 * Foxglove's schema of its channel.
 */
class View {
  static async open(url, { protocols = [kSubprotocol], headers } = {}) {
    const view = new View(new WebSocket(url, protocols, { headers }));
    await view.ready;
    return view;
  }

  constructor(ws) {
    this.ws = ws;
    this.client = new FoxgloveClient({ ws });
    this.channels = new Map();        // id -> channel
    this.subscriptions = new Map();   // subscription id -> channel
    this.latest = new Map();          // topic -> {message, bytes, order}
    this.scenes = new Map();          // topic -> Map(entity id -> entity)
    this.sceneMessages = new Map();   // topic -> [{replaceAll, entities, order}]
    this.transforms = new Map();      // child frame -> transform
    this.logs = [];
    this.statuses = [];               // {status, order}
    this.counts = new Map();          // topic -> messages
    this.bytes = new Map();           // topic -> payload bytes received
    this.invalid = [];
    this.order = 0;                   // every message and status, numbered as received
    this.openedAt = BigInt(Date.now()) * 1000000n;
    this.ready = new Promise((resolve, reject) => {
      let info = null;
      this.client.on('serverInfo', (i) => { info = i; this.serverInfo = i; });
      this.client.on('advertise', (channels) => {
        for (const c of channels) {
          this.channels.set(c.id, c);
          this.subscriptions.set(this.client.subscribe(c.id), c);
        }
        if (info) resolve();
      });
      this.client.on('error', reject);
      ws.on('unexpected-response', (_req, res) => reject(new Error(`upgrade refused: ${res.statusCode}`)));
    });
    this.client.on('status', (status) => this.statuses.push({ status, order: ++this.order }));
    this.client.on('message', (event) => this.onMessage(event));
    this.closed = new Promise((resolve) => ws.on('close', (code) => resolve(code)));
  }

  onMessage({ subscriptionId, timestamp, data }) {
    const channel = this.subscriptions.get(subscriptionId);
    if (!channel) {
      this.invalid.push(`a message for unknown subscription ${subscriptionId}`);
      return;
    }
    const now = BigInt(Date.now()) * 1000000n;
    if (timestamp < this.openedAt - 5000000000n || timestamp > now + 5000000000n)
      this.invalid.push(`${channel.topic}: receive time ${timestamp} ns is not now`);
    const text = new TextDecoder().decode(data);
    const message = JSON.parse(text);
    const validate = validatorFor(channel.schemaName);
    if (!validate(message) && this.invalid.length < 10)
      this.invalid.push(`${channel.topic}: ${ajv.errorsText(validate.errors).slice(0, 400)}`);
    const order = ++this.order;
    this.counts.set(channel.topic, (this.counts.get(channel.topic) || 0) + 1);
    this.bytes.set(channel.topic, (this.bytes.get(channel.topic) || 0) + data.byteLength);
    this.latest.set(channel.topic, { message, bytes: data.byteLength, order });
    if (channel.schemaName === 'foxglove.SceneUpdate') {
      const scene = this.scenes.get(channel.topic) || new Map();
      let replaceAll = false;
      for (const d of message.deletions) {
        if (d.type === 1) {
          scene.clear();
          replaceAll = true;
        } else {
          scene.delete(d.id);
        }
      }
      for (const e of message.entities) scene.set(e.id, e);
      this.scenes.set(channel.topic, scene);
      const list = this.sceneMessages.get(channel.topic) || [];
      list.push({ replaceAll, entities: message.entities.length, order });
      this.sceneMessages.set(channel.topic, list);
    } else if (channel.schemaName === 'foxglove.FrameTransforms') {
      for (const t of message.transforms) this.transforms.set(t.child_frame_id, t);
    } else if (channel.schemaName === 'foxglove.Log') {
      this.logs.push(message);
    }
  }

  topic(name) { return [...this.channels.values()].find((c) => c.topic === name); }
  close() { this.client.close(); }
}

/** Differences between the grid of a View and GET /api/v1/grid (values there are rounded to 4 decimals). */
async function gridDifferences(base, view, api = '/api/v1') {
  const latest = view.latest.get('/grid');
  if (!latest) return ['no /grid message yet'];
  const rest = await getJson(base, `${api}/grid`);
  const ours = decodeGrid(latest.message);
  const problems = [];
  if (ours.x0 !== rest.origin[0] || ours.y0 !== rest.origin[1]) problems.push(`origin ${ours.x0},${ours.y0} vs ${rest.origin}`);
  if (ours.width !== rest.width || ours.height !== rest.height) problems.push(`size ${ours.width}x${ours.height} vs ${rest.width}x${rest.height}`);
  if (ours.resolution !== rest.resolution) problems.push(`resolution ${ours.resolution} vs ${rest.resolution}`);
  if (problems.length) return problems;
  const p = ours.fields.probability;
  let differing = 0;
  for (let i = 0; i < p.length; ++i) {
    const want = rest.data[i];
    const same = want === null ? Number.isNaN(p[i]) : Math.round(p[i] * 1e4) / 1e4 === want;
    if (!same && differing++ < 5) problems.push(`cell ${i}: ${p[i]} vs ${want} (revision ${rest.revision})`);
  }
  if (differing > 5) problems.push(`... ${differing} cells differ`);
  return problems;
}

/** Differences between the scenes of a View and GET /api/v1/map. */
async function sceneDifferences(base, view, api = '/api/v1') {
  const map = await getJson(base, `${api}/map`);
  const problems = [];
  const elements = view.scenes.get('/map/elements') || new Map();
  if (elements.size !== map.elements.length) problems.push(`${elements.size} element entities for ${map.elements.length} elements`);
  for (const e of map.elements) {
    const entity = elements.get(e.id);
    if (!entity) {
      problems.push(`no entity for element ${e.id}`);
      continue;
    }
    const [line] = entity.lines;
    const points = line.points.map((q) => [q.x, q.y, q.z]);
    if (entity.lines.length !== 1 || line.type !== 2 || JSON.stringify(points) !== JSON.stringify([[...e.p0, 0], [...e.p1, 0]]))
      problems.push(`element ${e.id}: ${JSON.stringify(points)} vs ${JSON.stringify([e.p0, e.p1])}`);
    else if (hexColor(line.color) !== kElementColors[e.origin]) problems.push(`element ${e.id} (${e.origin}): colour ${hexColor(line.color)}`);
  }
  const plan = view.scenes.get('/map/plan') || new Map();
  if (plan.size !== map.objects.length) problems.push(`${plan.size} plan entities for ${map.objects.length} objects`);
  for (const o of map.objects) {
    const entity = plan.get(o.id);
    if (!entity) {
      problems.push(`no entity for object ${o.id}`);
      continue;
    }
    const want = o.edges.flatMap((edge) => [[...edge.p0, 0], [...edge.p1, 0]]);
    const points = entity.lines[0].points.map((q) => [q.x, q.y, q.z]);
    if (JSON.stringify(points) !== JSON.stringify(want)) problems.push(`object ${o.id}: ${JSON.stringify(points)} vs ${JSON.stringify(want)}`);
    const category = o.attributes.includes('solid') ? 'solid' : o.attributes.includes('not_deformable') ? 'not_deformable' : 'other';
    if (hexColor(entity.lines[0].color) !== kObjectColors[category]) problems.push(`object ${o.id}: colour ${hexColor(entity.lines[0].color)}`);
  }
  return problems;
}

/** Differences between the poses and transforms of a View and GET /api/v1/robots. */
async function poseDifferences(base, view, api = '/api/v1') {
  const { robots } = await getJson(base, `${api}/robots`);
  const problems = [];
  if (robots.length === 0) problems.push('no robot yet');
  for (const r of robots.filter((robot) => robot.pose)) {
    const topic = `/robots/${r.id}/pose`;
    if (!view.topic(topic)) {
      problems.push(`${topic} not advertised`);
      continue;
    }
    const latest = view.latest.get(topic);
    if (!latest) {
      problems.push(`no ${topic} message`);
      continue;
    }
    const { pose, frame_id: frame } = latest.message;
    if (frame !== 'map' || pose.position.x !== r.pose.x || pose.position.y !== r.pose.y || angleDiff(yaw(pose.orientation), r.pose.theta) > 1e-12)
      problems.push(`${topic}: ${JSON.stringify(pose)} vs ${JSON.stringify(r.pose)}`);
    const t = view.transforms.get(`${r.id}/base_link`);
    if (!t || t.parent_frame_id !== 'map' || t.translation.x !== r.pose.x || t.translation.y !== r.pose.y ||
        angleDiff(yaw(t.rotation), r.pose.theta) > 1e-12)
      problems.push(`/tf ${r.id}/base_link: ${JSON.stringify(t)} vs ${JSON.stringify(r.pose)}`);
  }
  return problems;
}

/** Differences between the log of a View and GET /api/v1/decisions (every decision, in order). */
async function logDifferences(base, view, api = '/api/v1') {
  const { decisions } = await getJson(base, `${api}/decisions?limit=10000`);
  const ours = new Map();
  for (const log of view.logs) {
    const m = /^decision (\d+): (\S+)/.exec(log.message);
    if (m) ours.set(Number(m[1]), { action: m[2], rule: log.name, level: log.level });
  }
  const problems = [];
  if (decisions.length === 0) problems.push('no decision yet');
  for (const d of decisions) {
    const got = ours.get(d.seq);
    if (!got) problems.push(`decision ${d.seq} not logged`);
    else if (got.action !== d.action || got.rule !== d.rule || got.level !== (d.fallback ? 3 : 2))
      problems.push(`decision ${d.seq}: ${JSON.stringify(got)} vs ${d.action} ${d.rule}`);
  }
  return problems;
}

/** The grid fields of a View's latest message on `topic` against the float32 tiles of GET /api/v1/grid/tiles. */
async function compareWithTiles(base, view, topic, layers) {
  const grid = decodeGrid(view.latest.get(topic).message);
  const listing = await getJson(base, '/api/v1/grid/tiles');
  const t = listing.tile_size_cells;
  const cx0 = Math.round(grid.x0 / grid.resolution), cy0 = Math.round(grid.y0 / grid.resolution);
  let cells = 0;
  for (const [tx, ty] of listing.tiles) {
    for (const [field, layer] of Object.entries(layers)) {
      const res = await fetch(`${base}/api/v1/grid/tiles/${layer}/${tx}/${ty}`);
      assert.equal(res.status, 200, `tile ${layer}/${tx}/${ty}`);
      const tile = new Float32Array(await res.arrayBuffer());
      for (let iy = 0; iy < t; ++iy) {
        for (let ix = 0; ix < t; ++ix) {
          const x = tx * t + ix - cx0, y = ty * t + iy - cy0;
          assert.ok(x >= 0 && x < grid.width && y >= 0 && y < grid.height, `tile ${tx},${ty} lies outside the ${topic} grid`);
          const ours = grid.fields[field][y * grid.width + x], want = tile[iy * t + ix];
          if (!Object.is(ours, want) && !(Number.isNaN(ours) && Number.isNaN(want)))
            assert.fail(`${topic} ${field} at tile ${tx},${ty} cell ${ix},${iy}: ${ours} vs ${want}`);
          ++cells;
        }
      }
    }
  }
  return { tiles: listing.tiles.length, cells };
}

describe('a Foxglove client subscribed to every channel during a replay', () => {
  const ctx = {};

  before(async () => {
    ctx.dir = fs.mkdtempSync(path.join(os.tmpdir(), 'wm-foxglove-test-'));
    ctx.wmd = await startWmd({ wmdPath, repo, dir: ctx.dir, extraArgs: ['--no-shm'] });
    ctx.base = ctx.wmd.url;
    ctx.view = await View.open(`${ctx.base.replace('http', 'ws')}/foxglove`);
  });

  after(async () => {
    if (ctx.view) ctx.view.close();
    const stopped = ctx.wmd ? await ctx.wmd.stop() : { code: 0 };
    if (ctx.dir) fs.rmSync(ctx.dir, { recursive: true, force: true });
    // A crash, or a sanitizer's report at exit, fails the suite.
    assert.equal(stopped.code, 0, `wmd stopped with ${stopped.code ?? stopped.signal}:\n${ctx.wmd?.output()}`);
  });

  test('the server says who it is and advertises its channels with schemas compatible with Foxglove\'s', () => {
    const info = ctx.view.serverInfo;
    assert.equal(info.op, 'serverInfo');
    assert.deepEqual(info.capabilities, []);
    assert.equal(info.metadata.api, '/api/v1');
    assert.match(info.sessionId, /^[0-9a-f]{16}$/);
    const topics = Object.fromEntries([...ctx.view.channels.values()].map((c) => [c.topic, c]));
    const expected = {
      '/grid': 'foxglove.Grid', '/grid/ds': 'foxglove.Grid', '/map/elements': 'foxglove.SceneUpdate',
      '/map/plan': 'foxglove.SceneUpdate', '/tf': 'foxglove.FrameTransforms', '/decisions': 'foxglove.Log',
    };
    for (const [topic, schemaName] of Object.entries(expected)) {
      assert.ok(topics[topic], `${topic} advertised`);
      assert.equal(topics[topic].schemaName, schemaName);
      assert.equal(topics[topic].encoding, 'json');
      assert.equal(topics[topic].schemaEncoding, 'jsonschema');
      // Every property we describe is Foxglove's, with Foxglove's JSON type; the grid's bytes are base64.
      const problems = [];
      const compatible = (ours, official, where) => {
        if (!official) return problems.push(`${where}: not in Foxglove's ${schemaName}`);
        if (ours.type && official.type && ours.type !== official.type) problems.push(`${where}: ${ours.type} vs ${official.type}`);
        if (ours.type === 'integer' && !official.type && !(official.oneOf || []).every((o) => Number.isInteger(o.const)))
          problems.push(`${where}: integer vs ${JSON.stringify(official)}`);
        if (ours.contentEncoding !== official.contentEncoding) problems.push(`${where}: contentEncoding ${ours.contentEncoding}`);
        for (const [key, value] of Object.entries(ours.properties || {})) compatible(value, (official.properties || {})[key], `${where}.${key}`);
        if (ours.items) compatible(ours.items, official.items, `${where}[]`);
      };
      compatible(JSON.parse(topics[topic].schema), officialSchema(schemaName), topic);
      assert.deepEqual(problems, []);
    }
  });

  test('after a floor plan and two robots\' replays, every channel equals the REST API', async () => {
    const view = ctx.view;
    await putJson(ctx.base, '/api/v1/floorplan', JSON.parse(fs.readFileSync(planPath, 'utf8')));
    const first = await replay(ctx.base);
    const second = await replay(ctx.base, ['--offset', '40,0', '--source', 'robot-2']);
    ctx.replaySeconds = first.seconds + second.seconds;

    await waitFor('the grid', () => gridDifferences(ctx.base, view));
    await waitFor('the scenes', () => sceneDifferences(ctx.base, view));
    await waitFor('the poses', () => poseDifferences(ctx.base, view));
    await waitFor('the decision log', () => logDifferences(ctx.base, view));
    // Bit for bit against the grid's float32 tiles, the Dempster–Shafer layers too.
    const bayes = await compareWithTiles(ctx.base, view, '/grid', { probability: 'bayes' });
    await waitFor('the DS grid', async () => {
      try {
        await compareWithTiles(ctx.base, view, '/grid/ds',
          { belief: 'ds_belief', plausibility: 'ds_plausibility', conflict: 'ds_conflict' });
        return [];
      } catch (error) {
        return [String(error.message)];
      }
    });
    assert.ok(bayes.cells > 0);
    assert.deepEqual(view.invalid, [], 'every message valid against Foxglove\'s schema');
    assert.deepEqual(view.statuses.map((s) => s.status.message), [], 'no status message (nothing refused, nothing dropped)');
    // Two robots, each with a channel of its own, advertised when first heard of.
    assert.ok(view.topic('/robots/robot-2/pose'));
    // The scene sent the whole map once per topic (deletion of all, then every entity), then only changes.
    const updates = view.sceneMessages.get('/map/elements');
    assert.ok(updates[0].replaceAll);
    assert.ok(updates.slice(1).some((u) => !u.replaceAll && u.entities < view.scenes.get('/map/elements').size),
      'later updates carry only the changed elements');
    const grid = view.latest.get('/grid');
    console.log(`# Foxglove: ${[...view.counts].map(([t, n]) => `${t} ${n}`).join(', ')} messages in `
      + `${ctx.replaySeconds.toFixed(2)} s of replay; last /grid ${grid.bytes} bytes `
      + `(${decodeGrid(grid.message).width}x${decodeGrid(grid.message).height} cells), ${bayes.tiles} tiles compared`);
  });

  test('a new subscriber gets the current state at once, and an unsubscribed channel goes quiet', async () => {
    const late = await View.open(`${ctx.base.replace('http', 'ws')}/foxglove`);
    try {
      await waitFor('the late grid', () => gridDifferences(ctx.base, late));
      await waitFor('the late scenes', () => sceneDifferences(ctx.base, late));
      await waitFor('the late poses', () => poseDifferences(ctx.base, late));
      const { decisions } = await getJson(ctx.base, '/api/v1/decisions?limit=10000');
      await waitFor('the last 100 decisions', async () => (late.logs.length === Math.min(100, decisions.length) ? [] : [`${late.logs.length} logs`]));
      const last = /^decision (\d+)/.exec(late.logs.at(-1).message);
      assert.equal(Number(last[1]), decisions.at(-1).seq, 'the initial log ends with the last decision');

      // Unsubscribe the grid, then change it: the grid channel stays quiet while the others follow.
      const gridSubscription = [...late.subscriptions].find(([, c]) => c.topic === '/grid')[0];
      late.client.unsubscribe(gridSubscription);
      await new Promise((r) => setTimeout(r, 300));
      const gridMessages = late.counts.get('/grid');
      await replay(ctx.base, ['--offset', '0,40', '--source', 'robot-3', '--limit', '10']);
      await waitFor('the late poses after a third robot', () => poseDifferences(ctx.base, late));
      await new Promise((r) => setTimeout(r, 1200));  // more than two grid periods
      assert.equal(late.counts.get('/grid'), gridMessages, 'no grid message after unsubscribing');
      assert.ok(ctx.view.counts.get('/grid') > 0);
      await waitFor('the first client\'s grid', () => gridDifferences(ctx.base, ctx.view));
      assert.deepEqual(late.invalid, []);
    } finally {
      late.close();
    }
  });

  test('bad client messages are answered with error statuses, not a closed connection', async () => {
    const view = await View.open(`${ctx.base.replace('http', 'ws')}/foxglove`);
    try {
      view.ws.send('not json');
      view.ws.send(JSON.stringify({ op: 'subscribe', subscriptions: [{ id: 900, channelId: 424242 }] }));
      const [subscription, channel] = [...view.subscriptions][0];
      view.ws.send(JSON.stringify({ op: 'subscribe', subscriptions: [{ id: subscription, channelId: channel.id }] }));
      view.ws.send(JSON.stringify({ op: 'getParameters', parameterNames: [] }));
      await waitFor('four error statuses', async () => (view.statuses.length >= 4 ? [] : [`${view.statuses.length} statuses`]));
      const messages = view.statuses.map((s) => s.status.message);
      assert.match(messages[0], /bad message: not JSON/);
      assert.match(messages[1], /no channel 424242/);
      assert.match(messages[2], new RegExp(`subscription id ${subscription} is in use`));
      assert.match(messages[3], /'getParameters' is not supported/);
      assert.deepEqual(view.statuses.map((s) => s.status.level), [2, 2, 2, 2], JSON.stringify(view.statuses));
      assert.equal(view.ws.readyState, WebSocket.OPEN);
    } finally {
      view.close();
    }
  });
});

describe('a token, a small queue and a subscriber that stops reading', () => {
  const ctx = {};
  const token = 'foxglove-test-token';

  before(async () => {
    ctx.dir = fs.mkdtempSync(path.join(os.tmpdir(), 'wm-foxglove-slow-'));
    ctx.wmd = await startWmd({
      wmdPath, repo, dir: ctx.dir, extraArgs: ['--no-shm', '--token', token, '--foxglove-queue-kb', '64'],
    });
    ctx.base = ctx.wmd.url;
    ctx.ws = `${ctx.base.replace('http', 'ws')}/foxglove`;
  });

  after(async () => {
    const stopped = ctx.wmd ? await ctx.wmd.stop() : { code: 0 };
    if (ctx.dir) fs.rmSync(ctx.dir, { recursive: true, force: true });
    assert.equal(stopped.code, 0, `wmd stopped with ${stopped.code ?? stopped.signal}:\n${ctx.wmd?.output()}`);
  });

  test('upgrades without the subprotocol or the token are refused with JSON errors', async () => {
    const plain = await fetch(`${ctx.base}/foxglove`);
    assert.equal(plain.status, 426);
    assert.match((await plain.json()).detail, /Sec-WebSocket-Protocol: foxglove\.websocket\.v1/);
    const noToken = await refusal(ctx.ws, [kSubprotocol]);
    assert.equal(noToken.status, 401);
    assert.equal(noToken.body.error, 'unauthorized');
    const noProtocol = await refusal(`${ctx.ws}?token=${token}`, []);
    assert.equal(noProtocol.status, 400);
    assert.equal(noProtocol.body.error, 'subprotocol_required');
    const otherProtocol = await refusal(ctx.ws, ['foxglove.websocket.v2'], { authorization: `Bearer ${token}` });
    assert.equal(otherProtocol.status, 400);
    const crossSite = await refusal(`${ctx.ws}?token=${token}`, [kSubprotocol], { origin: 'http://evil.example' });
    assert.equal(crossSite.status, 403);
    // With the token, in the header or the query: connected, and the subprotocol answered.
    for (const [url, headers] of [[`${ctx.ws}?token=${token}`, {}], [ctx.ws, { authorization: `Bearer ${token}` }]]) {
      const view = await View.open(url, { headers });
      assert.equal(view.ws.protocol, kSubprotocol);
      view.close();
    }
  });

  test('a paused subscriber does not hold up a replay; it falls behind and then gets the current state', async () => {
    // The same replay rate-bound (30 scans/s) without and with the paused client: ingest must not wait for it.
    const without = await replay(ctx.base, ['--rate', '30', '--source', 'alone'], token);
    const slow = await View.open(`${ctx.ws}?token=${token}`);
    await waitFor('the first grid', async () => (slow.latest.get('/grid') ? [] : ['no grid']));
    slow.ws.pause();  // stops reading the socket: the kernel's buffers fill, then the server's queue for it
    const pausedAt = Date.now();
    const withPaused = [];
    for (const [i, offset] of ['40,0', '0,40', '40,40'].entries())
      withPaused.push(await replay(ctx.base, ['--rate', '30', '--offset', offset, '--source', `paused-${i}`], token));
    const seconds = withPaused.reduce((sum, r) => sum + r.seconds, 0) / withPaused.length;
    console.log(`# replay of the excerpt at 30 scans/s: ${without.seconds.toFixed(2)} s alone, ${seconds.toFixed(2)} s `
      + 'on average with a paused Foxglove subscriber');
    assert.ok(seconds < 2 * without.seconds + 3, `${seconds} s with a paused subscriber, ${without.seconds} s without`);
    // Its queue overflows only once the kernel's socket buffers (megabytes on loopback) are full: grid messages fill
    // them at 2 Hz at most, so replay on for 8 s in all, however fast or slow this server runs (a sanitizer build on
    // a loaded machine sends fewer grids per replay).
    for (let i = 0; Date.now() - pausedAt < 8000 && i < 20; ++i) {
      const offset = `${(i % 2) * 40},${(Math.floor(i / 2) % 2) * 40}`;  // over the same four places: the grid stays as big
      await replay(ctx.base, ['--rate', '30', '--offset', offset, '--source', `more-${i}`], token);
    }

    const before = slow.order;
    slow.ws.resume();
    await waitFor('the fell-behind warning', async () => (slow.statuses.some((s) => s.order > before) ? [] : ['no status']));
    const warning = slow.statuses.find((s) => s.order > before);
    assert.equal(warning.status.level, 1);
    const dropped = Number(/fell behind: (\d+) messages were dropped/.exec(warning.status.message)[1]);
    assert.ok(dropped > 0, warning.status.message);
    // After the warning: the whole scene again (a deletion of all first), and the grid as it is now.
    await waitFor('the current state after the warning', async () => {
      const scene = (slow.sceneMessages.get('/map/elements') || []).find((m) => m.order > warning.order);
      const grid = slow.latest.get('/grid');
      if (!scene || !grid || grid.order < warning.order) return ['not yet'];
      return [...(scene.replaceAll ? [] : ['the first scene after it is not whole']),
        ...await gridDifferences(ctx.base, slow), ...await sceneDifferences(ctx.base, slow),
        ...await poseDifferences(ctx.base, slow)];
    });
    assert.deepEqual(slow.invalid, []);
    slow.close();
  });
});

describe('a Foxglove client of another map (/foxglove?map=ID)', () => {
  const ctx = {};
  const api = '/api/v1/maps/floor2';

  before(async () => {
    ctx.dir = fs.mkdtempSync(path.join(os.tmpdir(), 'wm-foxglove-maps-test-'));
    ctx.wmd = await startWmd({ wmdPath, repo, dir: ctx.dir, extraArgs: ['--no-shm'] });
    ctx.base = ctx.wmd.url;
    ctx.ws = `${ctx.base.replace('http', 'ws')}/foxglove`;
    await postJson(ctx.base, '/api/v1/maps', { id: 'floor2' });
  });

  after(async () => {
    const stopped = ctx.wmd ? await ctx.wmd.stop() : { code: 0 };
    if (ctx.dir) fs.rmSync(ctx.dir, { recursive: true, force: true });
    assert.equal(stopped.code, 0, `wmd stopped with ${stopped.code ?? stopped.signal}:\n${ctx.wmd?.output()}`);
  });

  test('it follows that map only, every channel equal to the map\'s REST API; a delete tells it and closes it', async () => {
    const floor2 = await View.open(`${ctx.ws}?map=floor2`);
    const main = await View.open(ctx.ws);
    const again = await View.open(`${ctx.ws}?map=floor2`);  // a second client of the same map's bridge
    assert.equal(floor2.serverInfo.metadata.map, 'floor2');
    assert.equal(floor2.serverInfo.metadata.api, api);
    assert.equal(floor2.serverInfo.sessionId, (await getJson(ctx.base, `${api}/map`)).server_instance);
    assert.notEqual(floor2.serverInfo.sessionId, main.serverInfo.sessionId);

    await putJson(ctx.base, `${api}/floorplan`, JSON.parse(fs.readFileSync(planPath, 'utf8')));
    await replay(ctx.base, ['--map', 'floor2']);
    for (const view of [floor2, again]) {
      await waitFor('the grid', () => gridDifferences(ctx.base, view, api));
      await waitFor('the scenes', () => sceneDifferences(ctx.base, view, api));
      await waitFor('the poses', () => poseDifferences(ctx.base, view, api));
      await waitFor('the decision log', () => logDifferences(ctx.base, view, api));
      assert.deepEqual(view.invalid, []);
    }
    assert.ok(floor2.scenes.get('/map/elements').size > 0);
    // The default map heard nothing: its client has an empty scene and no robot.
    await waitFor('the default map\'s scenes', () => sceneDifferences(ctx.base, main));
    assert.equal(main.scenes.get('/map/elements').size, 0);
    assert.equal(main.topic('/robots/intel/pose'), undefined);
    assert.ok(floor2.topic('/robots/intel/pose') || floor2.transforms.size > 0);

    // Deleted while its clients follow it: each is told why, then closed; the default map's client stays.
    await request(ctx.base, 'DELETE', '/api/v1/maps/floor2');
    for (const view of [floor2, again]) {
      await view.closed;
      const last = view.statuses.at(-1);
      assert.equal(last?.status.level, 2);
      assert.match(last.status.message, /the map 'floor2' was deleted/);
    }
    assert.equal(main.ws.readyState, WebSocket.OPEN);
    main.close();
  });

  test('a bad or unknown map is refused before the upgrade with a JSON error', async () => {
    for (const [map, status] of [['Floor2', 400], ['-x', 400], ['a%2Fb', 400], ['..', 400], ['x'.repeat(33), 400],
      ['nosuchmap', 404], ['floor2', 404]]) {
      const refused = await refusal(`${ctx.ws}?map=${map}`, [kSubprotocol]);
      assert.equal(refused.status, status, `map=${map}`);
      assert.ok(refused.body.error, `map=${map}`);
    }
    // map=default is the server's own bridge.
    const main = await View.open(`${ctx.ws}?map=default`);
    assert.equal(main.serverInfo.metadata.api, '/api/v1');
    main.close();
  });
});
