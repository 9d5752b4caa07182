// The drive panel's pure parts: the WebSocket address and the command for the held directions.
import assert from 'node:assert/strict';
import { test } from 'node:test';

import { commandOf, driveUrl } from '../../../clients/web/js/drive.js';

test('the drive WebSocket is the robot\'s drive route as a driver, with the token when there is one', () => {
  assert.equal(driveUrl('http://127.0.0.1:8080', 'sim-1'), 'ws://127.0.0.1:8080/api/v1/robots/sim-1/drive?role=driver');
  assert.equal(driveUrl('https://example.test', 'a:b', 's&t'),
    'wss://example.test/api/v1/robots/a%3Ab/drive?role=driver&token=s%26t');
});

test('held directions add up, are capped at the limits and scaled by the speed share', () => {
  const limits = { max_v: 0.4, max_w: 1.25 };
  assert.deepEqual(commandOf([[1, 0]], limits, 0.5), { v: 0.2, w: 0 });
  assert.deepEqual(commandOf([[1, 0], [0, 1]], limits, 1), { v: 0.4, w: 1.25 });
  assert.deepEqual(commandOf([[1, 0], [1, 0]], limits, 1), { v: 0.4, w: 0 }, 'a key and a button: not twice');
  assert.deepEqual(commandOf([[1, 0], [-1, 0]], limits, 1), { v: 0, w: 0 });
  assert.deepEqual(commandOf([], limits, 1), { v: 0, w: 0 });
});
