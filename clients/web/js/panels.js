// The side panels: status, the changes in the building, details with decision history, the live decision feed
// and the legend. Server text only ever goes into textContent, never into HTML.

import {
  changeEvidence, changeStyle, changeSummary, kChangeKinds, kChangeStyles,
} from './changes.js';
import { kColors } from './map_view.js';

/** A DOM element: el('li', {class: 'x', dataset: {seq: 3}}, 'text', child, ...). */
export function el(tag, attrs = {}, ...children) {
  const node = document.createElement(tag);
  for (const [k, v] of Object.entries(attrs)) {
    if (v === undefined || v === null) continue;
    if (k === 'class') node.className = v;
    else if (k === 'dataset') for (const [dk, dv] of Object.entries(v)) node.dataset[dk] = String(dv);
    else if (k === 'style') node.style.cssText = v;
    else node.setAttribute(k, v);
  }
  for (const c of children) {
    if (c === undefined || c === null || c === false) continue;
    node.append(c instanceof Node ? c : String(c));
  }
  return node;
}

/** A number for people: fixed digits, '–' for missing. */
export function fmt(v, digits = 3) {
  if (v === null || v === undefined || !Number.isFinite(Number(v))) return '–';
  return Number(v).toFixed(digits);
}

const sigma = (variance) => (Number.isFinite(variance) && variance >= 0 ? Math.sqrt(variance) : NaN);
const point = (p) => (Array.isArray(p) ? `(${fmt(p[0], 2)}, ${fmt(p[1], 2)})` : '–');
const deg = (rad) => (Number.isFinite(rad) ? `${fmt(rad, 4)} rad (${fmt((rad * 180) / Math.PI, 1)}°)` : '–');

function kv(dl, key, value) {
  dl.append(el('dt', {}, key), el('dd', { dataset: { key } }, value));
}

export function actionBadge(action) {
  return el('span', {
    class: 'action', dataset: { action },
    style: `--action-color: ${kColors.highlights[action] || kColors.highlights.ignore}`,
  }, action);
}

// ---- status ----------------------------------------------------------------------------------------------

export class StatusPanel {
  constructor() {
    this.$ = (id) => document.getElementById(id);
  }

  setConnection(state) {
    const badge = this.$('connection');
    badge.dataset.state = state;
    badge.textContent = { open: 'live', connecting: 'connecting…', closed: 'disconnected' }[state] || state;
  }

  /** Where the plan sits: a GET /api/v1/map "placement", or a "placement" event (which also says why). */
  setPlacement(placement, why) {
    const el = this.$('status-placement');
    if (!el || !placement) return;
    const deg = (placement.theta * 180) / Math.PI;
    const asDrawn = placement.x === 0 && placement.y === 0 && placement.theta === 0 && placement.scale === 1;
    el.textContent = asDrawn
      ? 'as drawn'
      : `x ${placement.x.toFixed(2)} m, y ${placement.y.toFixed(2)} m, ${deg.toFixed(2)}°` +
        (placement.scale === 1 ? '' : `, scale ${placement.scale.toPrecision(6)}`);
    el.title = why ?? '';
  }

  /**
   * The processing network (GET /api/v1/network): each executor's load and the deepest queue, so an operator sees
   * which stage holds ingest back. The full table is in the title.
   */
  setNetwork(network) {
    const el = this.$('status-network');
    if (!el || !network) return;
    const loads = network.executors.map((e) => `${e.name} ${Math.round(100 * e.load)}%`);
    const deepest = network.ports.reduce((a, p) => (a && a.depth >= p.depth ? a : p), null);
    const queue = deepest && deepest.depth > 0 ? ` · ${deepest.component}.${deepest.port} ${deepest.depth}/${deepest.capacity}` : ' · queues empty';
    el.textContent = loads.join(', ') + queue;
    el.title = network.functions
      .map((f) => `${f.component}.${f.function}: ${f.activations} × ${f.mean_ms.toFixed(2)} ms`)
      .join('\n');
  }

