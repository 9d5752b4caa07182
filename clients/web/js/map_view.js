// The map canvas: world ↔ screen transform, pan and zoom, drawing, and picking what was clicked.
// Vector layers are cached as Path2D objects in world coordinates and rebuilt only when the model changes,
// so a frame is a handful of drawImage/stroke calls under one transform whatever the zoom.

import { changeShapes } from './changes.js';
import { covarianceBand, elementCategory, objectCategory, pointSegmentDistance } from './geometry.js';
import { highlightTargets, kHighlightMs } from './model.js';

export const kColors = {
  objects: { solid: '#2451a6', not_deformable: '#1e9e4a', other: '#c08a00' },
  elements: { scan: '#ec6a00', grid: '#9c36b5', client: '#8d5524', other: '#6b6b6b' },
  highlights: {
    merge: '#00b8d9', rigid_adjust: '#7cd500', add: '#ff00e6', delete: '#ff2a2a', prune: '#ff2a2a',
    trim: '#ffb000',
    ignore: '#8d8d8d',
  },
  robots: ['#0077ff', '#d62828', '#2a9d8f', '#8338ec', '#fb8500'],
  band: 'rgba(236, 106, 0, 0.22)',
  selection: '#ffd400',
  background: '#3a3f47',
};

const kPickPx = 7;           // click tolerance [px]
const kMinScale = 0.05;      // px per m
const kMaxScale = 2000;

export class MapView {
  /**
   * @param canvas the visible canvas
   * @param model the WorldModel
   * @param grid the GridLayers
   * @param options {onPick(target|null), onView()}
   */
  constructor(canvas, model, grid, { onPick, onView }) {
    this.canvas = canvas;
    this.ctx = canvas.getContext('2d');
    this.model = model;
    this.grid = grid;
    this.onPick = onPick;
    this.onView = onView;
    this.view = { cx: 0, cy: 0, scale: 20 };  // world point at the canvas centre [m], px per m (CSS px)
    this.userMoved = false;
    this.fittedKinds = 0;  // bit 1: the map's bounds, bit 2: the grid's, once fitted to
    this.show = { grid: true, objects: true, elements: true, band: false, robots: true, changes: true };
    this.changes = null;               // the ChangeList drawn over the plan
    this.selection = null;             // {kind, id}
    this.highlights = new Map();       // key kind:id -> {kind, id, action, seq, start}
    this.recentHighlights = [];        // the last 100, for the test hook
    this.paths = null;
    this.pathsKey = '';
    this.drawn = {
      objects: 0, edges: 0, elements: 0, bands: 0, robots: 0, scanPoints: 0, changes: 0, changeKinds: {}, grid: false, frames: 0,
    };
    this.pending = false;
    this.installInput();
    new ResizeObserver(() => this.requestDraw()).observe(canvas);
  }

  requestDraw() {
    if (this.pending) return;
    this.pending = true;
    requestAnimationFrame(() => {
      this.pending = false;
      this.draw();
    });
  }

  // ---- transform -------------------------------------------------------------------------------------------

  size() {
    return { w: this.canvas.clientWidth, h: this.canvas.clientHeight };
  }

  /** Canvas CSS pixels of world point (x, y). */
  toCanvas(x, y) {
    const { w, h } = this.size();
    return [(x - this.view.cx) * this.view.scale + w / 2, (this.view.cy - y) * this.view.scale + h / 2];
  }

  /** World point of canvas CSS pixel (px, py). */
  toWorld(px, py) {
    const { w, h } = this.size();
    return [this.view.cx + (px - w / 2) / this.view.scale, this.view.cy - (py - h / 2) / this.view.scale];
  }

  /** Page (client) coordinates of world point (x, y): where a click lands on it. */
  toClient(x, y) {
    const r = this.canvas.getBoundingClientRect();
    const [px, py] = this.toCanvas(x, y);
    return { x: r.left + px, y: r.top + py };
  }

  /** Fits world box [x0, y0, x1, y1] into the canvas with a margin. */
  fitBox(box) {
    const { w, h } = this.size();
    if (!box || !w || !h) return false;
    const bw = Math.max(box[2] - box[0], 1), bh = Math.max(box[3] - box[1], 1);
    this.view.cx = (box[0] + box[2]) / 2;
    this.view.cy = (box[1] + box[3]) / 2;
    this.view.scale = clamp(Math.min(w / bw, h / bh) * 0.92, kMinScale, kMaxScale);
    this.requestDraw();
    this.onView();
    return true;
  }

