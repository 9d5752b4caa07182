// The viewer's wiring. Data flow:
//   REST sync (map + health, grid layers) on load, on every (re)connect, on a missed event and on "resync";
//   WebSocket events afterwards: "update" → model upserts + highlights + feed, "scan" → robot pose/points and
//   a dirty grid region (re-fetched by bbox, throttled), "floorplan" → map reload, "rules" → status.
// The changes in the building (GET /api/v1/changes) are re-read when the map's version moves, a scan came in or a
// change was decided, at most every 3 s (at once after a decision); Accept, Reject and Undo post with the token.
// Events that arrive while a sync is running are buffered and applied after it (updates at or below the synced
// map version are skipped, the rest are idempotent upserts).

import { Api, ApiError, apiBaseFromLocation, EventStream, eventsUrl, mapFromLocation } from './api.js';
import {
  changeCentre, ChangeList, decisionErrorText, loadToken, RefreshThrottle, saveToken,
} from './changes.js';
import { DrivePanel } from './drive.js';
import { RateMeter } from './geometry.js';
import { GridLayers } from './grid_layers.js';
import { MapView } from './map_view.js';
import { objectOfEdge, WorldModel } from './model.js';
import {
  ChangesPanel, DecisionFeed, renderDetails, renderHistory, renderLegend, StatusPanel, fmt,
} from './panels.js';

const $ = (id) => document.getElementById(id);

const api = new Api(apiBaseFromLocation(window.location), mapFromLocation(window.location));
const model = new WorldModel();
const status = new StatusPanel();
const rates = { events: new RateMeter(), scans: new RateMeter(), decisions: new RateMeter() };

const state = {
  syncing: false,
  syncAgain: false,
  syncAgainGrid: false,
  syncAgainFull: false,
  buffered: [],
  syncs: 0,
  dropBuffered: false,  // a resync was asked for during a sync: its buffered events wait for that one
  deltaSyncs: 0,  // syncs that fetched only what changed (GET /api/v1/map?since=)
  ready: false,
  connection: 'connecting',
  lastEventSeq: null,
  lastDecision: null,
  decisionsSeen: 0,
  selection: null,
  historyToken: 0,
  historyTimer: null,
  lastError: null,
};

const grid = new GridLayers(api, {
  onChange: () => {
    view.autoFit();
    view.requestDraw();
    status.setGrid(grid.active, grid.summary(), grid.resolution);
  },
  onError: (message) => {
    const box = $('grid-error');
    box.hidden = !message;
    box.textContent = message || '';
  },
  createCanvas: (width, height) => {
    const c = document.createElement('canvas');
    c.width = width;
    c.height = height;
    return c;
  },
});

const view = new MapView($('map-canvas'), model, grid, {
  onPick: (target) => select(target),
  onView: () => updateReadout(),
});

const feed = new DecisionFeed((d) => select(targetOfDecision(d)));

const changes = new ChangeList();
view.changes = changes;
const changesState = {
  throttle: new RefreshThrottle(3000),
  loads: 0,          // answers of GET /api/v1/changes applied
  decisions: 0,      // accepts, rejects and undos this page made
  lastOutcome: null, // {verdict, change, version, seq} of the last one
  lastError: null,   // {status, text} of the last failed one
  token: '',
};
// sessionStorage may be refused (storage blocked for the site): the token then lives as long as the page.
const tokenStorage = (() => {
  try {
    return window.sessionStorage;
  } catch {
    return null;
  }
})();
changesState.token = loadToken(tokenStorage, window.location.search);
// The drive panel uses the same token (the drive WebSocket needs it when wmd runs with --token).
const drive = new DrivePanel(api, () => changesState.token);
const changesPanel = new ChangesPanel({
  token: changesState.token,
  onDecide: (id, verdict) => decideChange(id, verdict),
  onUndo: () => decideChange(null, 'undo'),
  onShow: (id) => view.centreOn(changeCentre(changes.get(id))),
  onToken: (token) => {
    changesState.token = token;
    saveToken(tokenStorage, token);
  },
});