  setHealth(health, error) {
    const h = this.$('status-health');
    if (error) {
      h.textContent = 'unreachable';
      h.dataset.value = 'unreachable';
      h.title = error;
      return;
    }
    h.textContent = health.status ?? '?';
    h.dataset.value = health.status ?? '';
    h.title = '';
    this.$('status-version').textContent = health.version ? `v${health.version}` : '';
    this.$('status-plan').textContent = health.plan || '(no plan loaded)';
    this.lastDecisionSeq = null;  // the server's word wins (a new database starts again at 0)
    this.noteDecision(health.last_decision_seq);
    if (health.rules) this.setRules(health.rules);
  }

  /** The newest decision seq, from health polls and from live updates, whichever is newer. */
  noteDecision(seq) {
    if (!Number.isFinite(seq) || seq <= (this.lastDecisionSeq ?? -1)) return;
    this.lastDecisionSeq = seq;
    const d = this.$('status-decisions');
    d.textContent = `last seq ${seq}`;
    d.dataset.lastSeq = seq;
  }

  setRules(rules) {
    this.$('status-rules-generation').textContent = `generation ${rules.generation ?? '–'}`;
    const list = this.$('status-rules');
    list.replaceChildren(...(rules.files || []).map((f) => {
      const name = String(f.path || '').split('/').pop();
      const loaded = Number.isFinite(f.loaded_at) ? new Date(f.loaded_at * 1000).toLocaleTimeString() : '';
      return el('li', { dataset: { path: f.path || '' }, title: `${f.path}\nchecksum ${f.checksum}` },
        el('span', { class: 'file' }, name), ' ',
        el('code', {}, String(f.checksum || '').slice(0, 10)), ' ',
        el('span', { class: 'dim' }, loaded));
    }));
    const err = this.$('status-rules-error');
    if (rules.last_error) {
      err.hidden = false;
      err.textContent = rules.last_error;
    } else {
      err.hidden = true;
      err.textContent = '';
    }
  }

  setCounts(model) {
    let edges = 0;
    for (const o of model.objects.values()) edges += (o.edges || []).length;
    const c = this.$('status-counts');
    c.textContent = `${model.objects.size} objects · ${edges} edges · ${model.elements.size} elements · version ${model.version}`;
    c.dataset.objects = model.objects.size;
    c.dataset.edges = edges;
    c.dataset.elements = model.elements.size;
  }

  setRate(events, scans, decisions) {
    const r = this.$('status-rate');
    r.textContent = `${fmt(events, 1)} events/s (${fmt(scans, 1)} scans/s, ${fmt(decisions, 1)} decisions/s)`;
    r.dataset.eventsPerS = fmt(events, 2);
  }

  setGrid(active, summary, resolution) {
    const s = summary[active];
    this.$('status-grid').textContent = s.width
      ? `${active}: ${s.width}×${s.height} cells of ${fmt(resolution * 100, 1)} cm · rev ${s.revision ?? '–'}`
      : `${active}: ${s.empty ? 'no scan yet' : 'loading…'}`;
  }

  setSeq(seq, syncs) {
    this.$('status-seq').textContent = `seq ${seq ?? '–'} · ${syncs} sync${syncs === 1 ? '' : 's'}`;
  }
}

// ---- changes ---------------------------------------------------------------------------------------------

/**
 * The "Changes" panel: one row per listed change (kind, key, length, confidence; the explanation on hover and
 * under "why"), Accept and Reject per row, Undo, the write token and what the last request answered or why it
 * failed. It only shows; `onDecide(id, verdict)`, `onUndo()`, `onShow(change)` and `onToken(token)` act.
 */
export class ChangesPanel {
  constructor({ token = '', onDecide, onUndo, onShow, onToken }) {
    this.$ = (id) => document.getElementById(id);
    this.list = this.$('changes-list');
    this.open = new Set();  // ids whose "why" is expanded, kept across reloads
    this.onDecide = onDecide;
    this.onShow = onShow;
    const field = this.$('changes-token');
    field.value = token;
    field.addEventListener('input', () => onToken(field.value.trim()));
    this.$('changes-undo').addEventListener('click', () => onUndo());
    this.list.addEventListener('click', (e) => {
      const button = e.target.closest('button');
      const row = e.target.closest('li.change');
      if (!button || !row || this.list.dataset.busy === '1') return;
      if (button.classList.contains('accept')) this.onDecide(row.dataset.id, 'accept');
      else if (button.classList.contains('reject')) this.onDecide(row.dataset.id, 'reject');
      else if (button.classList.contains('key')) this.onShow(row.dataset.id);
    });
  }

