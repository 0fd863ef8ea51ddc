/* What the studio's canvases draw, each in a frame (canvas.js): the map (one Path2D per style, built once per
 * scene), traffic lights, the prompts' targets (as viz.marks), agents as oriented boxes, labels, tooltips and the
 * scale bar. The colours are the legend's (index.html) and the exported video's. See docs/studio.md, 'The page'.
 */
import { clamp } from '/common/dom.js';

const STOP_BAR_M = 4; // as viz.style.MARK_STOP_BAR_M

export const COLOURS = { vehicle: '#1a5fb4', pedestrian: '#c64600', cyclist: '#26a269', other: '#813d9c' };
export const LOGGED = '#9aa3ad';
export const TARGET = '#e01b8f';
export const COLLIDED = '#c01c28';
export const PICKED = '#e5a50a';
const LIGHTS = { stop: '#d0242b', caution: '#e5a50a', go: '#2ec27e', unknown: '#77767b' };
const MAP_BG = '#eef0f3';

export const agentById = (scene, id) => scene.agents.find((a) => String(a.id) === String(id));
/** Agent `a`'s logged pose [x, y, heading] at `step`, or null where it is absent. */
export const posAt = (a, step) => (a.track && a.track[step]) || null;
/** An agent's box colour: by type, grey where it is replayed from the log. */
export const colourOf = (a) => (a.sim === false ? LOGGED : COLOURS[a.type] || COLOURS.other);

// ------------------------------------------------------------------ the map

const mapCache = new Map();

/** The map's polylines as Path2D objects in world metres, one per style (built once per scene). */
function mapPaths(scene) {
  if (mapCache.has(scene.key)) return mapCache.get(scene.key);
  const P = { lane: new Path2D(), edge: new Path2D(), line: new Path2D(), dashed: new Path2D(),
    crosswalk: new Path2D(), bump: new Path2D(), driveway: new Path2D(), stops: [] };
  for (const f of scene.map || []) {
    const pts = f.points || [];
    if (!pts.length) continue;
    if (f.type === 'stop_sign') { P.stops.push(pts[0]); continue; }
    const closed = f.type === 'crosswalk' || f.type === 'speed_bump' || f.type === 'driveway';
    const target = { lane: P.lane, road_edge: P.edge, road_line: f.dashed ? P.dashed : P.line, crosswalk: P.crosswalk,
      speed_bump: P.bump, driveway: P.driveway }[f.type] || P.lane;
    target.moveTo(pts[0][0], pts[0][1]);
    for (let i = 1; i < pts.length; i += 1) target.lineTo(pts[i][0], pts[i][1]);
    if (closed) target.closePath();
  }
  mapCache.set(scene.key, P);
  return P;
}

let hatch = null;
function hatchPattern(ctx) {
  if (!hatch) {
    hatch = document.createElement('canvas');
    hatch.width = hatch.height = 8;
    const c = hatch.getContext('2d');
    c.fillStyle = 'rgba(255,255,255,0.85)';
    c.fillRect(0, 0, 8, 8);
    c.strokeStyle = '#8d96a0';
    c.lineWidth = 1.5;
    c.beginPath(); c.moveTo(0, 8); c.lineTo(8, 0); c.moveTo(-2, 2); c.lineTo(2, -2); c.moveTo(6, 10); c.lineTo(10, 6);
    c.stroke();
  }
  return ctx.createPattern(hatch, 'repeat');
}

/** Lanes thin grey, road edges solid, road lines (dashed where dashed), crosswalks hatched, bumps and driveways
 * filled, stop signs as small red dots. */
