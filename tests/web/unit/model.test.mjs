// The viewer's model: syncs, live updates, scans, and what a decision highlights.
import assert from 'node:assert/strict';
import { test } from 'node:test';

import { highlightTargets, objectOfEdge, WorldModel } from '../../../clients/web/js/model.js';

const edge = (id, p0, p1) => ({ id, p0, p1, rho: 0, phi: 0, cov: [[1e-4, 0], [0, 1e-4]], length: 1 });
const element = (id, p0 = [0, 0], p1 = [1, 0], source = 'scan') => ({ id, p0, p1, source, rho: 0, phi: Math.PI / 2, cov: [[1e-4, 0], [0, 1e-4]] });
const map = {
  version: 5,
  plan: 'p',
  objects: [
    { id: 'wall-1', attributes: ['solid'], edges: [edge('wall-1/0', [0, 5], [4, 5])] },
    { id: 'table-1', attributes: ['not_deformable'], edges: [edge('table-1/0', [1, 1], [2, 1]), edge('table-1/1', [2, 1], [2, 2])] },
  ],
  elements: [element('e1'), element('e2', [3, 3], [4, 4], 'client')],
};

test('loading a map indexes objects, their edges and elements', () => {
  const m = new WorldModel();
  m.loadMap(map);
  assert.equal(m.version, 5);
  assert.equal(m.objects.size, 2);
  assert.equal(m.edgeCount(), 3);
  assert.equal(m.edges.get('table-1/1').objectId, 'table-1');
  assert.equal(m.elements.size, 2);
  assert.deepEqual(m.bounds(), [0, 0, 4, 5]);
});

test('an update upserts, removes and keeps a ghost of what it removed', () => {
  const m = new WorldModel();
  m.loadMap(map);
  const result = m.applyUpdate({
    type: 'update', version: 6, decisions: [{ seq: 9, action: 'add', element: 'e3' }],
    elements: [element('e3', [7, 7], [8, 7]), { ...element('e1'), support: 2 }], removed: ['e2'],
    objects: [{ id: 'table-1', attributes: ['not_deformable'], edges: [edge('table-1/0', [1.1, 1], [2.1, 1])] }],
  }, 1000);
  assert.equal(result.decisions.length, 1);
  assert.equal(m.version, 6);
  assert.deepEqual([...m.elements.keys()].sort(), ['e1', 'e3']);
  assert.equal(m.elements.get('e1').support, 2);
  assert.equal(m.ghosts.get('e2').element.id, 'e2');
  assert.equal(m.edgeCount(), 2, 'the upserted object replaced its old edges');
  assert.equal(m.edges.has('table-1/1'), false);
  m.expireGhosts(1000 + 60_000);
  assert.equal(m.ghosts.size, 0);
});

test('updates already in the synced map are skipped', () => {
  const m = new WorldModel();
  m.loadMap(map);
  assert.equal(m.applyUpdate({ version: 5, elements: [element('e9')], removed: ['e1'] }), null);
  assert.equal(m.elements.has('e9'), false);
  assert.equal(m.elements.has('e1'), true);
});

test('a scan sets its observer pose and points', () => {
  const m = new WorldModel();
  m.applyScan({ type: 'scan', observer: 'intel', sensor: 'laser', pose: { x: 1, y: 2, theta: 0.5 }, points: [[1, 1]], scan_seq: 3 });
  m.applyScan({ type: 'scan', observer: 'intel', pose: { x: 2, y: 2, theta: 0 }, points: [] });
  assert.equal(m.robots.size, 1);
  assert.deepEqual(m.robots.get('intel').pose, { x: 2, y: 2, theta: 0 });
  m.applyScan({ type: 'scan', observer: 'bad', pose: { x: NaN, y: 0 } });
  assert.equal(m.robots.size, 1);
});