  /** Rebuilds the rows from a ChangeList. */
  render(changes) {
    for (const d of this.list.querySelectorAll('details[open]')) this.open.add(d.closest('li').dataset.id);
    for (const d of this.list.querySelectorAll('details:not([open])')) this.open.delete(d.closest('li').dataset.id);
    const rows = changes.items.map((c) => {
      const style = changeStyle(c.kind);
      const why = el('details', {}, el('summary', {}, 'why'),
        el('p', { class: 'explanation' }, c.explanation || ''),
        el('p', { class: 'evidence dim' }, changeEvidence(c)));
      if (this.open.has(c.id)) why.open = true;
      return el('li', { class: 'change', dataset: { id: c.id, kind: c.kind, key: c.key ?? '' }, title: c.explanation || '' },
        el('div', { class: 'head' },
          el('span', { class: 'action kind', style: `--action-color: ${style.color}` }, style.label), ' ',
          el('button', { type: 'button', class: 'link key', title: 'show it on the map' }, c.key ?? c.id)),
        el('div', { class: 'numbers' }, changeSummary(c), ' ', el('code', { class: 'dim' }, c.id)),
        el('div', { class: 'buttons' },
          el('button', { type: 'button', class: 'accept', title: 'put it into the plan (a new version of the plan)' }, 'Accept'),
          el('button', { type: 'button', class: 'reject', title: 'the plan is right: no longer list it' }, 'Reject')),
        why);
    });
    this.list.replaceChildren(...rows);
    const ids = new Set(changes.items.map((c) => c.id));
    for (const id of this.open) if (!ids.has(id)) this.open.delete(id);
    this.list.dataset.count = changes.size;
    this.list.dataset.version = changes.version ?? '';
    const count = this.$('changes-count');
    count.textContent = `${changes.size} · map version ${changes.version ?? '–'} · grid rev ${changes.gridRevision ?? '–'}`;
    this.$('changes-empty').hidden = changes.size > 0;
  }

  /** While a request is under way its buttons are disabled (one decision at a time). */
  setBusy(busy) {
    this.list.dataset.busy = busy ? '1' : '0';
    for (const b of this.list.querySelectorAll('button.accept, button.reject')) b.disabled = busy;
    this.$('changes-undo').disabled = busy;
  }

  /** Shows an error (with the HTTP status in data-status), or clears it with null. */
  setError(text, status = '') {
    const box = this.$('changes-error');
    box.hidden = !text;
    box.textContent = text || '';
    box.dataset.status = text ? String(status ?? '') : '';
  }

  /** What the last request did, e.g. "accepted c…: decision #42". */
  setMessage(text, verdict = '') {
    const box = this.$('changes-message');
    box.textContent = text || '';
    box.dataset.verdict = verdict;
  }

  /** Why the list could not be read (kept until the next good read). */
  setLoadError(text) {
    const box = this.$('changes-load-error');
    box.hidden = !text;
    box.textContent = text || '';
  }
}

// ---- details ---------------------------------------------------------------------------------------------