  /** Everything there is: objects, elements, robots and the grid's cells. */
  contentBox() {
    let box = this.model.bounds();
    const l = this.grid.layer();
    if (l.cells && this.grid.resolution) {
      const r = this.grid.resolution;
      const g = [l.cells.cx0 * r, l.cells.cy0 * r, l.cells.cx1 * r, l.cells.cy1 * r];
      box = box ? [Math.min(box[0], g[0]), Math.min(box[1], g[1]), Math.max(box[2], g[2]), Math.max(box[3], g[3])] : g;
    }
    return box;
  }

  fit() {
    this.fitBox(this.contentBox());
  }

  /**
   * Fits when a kind of content appears for the first time (the map, then the grid), unless the user has
   * moved the view already; later growth never moves the view under the user's pointer.
   */
  autoFit() {
    if (this.userMoved) return;
    const l = this.grid.layer();
    const kinds = (this.model.bounds() ? 1 : 0) | (l.cells ? 2 : 0);
    if ((kinds | this.fittedKinds) === this.fittedKinds) return;
    if (this.fitBox(this.contentBox())) this.fittedKinds |= kinds;
  }

  zoomAt(px, py, factor) {
    const [wx, wy] = this.toWorld(px, py);
    this.view.scale = clamp(this.view.scale * factor, kMinScale, kMaxScale);
    const [nx, ny] = this.toWorld(px, py);
    this.view.cx += wx - nx;
    this.view.cy += wy - ny;
    this.userMoved = true;
    this.requestDraw();
    this.onView();
  }

  installInput() {
    const c = this.canvas;
    let drag = null;
    c.addEventListener('pointerdown', (e) => {
      if (e.button !== 0) return;
      drag = { x: e.clientX, y: e.clientY, cx: this.view.cx, cy: this.view.cy, moved: false };
      c.setPointerCapture(e.pointerId);
    });
    c.addEventListener('pointermove', (e) => {
      const r = c.getBoundingClientRect();
      this.cursor = this.toWorld(e.clientX - r.left, e.clientY - r.top);
      this.onView();
      if (!drag) return;
      const dx = e.clientX - drag.x, dy = e.clientY - drag.y;
      if (!drag.moved && Math.hypot(dx, dy) < 4) return;
      drag.moved = true;
      this.view.cx = drag.cx - dx / this.view.scale;
      this.view.cy = drag.cy + dy / this.view.scale;
      this.userMoved = true;
      this.requestDraw();
    });
    c.addEventListener('pointerup', (e) => {
      if (!drag) return;
      const wasDrag = drag.moved;
      drag = null;
      if (wasDrag) return;
      const r = c.getBoundingClientRect();
      this.onPick(this.pick(e.clientX - r.left, e.clientY - r.top));
    });
    c.addEventListener('pointercancel', () => { drag = null; });
    c.addEventListener('wheel', (e) => {
      e.preventDefault();
      const r = c.getBoundingClientRect();
      // Trackpads send small deltas, wheels ±100: an exponential keeps both smooth.
      const delta = e.deltaMode === 1 ? e.deltaY * 33 : e.deltaY;
      this.zoomAt(e.clientX - r.left, e.clientY - r.top, Math.exp(-delta * 0.0015));
    }, { passive: false });
    c.addEventListener('keydown', (e) => {
      const { w, h } = this.size();
      const step = 80 / this.view.scale;
      const moves = { ArrowLeft: [-step, 0], ArrowRight: [step, 0], ArrowUp: [0, step], ArrowDown: [0, -step] };
      if (moves[e.key]) {
        this.view.cx += moves[e.key][0];
        this.view.cy += moves[e.key][1];
        this.userMoved = true;
        this.requestDraw();
        e.preventDefault();
      } else if (e.key === '+' || e.key === '=') {
        this.zoomAt(w / 2, h / 2, 1.25);
      } else if (e.key === '-') {
        this.zoomAt(w / 2, h / 2, 0.8);
      }
    });
  }

  // ---- picking ---------------------------------------------------------------------------------------------