test('robots come from GET /api/v1/robots and robot events, and keep the points of their last scan', () => {
  const m = new WorldModel();
  m.loadRobots({ robots: [
    { id: 'r1', status: 'stale', pose: { x: 1, y: 2, theta: 0.5 }, track: [[0, 0, 0, 1], [1, 2, 0.5, 2], [NaN, 0, 0, 3]] },
    { id: 'listener', status: 'alive', pose: null, track: [] },  // primitives only: nowhere to draw it
  ] });
  assert.equal(m.robots.size, 1);
  assert.equal(m.robots.get('r1').status, 'stale');
  assert.equal(m.robots.get('r1').track.length, 2);
  m.applyScan({ type: 'scan', observer: 'r1', sensor: 'laser', pose: { x: 3, y: 2, theta: 0 }, points: [[4, 2]] });
  assert.equal(m.robots.get('r1').track.length, 2, 'a scan keeps the track');
  m.applyRobot({ id: 'r1', status: 'alive', pose: { x: 3, y: 2, theta: 0 }, track: [[0, 0, 0, 1], [1, 2, 0.5, 2], [3, 2, 0, 4]] });
  assert.deepEqual(m.robots.get('r1').points, [[4, 2]]);
  assert.equal(m.robots.get('r1').status, 'alive');
  assert.equal(m.robots.get('r1').track.length, 3);
  m.applyRobot({ id: 'r1', pose: { x: NaN, y: 0 } });
  assert.equal(m.robots.get('r1').pose.x, 3, 'a robot without a finite pose changes nothing');
});

test('decisions highlight what they touched', () => {
  assert.equal(objectOfEdge('wall-3/0'), 'wall-3');
  assert.equal(objectOfEdge('e12'), null);
  assert.deepEqual(highlightTargets({ action: 'add', element: 'e4', matched: {} }), [{ kind: 'element', id: 'e4', action: 'add' }]);
  assert.deepEqual(highlightTargets({ action: 'merge', element: 'e2', matched: { element: 'e2' } }), [{ kind: 'element', id: 'e2', action: 'merge' }]);
  assert.deepEqual(highlightTargets({ action: 'rigid_adjust', element: 'table-1/2', object: 'table-1' }),
    [{ kind: 'object', id: 'table-1', action: 'rigid_adjust' }]);
  assert.deepEqual(highlightTargets({ action: 'delete', element: null, object: 'wall-3', matched: { element: 'wall-3/0', object: 'wall-3' } }),
    [{ kind: 'edge', id: 'wall-3/0', action: 'delete' }]);
  assert.deepEqual(highlightTargets({ action: 'prune', element: 'e7' }), [{ kind: 'element', id: 'e7', action: 'prune' }]);
  assert.deepEqual(highlightTargets({ action: 'trim', element: 'e8' }), [{ kind: 'element', id: 'e8', action: 'trim' }]);
  assert.deepEqual(highlightTargets(null), []);
});

test('a delta since the synced version removes, then upserts; another run\'s or base\'s delta is refused', () => {
  const m = new WorldModel();
  m.loadMap({ ...map, server_instance: 'run-1' });
  const delta = {
    since: 5, version: 9, server_instance: 'run-1', plan: 'lab-2',
    objects: [{ id: 'crate-1', edges: [edge('crate-1/0', [5, 5], [6, 5])] }],
    elements: [{ ...element('e1'), support: 4 }, element('e7', [3, 3], [4, 3])],
    removed: { objects: ['table-1'], elements: ['e2'] },
  };
  assert.equal(m.applyDelta({ ...delta, server_instance: 'run-2' }), false);
  assert.equal(m.applyDelta({ ...delta, since: 4 }), false);
  assert.equal(m.version, 5, 'a refused delta changes nothing');
  assert.equal(m.applyDelta(delta), true);
  assert.equal(m.version, 9);
  assert.equal(m.plan, 'lab-2');
  assert.deepEqual([...m.objects.keys()].sort(), ['crate-1', 'wall-1']);
  assert.equal(m.edges.has('table-1/0'), false, 'a removed object takes its edges along');
  assert.equal(m.edges.get('crate-1/0').objectId, 'crate-1');
  assert.deepEqual([...m.elements.keys()].sort(), ['e1', 'e7']);
  assert.equal(m.elements.get('e1').support, 4);
});
