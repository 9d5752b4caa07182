// PGM and map.yaml parsing as the grid API sends them.
import assert from 'node:assert/strict';
import { test } from 'node:test';

import {
  displayGrey, kUnknown, kUnknownRgb, parsePgm, pgmToRgba, tileToPgmPixels,
} from '../../../clients/web/js/pgm.js';

const pgm = (header, pixels) => new Uint8Array([...Buffer.from(header, 'latin1'), ...pixels]);

test('parses the server header with its comment and keeps the pixel order', () => {
  const image = parsePgm(pgm('P5\n# worldmodel occupancy grid\n3 2\n255\n', [0, 205, 255, 10, 20, 30]));
  assert.equal(image.width, 3);
  assert.equal(image.height, 2);
  assert.deepEqual([...image.pixels], [0, 205, 255, 10, 20, 30]);
});

test('a pixel value that looks like whitespace right after the header is data', () => {
  const image = parsePgm(pgm('P5 1 1 255\n', [10]));
  assert.deepEqual([...image.pixels], [10]);
});

test('refuses other formats, depths and short data', () => {
  assert.throws(() => parsePgm(pgm('P2\n1 1\n255\n', [0])), /P5/);
  assert.throws(() => parsePgm(pgm('P5\n1 1\n65535\n', [0, 0])), /maxval/);
  assert.throws(() => parsePgm(pgm('P5\n2 2\n255\n', [0, 0, 0])), /pixel bytes/);
  assert.throws(() => parsePgm(pgm('P5\n2', [])), /truncated|size/);
});

test('free reads white, occupied black, unknown bluish grey; conflict is tinted red', () => {
  assert.deepEqual([...pgmToRgba(new Uint8Array([0, 255, kUnknown]))], [0, 0, 0, 255, 255, 255, 255, 255, ...kUnknownRgb, 255]);
  const g = displayGrey(100);
  assert.deepEqual([...pgmToRgba(new Uint8Array([100, kUnknown]), 'ds_conflict')], [255, g, g, 255, ...kUnknownRgb, 255]);
});

test('display grey keeps the order of probabilities and makes p = 0.1 nearly white', () => {
  for (let v = 1; v < 256; ++v) assert.ok(displayGrey(v) >= displayGrey(v - 1), `monotonic at ${v}`);
  assert.ok(displayGrey(Math.round(255 * 0.9)) >= 245);
  assert.equal(displayGrey(Math.round(255 * 0.5)), 215);
});

test('a binary tile becomes PGM pixels: top row first, 255(1-p), NaN unknown', () => {
  const values = new Float32Array([0, 1, NaN, 0.5]);  // bottom row: 0, 1; top row: unknown, 0.5
  const pixels = tileToPgmPixels(values.buffer, 2);
  assert.deepEqual([...pixels], [kUnknown, 128, 255, 0]);
  assert.throws(() => tileToPgmPixels(new ArrayBuffer(12), 2), /expected 16/);
});