  /** The element, object (by its edge) or robot nearest to canvas pixel (px, py) within kPickPx, or null. */
  pick(px, py) {
    const p = this.toWorld(px, py);
    const tolerance = kPickPx / this.view.scale;
    let best = null, bestD = tolerance;
    if (this.show.elements) {
      for (const e of this.model.elements.values()) {
        const d = pointSegmentDistance(p, e.p0, e.p1);
        if (d <= bestD) { best = { kind: 'element', id: e.id }; bestD = d; }
      }
    }
    if (this.show.objects) {
      // Elements are drawn above objects: an edge wins only when it is clearly nearer.
      const elementD = best ? bestD : Infinity;
      for (const [edgeId, { objectId, edge }] of this.model.edges) {
        const d = pointSegmentDistance(p, edge.p0, edge.p1);
        if (d <= bestD && d < elementD * 0.5) { best = { kind: 'object', id: objectId, edge: edgeId }; bestD = d; }
      }
    }
    if (this.show.robots) {
      for (const r of this.model.robots.values()) {
        const d = Math.hypot(p[0] - r.pose.x, p[1] - r.pose.y);
        if (d <= Math.max(bestD, 0.3)) { best = { kind: 'robot', id: r.id }; bestD = d; }
      }
    }
    return best;
  }

  // ---- highlights ------------------------------------------------------------------------------------------

  /** Highlights what a decision touched, for kHighlightMs. */
  highlightDecision(decision, nowMs = performance.now()) {
    for (const t of highlightTargets(decision)) {
      const h = { ...t, seq: decision.seq ?? null, rule: decision.rule ?? null, start: nowMs };
      this.highlights.set(`${t.kind}:${t.id}`, h);
      this.recentHighlights.push({ kind: t.kind, id: t.id, action: t.action, seq: h.seq, rule: h.rule });
    }
    if (this.recentHighlights.length > 100) this.recentHighlights.splice(0, this.recentHighlights.length - 100);
    this.requestDraw();
  }

  // ---- drawing ---------------------------------------------------------------------------------------------

  rebuildPaths() {
    const m = this.model;
    const key = `${m.objectsRevision}/${m.elementsRevision}/${this.show.band}`;
    if (this.paths && key === this.pathsKey) return;
    this.pathsKey = key;
    const objects = { solid: new Path2D(), not_deformable: new Path2D(), other: new Path2D() };
    let edges = 0;
    for (const o of m.objects.values()) {
      const path = objects[objectCategory(o)];
      for (const e of o.edges || []) {
        path.moveTo(e.p0[0], e.p0[1]);
        path.lineTo(e.p1[0], e.p1[1]);
        ++edges;
      }
    }
    const elements = { scan: new Path2D(), grid: new Path2D(), client: new Path2D(), other: new Path2D() };
    const band = new Path2D();
    let bands = 0;
    for (const e of m.elements.values()) {
      const path = elements[elementCategory(e)];
      path.moveTo(e.p0[0], e.p0[1]);
      path.lineTo(e.p1[0], e.p1[1]);
      if (this.show.band) {
        const polygon = covarianceBand(e.p0, e.p1, e.phi, e.cov);
        if (polygon.length) {
          band.moveTo(polygon[0][0], polygon[0][1]);
          for (let i = 1; i < polygon.length; ++i) band.lineTo(polygon[i][0], polygon[i][1]);
          band.closePath();
          ++bands;
        }
      }
    }
    this.paths = { objects, elements, band, counts: { objects: m.objects.size, edges, elements: m.elements.size, bands } };
  }

