// The server's REST API and live-event WebSocket, as the viewer uses them. No state beyond the connection.

/** An answer of the server with a non-2xx status: `status`, the server's error `code` and `detail`. */
export class ApiError extends Error {
  constructor(path, status, code, detail) {
    super(`${path}: ${status} ${code}${detail ? ` (${detail})` : ''}`);
    this.status = status;
    this.code = code;
    this.detail = detail;
  }
}

/**
 * The API origin: `?api=http://host:port` when given (for serving the page from elsewhere during
 * development; the server must then allow it), else the page's own origin. Only http(s) URLs are accepted.
 */
export function apiBaseFromLocation(location) {
  const given = new URLSearchParams(location.search).get('api');
  if (given) {
    try {
      const url = new URL(given);
      if (url.protocol === 'http:' || url.protocol === 'https:') return url.origin;
    } catch {
      // fall through to the page's origin
    }
  }
  return location.origin;
}

/** Map ids: what the server accepts (1-32 of a-z, 0-9, '_' and '-', not starting with '_' or '-'). */
const MAP_ID = /^[a-z0-9][a-z0-9_-]{0,31}$/;

/** The map the page shows: `?map=ID` when it is a map id, else the default map. */
export function mapFromLocation(location) {
  const given = new URLSearchParams(location.search).get('map');
  return given && MAP_ID.test(given) ? given : 'default';
}

/**
 * A path of the API as one map's: "/api/v1/X" becomes "/api/v1/maps/{map}/X" (the default map's too, so that a list
 * such as the robots is that map's own), except the server's own resources (the maps, the network).
 */
export function mapPath(path, map = 'default') {
  const prefix = '/api/v1/';
  if (!path.startsWith(prefix)) return path;
  const first = path.slice(prefix.length).split(/[/?]/, 1)[0];
  if (first === 'maps' || first === 'network') return path;
  return `${prefix}maps/${encodeURIComponent(map)}/${path.slice(prefix.length)}`;
}

/**
 * ws(s)://host/api/v1/events (of the map `map`) for an http(s) API origin. A server started with --token needs the token on
 * the upgrade, and a browser cannot set headers on a WebSocket: a `token` given to the page
 * (`/?token=...`) is passed on as `?token=`.
 */
export function eventsUrl(base, token = '', map = 'default') {
  const url = new URL(mapPath('/api/v1/events', map), base);
  url.protocol = url.protocol === 'https:' ? 'wss:' : 'ws:';
  if (token) url.searchParams.set('token', token);
  return url.href;
}

export class Api {
  /** `map`: the map every request is about (the server's own resources aside). */
  constructor(base, map = 'default') {
    this.base = base;
    this.mapId = map;
  }

  url(path) {
    return new URL(mapPath(path, this.mapId), this.base).href;
  }

  /** The server's maps (GET /api/v1/maps). */
  maps() { return this.json('/api/v1/maps'); }

  async fetchOk(path, cache = 'no-store', init = {}) {
    const res = await fetch(this.url(path), { cache, ...init });
    if (!res.ok) {
      let code = 'http_error', detail = '';
      try {
        const body = await res.json();
        code = body.error || code;
        detail = body.detail || '';
      } catch {
        // not JSON: keep the status alone
      }
      throw new ApiError(path, res.status, code, detail);
    }
    return res;
  }

  async json(path, cache = 'no-store') {
    return (await this.fetchOk(path, cache)).json();
  }

  async text(path) {
    return (await this.fetchOk(path)).text();
  }

  async bytes(path) {
    return new Uint8Array(await (await this.fetchOk(path)).arrayBuffer());
  }

  /**
   * POST `body` as JSON, with `Authorization: Bearer <token>` when a token is given (a server started with
   * --token refuses writes without it: 401). Resolves with the answer's JSON; an ApiError otherwise.
   */
  async post(path, body, token = '') {
    const headers = { 'content-type': 'application/json' };
    if (token) headers.authorization = `Bearer ${token}`;
    const init = { method: 'POST', headers, body: JSON.stringify(body ?? {}) };
    return (await this.fetchOk(path, 'no-store', init)).json();
  }

