// The occupancy grid as images: one offscreen canvas per layer, one pixel per cell, covering a cell box
// (`extent`) that grows as the robots explore. The view draws the active layer's canvas with a transform, so
// pan and zoom never touch the pixels. The grid comes as tiles (GET /api/v1/grid/tiles): each tile has a
// revision, and after a scan only the tiles whose revision moved are read again, throttled, one sync at a time.

import { cellCount, containsCells, padCells, unionCells } from './geometry.js';
import { kUnknownRgb, pgmToRgba, tileToPgmPixels } from './pgm.js';

export const kLayers = ['bayes', 'ds_belief', 'ds_plausibility', 'ds_conflict', 'ds_decision', 'laser_bayes',
  'sonar_bayes', 'laser_sonar_conflict'];

/** Minimum time between two region fetches of the active layer [ms]. */
const kThrottleMs = 400;
/** Tiles read at once, and at most per sync (the rest follow in the next sync). */
const kParallelTiles = 8;
const kTilesPerSync = 512;
/** Chromium refuses canvases above 16384 px a side or 268 M px; stay well below. */
const kMaxCanvasSide = 16384;
const kMaxCanvasCells = 120_000_000;

/** 32-bit FNV-1a of bytes. */
export function fnv1a(bytes) {
  let h = 0x811c9dc5;
  for (let i = 0; i < bytes.length; ++i) {
    h ^= bytes[i];
    h = Math.imul(h, 0x01000193) >>> 0;
  }
  return h;
}

/** The cells of tile (tx, ty): [tx·T, (tx+1)·T) × [ty·T, (ty+1)·T). */
function tileCells(tx, ty, size) {
  return { cx0: tx * size, cy0: ty * size, cx1: (tx + 1) * size, cy1: (ty + 1) * size };
}

export class GridLayers {
  /**
   * @param api the Api
   * @param callbacks onChange() after pixels changed, onError(message or null)
   * @param createCanvas (width, height) -> a canvas element (injected so tests could pass their own)
   */
  constructor(api, { onChange, onError, createCanvas }) {
    this.api = api;
    this.onChange = onChange;
    this.onError = onError;
    this.createCanvas = createCanvas;
    this.active = 'bayes';
    this.resolution = null;       // [m] per cell, from the server
    this.tileSize = null;         // cells per tile side, from the server
    this.serverInstance = null;   // the server run the tile revisions count in
    this.latestRevision = 0;      // highest grid_revision seen in events
    this.layers = new Map(kLayers.map((name) => [name, {
      name, canvas: null, extent: null, cells: null, needsFull: true, dirty: true, revision: null, fetches: 0, empty: false,
      tiles: new Map(),  // "tx,ty" -> the revision drawn
    }]));
    this.busy = false;
    this.timer = null;
    this.lastFetchMs = -Infinity;
  }

  layer(name = this.active) {
    return this.layers.get(name);
  }

  setActive(name) {
    if (!this.layers.has(name) || name === this.active) return;
    this.active = name;
    this.onChange();
    this.schedule();
  }

  /** Forgets nothing but marks every layer for a full re-read (after a reconnect or a missed event). */
  resyncAll() {
    for (const l of this.layers.values()) l.needsFull = true;
    this.schedule(true);
  }

  /** A scan event changed the grid; `revision` is its grid_revision (the tiles say where). */
  markDirty(revision) {
    if (Number.isFinite(revision)) this.latestRevision = Math.max(this.latestRevision, revision);
    for (const l of this.layers.values()) l.dirty = true;
    this.schedule();
  }

  schedule(now = false) {
    if (this.busy || this.timer) return;
    const l = this.layer();
    if (!l.needsFull && !l.dirty) return;
    const wait = now ? 0 : Math.max(0, this.lastFetchMs + kThrottleMs - performance.now());
    this.timer = setTimeout(() => {
      this.timer = null;
      this.flush();
    }, wait);
  }

  async flush() {
    if (this.busy) return;
    const l = this.layer();
    this.busy = true;
    this.lastFetchMs = performance.now();
    let failed = false;
    try {
      await this.syncTiles(l);
      this.onError(null);
    } catch (error) {
      this.onError(`grid ${l.name}: ${error.message}`);
      l.needsFull = true;  // start again from scratch
      failed = true;
    } finally {
      this.busy = false;
    }
    this.onChange();
    if (failed) {
      setTimeout(() => this.schedule(), 2000);
    } else {
      this.schedule();  // what changed meanwhile, or the layer switched to
    }
  }

