// The changes in the building (GET /api/v1/changes) as the viewer shows them: what each looks like on the
// map, how the panel lists and words them, when to re-read them, and where the write token is kept.
// Pure: no DOM, so `node --test` checks it directly. World coordinates are metres.

/** The kinds of change the server lists, in the order the legend and the panel name them. */
export const kChangeKinds = ['wall_missing', 'wall_partly_missing', 'object_gone', 'object_moved', 'new_wall'];

/**
 * Colour, dash pattern [CSS px] and width [CSS px] of each kind, and its name for people. `under`: drawn as a
 * translucent halo beneath the observed elements (a new wall is an element: its own colour stays readable).
 */
export const kChangeStyles = {
  wall_missing: { color: '#ff2d2d', dash: [7, 5], width: 4, under: false, label: 'wall missing' },
  wall_partly_missing: { color: '#ff8c1a', dash: [7, 5], width: 4, under: false, label: 'wall partly missing' },
  object_gone: { color: '#e0119d', dash: null, width: 3, under: false, label: 'object gone' },
  object_moved: { color: '#a66bff', dash: null, width: 2.5, under: false, label: 'object moved' },
  new_wall: { color: '#21d45e', dash: null, width: 8, under: true, label: 'new wall' },
};

const kUnknownStyle = { color: '#bbbbbb', dash: [2, 4], width: 2, under: false, label: 'change' };

/** The style of a change kind; an unknown kind (a newer server) gets a neutral dotted grey under its own name. */
export function changeStyle(kind) {
  return kChangeStyles[kind] || { ...kUnknownStyle, label: String(kind ?? 'change').replaceAll('_', ' ') };
}

const finitePoint = (p) => Array.isArray(p) && Number.isFinite(p[0]) && Number.isFinite(p[1]);

/**
 * Where a moved object was drawn: world point `p` of the object as it stands now (at `pose`), carried back by
 * the move `movedBy` ({dx, dy, dtheta}, world frame): the drawn pose is (x − dx, y − dy, θ − dθ), so the point
 * is (pose − d) + R(−dθ)(p − pose).
 */
export function drawnPoint(p, pose, movedBy) {
  const c = Math.cos(-(movedBy.dtheta || 0)), s = Math.sin(-(movedBy.dtheta || 0));
  const rx = p[0] - pose.x, ry = p[1] - pose.y;
  return [pose.x - (movedBy.dx || 0) + c * rx - s * ry, pose.y - (movedBy.dy || 0) + s * rx + c * ry];
}

/**
 * What to draw for a change: {kind, color, dash, width, under, segments: [[p0, p1], ...], ghost: [[p0, p1], ...]}
 * in world coordinates (dash and width in CSS px), or null when the change has no finite geometry.
 * - wall_missing, wall_partly_missing: the stretch p0–p1 (dashed, over the drawn wall);
 * - new_wall: the observed element p0–p1;
 * - object_gone: the object crossed out: both diagonals of its edges' bounding box (at least `crossPx` wide),
 *   a cross at its pose p0 when its edges are not known;
 * - object_moved: an arrow from the drawn pose p0 to the pose p1 (head `headPx` long, shaft at least as long),
 *   and, when the object's edges are known, the outline where it was drawn as `ghost` (drawn dashed).
 * `object` is the object as the map has it ({pose, edges}) or undefined; `pxM` is one CSS pixel in metres.
 */