  draw() {
    const ctx = this.ctx;
    const dpr = window.devicePixelRatio || 1;
    const { w, h } = this.size();
    if (this.canvas.width !== Math.round(w * dpr) || this.canvas.height !== Math.round(h * dpr)) {
      this.canvas.width = Math.round(w * dpr);
      this.canvas.height = Math.round(h * dpr);
    }
    ctx.setTransform(1, 0, 0, 1, 0, 0);
    ctx.fillStyle = kColors.background;
    ctx.fillRect(0, 0, this.canvas.width, this.canvas.height);
    const s = this.view.scale;
    const now = performance.now();
    const drawn = { objects: 0, edges: 0, elements: 0, bands: 0, robots: 0, scanPoints: 0, changes: 0, changeKinds: {}, grid: false };

    // Grid: one drawImage of the layer's canvas; pixels stay crisp when zoomed in.
    const l = this.grid.layer();
    if (this.show.grid && l.canvas && this.grid.resolution) {
      const r = this.grid.resolution;
      const [left, top] = this.toCanvas(l.extent.cx0 * r, l.extent.cy1 * r);
      ctx.setTransform(dpr * s * r, 0, 0, dpr * s * r, dpr * left, dpr * top);
      ctx.imageSmoothingEnabled = s * r < 1;  // smooth only when a pixel is smaller than a cell
      ctx.drawImage(l.canvas, 0, 0);
      drawn.grid = true;
    }

    // World transform for vectors: y up.
    ctx.setTransform(dpr * s, 0, 0, -dpr * s, dpr * (w / 2 - this.view.cx * s), dpr * (h / 2 + this.view.cy * s));
    const px = 1 / s;  // one CSS pixel in metres
    ctx.lineCap = 'round';
    ctx.lineJoin = 'round';
    this.rebuildPaths();
    const p = this.paths;

    if (this.show.objects) {
      ctx.lineWidth = 2.5 * px;
      for (const [category, path] of Object.entries(p.objects)) {
        ctx.strokeStyle = kColors.objects[category];
        ctx.stroke(path);
      }
      drawn.objects = p.counts.objects;
      drawn.edges = p.counts.edges;
    }
    // Halos (new walls) go beneath the elements they are, the rest over them.
    if (this.show.changes && this.changes) this.drawChanges(ctx, px, drawn, true);
    if (this.show.elements) {
      if (this.show.band) {
        ctx.fillStyle = kColors.band;
        ctx.fill(p.band, 'nonzero');
        drawn.bands = p.counts.bands;
      }
      ctx.lineWidth = 2 * px;
      for (const [category, path] of Object.entries(p.elements)) {
        ctx.strokeStyle = kColors.elements[category];
        ctx.stroke(path);
      }
      drawn.elements = p.counts.elements;
    }

    if (this.show.changes && this.changes) this.drawChanges(ctx, px, drawn, false);

    if (this.show.robots) {
      let i = 0;
      for (const r of this.model.robots.values()) {
        const color = kColors.robots[i++ % kColors.robots.length];
        // Its recent track, thin; a robot that is stale or stopped is drawn faded.
        if (r.track?.length > 1) {
          ctx.strokeStyle = color;
          ctx.globalAlpha = 0.5;
          ctx.lineWidth = 1.5 * px;
          ctx.beginPath();
          ctx.moveTo(r.track[0][0], r.track[0][1]);
          for (const q of r.track) ctx.lineTo(q[0], q[1]);
          ctx.stroke();
        }
        ctx.globalAlpha = r.status === 'stale' || r.status === 'stopped' ? 0.45 : 1;
        ctx.fillStyle = color;
        const dot = 2.2 * px;
        for (const q of r.points) {
          if (Array.isArray(q) && Number.isFinite(q[0]) && Number.isFinite(q[1])) ctx.fillRect(q[0] - dot / 2, q[1] - dot / 2, dot, dot);
        }
        drawn.scanPoints += r.points.length;
        const size = Math.max(0.35, 9 * px);
        const c = Math.cos(r.pose.theta), sn = Math.sin(r.pose.theta);
        ctx.beginPath();
        ctx.moveTo(r.pose.x + c * size, r.pose.y + sn * size);
        ctx.lineTo(r.pose.x - c * size * 0.6 - sn * size * 0.6, r.pose.y - sn * size * 0.6 + c * size * 0.6);
        ctx.lineTo(r.pose.x - c * size * 0.6 + sn * size * 0.6, r.pose.y - sn * size * 0.6 - c * size * 0.6);
        ctx.closePath();
        ctx.fill();
        ctx.strokeStyle = '#ffffff';
        ctx.lineWidth = 1.5 * px;
        ctx.stroke();
        ctx.globalAlpha = 1;
        ++drawn.robots;
      }
    }

    // Highlights: a wide translucent stroke that fades out.
    this.model.expireGhosts(now);
    let live = false;
    for (const [key, hl] of this.highlights) {
      const age = now - hl.start;
      if (age > kHighlightMs) { this.highlights.delete(key); continue; }
      live = true;
      const segments = this.segmentsOf(hl);
      if (!segments.length) continue;
      ctx.globalAlpha = 0.85 * (1 - age / kHighlightMs) + 0.15;
      ctx.strokeStyle = kColors.highlights[hl.action] || kColors.highlights.ignore;
      ctx.lineWidth = (9 - 4 * age / kHighlightMs) * px;
      ctx.beginPath();
      for (const [a, b] of segments) { ctx.moveTo(a[0], a[1]); ctx.lineTo(b[0], b[1]); }
      ctx.stroke();
    }
    ctx.globalAlpha = 1;

    if (this.selection) {
      const segments = this.segmentsOf(this.selection);
      if (segments.length) {
        ctx.strokeStyle = kColors.selection;
        ctx.setLineDash([6 * px, 4 * px]);
        ctx.lineWidth = 2 * px;
        ctx.beginPath();
        for (const [a, b] of segments) { ctx.moveTo(a[0], a[1]); ctx.lineTo(b[0], b[1]); }
        ctx.stroke();
        ctx.setLineDash([]);
      }
    }

    drawn.frames = this.drawn.frames + 1;
    this.drawn = drawn;
    if (live) this.requestDraw();
  }

