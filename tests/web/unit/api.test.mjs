// The API origin and the live-event stream's sequence tracking, with a stand-in WebSocket.
import assert from 'node:assert/strict';
import { test } from 'node:test';

import {
  apiBaseFromLocation, EventStream, eventsUrl, mapFromLocation, mapPath,
} from '../../../clients/web/js/api.js';

test('the API origin is the page origin unless ?api= names an http(s) origin', () => {
  const page = (search) => ({ origin: 'http://127.0.0.1:8080', search });
  assert.equal(apiBaseFromLocation(page('')), 'http://127.0.0.1:8080');
  assert.equal(apiBaseFromLocation(page('?api=http://127.0.0.1:9000/ignored/path')), 'http://127.0.0.1:9000');
  assert.equal(apiBaseFromLocation(page('?api=javascript:alert(1)')), 'http://127.0.0.1:8080');
  assert.equal(apiBaseFromLocation(page('?api=not a url')), 'http://127.0.0.1:8080');
  assert.equal(eventsUrl('http://127.0.0.1:9000'), 'ws://127.0.0.1:9000/api/v1/maps/default/events');
  assert.equal(eventsUrl('https://example.test', '', 'floor2'), 'wss://example.test/api/v1/maps/floor2/events');
  assert.equal(eventsUrl('http://127.0.0.1:9000', 's3cr&t'),
    'ws://127.0.0.1:9000/api/v1/maps/default/events?token=s3cr%26t');
});

test('the page shows the map ?map= names, when it is a map id, and asks for that map\'s resources', () => {
  const page = (search) => ({ origin: 'http://127.0.0.1:8080', search });
  assert.equal(mapFromLocation(page('')), 'default');
  assert.equal(mapFromLocation(page('?map=floor-2_b')), 'floor-2_b');
  for (const bad of ['Floor2', '-x', '_x', '../x', 'a/b', 'a'.repeat(33), '', 'x%2Fy']) {
    assert.equal(mapFromLocation(page(`?map=${bad}`)), 'default', bad);
  }
  assert.equal(mapPath('/api/v1/map?since=3', 'floor2'), '/api/v1/maps/floor2/map?since=3');
  assert.equal(mapPath('/api/v1/grid/tiles/bayes/0/1', 'default'), '/api/v1/maps/default/grid/tiles/bayes/0/1');
  assert.equal(mapPath('/api/v1/robots', 'floor2'), '/api/v1/maps/floor2/robots');
  // The server's own resources stay where they are.
  assert.equal(mapPath('/api/v1/maps', 'floor2'), '/api/v1/maps');
  assert.equal(mapPath('/api/v1/network', 'floor2'), '/api/v1/network');
  assert.equal(mapPath('/web/style.css', 'floor2'), '/web/style.css');
});

class FakeSocket {
  static last = null;
  constructor(url) {
    this.url = url;
    FakeSocket.last = this;
  }
  send(event) { this.onmessage({ data: JSON.stringify(event) }); }
  close() { this.onclose?.(); }
}

function stream() {
  const seen = { events: [], gaps: [], states: [] };
  globalThis.WebSocket = FakeSocket;
  const s = new EventStream('ws://x/api/v1/events', {
    onEvent: (e) => seen.events.push(e),
    onState: (st) => seen.states.push(st),
    onGap: (reason) => seen.gaps.push(reason),
  });
  s.start();
  FakeSocket.last.onopen();
  return { s, seen, socket: FakeSocket.last };
}

test('opening the stream asks for a sync; consecutive events do not', () => {
  const { s, seen, socket } = stream();
  socket.send({ type: 'hello', api: '/api/v1' });
  socket.send({ seq: 7, type: 'scan' });
  socket.send({ seq: 8, type: 'update' });
  assert.deepEqual(seen.gaps, ['connected']);
  assert.deepEqual(seen.events.map((e) => e.type), ['hello', 'scan', 'update']);
  assert.deepEqual(seen.states, ['connecting', 'open']);
  s.stop();
});

test('a hole in seq or a resync event asks for a sync', () => {
  const { s, seen, socket } = stream();
  socket.send({ seq: 3, type: 'hello' });
  socket.send({ seq: 4, type: 'update' });
  socket.send({ seq: 6, type: 'update' });
  assert.equal(seen.gaps.length, 2);
  assert.match(seen.gaps[1], /missed events 5\.\.5/);
  socket.send({ seq: 7, type: 'resync', reason: 'fell behind' });
  socket.send({ type: 'resync' });
  assert.deepEqual(seen.gaps.slice(2), ['fell behind', 'resync']);
  socket.send({ seq: 5, type: 'update' });  // late or repeated: no sync
  assert.equal(seen.gaps.length, 4);
  s.stop();
});

test('a closed stream reconnects and the new connection asks for a sync', async () => {
  const { s, seen, socket } = stream();
  socket.close();
  assert.equal(seen.states.at(-1), 'closed');
  await new Promise((resolve) => setTimeout(resolve, 600));
  assert.notEqual(FakeSocket.last, socket, 'a new socket');
  FakeSocket.last.onopen();
  assert.deepEqual(seen.gaps, ['connected', 'connected']);
  s.stop();
});