function drawMap(ctx, P, frame, surf) {
  const px = 1 / frame.s; // one CSS pixel in metres
  frame.apply(ctx, surf.w, surf.hgt, surf.dpr);
  ctx.lineJoin = 'round';
  ctx.lineCap = 'round';
  ctx.fillStyle = '#e4e1d6';
  ctx.fill(P.driveway);
  const pattern = hatchPattern(ctx);
  pattern.setTransform(new DOMMatrix().scale(px / surf.dpr, -px / surf.dpr));
  ctx.fillStyle = pattern;
  ctx.fill(P.crosswalk);
  ctx.fillStyle = 'rgba(230, 160, 40, 0.45)';
  ctx.fill(P.bump);
  ctx.setLineDash([]);
  ctx.lineWidth = px;
  ctx.strokeStyle = '#b9c0c8';
  ctx.stroke(P.lane);
  ctx.strokeStyle = '#8d96a0';
  ctx.stroke(P.crosswalk);
  ctx.lineWidth = 1.2 * px;
  ctx.strokeStyle = '#7b848e';
  ctx.stroke(P.line);
  ctx.setLineDash([6 * px, 5 * px]);
  ctx.stroke(P.dashed);
  ctx.setLineDash([]);
  ctx.lineWidth = 2 * px;
  ctx.strokeStyle = '#2e3640';
  ctx.stroke(P.edge);
  ctx.fillStyle = '#c01c28';
  for (const [x, y] of P.stops) {
    ctx.beginPath();
    ctx.arc(x, y, Math.max(0.8, 3 * px), 0, 2 * Math.PI);
    ctx.fill();
  }
  ctx.setTransform(1, 0, 0, 1, 0, 0);
}

/** Paint `surf`'s background: the map of `scene` in `frame`, then `extra(ctx)` (CSS pixels) where given; cached
 * until the frame, the size or `extraKey` change. */
export function paintBackground(surf, frame, scene, extra = null, extraKey = '') {
  surf.background(`${scene.key}:${frame.key(surf.w, surf.hgt)}:${extraKey}`, (ctx) => {
    ctx.fillStyle = MAP_BG;
    ctx.fillRect(0, 0, surf.bg.width, surf.bg.height);
    drawMap(ctx, mapPaths(scene), frame, surf);
    if (extra) { ctx.setTransform(surf.dpr, 0, 0, surf.dpr, 0, 0); extra(ctx); }
  });
}

/** An empty canvas (no scene yet). */
export function paintBlank(surf) {
  surf.ctx.setTransform(1, 0, 0, 1, 0, 0);
  surf.ctx.fillStyle = MAP_BG;
  surf.ctx.fillRect(0, 0, surf.canvas.width, surf.canvas.height);
}

export function drawLights(ctx, lights, frame, surf) {
  for (const l of lights || []) {
    const x = frame.x(l.x, surf.w);
    const y = frame.y(l.y, surf.hgt);
    ctx.beginPath();
    ctx.arc(x, y, Math.max(3.5, 1.0 * frame.s), 0, 2 * Math.PI);
    ctx.fillStyle = LIGHTS[l.state] || LIGHTS.unknown;
    ctx.fill();
    ctx.lineWidth = 1;
    ctx.strokeStyle = '#1d232b';
    ctx.stroke();
  }
}

// ------------------------------------------------------------------ targets (as viz.marks._target_marks)

/** The point of `path` nearest `at`, and the path's direction there (unit vector or null). */
function nearestOnPath(path, at) {
  let k = 0; let best = Infinity;
  for (let i = 0; i < path.length; i += 1) {
    const d = Math.hypot(path[i][0] - at[0], path[i][1] - at[1]);
    if (d < best) { best = d; k = i; }
  }
  const a = path[Math.max(k - 1, 0)];
  const b = path[Math.min(k + 1, path.length - 1)];
  const n = Math.hypot(b[0] - a[0], b[1] - a[1]);
  return { k, dir: n > 1e-6 ? [(b[0] - a[0]) / n, (b[1] - a[1]) / n] : null };
}

/** `path` up to its point nearest `at`, ending at `at` (as viz.marks.until). */
function until(path, at) {
  const { k } = nearestOnPath(path, at);
  const p = path[k];
  const q = path[k + 1];
  const past = q && (at[0] - p[0]) * (q[0] - p[0]) + (at[1] - p[1]) * (q[1] - p[1]) > 0;
  return [...path.slice(0, past ? k + 1 : k), at];
}

/** Normalize a target of either shape (the prompts endpoint's or the simulation's `to_json`) to
 * {agent, other, behaviour, path, stopAt, goal, conflict, first}. */
