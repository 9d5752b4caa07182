// The first laser scans of a CARMEN log (old FLASER format), as POST /api/v1/scans bodies.
import fs from 'node:fs';
import zlib from 'node:zlib';

/**
 * "No return" in the CARMEN logs is written as the sensor's maximum (81.83–81.91 m in intel, 50 m in others);
 * readings at or above this are sent as null (no reading), as logs' reader does [m].
 */
export const kNoReturnM = 50.0;

/**
 * The first `count` FLASER lines of `path` (plain or gzip): [{line, stamp, pose: {x, y, theta}, ranges}].
 * `FLASER n r1..rn x y theta odom_x odom_y odom_theta ipc_timestamp host logger_timestamp`; the pose is the
 * corrected robot pose (the intel log's laser offset is 0).
 * @throws Error naming the line when a FLASER line is malformed.
 */
export function readFlaserScans(path, count) {
  let bytes = fs.readFileSync(path);
  if (bytes[0] === 0x1f && bytes[1] === 0x8b) bytes = zlib.gunzipSync(bytes);
  const lines = bytes.toString('latin1').split('\n');
  const scans = [];
  for (let i = 0; i < lines.length && scans.length < count; ++i) {
    if (!lines[i].startsWith('FLASER ')) continue;
    const f = lines[i].trim().split(/\s+/);
    const n = Number(f[1]);
    if (!Number.isInteger(n) || n < 2 || f.length < 2 + n + 9) throw new Error(`${path}:${i + 1}: malformed FLASER line`);
    const ranges = f.slice(2, 2 + n).map(Number);
    const [x, y, theta] = f.slice(2 + n, 5 + n).map(Number);
    const stamp = Number(f[8 + n]);
    if (![x, y, theta].every(Number.isFinite) || !ranges.every(Number.isFinite))
      throw new Error(`${path}:${i + 1}: non-numeric FLASER field`);
    scans.push({ line: i + 1, stamp, pose: { x, y, theta }, ranges });
  }
  return scans;
}

/** The POST /api/v1/scans body of one FLASER scan: 180 beams over 180° from −90°, 1° apart. */
export function scanRequest(scan, source = 'intel') {
  const n = scan.ranges.length;
  // Even counts (180, 360) stop one step short of +90°, odd ones (181, 361) cover both ends.
  const increment = n % 2 === 0 ? Math.PI / n : Math.PI / (n - 1);
  return {
    sensor: 'laser',
    source,
    stamp: scan.stamp,
    pose: scan.pose,
    angle_min: -Math.PI / 2,
    angle_increment: increment,
    ranges: scan.ranges.map((r) => (r >= kNoReturnM ? null : r)),
    range_min: 0.0,
    range_max: kNoReturnM,
    sigma_range: 0.02,
  };
}
