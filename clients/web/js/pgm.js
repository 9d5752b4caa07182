// Binary PGM (P5) as the grid API sends it: ROS convention, value = round(255·(1 − p)), unknown = 205,
// rows from the top (largest y). Pure: no DOM.

/** The value the server writes for an unknown cell. */
export const kUnknown = 205;

/**
 * Parses a binary PGM: {width, height, maxval, pixels: Uint8Array (width·height, top row first)}.
 * Header comments (`# ...`) are skipped.
 * @throws Error naming the problem when the bytes are not an 8-bit P5 image of the announced size.
 */
export function parsePgm(bytes) {
  const data = bytes instanceof Uint8Array ? bytes : new Uint8Array(bytes);
  let pos = 0;
  const isSpace = (c) => c === 0x20 || c === 0x09 || c === 0x0a || c === 0x0d;
  const token = () => {
    for (;;) {
      while (pos < data.length && isSpace(data[pos])) ++pos;
      if (data[pos] === 0x23) {  // '#': comment to the end of the line
        while (pos < data.length && data[pos] !== 0x0a) ++pos;
        continue;
      }
      break;
    }
    const start = pos;
    while (pos < data.length && !isSpace(data[pos]) && data[pos] !== 0x23) ++pos;
    if (start === pos) throw new Error('parsePgm: truncated header');
    return String.fromCharCode(...data.subarray(start, pos));
  };
  if (token() !== 'P5') throw new Error('parsePgm: not a binary PGM (P5)');
  const width = Number(token());
  const height = Number(token());
  const maxval = Number(token());
  if (!Number.isInteger(width) || !Number.isInteger(height) || width < 0 || height < 0)
    throw new Error('parsePgm: bad size');
  if (maxval !== 255) throw new Error(`parsePgm: maxval ${maxval}, expected 255`);
  pos += 1;  // exactly one whitespace byte ends the header
  const count = width * height;
  if (data.length - pos < count) throw new Error(`parsePgm: ${data.length - pos} pixel bytes for ${count} pixels`);
  return { width, height, maxval, pixels: data.subarray(pos, pos + count) };
}

/** Display colour of unknown cells: a bluish grey, so it never reads as a probability. */
export const kUnknownRgb = [188, 194, 204];

/**
 * Display grey [0, 255] of a PGM value v = 255·(1 − p), v ≠ unknown: p < 0.5 spreads over 255..215 (free reads
 * white even when a cell has been seen only a few times, p ≈ 0.1), p ≥ 0.5 over 215..0 (occupied reads dark).
 * Monotonic in p, so no two probabilities swap order.
 */
export function displayGrey(v) {
  const p = 1 - v / 255;
  return Math.round(p < 0.5 ? 255 - (p / 0.5) * 40 : 215 * (1 - p) / 0.5);
}

/**
 * RGBA bytes (Uint8ClampedArray, width·height·4) for PGM pixels: free white, occupied black (displayGrey), unknown
 * kUnknownRgb. For the conflict layers the grey is tinted red, so conflict does not read as an obstacle.
 */
export function pgmToRgba(pixels, layer = 'bayes') {
  const lut = new Uint8Array(256);
  for (let v = 0; v < 256; ++v) lut[v] = displayGrey(v);
  const out = new Uint8ClampedArray(pixels.length * 4);
  const tint = layer === 'ds_conflict' || layer === 'laser_sonar_conflict';
  for (let i = 0, j = 0; i < pixels.length; ++i, j += 4) {
    const v = pixels[i];
    if (v === kUnknown) {
      out[j] = kUnknownRgb[0]; out[j + 1] = kUnknownRgb[1]; out[j + 2] = kUnknownRgb[2];
    } else {
      const g = lut[v];
      out[j] = tint ? 255 : g; out[j + 1] = g; out[j + 2] = g;
    }
    out[j + 3] = 255;
  }
  return out;
}

/**
 * A grid tile as GET /api/v1/grid/tiles/{layer}/{tx}/{ty} sends it (size² little-endian float32, rows from the
 * bottom, NaN unknown) → PGM pixels as the server's PGM would hold them (top row first, 255·(1−p), unknown 205).
 */
export function tileToPgmPixels(buffer, size) {
  const bytes = buffer instanceof ArrayBuffer ? buffer : buffer.buffer.slice(buffer.byteOffset, buffer.byteOffset + buffer.byteLength);
  if (bytes.byteLength !== size * size * 4) throw new Error(`a tile of ${bytes.byteLength} bytes, expected ${size * size * 4}`);
  const view = new DataView(bytes);
  const out = new Uint8Array(size * size);
  for (let row = 0; row < size; ++row) {
    const from = (size - 1 - row) * size;
    for (let x = 0; x < size; ++x) {
      const p = view.getFloat32((from + x) * 4, true);
      out[row * size + x] = Number.isNaN(p) ? kUnknown : Math.round(255 * (1 - Math.min(1, Math.max(0, p))));
    }
  }
  return out;
}
