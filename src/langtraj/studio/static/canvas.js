/* A view of the world on a canvas: the world-to-screen frame (metres to CSS pixels, y up) and a canvas that keeps
 * its backing store at its CSS size times the device pixel ratio, with the map as a cached bitmap behind what
 * moves. See docs/studio.md, 'The page's code'.
 */

const FIT_PAD_M = 12; // a fitted view: the box plus this margin
const MIN_EXTENT_M = 40;

/** A world-to-screen frame: centre (cx, cy) metres, `s` CSS pixels per metre; y points up. */
export class Frame {
  constructor(cx = 0, cy = 0, s = 1) { Object.assign(this, { cx, cy, s }); }
  x(wx, w) { return w / 2 + (wx - this.cx) * this.s; }
  y(wy, hgt) { return hgt / 2 - (wy - this.cy) * this.s; }
  world(px, py, w, hgt) { return [this.cx + (px - w / 2) / this.s, this.cy - (py - hgt / 2) / this.s]; }
  /** Set ctx to draw in world metres (dpr: device pixels per CSS pixel). */
  apply(ctx, w, hgt, dpr) {
    ctx.setTransform(dpr * this.s, 0, 0, -dpr * this.s, dpr * (w / 2 - this.cx * this.s), dpr * (hgt / 2 + this.cy * this.s));
  }
  key(w, hgt) { return `${this.cx},${this.cy},${this.s},${w},${hgt}`; }
  /** The frame showing `box` [x0, y0, x1, y1] (plus `pad` metres, at least MIN_EXTENT_M across) in w x hgt. */
  static fit(box, w, hgt, pad = FIT_PAD_M) {
    let [x0, y0, x1, y1] = box;
    x0 -= pad; y0 -= pad; x1 += pad; y1 += pad;
    const ex = Math.max(x1 - x0, MIN_EXTENT_M);
    const ey = Math.max(y1 - y0, MIN_EXTENT_M);
    return new Frame((x0 + x1) / 2, (y0 + y1) / 2, Math.min(w / ex, hgt / ey));
  }
}

/** The bounding box [x0, y0, x1, y1] of the finite `points` [[x, y], ...], or null. */
export function boxOf(points) {
  let x0 = Infinity; let y0 = Infinity; let x1 = -Infinity; let y1 = -Infinity;
  for (const [x, y] of points) {
    if (!Number.isFinite(x) || !Number.isFinite(y)) continue;
    x0 = Math.min(x0, x); y0 = Math.min(y0, y); x1 = Math.max(x1, x); y1 = Math.max(y1, y);
  }
  return x0 <= x1 ? [x0, y0, x1, y1] : null;
}

/** A canvas that keeps its backing store at its CSS size times the device pixel ratio. */
export class Surface {
  constructor(canvas) {
    this.canvas = canvas;
    this.ctx = canvas.getContext('2d');
    this.bg = document.createElement('canvas');
    this.bgKey = '';
    this.w = 0; this.hgt = 0; this.dpr = 1;
    this.measure();
  }
  /** Follow the canvas's CSS size; true when it changed (the backing stores are then cleared). */
  measure() {
    const r = this.canvas.getBoundingClientRect();
    const dpr = window.devicePixelRatio || 1;
    const w = Math.max(1, Math.round(r.width));
    const hgt = Math.max(1, Math.round(r.height));
    if (w === this.w && hgt === this.hgt && dpr === this.dpr) return false;
    Object.assign(this, { w, hgt, dpr });
    this.canvas.width = this.bg.width = Math.round(w * dpr);
    this.canvas.height = this.bg.height = Math.round(hgt * dpr);
    this.bgKey = '';
    return true;
  }
  /** Copy the background bitmap onto the canvas, first redrawing it with `paint(ctx)` (device pixels) when `key`
   * (what it shows) changed. */
  background(key, paint) {
    if (key !== this.bgKey) {
      const ctx = this.bg.getContext('2d');
      ctx.setTransform(1, 0, 0, 1, 0, 0);
      paint(ctx);
      this.bgKey = key;
    }
    this.ctx.setTransform(1, 0, 0, 1, 0, 0);
    this.ctx.drawImage(this.bg, 0, 0);
  }
}