  /**
   * The changes in the building over the plan, each in its kind's colour (see changes.js): missing stretches
   * dashed over the drawn wall, new walls solid, gone objects crossed out, moved objects an arrow from where they
   * were drawn (outline dashed) to where they stand; new walls a green halo under the element. `under` picks the
   * halos (drawn before the elements) or the rest (after). Counts what it drew in `drawn.changes` and `changeKinds`.
   */
  drawChanges(ctx, px, drawn, under) {
    for (const change of this.changes.items) {
      const shape = changeShapes(change, change.object ? this.model.objects.get(change.object) : undefined, { pxM: px });
      if (!shape || !shape.segments.length || shape.under !== under) continue;
      drawn.changes++;
      drawn.changeKinds[shape.kind] = (drawn.changeKinds[shape.kind] || 0) + 1;
      if (shape.under) {
        ctx.globalAlpha = 0.6;
        ctx.strokeStyle = shape.color;
        ctx.lineWidth = shape.width * px;
        ctx.beginPath();
        for (const [a, b] of shape.segments) { ctx.moveTo(a[0], a[1]); ctx.lineTo(b[0], b[1]); }
        ctx.stroke();
        ctx.globalAlpha = 1;
        continue;
      }
      ctx.strokeStyle = shape.color;
      if (shape.ghost.length) {
        ctx.globalAlpha = 0.8;
        ctx.lineWidth = 1.5 * px;
        ctx.setLineDash([4 * px, 3 * px]);
        ctx.beginPath();
        for (const [a, b] of shape.ghost) { ctx.moveTo(a[0], a[1]); ctx.lineTo(b[0], b[1]); }
        ctx.stroke();
        ctx.globalAlpha = 1;
      }
      // A dark outline under the colour keeps it readable on white (free) and black (occupied) cells alike.
      ctx.setLineDash(shape.dash ? shape.dash.map((d) => d * px) : []);
      ctx.beginPath();
      for (const [a, b] of shape.segments) { ctx.moveTo(a[0], a[1]); ctx.lineTo(b[0], b[1]); }
      ctx.strokeStyle = 'rgba(20, 22, 26, 0.55)';
      ctx.lineWidth = (shape.width + 2) * px;
      ctx.stroke();
      ctx.strokeStyle = shape.color;
      ctx.lineWidth = shape.width * px;
      ctx.stroke();
      ctx.setLineDash([]);
    }
  }

  /** Centres the view on world point [x, y] (the zoom stays). */
  centreOn(p) {
    if (!p) return;
    this.view.cx = p[0];
    this.view.cy = p[1];
    this.userMoved = true;
    this.requestDraw();
    this.onView();
  }

  /** World segments [[p0, p1], ...] of a highlight or selection target. */
  segmentsOf(t) {
    const m = this.model;
    if (t.kind === 'element') {
      const e = m.elements.get(t.id) || m.ghosts.get(t.id)?.element;
      return e ? [[e.p0, e.p1]] : [];
    }
    if (t.kind === 'edge') {
      const found = m.edges.get(t.id);
      return found ? [[found.edge.p0, found.edge.p1]] : [];
    }
    if (t.kind === 'object') {
      const o = m.objects.get(t.id);
      return o ? (o.edges || []).map((e) => [e.p0, e.p1]) : [];
    }
    if (t.kind === 'robot') {
      const r = m.robots.get(t.id);
      if (!r) return [];
      const d = 0.4;
      return [[[r.pose.x - d, r.pose.y - d], [r.pose.x + d, r.pose.y + d]], [[r.pose.x - d, r.pose.y + d], [r.pose.x + d, r.pose.y - d]]];
    }
    return [];
  }
}

function clamp(v, lo, hi) {
  return Math.min(hi, Math.max(lo, v));
}