  /**
   * Reads the tile index and the tiles of layer `l` whose revision is not the one drawn (all of them after a
   * resync). A tile read after the index may be newer than the index said: it is then read once more next time.
   */
  async syncTiles(l) {
    l.dirty = false;
    if (l.needsFull) {
      l.needsFull = false;
      l.tiles.clear();
    }
    const index = await this.api.json('/api/v1/grid/tiles');
    if (!(index.resolution > 0) || !(index.tile_size_cells > 0)) throw new Error('server sent no tile geometry');
    this.resolution = index.resolution;
    if (Number.isFinite(index.revision)) this.latestRevision = Math.max(this.latestRevision, index.revision);
    const size = index.tile_size_cells;
    if (this.serverInstance !== index.server_instance || this.tileSize !== size) {
      // Another server run (or tile size): nothing drawn is known to be current.
      this.serverInstance = index.server_instance;
      this.tileSize = size;
      for (const other of this.layers.values()) other.tiles.clear();
    }
    const tiles = index.tiles || [];
    if (!tiles.length) {
      l.empty = true;  // no scan yet
      l.revision = index.revision;
      return;
    }
    let bounds = null;
    for (const [tx, ty] of tiles) bounds = unionCells(bounds, tileCells(tx, ty, size));
    if (cellCount(bounds) > kMaxCanvasCells) throw new Error(`grid of ${cellCount(bounds)} cells is too large to draw`);
    this.ensureExtent(l, bounds);
    const stale = tiles.filter(([tx, ty, revision]) => l.tiles.get(`${tx},${ty}`) !== revision);
    const now = stale.slice(0, kTilesPerSync);
    for (let i = 0; i < now.length; i += kParallelTiles) {
      const batch = now.slice(i, i + kParallelTiles);
      const bodies = await Promise.all(batch.map(([tx, ty]) => this.api.bytes(`/api/v1/grid/tiles/${l.name}/${tx}/${ty}`)));
      batch.forEach(([tx, ty, revision], k) => {
        this.paint(l, tileCells(tx, ty, size), { width: size, height: size, pixels: tileToPgmPixels(bodies[k], size) });
        l.tiles.set(`${tx},${ty}`, revision);
      });
    }
    l.cells = bounds;
    l.empty = false;
    if (now.length) l.fetches++;
    if (stale.length > now.length) {
      l.dirty = true;  // more next time
    } else {
      l.revision = Math.max(l.revision ?? 0, index.revision);
    }
  }

  /** Grows the layer's canvas (keeping its pixels) so that it covers `cells`. */
  ensureExtent(l, cells) {
    if (l.canvas && containsCells(l.extent, cells)) return;
    const extent = padCells(l.extent ? unionCells(l.extent, cells) : cells);
    const old = l.canvas, oldExtent = l.extent;
    this.replaceCanvas(l, extent);
    if (old) l.canvas.getContext('2d').drawImage(old, oldExtent.cx0 - extent.cx0, extent.cy1 - oldExtent.cy1);
  }

  /** A fresh canvas for `extent`, filled with the unknown grey (cells never fetched are unknown). */
  replaceCanvas(l, extent) {
    const width = extent.cx1 - extent.cx0, height = extent.cy1 - extent.cy0;
    if (width > kMaxCanvasSide || height > kMaxCanvasSide || width * height > kMaxCanvasCells)
      throw new Error(`grid of ${width}×${height} cells is too large to draw`);
    const canvas = this.createCanvas(Math.max(1, width), Math.max(1, height));
    const ctx = canvas.getContext('2d');
    ctx.fillStyle = `rgb(${kUnknownRgb.join(',')})`;
    ctx.fillRect(0, 0, canvas.width, canvas.height);
    l.canvas = canvas;
    l.extent = extent;
  }

  paint(l, cells, image) {
    if (!image.width || !image.height) return;
    const data = new ImageData(pgmToRgba(image.pixels, l.name), image.width, image.height);
    // Canvas rows run from the top (largest y), as the PGM's do.
    l.canvas.getContext('2d').putImageData(data, cells.cx0 - l.extent.cx0, l.extent.cy1 - cells.cy1);
  }

  /**
   * A digest (32-bit FNV-1a) of the RGBA pixels a layer shows for its cells, top row first, and their size: what
   * a test compares with the server's PGM of the same cells coloured the same way.
   */
  digest(name = this.active) {
    const l = this.layers.get(name);
    if (!l || !l.canvas || !l.cells) return null;
    const width = l.cells.cx1 - l.cells.cx0, height = l.cells.cy1 - l.cells.cy0;
    const data = l.canvas.getContext('2d').getImageData(l.cells.cx0 - l.extent.cx0, l.extent.cy1 - l.cells.cy1, width, height).data;
    return { width, height, digest: fnv1a(data) };
  }

  /**
   * What the test hook reports per layer: the cells read from the server (width, height, origin [m]), the
   * canvas holding them (padded for growth), the grid revision it shows at least, and how many reads it took.
   */
  summary() {
    const out = {};
    for (const [name, l] of this.layers) {
      out[name] = {
        width: l.cells ? l.cells.cx1 - l.cells.cx0 : 0,
        height: l.cells ? l.cells.cy1 - l.cells.cy0 : 0,
        origin: l.cells && this.resolution ? [l.cells.cx0 * this.resolution, l.cells.cy0 * this.resolution] : null,
        canvasWidth: l.canvas ? l.canvas.width : 0,
        canvasHeight: l.canvas ? l.canvas.height : 0,
        revision: l.revision,
        fetches: l.fetches,
        empty: l.empty,
      };
    }
    return out;
  }
}
