// Pure geometry and bookkeeping helpers of the viewer: no DOM, so `node --test` checks them directly.
// World coordinates are metres, angles radians; a line is (rho, phi): x cos(phi) + y sin(phi) = rho.

/** sqrt of the chi-square 95 % quantile with 2 degrees of freedom (5.991): the band drawn around a line
 *  contains every line of the (rho, phi) 95 % confidence ellipse, the same region the matcher's gate uses. */
export const kBand95 = Math.sqrt(5.991);

/**
 * Lateral standard deviation [m] of a line's position at abscissa t [m] along the line, measured from the
 * foot point rho·n, for a (rho, phi) covariance `cov` = [[var_rho, cov_rho_phi], [cov_rho_phi, var_phi]].
 * A point p = rho·n + t·d (n = (cos phi, sin phi), d = (−sin phi, cos phi)) moves across the perturbed line by
 * t·dphi − drho, so its variance is t²·var_phi − 2t·cov_rho_phi + var_rho. Negative round-off is clamped to 0.
 */
export function lateralSigma(cov, t) {
  const v = t * t * cov[1][1] - 2 * t * cov[0][1] + cov[0][0];
  return Math.sqrt(Math.max(0, v));
}

/**
 * The closed polygon (list of [x, y], world frame) of the band of half-width k·sigma(t) around the segment
 * p0–p1 of a line with angle `phi` and covariance `cov` over (rho, phi); `samples` points per side (≥ 2), as
 * sigma(t) is a hyperbola, not a straight line. Returns [] for a degenerate segment or a non-finite cov.
 */
export function covarianceBand(p0, p1, phi, cov, k = kBand95, samples = 9) {
  if (!cov || !Array.isArray(cov) || cov.length < 2) return [];
  const flat = [cov[0][0], cov[0][1], cov[1][1]];
  if (!flat.every(Number.isFinite)) return [];
  const nx = Math.cos(phi), ny = Math.sin(phi);
  const dx = -ny, dy = nx;
  const t0 = p0[0] * dx + p0[1] * dy;
  const t1 = p1[0] * dx + p1[1] * dy;
  if (!(Math.abs(t1 - t0) > 1e-9)) return [];
  const n = Math.max(2, samples | 0);
  const left = [], right = [];
  for (let i = 0; i < n; ++i) {
    const f = i / (n - 1);
    // Interpolate on the segment itself so the band follows the drawn endpoints exactly.
    const x = p0[0] + f * (p1[0] - p0[0]);
    const y = p0[1] + f * (p1[1] - p0[1]);
    const w = k * lateralSigma(cov, t0 + f * (t1 - t0));
    left.push([x + w * nx, y + w * ny]);
    right.push([x - w * nx, y - w * ny]);
  }
  return left.concat(right.reverse());
}

/** Distance [m] from point p to the segment a–b (to a when a = b). */
export function pointSegmentDistance(p, a, b) {
  const vx = b[0] - a[0], vy = b[1] - a[1];
  const len2 = vx * vx + vy * vy;
  let f = len2 > 0 ? ((p[0] - a[0]) * vx + (p[1] - a[1]) * vy) / len2 : 0;
  f = Math.min(1, Math.max(0, f));
  return Math.hypot(p[0] - (a[0] + f * vx), p[1] - (a[1] + f * vy));
}

/** Drawing category of a CAD object from its attributes: "solid", "not_deformable" or "other". */
export function objectCategory(object) {
  const attributes = object && Array.isArray(object.attributes) ? object.attributes : [];
  if (attributes.includes('solid')) return 'solid';
  if (attributes.includes('not_deformable')) return 'not_deformable';
  return 'other';
}

/** Drawing category of an observed element from its source: "scan", "grid", "client" or "other". */
export function elementCategory(element) {
  const source = element && element.source;
  return source === 'scan' || source === 'grid' || source === 'client' ? source : 'other';
}

/** Union of two world boxes [x0, y0, x1, y1]; null is the empty box. */
export function unionBox(a, b) {
  if (!a) return b ? b.slice() : null;
  if (!b) return a.slice();
  return [Math.min(a[0], b[0]), Math.min(a[1], b[1]), Math.max(a[2], b[2]), Math.max(a[3], b[3])];
}

/** Union of two cell boxes; null is the empty box. */
export function unionCells(a, b) {
  if (!a) return b ? { ...b } : null;
  if (!b) return { ...a };
  return {
    cx0: Math.min(a.cx0, b.cx0), cy0: Math.min(a.cy0, b.cy0),
    cx1: Math.max(a.cx1, b.cx1), cy1: Math.max(a.cy1, b.cy1),
  };
}

/** True when cell box `inner` lies inside `outer`. */
export function containsCells(outer, inner) {
  return !!outer && inner.cx0 >= outer.cx0 && inner.cy0 >= outer.cy0 && inner.cx1 <= outer.cx1 && inner.cy1 <= outer.cy1;
}

/** Number of cells of a cell box. */
export function cellCount(c) {
  return Math.max(0, c.cx1 - c.cx0) * Math.max(0, c.cy1 - c.cy0);
}

/**
 * Cell box `c` grown to multiples of `chunk` cells on every side, so a canvas that grows as a robot explores
 * is reallocated every few metres rather than after every scan.
 */
export function padCells(c, chunk = 64) {
  return {
    cx0: Math.floor(c.cx0 / chunk) * chunk, cy0: Math.floor(c.cy0 / chunk) * chunk,
    cx1: Math.ceil(c.cx1 / chunk) * chunk, cy1: Math.ceil(c.cy1 / chunk) * chunk,
  };
}

/**
 * Events per second over a sliding window: add(t) per event, rate(t) = events in (t − window, t] / window.
 * Times in milliseconds.
 */
export class RateMeter {
  constructor(windowMs = 5000) {
    this.windowMs = windowMs;
    this.times = [];
  }

  add(nowMs, count = 1) {
    for (let i = 0; i < count; ++i) this.times.push(nowMs);
    this.trim(nowMs);
  }

  rate(nowMs) {
    this.trim(nowMs);
    return this.times.length / (this.windowMs / 1000);
  }

  trim(nowMs) {
    let drop = 0;
    while (drop < this.times.length && this.times[drop] <= nowMs - this.windowMs) ++drop;
    if (drop) this.times.splice(0, drop);
  }
}