// ---- sync ------------------------------------------------------------------------------------------------

/**
 * Re-reads the map and health (and, unless `withGrid` is false, every grid layer). Events arriving meanwhile
 * are buffered and applied afterwards, so none is lost and none is overwritten by an older snapshot.
 */
async function resync(reason, { withGrid = true, full = false } = {}) {
  if (state.syncing) {
    state.syncAgain = true;
    state.syncAgainGrid ||= withGrid;
    state.syncAgainFull ||= full;
    // The sync under way may read a map older than events after a hole; applied on it, they would move the
    // model's version past the hole and the next delta would skip it. The next sync brings them all.
    state.dropBuffered = true;
    return;
  }
  state.syncing = true;
  state.buffered = [];
  if (withGrid) grid.resyncAll();
  try {
    const [map, health, robots] = await Promise.all([syncMap(full), api.health(), api.robots().catch(() => null)]);
    if (robots) model.loadRobots(robots, performance.now());
    status.setHealth(health);
    status.setPlacement(map.placement);
    state.syncs++;
    state.lastSyncReason = reason;
    changesState.throttle.mark();
  } catch (error) {
    status.setHealth(null, error.message);
    state.lastError = error.message;
    setTimeout(() => resync('retry'), 2000);
  } finally {
    state.syncing = false;
  }
  const buffered = state.dropBuffered ? [] : state.buffered;
  state.buffered = [];
  state.dropBuffered = false;
  for (const event of buffered) handle(event);
  state.ready = state.syncs > 0;
  document.documentElement.dataset.viewerReady = state.ready ? '1' : '0';
  afterModelChange();
  view.autoFit();
  if (state.selection) select(state.selection);
  if (state.syncAgain) {
    const again = { withGrid: state.syncAgainGrid, full: state.syncAgainFull };
    state.syncAgain = false;
    state.syncAgainGrid = false;
    state.syncAgainFull = false;
    resync('requested during a sync', again);
  }
}

/**
 * Brings the model to the server's map: only what changed since the model's version when the server can tell
 * (GET /api/v1/map?since=), else (or when `full`) the whole map. Returns the answer applied (both carry the
 * placement).
 */
async function syncMap(full = false) {
  if (!full && model.version >= 0 && model.serverInstance) {
    try {
      const delta = await api.mapSince(model.version);
      if (model.applyDelta(delta)) {
        state.deltaSyncs++;
        return delta;
      }
    } catch (error) {
      // 410: older than the server remembers; 400: a version this server never had (another database).
      if (!(error instanceof ApiError) || (error.status !== 410 && error.status !== 400)) throw error;
    }
  }
  const map = await api.map();
  model.loadMap(map);
  return map;
}

// ---- changes in the building -----------------------------------------------------------------------------

/** Re-reads GET /api/v1/changes when it is due (see RefreshThrottle); `force` asks for it now. */
async function refreshChanges(force = false) {
  if (force) changesState.throttle.mark(true);
  if (!changesState.throttle.due(performance.now())) return;
  changesState.throttle.started(performance.now());
  try {
    const answer = await api.changes();
    if (changes.load(answer)) view.requestDraw();
    changesPanel.render(changes);
    changesPanel.setLoadError(null);
    changesState.loads++;
  } catch (error) {
    changesPanel.setLoadError(`GET /api/v1/changes: ${error.message}`);
  } finally {
    changesState.throttle.finished();
  }
  // A mark that came in during the read (a forced one: at once) is served on the next tick or now.
  if (changesState.throttle.forced) refreshChanges();
}

