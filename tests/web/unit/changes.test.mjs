// The changes in the building as the viewer shows them: shapes, the list, error words, refresh timing, token.
import assert from 'node:assert/strict';
import { test } from 'node:test';

import {
  changeCentre, changeEvidence, ChangeList, changeShapes, changeStyle, changeSummary, decisionErrorText, drawnPoint,
  kChangeKinds, kChangeStyles, kTokenKey, loadToken, percent, RefreshThrottle, saveToken,
} from '../../../clients/web/js/changes.js';

const near = (a, b, eps = 1e-9) => assert.ok(Math.abs(a - b) <= eps, `${a} vs ${b}`);
const nearPoint = (p, q, eps = 1e-9) => { near(p[0], q[0], eps); near(p[1], q[1], eps); };

const missing = {
  id: 'c0123456789ab', key: 'missing:wall-test/0', kind: 'wall_missing', object: 'wall-test', edge: 'wall-test/0',
  stretch: [0, 2], p0: [1, 2], p1: [3, 2], length: 2, confidence: 0.934, rule: 'wall_missing',
  evidence: { backed: 0, seen_through: 0.9, observed: 0.96, length: 2, beams_through: 412, beams_ended: 3 },
  explanation: 'seen through',
};
const table = {
  id: 'table-1', pose: { x: 6, y: -11, theta: 0 },
  edges: [{ p0: [5, -12], p1: [7, -12] }, { p0: [7, -12], p1: [7, -10] }, { p0: [7, -10], p1: [5, -10] }, { p0: [5, -10], p1: [5, -12] }],
};

test('every kind has its own colour, and the missing ones are dashed', () => {
  const colours = new Set(kChangeKinds.map((k) => kChangeStyles[k].color));
  assert.equal(colours.size, kChangeKinds.length);
  assert.ok(changeStyle('wall_missing').dash && changeStyle('wall_partly_missing').dash);
  assert.equal(changeStyle('new_wall').dash, null);
  assert.equal(changeStyle('new_wall').under, true, 'a new wall is a halo under its element');
  assert.equal(changeStyle('wall_missing').under, false, 'a missing wall is drawn over the plan');
  assert.equal(changeStyle('door_added').label, 'door added', 'a kind a newer server lists is still named');
  assert.equal(changeStyle(undefined).label, 'change');
});

test('a missing wall and a new wall are their stretch p0-p1', () => {
  const s = changeShapes(missing, undefined);
  assert.deepEqual(s.segments, [[[1, 2], [3, 2]]]);
  assert.equal(s.color, kChangeStyles.wall_missing.color);
  assert.deepEqual(s.ghost, []);
  const w = changeShapes({ kind: 'new_wall', p0: [0, 0], p1: [0, 4] });
  assert.deepEqual(w.segments, [[[0, 0], [0, 4]]]);
  assert.equal(w.color, kChangeStyles.new_wall.color);
  assert.equal(w.under, true);
  assert.equal(changeShapes({ kind: 'new_wall', p0: [0, NaN], p1: [0, 4] }), null, 'no geometry: nothing drawn');
  assert.equal(changeShapes(null), null);
});

test('a gone object is crossed out over its edges, or at its pose when they are not known', () => {
  const s = changeShapes({ kind: 'object_gone', object: 'table-1', p0: [6, -11], p1: [6, -11] }, table);
  assert.deepEqual(s.segments, [[[5, -12], [7, -10]], [[5, -10], [7, -12]]]);
  // Unknown edges: a cross `crossPx` wide at the pose.
  const c = changeShapes({ kind: 'object_gone', p0: [1, 1], p1: [1, 1] }, undefined, { pxM: 0.1, crossPx: 10 });
  assert.deepEqual(c.segments, [[[0.5, 0.5], [1.5, 1.5]], [[0.5, 1.5], [1.5, 0.5]]]);
});

test('a moved object is an arrow from its drawn pose to where it stands, with its drawn outline', () => {
  const moved = { kind: 'object_moved', object: 'table-1', p0: [5, -11], p1: [6, -11],
    moved_by: { dx: 1, dy: 0, dtheta: 0, distance: 1, sigma_xy: 0.01 } };
  const s = changeShapes(moved, table, { pxM: 0.01, headPx: 10 });
  assert.deepEqual(s.segments[0], [[5, -11], [6, -11]], 'the shaft');
  assert.equal(s.segments.length, 3, 'shaft and two barbs');
  for (const [a, b] of s.segments.slice(1)) {
    assert.deepEqual(a, [6, -11]);
    near(b[0], 6 - 0.1);
    near(Math.abs(b[1] + 11), 0.045);
  }
  assert.equal(s.ghost.length, 4);
  nearPoint(s.ghost[0][0], [4, -12]);
  nearPoint(s.ghost[0][1], [6, -12]);
  // A move shorter than the head still draws a head-long shaft ending at the object.
  const tiny = changeShapes({ ...moved, p0: [5.999, -11] }, undefined, { pxM: 0.01, headPx: 10 });
  nearPoint(tiny.segments[0][0], [5.9, -11]);
  assert.deepEqual(tiny.segments[0][1], [6, -11]);
  assert.deepEqual(tiny.ghost, [], 'no outline without the object');
});