/** Fills the details box for a picked target from the model (no request). */
export function renderDetails(target, model) {
  const box = document.getElementById('details');
  box.dataset.kind = target ? target.kind : '';
  box.dataset.id = target ? target.id : '';
  if (!target) {
    box.replaceChildren(el('p', { class: 'dim' }, 'Click a line, an object or a robot on the map.'));
    return;
  }
  const dl = el('dl', { class: 'kv' });
  let title = target.id;
  if (target.kind === 'element') {
    const e = model.elements.get(target.id) || model.ghosts.get(target.id)?.element;
    title = `element ${target.id}`;
    if (!e) {
      kv(dl, 'state', 'removed');
    } else {
      kv(dl, 'source', e.source);
      kv(dl, 'observer', e.observer ?? '–');
      kv(dl, 'p0 → p1', `${point(e.p0)} → ${point(e.p1)}`);
      kv(dl, 'length', `${fmt(e.length)} m`);
      kv(dl, 'ρ', `${fmt(e.rho, 4)} m ± ${fmt(sigma(e.cov?.[0]?.[0]) * 100, 2)} cm`);
      kv(dl, 'φ', `${deg(e.phi)} ± ${fmt(sigma(e.cov?.[1]?.[1]), 5)} rad`);
      kv(dl, 'support', e.support ?? '–');
      kv(dl, 'versions', `created ${e.created_version ?? '–'}, updated ${e.updated_version ?? '–'}`);
    }
  } else if (target.kind === 'object') {
    const o = model.objects.get(target.id);
    title = `object ${target.id}`;
    if (!o) {
      kv(dl, 'state', 'not in the plan');
    } else {
      kv(dl, 'kind', o.kind);
      kv(dl, 'attributes', (o.attributes || []).join(', ') || '–');
      const c = o.pose_cov || [];
      kv(dl, 'pose', `x ${fmt(o.pose?.x)} ± ${fmt(sigma(c[0]?.[0]))}, y ${fmt(o.pose?.y)} ± ${fmt(sigma(c[1]?.[1]))} m, θ ${fmt(o.pose?.theta, 4)} ± ${fmt(sigma(c[2]?.[2]), 4)} rad`);
      if (o.drawn_pose) {
        const dx = o.pose.x - o.drawn_pose.x, dy = o.pose.y - o.drawn_pose.y;
        kv(dl, 'moved', `${fmt(Math.hypot(dx, dy) * 100, 1)} cm, ${fmt(((o.pose.theta - o.drawn_pose.theta) * 180) / Math.PI, 2)}° from the drawing`);
      }
      kv(dl, 'confirmed', `${o.confirmations ?? 0}× · adjusted ${o.adjustments ?? 0}×`);
      kv(dl, 'edges', `${(o.edges || []).length}${target.edge ? ` (clicked ${target.edge})` : ''}`);
    }
  } else if (target.kind === 'robot') {
    const r = model.robots.get(target.id);
    title = `robot ${target.id}`;
    if (r) {
      kv(dl, 'pose', `x ${fmt(r.pose.x)} y ${fmt(r.pose.y)} m, θ ${fmt(r.pose.theta, 3)} rad`);
      kv(dl, 'sensor', r.sensor ?? '–');
      kv(dl, 'last scan', `#${r.scanSeq ?? '–'}: ${r.points.length} points, grid rev ${r.gridRevision ?? '–'}`);
    }
  }
  box.replaceChildren(el('h3', {}, title), dl);
}

/** One decision of a history, with its rule, explanation and numbers. */
export function decisionItem(d) {
  const numbers = [];
  if (Number.isFinite(d.mahalanobis_sq)) numbers.push(`d² ${fmt(d.mahalanobis_sq, 3)}`);
  if (d.fallback) numbers.push('fallback');
  numbers.push(`${d.source ?? '–'} · ${d.origin ?? '–'} · ${d.sensor ?? '–'}`);
  if (d.observed) numbers.push(`observed ρ ${fmt(d.observed.rho, 3)} φ ${fmt(d.observed.phi, 4)}`);
  const matched = d.matched && (d.matched.element || d.matched.object)
    ? `matched ${d.matched.element ?? ''}${d.matched.object ? ` of ${d.matched.object}` : ''}` : 'matched nothing';
  const li = el('li', { class: 'decision', dataset: { seq: d.seq, action: d.action, rule: d.rule } },
    el('div', { class: 'head' },
      el('span', { class: 'seq' }, `#${d.seq}`), ' ', actionBadge(d.action), ' ',
      el('code', { class: 'rule' }, d.rule), ' ',
      el('span', { class: 'dim' }, `obs ${d.observation}${d.index >= 0 ? `.${d.index}` : ''}`)),
    el('p', { class: 'explanation' }, d.explanation || ''),
    el('div', { class: 'numbers' }, `${matched} · ${numbers.join(' · ')}`));
  const change = beforeAfter(d.before, d.after);
  if (change) li.append(change);
  return li;
}