/** Accept or reject change `id`, or undo the last decision (`verdict` 'undo'); then the list and the map reload. */
async function decideChange(id, verdict) {
  if (changes.busy) return;
  const what = verdict === 'undo' ? 'undo' : `${verdict} ${id}`;
  changes.busy = { id, verdict };
  changesPanel.setBusy(true);
  changesPanel.setError(null);
  changesPanel.setMessage(`${what}…`);
  try {
    const answer = verdict === 'undo'
      ? await api.undoChange(changesState.token)
      : await api.decideChange(id, verdict, changesState.token);
    const done = { accept: 'accepted', reject: 'rejected', undo: 'undid' }[verdict];
    changesState.lastOutcome = { verdict, change: answer.change, version: answer.version, seq: answer.decision?.seq ?? null };
    changesState.lastError = null;
    changesState.decisions++;
    changesPanel.setMessage(`${done} ${answer.change}: decision #${answer.decision?.seq ?? '–'}` +
      `${answer.object ? `, drawn as ${answer.object}` : ''} (map version ${answer.version})`, verdict);
  } catch (error) {
    const status = error instanceof ApiError ? error.status : null;
    changesState.lastError = { status, text: decisionErrorText(error, what) };
    changesPanel.setError(changesState.lastError.text, status);
    changesPanel.setMessage('');
    if (status === 401) document.getElementById('changes-token').focus();
  } finally {
    changes.busy = null;
    changesPanel.setBusy(false);
  }
  // The plan may be another version now, or the list was out of date (404): read both again (the whole map:
  // see the "change" event).
  resync('change decided', { withGrid: false, full: true });
  refreshChanges(true);
}

// ---- events ----------------------------------------------------------------------------------------------

function onEvent(event) {
  if (Number.isFinite(event.seq)) state.lastEventSeq = event.seq;
  const now = performance.now();
  if (event.type === 'update' || event.type === 'scan') rates.events.add(now);
  if (event.type === 'scan') rates.scans.add(now);
  if (event.type === 'update' && Array.isArray(event.decisions)) rates.decisions.add(now, event.decisions.length);
  if (state.syncing && (event.type === 'update' || event.type === 'scan' || event.type === 'floorplan')) {
    state.buffered.push(event);
    return;
  }
  handle(event);
}

function handle(event) {
  const now = performance.now();
  switch (event.type) {
    case 'update': {
      const applied = model.applyUpdate(event, now);
      if (!applied) return;
      for (const d of applied.decisions) {
        view.highlightDecision(d, now);
        feed.push(d);
        state.lastDecision = { seq: d.seq, action: d.action, rule: d.rule, element: d.element, object: d.object };
        state.decisionsSeen++;
        status.noteDecision(d.seq);
      }
      if (state.selection && touchesSelection(applied)) refreshHistorySoon();
      changesState.throttle.mark();
      afterModelChange();
      break;
    }
    case 'change':
      // Someone (this page, wmctl, another viewer) accepted, rejected or undid a change. The "update" event
      // before it moved the model to the new map version but names no object the edit took out of the plan
      // (an accepted missing wall, an undone new wall), and a delta from that version would not either: the whole
      // map is read again (revalidated by its ETag).
      refreshChanges(true);
      resync(`change ${event.verdict ?? ''}`, { withGrid: false, full: true });
      break;
    case 'scan':
      changesState.throttle.mark();
      model.applyScan(event, now);
      grid.markDirty(event.grid_revision);
      view.requestDraw();
      if (state.selection?.kind === 'robot') renderDetails(state.selection, model);
      break;
    case 'robot':
      model.applyRobot(event.robot, now);
      view.requestDraw();
      if (state.selection?.kind === 'robot' && state.selection.id === event.robot?.id) renderDetails(state.selection, model);
      break;
    case 'floorplan':
      changesState.throttle.mark(true);
      resync('new floor plan', { withGrid: false });
      break;
    case 'rules':
      if (event.status) status.setRules(event.status);
      break;
    case 'placement':
      // The objects moved with the "update" event before this one; here the status says where and why.
      status.setPlacement(event.placement, event.explanation);
      break;
    default:
      break;  // hello, resync (handled by the stream's onGap), or something newer than this page
  }
}