test('the drawn point undoes the turn about the object and then its shift', () => {
  const pose = { x: 2, y: 1, theta: Math.PI / 2 };
  // Turned by +90° about (2, 1) and shifted by (1, 0): a corner now at (2, 2) was drawn at (2, 1) + R(-90°)(0, 1) - (1, 0).
  nearPoint(drawnPoint([2, 2], pose, { dx: 1, dy: 0, dtheta: Math.PI / 2 }), [2, 1]);
  nearPoint(drawnPoint([3, 1], pose, { dx: 0, dy: 0, dtheta: 0 }), [3, 1]);
});

test('the panel words: summary, evidence, percentages, centre', () => {
  assert.equal(percent(0.934), '93 %');
  assert.equal(percent(undefined), '–');
  assert.equal(changeSummary(missing), '2.00 m · confidence 93 %');
  assert.equal(changeSummary({ kind: 'object_moved', length: 0.12, confidence: 1 }), 'moved 0.12 m · confidence 100 %');
  assert.match(changeEvidence(missing), /edge 2\.00 m: seen 96 %, seen through 90 %, backed 0 %; beams through 412, ended 3 · rule wall_missing/);
  assert.match(changeEvidence({ moved_by: { dx: 0.1, dy: -0.2, dtheta: Math.PI / 180, sigma_xy: 0.01 } }), /dx 0\.100 m, dy -0\.200 m, dθ 1\.00°, σ 0\.010 m/);
  assert.equal(changeEvidence({ support: 7 }), '7 observations');
  assert.deepEqual(changeCentre(missing), [2, 2]);
  assert.equal(changeCentre({ p0: [0, 0] }), null);
});

test('the list keeps the server order, says when it changed and counts kinds', () => {
  const list = new ChangeList();
  const answer = { version: 7, grid_revision: 50, changes: [missing, { id: 'c1', kind: 'new_wall', p0: [0, 0], p1: [1, 0] }, { kind: 'x' }] };
  assert.equal(list.load(answer), true);
  assert.equal(list.size, 2, 'an entry without id is left out');
  assert.deepEqual(list.items.map((c) => c.id), [missing.id, 'c1']);
  assert.equal(list.get('c1').kind, 'new_wall');
  assert.deepEqual(list.countsByKind(), { wall_missing: 1, new_wall: 1 });
  const revision = list.revision;
  assert.equal(list.load(structuredClone(answer)), false, 'the same answer again changes nothing');
  assert.equal(list.revision, revision);
  assert.equal(list.load({ ...answer, version: 8 }), true, 'a new map version is news');
  assert.equal(list.load({ version: 9, grid_revision: 51, changes: [] }), true);
  assert.equal(list.size, 0);
  assert.equal(list.get('c1'), undefined);
});

test('a failed decision says what went wrong and what to do', () => {
  const err = (status, code, detail) => ({ status, code, detail, message: `${status}` });
  assert.match(decisionErrorText(err(401, 'unauthorized', 'needs a token'), 'accept c1'), /^accept c1: 401 not authorised: needs a token\. Enter the server's token/);
  assert.match(decisionErrorText(err(404, 'not_found', 'no change'), 'reject c1'), /404 no longer listed: no change\. The list was reloaded/);
  assert.equal(decisionErrorText(err(409, 'conflict', 'nothing to undo'), 'undo'), 'undo: 409 conflict: nothing to undo');
  assert.equal(decisionErrorText(err(503, 'busy', ''), 'undo'), 'undo: 503 busy');
  assert.equal(decisionErrorText(new Error('Failed to fetch'), 'undo'), 'undo: Failed to fetch');
});

test('the list is re-read when marked, never twice at once and at most every minMs unless forced', () => {
  const t = new RefreshThrottle(3000);
  assert.equal(t.due(0), true, 'the first read is due at once');
  t.started(0);
  t.mark();
  assert.equal(t.due(100), false, 'one read at a time');
  t.finished();
  assert.equal(t.due(2999), false, 'marked during the read: waits for the interval');
  assert.equal(t.due(3000), true);
  t.started(3000);
  t.finished();
  assert.equal(t.due(10000), false, 'not marked: no read');
  t.mark(true);
  assert.equal(t.due(3001), true, 'forced: at once');
  t.started(3001);
  assert.equal(t.forced, false);
  t.mark(true);
  assert.equal(t.due(3002), false, 'forced, but a read is under way');
  t.finished();
  assert.equal(t.due(3002), true, 'the forced mark is served after it');
});

test('the token: this tab\'s stored one, else the page\'s ?token=, kept in session storage', () => {
  const store = () => {
    const m = new Map();
    return { getItem: (k) => m.get(k) ?? null, setItem: (k, v) => m.set(k, String(v)), removeItem: (k) => m.delete(k), m };
  };
  const s = store();
  assert.equal(loadToken(s, ''), '');
  assert.equal(loadToken(s, '?token=abc'), 'abc');
  assert.equal(saveToken(s, 'typed'), true);
  assert.equal(s.m.get(kTokenKey), 'typed');
  assert.equal(loadToken(s, '?token=abc'), 'typed', 'what was typed wins');
  saveToken(s, '');
  assert.equal(s.m.has(kTokenKey), false);
  const blocked = { getItem() { throw new Error('blocked'); }, setItem() { throw new Error('blocked'); }, removeItem() {} };
  assert.equal(loadToken(blocked, '?token=x'), 'x');
  assert.equal(saveToken(blocked, 'y'), false);
  assert.equal(saveToken(null, 'y'), false);
  assert.equal(loadToken(null, ''), '');
});