function beforeAfter(before, after) {
  if (!before && !after) return null;
  const describe = (s) => {
    if (!s) return '–';
    if (s.pose) {
      const c = s.pose_cov || [];
      return `x ${fmt(s.pose.x)} y ${fmt(s.pose.y)} θ ${fmt(s.pose.theta, 4)} (σ ${fmt(sigma(c[0]?.[0]))}, ${fmt(sigma(c[1]?.[1]))}, ${fmt(sigma(c[2]?.[2]), 4)})`;
    }
    if (Number.isFinite(s.rho)) {
      return `ρ ${fmt(s.rho, 4)} φ ${fmt(s.phi, 4)} (σ ${fmt(sigma(s.cov?.[0]?.[0]), 4)}, ${fmt(sigma(s.cov?.[1]?.[1]), 5)})`;
    }
    return JSON.stringify(s);
  };
  return el('div', { class: 'change' }, `before ${describe(before)} → after ${describe(after)}`);
}

/**
 * Shows a history answer ({id, exists, decisions}) under the details; `error` instead when it failed.
 */
export function renderHistory(target, history, error) {
  const box = document.getElementById('details-history');
  box.dataset.id = target ? target.id : '';
  if (!target || target.kind === 'robot') {
    box.replaceChildren();
    box.dataset.state = 'none';
    return;
  }
  if (error) {
    box.replaceChildren(el('p', { class: 'error' }, `history: ${error}`));
    box.dataset.state = 'error';
    return;
  }
  if (!history) {
    box.replaceChildren(el('p', { class: 'dim' }, 'loading history…'));
    box.dataset.state = 'loading';
    return;
  }
  const decisions = history.decisions || [];
  box.replaceChildren(
    el('h3', {}, `decision history (${decisions.length})`),
    decisions.length ? el('ol', { class: 'history' }, ...decisions.slice().reverse().map(decisionItem))
      : el('p', { class: 'dim' }, 'no decision about it yet'));
  box.dataset.state = 'loaded';
  box.dataset.count = decisions.length;
}

// ---- feed and legend -------------------------------------------------------------------------------------

export class DecisionFeed {
  constructor(onSelect, max = 60) {
    this.list = document.getElementById('decision-feed');
    this.onSelect = onSelect;
    this.max = max;
  }

  push(d) {
    const target = d.element || d.object || d.matched?.element;
    const li = el('li', { dataset: { seq: d.seq, action: d.action, rule: d.rule }, title: d.explanation || '' },
      el('span', { class: 'seq' }, `#${d.seq}`), ' ', actionBadge(d.action), ' ',
      el('button', { type: 'button', class: 'link' }, target || '–'), ' ',
      el('code', { class: 'rule' }, d.rule));
    li.querySelector('button').addEventListener('click', () => this.onSelect(d));
    this.list.prepend(li);
    while (this.list.children.length > this.max) this.list.lastElementChild.remove();
  }
}

export function renderLegend() {
  const swatch = (color, label, kind) => el('li', {}, el('span', { class: `swatch ${kind}`, style: `--swatch: ${color}` }), label);
  const group = (title, entries, kind) => el('div', { class: 'legend-group' }, el('h4', {}, title),
    el('ul', {}, ...entries.map(([label, color]) => swatch(color, label, kind))));
  document.getElementById('legend').replaceChildren(
    group('plan objects', [['solid', kColors.objects.solid], ['not_deformable', kColors.objects.not_deformable],
      ['other', kColors.objects.other]], 'line'),
    group('observed elements', [['scan', kColors.elements.scan], ['grid', kColors.elements.grid],
      ['client', kColors.elements.client]], 'line'),
    group('decisions (flash)', [['merged', kColors.highlights.merge], ['rigid_adjust', kColors.highlights.rigid_adjust],
      ['added', kColors.highlights.add], ['deleted / pruned', kColors.highlights.delete],
      ['trimmed', kColors.highlights.trim]], 'wide'),
    el('div', { class: 'legend-group' }, el('h4', {}, 'changes in the building'),
      el('ul', {}, ...kChangeKinds.map((kind) => {
        const style = kChangeStyles[kind];
        return el('li', { dataset: { kind } },
          el('span', { class: `swatch ${style.dash ? 'dash' : style.under ? 'wide' : 'line'}`, style: `--swatch: ${style.color}` }), style.label);
      }))),
    group('grid', [['free', '#ffffff'], ['occupied', '#000000'], ['unknown', 'rgb(188, 194, 204)']], 'box'));
}