function touchesSelection(applied) {
  const id = state.selection.id;
  const ids = (d) => [d.element, d.object, d.matched?.element, d.matched?.object, objectOfEdge(d.element)];
  return applied.decisions.some((d) => ids(d).includes(id)) || applied.removed.includes(id);
}

function afterModelChange() {
  status.setCounts(model);
  view.requestDraw();
  if (state.selection && state.selection.kind !== 'robot') renderDetails(state.selection, model);
}

// ---- selection -------------------------------------------------------------------------------------------

function targetOfDecision(d) {
  if (d.element && model.elements.has(d.element)) return { kind: 'element', id: d.element };
  const object = d.object || objectOfEdge(d.element) || d.matched?.object;
  if (object) return { kind: 'object', id: object, edge: objectOfEdge(d.element) ? d.element : undefined };
  return d.element ? { kind: 'element', id: d.element } : null;
}

function select(target) {
  if (target?.kind === 'robot') drive.select(target.id);  // a robot clicked on the map is the one to drive
  state.selection = target;
  view.selection = target;
  view.requestDraw();
  renderDetails(target, model);
  loadHistory();
}

async function loadHistory() {
  const target = state.selection;
  const token = ++state.historyToken;
  if (!target || target.kind === 'robot') {
    renderHistory(target, null, null);
    return;
  }
  renderHistory(target, null, null);
  try {
    const history = target.kind === 'object'
      ? await api.objectHistory(target.id, (model.objects.get(target.id)?.edges || []).map((e) => e.id))
      : await api.history(target.kind, target.id);
    if (token === state.historyToken) renderHistory(target, history, null);
  } catch (error) {
    if (token === state.historyToken) renderHistory(target, null, error.message);
  }
}

function refreshHistorySoon() {
  clearTimeout(state.historyTimer);
  state.historyTimer = setTimeout(loadHistory, 250);
}

// ---- status ----------------------------------------------------------------------------------------------

async function pollHealth() {
  try {
    status.setHealth(await api.health());
  } catch (error) {
    status.setHealth(null, error.message);
    return;
  }
  try {
    status.setNetwork(await api.network());
  } catch {
    // an older server without the endpoint: the row stays as it is
  }
}

function updateReadout() {
  const c = view.cursor;
  const scaleM = niceLength(120 / view.view.scale);
  $('map-readout').textContent = `${c ? `x ${fmt(c[0], 2)} y ${fmt(c[1], 2)} m · ` : ''}${fmt(view.view.scale, 1)} px/m · ▬ ${scaleM} m`;
}

function niceLength(m) {
  const p = 10 ** Math.floor(Math.log10(m));
  for (const f of [1, 2, 5, 10]) if (f * p >= m) return +(f * p).toPrecision(2);
  return m;
}

function tick() {
  const now = performance.now();
  status.setRate(rates.events.rate(now), rates.scans.rate(now), rates.decisions.rate(now));
  status.setSeq(state.lastEventSeq, state.syncs);
  status.setGrid(grid.active, grid.summary(), grid.resolution);
}

// ---- controls --------------------------------------------------------------------------------------------

$('layer-select').addEventListener('change', (e) => {
  grid.setActive(e.target.value);
  tick();
});
for (const [id, key] of [['toggle-grid', 'grid'], ['toggle-objects', 'objects'], ['toggle-elements', 'elements'],
  ['toggle-band', 'band'], ['toggle-robots', 'robots'], ['toggle-changes', 'changes']]) {
  const box = $(id);
  view.show[key] = box.checked;
  box.addEventListener('change', () => {
    view.show[key] = box.checked;
    view.requestDraw();
  });
}
$('fit-button').addEventListener('click', () => view.fit());

// ---- test hook -------------------------------------------------------------------------------------------