export function changeShapes(change, object, { pxM = 0.05, headPx = 9, crossPx = 14 } = {}) {
  if (!change || !finitePoint(change.p0) || !finitePoint(change.p1)) return null;
  const style = changeStyle(change.kind);
  const shape = {
    kind: change.kind, color: style.color, dash: style.dash, width: style.width, under: style.under, segments: [], ghost: [],
  };
  const [p0, p1] = [change.p0, change.p1];
  const edges = (object?.edges || []).filter((e) => finitePoint(e.p0) && finitePoint(e.p1));
  if (change.kind === 'object_gone') {
    let box = null;
    for (const e of edges) {
      for (const p of [e.p0, e.p1]) {
        box = box ? [Math.min(box[0], p[0]), Math.min(box[1], p[1]), Math.max(box[2], p[0]), Math.max(box[3], p[1])]
          : [p[0], p[1], p[0], p[1]];
      }
    }
    const half = (crossPx / 2) * pxM;
    if (!box) box = [p0[0], p0[1], p0[0], p0[1]];
    const cx = (box[0] + box[2]) / 2, cy = (box[1] + box[3]) / 2;
    const hx = Math.max((box[2] - box[0]) / 2, half), hy = Math.max((box[3] - box[1]) / 2, half);
    shape.segments.push([[cx - hx, cy - hy], [cx + hx, cy + hy]], [[cx - hx, cy + hy], [cx + hx, cy - hy]]);
    return shape;
  }
  if (change.kind === 'object_moved') {
    const dx = p1[0] - p0[0], dy = p1[1] - p0[1];
    const length = Math.hypot(dx, dy);
    const head = headPx * pxM;
    // A move shorter than the head (or a turn in place) still shows: the shaft is at least a head long.
    const [ux, uy] = length > 1e-9 ? [dx / length, dy / length] : [1, 0];
    const start = length >= head ? p0 : [p1[0] - ux * head, p1[1] - uy * head];
    shape.segments.push([start, p1]);
    const back = [-ux * head, -uy * head];
    const side = 0.45;
    shape.segments.push([p1, [p1[0] + back[0] - uy * head * side, p1[1] + back[1] + ux * head * side]]);
    shape.segments.push([p1, [p1[0] + back[0] + uy * head * side, p1[1] + back[1] - ux * head * side]]);
    const pose = object?.pose;
    if (change.moved_by && pose && Number.isFinite(pose.x) && Number.isFinite(pose.y)) {
      for (const e of edges) shape.ghost.push([drawnPoint(e.p0, pose, change.moved_by), drawnPoint(e.p1, pose, change.moved_by)]);
    }
    return shape;
  }
  shape.segments.push([p0, p1]);
  return shape;
}

/** The world point to centre the view on for a change: the middle of p0–p1. */
export function changeCentre(change) {
  if (!change || !finitePoint(change.p0) || !finitePoint(change.p1)) return null;
  return [(change.p0[0] + change.p1[0]) / 2, (change.p0[1] + change.p1[1]) / 2];
}

// ---- the list --------------------------------------------------------------------------------------------

/** A share as a whole percentage, '–' when unknown. */
export function percent(share) {
  return Number.isFinite(share) ? `${Math.round(share * 100)} %` : '–';
}

/** One line of numbers for a change: length (or distance moved) and confidence. */
export function changeSummary(change) {
  const length = Number.isFinite(change.length) ? `${change.length.toFixed(2)} m` : '–';
  const what = change.kind === 'object_moved' ? `moved ${length}` : length;
  return `${what} · confidence ${percent(change.confidence)}`;
}

/** The evidence behind a change, in words (for the expanded row), or '' when it carries none. */
export function changeEvidence(change) {
  const parts = [];
  const e = change.evidence;
  if (e) {
    parts.push(`edge ${Number.isFinite(e.length) ? e.length.toFixed(2) : '–'} m: seen ${percent(e.observed)}, ` +
      `seen through ${percent(e.seen_through)}, backed ${percent(e.backed)}; ` +
      `beams through ${e.beams_through ?? '–'}, ended ${e.beams_ended ?? '–'}`);
  }
  const m = change.moved_by;
  if (m) {
    const f = (v, d = 3) => (Number.isFinite(v) ? v.toFixed(d) : '–');
    parts.push(`dx ${f(m.dx)} m, dy ${f(m.dy)} m, dθ ${f(Number.isFinite(m.dtheta) ? (m.dtheta * 180) / Math.PI : NaN, 2)}°, ` +
      `σ ${f(m.sigma_xy)} m`);
  }
  if (Number.isFinite(change.support)) parts.push(`${change.support} observations`);
  if (change.rule) parts.push(`rule ${change.rule}`);
  return parts.join(' · ');
}

/**
 * The viewer's copy of GET /api/v1/changes: the list in the server's order, the map version and grid revision
 * it was made at, and which change a request is under way for.
 */
