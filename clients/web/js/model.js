// The viewer's copy of the world model, kept in step with the server by REST syncs and WebSocket events.
// Pure: no DOM, so `node --test` checks the event handling directly.

/** Highlight colours' keys: what a decision did to what it touched. */
export const kHighlightActions = ['merge', 'rigid_adjust', 'add', 'delete', 'prune', 'trim', 'ignore'];

/** How long a decision's highlight lasts [ms]. */
export const kHighlightMs = 3000;

/** Edge ids are "<object id>/<k>"; object ids may not contain '/'. */
export function objectOfEdge(edgeId) {
  const slash = typeof edgeId === 'string' ? edgeId.lastIndexOf('/') : -1;
  return slash > 0 ? edgeId.slice(0, slash) : null;
}

/**
 * What a decision should highlight: a list of {kind: 'element'|'edge'|'object', id, action}.
 * - add / merge: the element the action produced or touched (`element`);
 * - rigid_adjust: the whole object (`object`), since all its edges moved;
 * - delete (the plan confirmed the observation): the matched CAD edge, else the object;
 * - prune: the removed element; trim: the element whose ends were cut; ignore: whatever was matched.
 */
export function highlightTargets(decision) {
  if (!decision || typeof decision.action !== 'string') return [];
  const action = decision.action;
  const matched = decision.matched || {};
  const asTarget = (id) => {
    if (!id) return null;
    return objectOfEdge(id) ? { kind: 'edge', id, action } : { kind: 'element', id, action };
  };
  const out = [];
  if (action === 'rigid_adjust') {
    const object = decision.object || matched.object || objectOfEdge(decision.element);
    if (object) out.push({ kind: 'object', id: object, action });
  } else if (action === 'delete' || action === 'ignore') {
    const t = asTarget(decision.element || matched.element);
    if (t) out.push(t);
    else if (decision.object || matched.object) out.push({ kind: 'object', id: decision.object || matched.object, action });
  } else {
    const t = asTarget(decision.element || matched.element);
    if (t) out.push(t);
  }
  return out;
}

export class WorldModel {
  constructor() {
    this.reset();
  }

  reset() {
    this.version = -1;         // map version of the last sync or applied update
    this.serverInstance = null; // the server run the version counts in (deltas from another run do not apply)
    this.plan = null;
    this.objects = new Map();  // id -> object JSON (as in /api/v1/map)
    this.edges = new Map();    // edge id -> {objectId, edge}
    this.elements = new Map(); // id -> element JSON
    this.robots = new Map();   // observer -> {pose, points, sensor, scanSeq, gridRevision, at}
    this.ghosts = new Map();   // removed element id -> its last JSON (drawn while its highlight lasts)
    this.decisions = [];       // the most recent decisions seen live, newest last
    this.objectsRevision = 0;  // bumped on every change, so drawings know when to rebuild
    this.elementsRevision = 0;
    this.robotsRevision = 0;
  }

  /** Replaces objects and elements by a GET /api/v1/map answer (robots and recent decisions stay). */
  loadMap(map) {
    this.version = Number.isFinite(map.version) ? map.version : -1;
    this.serverInstance = map.server_instance ?? null;
    this.plan = map.plan ?? null;
    this.objects.clear();
    this.edges.clear();
    for (const o of map.objects || []) this.upsertObject(o);
    this.elements.clear();
    for (const e of map.elements || []) this.elements.set(e.id, e);
    this.objectsRevision++;
    this.elementsRevision++;
  }

  /**
   * Applies a GET /api/v1/map?since= answer: the removals, then the upserts; the version and plan follow.
   * Returns false (and changes nothing) when the delta is not for this map: another server run, or another base.
   */
  applyDelta(delta) {
    if (delta.server_instance !== this.serverInstance || delta.since !== this.version) return false;
    for (const id of delta.removed?.objects || []) {
      const previous = this.objects.get(id);
      if (previous) for (const e of previous.edges || []) this.edges.delete(e.id);
      this.objects.delete(id);
    }
    for (const id of delta.removed?.elements || []) this.elements.delete(id);
    for (const o of delta.objects || []) this.upsertObject(o);
    for (const e of delta.elements || []) {
      this.elements.set(e.id, e);
      this.ghosts.delete(e.id);
    }
    this.version = delta.version;
    this.plan = delta.plan ?? null;
    this.objectsRevision++;
    this.elementsRevision++;
    return true;
  }

