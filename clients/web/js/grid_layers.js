// The occupancy grid as images: one offscreen canvas per layer, one pixel per cell, covering a cell box
// (`extent`) that grows as the robots explore. The view draws the active layer's canvas with a transform, so
// pan and zoom never touch the pixels; scans only re-fetch the region they changed (the event's bbox),
// throttled, one request at a time.

import { ApiError } from './api.js';
import {
  bboxQueryForCells, cellBox, cellCount, containsCells, isBox, padCells, unionCells,
} from './geometry.js';
import { kUnknownRgb, parseMapYaml, parsePgm, pgmToRgba } from './pgm.js';

export const kLayers = ['bayes', 'ds_belief', 'ds_plausibility', 'ds_conflict'];

/** Minimum time between two region fetches of the active layer [ms]. */
const kThrottleMs = 400;
/** A changed region above this many cells is fetched as the whole grid instead. */
const kMaxRegionCells = 16_000_000;
/** Chromium refuses canvases above 16384 px a side or 268 M px; stay well below. */
const kMaxCanvasSide = 16384;
const kMaxCanvasCells = 120_000_000;

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
    this.latestRevision = 0;      // highest grid_revision seen in events
    this.layers = new Map(kLayers.map((name) => [name, {
      name, canvas: null, extent: null, cells: null, needsFull: true, dirty: null, revision: null, fetches: 0, empty: false,
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

  /** A scan event changed the world box `bbox` [x0, y0, x1, y1] (metres); `revision` is its grid_revision. */
  markDirty(bbox, revision) {
    if (Number.isFinite(revision)) this.latestRevision = Math.max(this.latestRevision, revision);
    for (const l of this.layers.values()) {
      if (!isBox(bbox) || !this.resolution) {
        l.needsFull = true;  // no box, or we do not know the cells yet: read it all
        continue;
      }
      l.dirty = unionCells(l.dirty, cellBox(bbox, this.resolution));
    }
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
      if (l.needsFull || (l.dirty && cellCount(l.dirty) > kMaxRegionCells)) {
        await this.loadFull(l);
      } else if (l.dirty) {
        const region = l.dirty;
        l.dirty = null;
        await this.fetchRegion(l, region);
      }
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

  async ensureResolution() {
    if (this.resolution) return;
    // A one-cell JSON export names the exact resolution (the YAML prints it rounded).
    const probe = await this.api.json('/api/v1/grid?layer=bayes&format=json&bbox=0,0,0.0001,0.0001');
    if (!(probe.resolution > 0)) throw new Error('server sent no grid resolution');
    this.resolution = probe.resolution;
    if (Number.isFinite(probe.revision)) this.latestRevision = Math.max(this.latestRevision, probe.revision);
  }

  /**
   * Reads a whole layer. The PGM of the whole grid does not carry its origin, so the origin comes from
   * map.yaml read before and after it: the observed bounds only ever grow, so when both agree the image
   * starts there.
   */
  async loadFull(l) {
    l.needsFull = false;
    l.dirty = null;
    await this.ensureResolution();
    const revision = this.latestRevision;
    for (let attempt = 0; attempt < 4; ++attempt) {
      const before = await this.mapYaml();
      if (!before) {
        l.empty = true;  // no scan yet: the first scan event's bbox starts the canvas
        l.revision = revision;
        return;
      }
      const image = parsePgm(await this.api.bytes(`/api/v1/grid?layer=${l.name}&format=pgm`));
      const after = await this.mapYaml();
      if (!after || after.origin[0] !== before.origin[0] || after.origin[1] !== before.origin[1]) continue;
      const cx0 = Math.round(before.origin[0] / this.resolution);
      const cy0 = Math.round(before.origin[1] / this.resolution);
      const cells = { cx0, cy0, cx1: cx0 + image.width, cy1: cy0 + image.height };
      this.replaceCanvas(l, padCells(cells));
      this.paint(l, cells, image);
      l.cells = cells;
      l.empty = false;
      l.revision = revision;
      l.fetches++;
      return;
    }
    throw new Error('the grid kept growing while it was read; will retry');
  }

  async mapYaml() {
    try {
      return parseMapYaml(await this.api.text('/api/v1/grid/map.yaml'));
    } catch (error) {
      if (error instanceof ApiError && error.status === 404) return null;
      throw error;
    }
  }

  async fetchRegion(l, cells) {
    await this.ensureResolution();
    const revision = this.latestRevision;
    const query = bboxQueryForCells(cells, this.resolution);
    const image = parsePgm(await this.api.bytes(`/api/v1/grid?layer=${l.name}&format=pgm&bbox=${query}`));
    if (image.width !== cells.cx1 - cells.cx0 || image.height !== cells.cy1 - cells.cy0) {
      l.needsFull = true;  // the server snapped differently than we did: read it all rather than misplace it
      return;
    }
    this.ensureExtent(l, cells);
    this.paint(l, cells, image);
    l.cells = unionCells(l.cells, cells);
    l.empty = false;
    l.revision = Math.max(l.revision ?? 0, revision);
    l.fetches++;
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