export class ChangeList {
  constructor() {
    this.version = null;
    this.gridRevision = null;
    this.items = [];
    this.byId = new Map();
    this.revision = 0;   // bumped on every load, so drawings know when to rebuild
    this.busy = null;    // {id, verdict} of the request under way, or {undo: true}
  }

  /** Replaces the list by an answer; entries without an id are left out. Returns true when anything differs. */
  load(answer) {
    const items = (answer?.changes || []).filter((c) => c && typeof c.id === 'string');
    const same = this.version === (answer?.version ?? null) && this.gridRevision === (answer?.grid_revision ?? null) &&
      items.length === this.items.length && items.every((c, i) => JSON.stringify(c) === JSON.stringify(this.items[i]));
    this.version = answer?.version ?? null;
    this.gridRevision = answer?.grid_revision ?? null;
    if (same) return false;
    this.items = items;
    this.byId = new Map(items.map((c) => [c.id, c]));
    this.revision++;
    return true;
  }

  get size() {
    return this.items.length;
  }

  get(id) {
    return this.byId.get(id);
  }

  /** How many of each kind: {wall_missing: 2, ...} (kinds with none left out). */
  countsByKind() {
    const counts = {};
    for (const c of this.items) counts[c.kind] = (counts[c.kind] || 0) + 1;
    return counts;
  }
}

/**
 * Words for a failed accept, reject or undo (an ApiError-like {status, code, detail, message}), for the panel:
 * what went wrong and what to do about it.
 */
export function decisionErrorText(error, what) {
  const status = error?.status;
  const detail = error?.detail ? `: ${error.detail}` : '';
  if (status === 401) return `${what}: 401 not authorised${detail}. Enter the server's token above.`;
  if (status === 403) return `${what}: 403 forbidden${detail}`;
  if (status === 404) return `${what}: 404 no longer listed${detail}. The list was reloaded.`;
  if (status === 409) return `${what}: 409 ${error.code || 'conflict'}${detail}`;
  if (Number.isFinite(status)) return `${what}: ${status} ${error.code || 'error'}${detail}`;
  return `${what}: ${error?.message || String(error)}`;
}

// ---- when to re-read -------------------------------------------------------------------------------------

/**
 * Decides when to re-read the list: `mark()` says something may have changed (a new map version, a scan, a
 * change event), `due(now)` says whether to fetch now: marked, none under way, and at least `minMs` since the
 * last fetch started (`force` skips that wait). `started(now)` / `finished()` bracket each fetch; a mark that
 * arrives during a fetch is kept for the next one.
 */
export class RefreshThrottle {
  constructor(minMs = 3000) {
    this.minMs = minMs;
    this.dirty = true;
    this.forced = false;
    this.inFlight = false;
    this.lastStart = -Infinity;
  }

  mark(force = false) {
    this.dirty = true;
    this.forced ||= force;
  }

  due(now) {
    if (!this.dirty || this.inFlight) return false;
    return this.forced || now - this.lastStart >= this.minMs;
  }

  started(now) {
    this.inFlight = true;
    this.dirty = false;
    this.forced = false;
    this.lastStart = now;
  }

  finished() {
    this.inFlight = false;
  }
}

// ---- the write token -------------------------------------------------------------------------------------

/** The sessionStorage key of the write token. */
export const kTokenKey = 'worldmodel.token';

/**
 * The token for writes: the one stored in this tab's session, else a `?token=` given to the page (the same one
 * the events WebSocket uses), else ''. `storage` is sessionStorage or a stand-in; it may be missing or throw.
 */
export function loadToken(storage, search = '') {
  try {
    const stored = storage?.getItem(kTokenKey);
    if (stored) return stored;
  } catch {
    // storage blocked: fall back to the page's parameter
  }
  return new URLSearchParams(search).get('token') ?? '';
}

/** Keeps `token` for this tab's session (an empty one removes it). Returns false when storage refused. */
export function saveToken(storage, token) {
  try {
    if (token) storage.setItem(kTokenKey, token);
    else storage.removeItem(kTokenKey);
    return true;
  } catch {
    return false;
  }
}