export function normTarget(t) {
  if (!t) return null;
  const path = Array.isArray(t.path) ? t.path.filter((p) => Array.isArray(p) && p.length >= 2) : [];
  let stopAt = null;
  if (Array.isArray(t.stop)) stopAt = t.stop; // the prompts endpoint: the stop point
  else if (t.stop === true && Array.isArray(t.goal)) stopAt = t.goal; // the simulation: stand still at the goal
  const goal = !stopAt && Array.isArray(t.goal) ? t.goal : null;
  return { agent: t.agent ?? t.track_id ?? null, other: t.other ?? t.other_id ?? null, behaviour: t.behaviour,
    path: stopAt && path.length >= 2 ? until(path, stopAt) : path, stopAt, goal,
    conflict: Array.isArray(t.conflict) ? t.conflict : null, first: t.first ?? null };
}

function octagon(ctx, x, y, r) {
  ctx.beginPath();
  for (let i = 0; i < 8; i += 1) {
    const a = Math.PI / 8 + (i * Math.PI) / 4;
    ctx.lineTo(x + r * Math.cos(a), y + r * Math.sin(a));
  }
  ctx.closePath();
}

function star(ctx, x, y, r) {
  ctx.beginPath();
  for (let i = 0; i < 10; i += 1) {
    const a = -Math.PI / 2 + (i * Math.PI) / 5;
    const rr = i % 2 ? r * 0.45 : r;
    ctx.lineTo(x + rr * Math.cos(a), y + rr * Math.sin(a));
  }
  ctx.closePath();
}

/** A dashed path in the highlight colour, a stop bar across it at the stop point, a star at a goal, a cross at
 * the conflict point, each labelled; drawn in CSS pixels. */
export function drawTargets(ctx, targets, frame, surf) {
  const X = (p) => frame.x(p[0], surf.w);
  const Y = (p) => frame.y(p[1], surf.hgt);
  ctx.save();
  ctx.strokeStyle = TARGET;
  ctx.fillStyle = TARGET;
  ctx.font = '600 11px system-ui, sans-serif';
  for (const t of targets) {
    if (!t) continue;
    const who = t.agent !== null ? `@${t.agent}` : '';
    if (t.path.length >= 2) {
      ctx.lineWidth = 2.5;
      ctx.setLineDash([8, 5]);
      ctx.beginPath();
      ctx.moveTo(X(t.path[0]), Y(t.path[0]));
      for (const p of t.path.slice(1)) ctx.lineTo(X(p), Y(p));
      ctx.stroke();
      ctx.setLineDash([]);
    }
    if (t.stopAt) {
      const near = t.path.length >= 2 ? nearestOnPath(t.path, t.stopAt) : { dir: null };
      const half = Math.max(STOP_BAR_M / 2 * frame.s, 7);
      ctx.lineWidth = 4;
      ctx.beginPath();
      if (near.dir) {
        const [ux, uy] = near.dir; // across the path: (-uy, ux) in world, y flipped on screen
        ctx.moveTo(X(t.stopAt) - uy * half, Y(t.stopAt) - ux * half);
        ctx.lineTo(X(t.stopAt) + uy * half, Y(t.stopAt) + ux * half);
        ctx.stroke();
      } else {
        octagon(ctx, X(t.stopAt), Y(t.stopAt), 7);
        ctx.fill();
      }
      ctx.fillText(`${who} stop`.trim(), X(t.stopAt) + half + 3, Y(t.stopAt) - 3);
    }
    if (t.conflict) {
      const x = X(t.conflict); const y = Y(t.conflict);
      ctx.lineWidth = 3;
      ctx.beginPath();
      ctx.moveTo(x - 7, y - 7); ctx.lineTo(x + 7, y + 7); ctx.moveTo(x - 7, y + 7); ctx.lineTo(x + 7, y - 7);
      ctx.stroke();
      const order = t.first === true ? 'before' : t.first === false ? 'after' : 'crosses';
      ctx.fillText(t.other !== null ? `${who} ${order} @${t.other}` : `${who} conflict`, x + 9, y - 6);
    }
    if (t.goal && !(t.conflict && Math.hypot(t.goal[0] - t.conflict[0], t.goal[1] - t.conflict[1]) <= 1)) {
      star(ctx, X(t.goal), Y(t.goal), 8);
      ctx.fill();
      ctx.fillText(`${who} ${String(t.behaviour || 'target').replace(/_/g, ' ')}`.trim(), X(t.goal) + 10, Y(t.goal) - 6);
    }
  }
  ctx.restore();
}