  health() { return this.json('/api/v1/health'); }
  /** The differences between plan and building a person may accept or reject. */
  changes() { return this.json('/api/v1/changes'); }
  /** Accepts (`verdict` 'accept') or rejects ('reject') change `id`: {version, change, decision, object?}. */
  decideChange(id, verdict, token = '', source = 'viewer') {
    if (verdict !== 'accept' && verdict !== 'reject') throw new Error(`unknown verdict ${verdict}`);
    return this.post(`/api/v1/changes/${encodeURIComponent(id)}/${verdict}`, { source }, token);
  }
  /** Undoes the last accept or reject (409 when there is none). */
  undoChange(token = '', source = 'viewer') { return this.post('/api/v1/changes/undo', { source }, token); }
  network() { return this.json('/api/v1/network'); }
  /** The whole map. The browser keeps its last copy and revalidates it (ETag): an unchanged map costs a 304. */
  map() { return this.json('/api/v1/map', 'no-cache'); }
  robots() { return this.json('/api/v1/robots'); }
  /** What changed after `version` (GET /api/v1/map?since=); an ApiError with status 410 when the server cannot tell. */
  mapSince(version) { return this.json(`/api/v1/map?since=${encodeURIComponent(version)}`); }
  history(kind, id) {
    return this.json(`/api/v1/${kind === 'object' ? 'objects' : 'elements'}/${encodeURIComponent(id)}/history`);
  }

  /**
   * An object's history together with its edges' (at most 32): a decision names the edge it matched
   * (`element` "table-1/0") and the object, and a server that files it under the edge only would otherwise show
   * an object without history. Merged by seq, in order.
   */
  async objectHistory(id, edgeIds = []) {
    const parts = await Promise.all([
      this.history('object', id),
      ...edgeIds.slice(0, 32).map((edge) =>
        this.json(`/api/v1/decisions?since=0&limit=10000&element=${encodeURIComponent(edge)}`).catch(() => null)),
    ]);
    const bySeq = new Map();
    for (const part of parts) for (const d of part?.decisions || []) bySeq.set(d.seq, d);
    return { ...parts[0], decisions: [...bySeq.values()].sort((a, b) => a.seq - b.seq) };
  }
}

/**
 * The live-event WebSocket with reconnection (0.5 s doubling to 5 s). Tracks `seq`: the first numbered
 * message sets the baseline, an event numbered above last + 1 means events were missed and calls
 * `onGap(reason)`, as does every reconnect and every {"type": "resync"}; the caller then re-reads the REST API.
 * Callbacks: onEvent(event), onState('connecting'|'open'|'closed'), onGap(reason).
 */
export class EventStream {
  constructor(url, { onEvent, onState, onGap }) {
    this.url = url;
    this.onEvent = onEvent;
    this.onState = onState;
    this.onGap = onGap;
    this.socket = null;
    this.lastSeq = null;
    this.retryMs = 500;
    this.stopped = false;
    this.timer = null;
  }

  start() {
    this.stopped = false;
    this.connect();
  }

  stop() {
    this.stopped = true;
    clearTimeout(this.timer);
    if (this.socket) this.socket.close();
  }

  connect() {
    this.onState('connecting');
    let socket;
    try {
      socket = new WebSocket(this.url);
    } catch {
      this.scheduleReconnect();
      return;
    }
    this.socket = socket;
    this.lastSeq = null;
    socket.onopen = () => {
      this.retryMs = 500;
      this.onState('open');
      this.onGap('connected');  // whatever happened while we were away: re-read everything
    };
    socket.onmessage = (message) => {
      let event;
      try {
        event = JSON.parse(message.data);
      } catch {
        return;  // not ours
      }
      if (!event || typeof event !== 'object') return;
      this.track(event);
      this.onEvent(event);
    };
    socket.onclose = () => {
      if (this.socket === socket) this.socket = null;
      this.onState('closed');
      if (!this.stopped) this.scheduleReconnect();
    };
    socket.onerror = () => {
      // onclose follows and reconnects
    };
  }

  track(event) {
    if (event.type === 'resync') {
      this.onGap(event.reason || 'resync');
    }
    if (!Number.isFinite(event.seq)) return;
    if (this.lastSeq !== null && event.seq > this.lastSeq + 1 && event.type !== 'resync') {
      this.onGap(`missed events ${this.lastSeq + 1}..${event.seq - 1}`);
    }
    if (this.lastSeq === null || event.seq > this.lastSeq) this.lastSeq = event.seq;
  }

  scheduleReconnect() {
    clearTimeout(this.timer);
    this.timer = setTimeout(() => this.connect(), this.retryMs);
    this.retryMs = Math.min(5000, this.retryMs * 2);
  }
}