  upsertObject(object) {
    const previous = this.objects.get(object.id);
    if (previous) for (const e of previous.edges || []) this.edges.delete(e.id);
    this.objects.set(object.id, object);
    for (const e of object.edges || []) this.edges.set(e.id, { objectId: object.id, edge: e });
  }

  /**
   * Applies an "update" event. Updates at or below the synced map version are already in it and are
   * skipped (returns null); otherwise returns {decisions, removed} of the update.
   */
  applyUpdate(event, nowMs = 0) {
    if (Number.isFinite(event.version) && event.version <= this.version) return null;
    if (Number.isFinite(event.version)) this.version = event.version;
    const objects = event.objects || [];
    for (const o of objects) this.upsertObject(o);
    if (objects.length) this.objectsRevision++;
    const elements = event.elements || [];
    for (const e of elements) {
      this.elements.set(e.id, e);
      this.ghosts.delete(e.id);
    }
    const removed = event.removed || [];
    for (const id of removed) {
      const last = this.elements.get(id);
      if (last) this.ghosts.set(id, { element: last, until: nowMs + kHighlightMs });
      this.elements.delete(id);
    }
    if (elements.length || removed.length) this.elementsRevision++;
    const decisions = event.decisions || [];
    for (const d of decisions) this.decisions.push(d);
    if (this.decisions.length > 200) this.decisions.splice(0, this.decisions.length - 200);
    return { decisions, removed };
  }

  /** Applies a "scan" event: the robot's (observer's) latest pose and scan points. */
  applyScan(event, nowMs = 0) {
    const id = event.observer || event.source || 'robot';
    const pose = event.pose || {};
    if (!Number.isFinite(pose.x) || !Number.isFinite(pose.y)) return;
    const known = this.robots.get(id);
    this.robots.set(id, {
      status: known?.status ?? 'alive',
      track: known?.track ?? [],
      id,
      pose: { x: pose.x, y: pose.y, theta: Number.isFinite(pose.theta) ? pose.theta : 0 },
      points: Array.isArray(event.points) ? event.points : [],
      sensor: event.sensor ?? null,
      scanSeq: event.scan_seq ?? null,
      gridRevision: event.grid_revision ?? null,
      at: nowMs,
    });
    this.robotsRevision++;
  }

  /** Puts the robots of a GET /api/v1/robots answer in place (those with a pose): where they are before any scan. */
  loadRobots(answer, nowMs = 0) {
    for (const robot of answer?.robots ?? []) this.applyRobot(robot, nowMs);
  }

  /** Applies a robot as GET /api/v1/robots and "robot" events give it: pose, status and recent track (its last
   * scan's points stay). */
  applyRobot(robot, nowMs = 0) {
    const pose = robot?.pose;
    if (!robot?.id || !pose || !Number.isFinite(pose.x) || !Number.isFinite(pose.y)) return;
    const known = this.robots.get(robot.id);
    this.robots.set(robot.id, {
      points: known?.points ?? [],
      sensor: known?.sensor ?? null,
      scanSeq: known?.scanSeq ?? null,
      gridRevision: known?.gridRevision ?? null,
      id: robot.id,
      pose: { x: pose.x, y: pose.y, theta: Number.isFinite(pose.theta) ? pose.theta : 0 },
      status: robot.status ?? 'alive',
      track: Array.isArray(robot.track) ? robot.track.filter((p) => Number.isFinite(p?.[0]) && Number.isFinite(p?.[1])) : [],
      at: nowMs,
    });
    this.robotsRevision++;
  }

  /** Drops ghosts whose highlight is over. */
  expireGhosts(nowMs) {
    for (const [id, g] of this.ghosts) if (g.until <= nowMs) this.ghosts.delete(id);
  }

  /** World bounds [x0, y0, x1, y1] of objects and elements, or null when there is nothing. */
  bounds() {
    let b = null;
    const add = (p) => {
      if (!p || !Number.isFinite(p[0]) || !Number.isFinite(p[1])) return;
      if (!b) b = [p[0], p[1], p[0], p[1]];
      else b = [Math.min(b[0], p[0]), Math.min(b[1], p[1]), Math.max(b[2], p[0]), Math.max(b[3], p[1])];
    };
    for (const { edge } of this.edges.values()) { add(edge.p0); add(edge.p1); }
    for (const e of this.elements.values()) { add(e.p0); add(e.p1); }
    for (const r of this.robots.values()) add([r.pose.x, r.pose.y]);
    return b;
  }

  edgeCount() {
    return this.edges.size;
  }
}