// ------------------------------------------------------------------ agents, labels, tooltips, the scale bar

/** One agent as an oriented box (at least a few pixels), with a nose tick; `mark`: outline colour, `markPx` its
 * width (thinner on a thumbnail). */
export function drawAgent(ctx, a, x, y, heading, frame, surf, { alpha = 1, mark = null, markPx = 3 } = {}) {
  const sx = frame.x(x, surf.w);
  const sy = frame.y(y, surf.hgt);
  const len = Math.max((a.length || 4) * frame.s, 5);
  const wid = Math.max((a.width || 2) * frame.s, 4);
  ctx.save();
  ctx.translate(sx, sy);
  ctx.rotate(-(heading || 0));
  ctx.globalAlpha = alpha;
  ctx.fillStyle = colourOf(a);
  ctx.fillRect(-len / 2, -wid / 2, len, wid);
  ctx.globalAlpha = 1;
  ctx.lineWidth = a.sdc ? 2 : 1;
  ctx.strokeStyle = a.sdc ? '#000' : 'rgba(0,0,0,0.55)';
  ctx.strokeRect(-len / 2, -wid / 2, len, wid);
  ctx.beginPath(); // the nose
  ctx.moveTo(len / 2 - Math.min(len * 0.3, 6), 0);
  ctx.lineTo(len / 2, 0);
  ctx.strokeStyle = '#fff';
  ctx.lineWidth = 2;
  ctx.stroke();
  if (mark) {
    ctx.lineWidth = markPx;
    ctx.strokeStyle = mark;
    ctx.strokeRect(-len / 2 - markPx, -wid / 2 - markPx, len + 2 * markPx, wid + 2 * markPx);
  }
  ctx.restore();
}

export function drawLabel(ctx, text, x, y, frame, surf) {
  const sx = frame.x(x, surf.w) + 6;
  const sy = frame.y(y, surf.hgt) - 6;
  ctx.font = '11px system-ui, sans-serif';
  ctx.lineWidth = 3;
  ctx.strokeStyle = 'rgba(255,255,255,0.85)';
  ctx.strokeText(text, sx, sy);
  ctx.fillStyle = '#1d232b';
  ctx.fillText(text, sx, sy);
}

export function tooltip(ctx, text, x, y, surf) {
  ctx.font = '600 12px system-ui, sans-serif';
  const w = ctx.measureText(text).width + 10;
  const bx = clamp(x + 10, 2, surf.w - w - 2);
  const by = clamp(y - 30, 2, surf.hgt - 22);
  ctx.fillStyle = 'rgba(29,35,43,0.92)';
  ctx.fillRect(bx, by, w, 20);
  ctx.fillStyle = '#fff';
  ctx.fillText(text, bx + 5, by + 14);
}

const BAR_LENGTHS_M = [1, 2, 5, 10, 20, 50, 100, 200, 500, 1000];

/** The scale bar's length: the roundest of about a quarter of the panel's width, in metres. */
export const scaleBarMetres = (frame, surf) => BAR_LENGTHS_M.filter((m) => m * frame.s <= surf.w / 4).pop()
  || BAR_LENGTHS_M[0];

/** A scale bar bottom left on a light box, well inside the panel. */
export function drawScaleBar(ctx, frame, surf) {
  const metres = scaleBarMetres(frame, surf);
  const px = metres * frame.s;
  ctx.save();
  ctx.font = '11px system-ui, sans-serif';
  const label = `${metres} m`;
  const x0 = 12; const y0 = surf.hgt - 14;
  ctx.fillStyle = 'rgba(255,255,255,0.8)';
  ctx.fillRect(x0 - 6, y0 - 14, px + ctx.measureText(label).width + 18, 22);
  ctx.strokeStyle = '#222'; ctx.fillStyle = '#222'; ctx.lineWidth = 2;
  ctx.beginPath(); ctx.moveTo(x0, y0 - 5); ctx.lineTo(x0, y0); ctx.lineTo(x0 + px, y0); ctx.lineTo(x0 + px, y0 - 5); ctx.stroke();
  ctx.fillText(label, x0 + px + 5, y0 + 1);
  ctx.restore();
}
