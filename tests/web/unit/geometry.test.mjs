// The viewer's pure geometry: covariance bands, picking distances, cell boxes, rates.
import assert from 'node:assert/strict';
import { test } from 'node:test';

import {
  containsCells, covarianceBand, elementCategory, kBand95, lateralSigma,
  objectCategory, padCells, pointSegmentDistance, RateMeter, unionBox, unionCells,
} from '../../../clients/web/js/geometry.js';

const close = (a, b, eps = 1e-9) => assert.ok(Math.abs(a - b) <= eps, `${a} != ${b}`);

test('lateral sigma is sigma_rho at the foot point and grows with sigma_phi along the line', () => {
  const cov = [[0.0004, 0], [0, 0.0001]];
  close(lateralSigma(cov, 0), 0.02);
  close(lateralSigma(cov, 3), Math.sqrt(0.0004 + 9 * 0.0001));
});

test('lateral sigma uses the rho-phi correlation with the sign of the abscissa', () => {
  const cov = [[0.0004, 0.0001], [0.0001, 0.0001]];
  // t² var_phi − 2 t cov + var_rho: the correlation narrows the band on the positive side
  close(lateralSigma(cov, 1), Math.sqrt(0.0001 - 0.0002 + 0.0004));
  close(lateralSigma(cov, -1), Math.sqrt(0.0001 + 0.0002 + 0.0004));
});

test('band of a horizontal line with pure rho uncertainty is a rectangle of half-width k sigma', () => {
  // y = 2: phi = pi/2, rho = 2
  const band = covarianceBand([0, 2], [4, 2], Math.PI / 2, [[0.01, 0], [0, 0]], kBand95, 3);
  assert.equal(band.length, 6);
  const w = kBand95 * 0.1;
  for (const [, y] of band.slice(0, 3)) close(y, 2 + w);
  for (const [, y] of band.slice(3)) close(y, 2 - w);
  close(band[0][0], 0, 1e-12);
  close(band[2][0], 4, 1e-12);
});

test('band is empty for a degenerate segment or a missing covariance', () => {
  assert.deepEqual(covarianceBand([1, 1], [1, 1], 0, [[1, 0], [0, 1]]), []);
  assert.deepEqual(covarianceBand([0, 0], [1, 0], Math.PI / 2, null), []);
  assert.deepEqual(covarianceBand([0, 0], [1, 0], Math.PI / 2, [[NaN, 0], [0, 1]]), []);
});

test('point to segment distance clamps to the endpoints', () => {
  close(pointSegmentDistance([1, 1], [0, 0], [2, 0]), 1);
  close(pointSegmentDistance([3, 0], [0, 0], [2, 0]), 1);
  close(pointSegmentDistance([-3, 4], [0, 0], [2, 0]), 5);
  close(pointSegmentDistance([1, 1], [0, 0], [0, 0]), Math.SQRT2);
});

test('categories follow attributes and sources, with other for the rest', () => {
  assert.equal(objectCategory({ attributes: ['solid', 'glass'] }), 'solid');
  assert.equal(objectCategory({ attributes: ['not_deformable'] }), 'not_deformable');
  assert.equal(objectCategory({ attributes: ['movable'] }), 'other');
  assert.equal(objectCategory({}), 'other');
  assert.equal(elementCategory({ source: 'scan' }), 'scan');
  assert.equal(elementCategory({ source: 'grid' }), 'grid');
  assert.equal(elementCategory({ source: 'client' }), 'client');
  assert.equal(elementCategory({ source: 'robot-7' }), 'other');
});

test('unions of cell boxes cover both', () => {
  const u = unionCells({ cx0: 0, cy0: 0, cx1: 2, cy1: 2 }, { cx0: -1, cy0: 1, cx1: 1, cy1: 5 });
  assert.deepEqual(u, { cx0: -1, cy0: 0, cx1: 2, cy1: 5 });
  assert.ok(containsCells(u, { cx0: 0, cy0: 0, cx1: 2, cy1: 2 }));
  assert.ok(!containsCells(u, { cx0: 0, cy0: 0, cx1: 3, cy1: 2 }));
  assert.equal(unionCells(null, null), null);
  assert.deepEqual(unionBox(null, [0, 0, 1, 1]), [0, 0, 1, 1]);
});

test('padding grows a cell box to chunk multiples without shrinking it', () => {
  assert.deepEqual(padCells({ cx0: -3, cy0: 5, cx1: 70, cy1: 64 }, 64), { cx0: -64, cy0: 0, cx1: 128, cy1: 64 });
});

test('rate meter counts the events of the sliding window', () => {
  const r = new RateMeter(2000);
  r.add(0);
  r.add(500, 3);
  assert.equal(r.rate(1000), 2);
  assert.equal(r.rate(2100), 1.5);
  assert.equal(r.rate(2600), 0);
});