/** Read-only numbers for tests and curious people: what was drawn, and where things are on screen. */
const hook = {
  get ready() { return state.ready; },
  /** The map shown (?map=ID; "default" without it). */
  get map() { return api.mapId; },
  get connection() { return state.connection; },
  get syncs() { return state.syncs; },
  get deltaSyncs() { return state.deltaSyncs; },
  get lastEventSeq() { return state.lastEventSeq; },
  get lastDecision() { return state.lastDecision ? { ...state.lastDecision } : null; },
  get decisionsSeen() { return state.decisionsSeen; },
  get mapVersion() { return model.version; },
  /** Counts of what the last frame drew (objects, edges, elements, bands, robots, scanPoints, changes and
   *  changeKinds (per kind), grid). */
  get drawn() { return { ...view.drawn, changeKinds: { ...view.drawn.changeKinds } }; },
  /** Counts in the viewer's model (what the next frame will draw). */
  get counts() {
    return { objects: model.objects.size, edges: model.edgeCount(), elements: model.elements.size, robots: model.robots.size };
  },
  get grid() { return { active: grid.active, resolution: grid.resolution, tileSize: grid.tileSize, layers: grid.summary() }; },
  /** The layer's pixels as a digest (see GridLayers.digest). */
  gridDigest(name) { return grid.digest(name); },
  get highlights() { return [...view.highlights.values()].map(({ kind, id, action, seq }) => ({ kind, id, action, seq })); },
  get recentHighlights() { return view.recentHighlights.map((h) => ({ ...h })); },
  get selection() { return state.selection ? { ...state.selection } : null; },
  get view() { return { ...view.view }; },
  get apiBase() { return api.base; },
  /** The changes listed (GET /api/v1/changes as last read) and what this page decided about them. */
  get changes() {
    return {
      version: changes.version, gridRevision: changes.gridRevision, ids: changes.items.map((c) => c.id),
      kinds: changes.countsByKind(), loads: changesState.loads, decisions: changesState.decisions,
      busy: Boolean(changes.busy),
      lastOutcome: changesState.lastOutcome ? { ...changesState.lastOutcome } : null,
      lastError: changesState.lastError ? { ...changesState.lastError } : null,
    };
  },
  /** Page coordinates {x, y} of world point (x, y) [m]: where a click lands on it. */
  toClient(x, y) { return view.toClient(x, y); },
};
Object.defineProperty(window, 'worldmodelViewer', { value: Object.freeze(hook), writable: false, configurable: false });

// ---- start -----------------------------------------------------------------------------------------------

renderLegend();
updateReadout();
/** The map picker: the server's maps; choosing one loads the page on it, and the URL keeps it (?map=ID). */
async function fillMapPicker() {
  const picker = $('map-picker');
  try {
    const { maps } = await api.maps();
    picker.replaceChildren(...maps.map((m) => {
      const option = document.createElement('option');
      option.value = m.id;
      option.textContent = `${m.id}${m.plan_name ? ` (${m.plan_name})` : ''}`;
      option.selected = m.id === api.mapId;
      return option;
    }));
  } catch {
    picker.replaceChildren(new Option(api.mapId, api.mapId, true, true));
  }
  picker.addEventListener('change', () => {
    const params = new URLSearchParams(location.search);
    if (picker.value === 'default') params.delete('map'); else params.set('map', picker.value);
    const query = params.toString();
    location.search = query ? `?${query}` : '';
  });
}

fillMapPicker();
const stream = new EventStream(eventsUrl(api.base, new URLSearchParams(location.search).get('token') ?? '', api.mapId), {
  onEvent,
  onState: (s) => {
    state.connection = s;
    status.setConnection(s);
  },
  onGap: (reason) => resync(reason),
});
stream.start();
resync('page load');
setInterval(tick, 1000);
setInterval(() => refreshChanges(), 500);
setInterval(pollHealth, 5000);
