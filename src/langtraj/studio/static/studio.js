/* LangTraj Studio: pick a scene, write @id prompts and see how each is read, run the simulation as a job, watch
 * the rollouts replayed from their positions, judge them, keep one as a test case (docs/studio.md, 'The page').
 * Vanilla JS without a build step, served under a strict CSP (no inline code or style); all text coming from
 * the server or the user is inserted with textContent / createElement, never as markup. The canvases are drawn
 * from the arrays the API returns: the map once per view (an offscreen bitmap), the agents every frame.
 */
// ------------------------------------------------------------------ constants and state

const READ_DEBOUNCE_MS = 300; // a prompt is read this long after the last keystroke
const FILTER_DEBOUNCE_MS = 250;
const POLL_ACTIVE_MS = 1000; // the jobs list while a job is queued or running
const POLL_IDLE_MS = 4000; // otherwise (jobs started in other tabs appear)
const FIT_PAD_M = 12; // the initial view: the agents plus this margin
const MIN_EXTENT_M = 40;
const HIT_TOL_PX = 6; // a click this close to an agent's box picks it
const TRAIL_STEPS = 10; // the replay's trail behind each agent
const STOP_BAR_M = 4; // as viz.style.MARK_STOP_BAR_M
const MAX_STATS = 4000;

const COLOURS = { vehicle: '#1a5fb4', pedestrian: '#c64600', cyclist: '#26a269', other: '#813d9c' };
const LOGGED = '#9aa3ad';
const TARGET = '#e01b8f';
const LIGHTS = { stop: '#d0242b', caution: '#e5a50a', go: '#2ec27e', unknown: '#77767b' };
const MAP_BG = '#eef0f3';

const S = {
  scenes: [], kinds: new Set(), sceneKey: null, scene: null, sceneCache: new Map(), mapCache: new Map(),
  view: null, prompts: [{ text: '', result: null }], active: 0, readSeq: 0, reading: null,
  jobs: [], jobItems: new Map(), pollTimer: null, openJob: null, replay: null,
};

/** Frame times of the replay (requestAnimationFrame timestamps, ms) for measuring smoothness. */
window.studioStats = { frames: [] };

const $ = (id) => document.getElementById(id);

// ------------------------------------------------------------------ DOM helpers (text only, never markup)

function h(tag, attrs = {}, ...kids) {
  const el = document.createElement(tag);
  for (const [k, v] of Object.entries(attrs)) {
    if (v === null || v === undefined || v === false) continue;
    if (k === 'class') el.className = v;
    else if (k.startsWith('on')) el.addEventListener(k.slice(2), v);
    else el.setAttribute(k, v === true ? '' : String(v));
  }
  for (const kid of kids.flat()) {
    if (kid !== null && kid !== undefined && kid !== false) el.append(kid instanceof Node ? kid : String(kid));
  }
  return el;
}

const say = (text) => { $('status').textContent = text; };
function showIn(id, text) { $(id).textContent = text || ''; $(id).hidden = !text; }
const showError = (text) => showIn('error', text);
const clamp = (x, lo, hi) => Math.min(Math.max(x, lo), hi);
const debounce = (fn, ms) => { let t = null; return (...a) => { clearTimeout(t); t = setTimeout(() => fn(...a), ms); }; };
const fmt = (x, digits = 3) => {
  if (typeof x === 'number') return Number.isFinite(x) ? x.toFixed(digits) : '—';
  return x === null || x === undefined || x === '' ? '—' : String(x);
};

// ------------------------------------------------------------------ API

/** JSON request; an HTTP error throws an Error whose message is the server's `error`. */
async function api(method, path, body) {
  const init = { method, headers: {} };
  if (body !== undefined) { init.headers['Content-Type'] = 'application/json'; init.body = JSON.stringify(body); }
  let res;
  try { res = await fetch(path, init); } catch (err) { throw new Error(`cannot reach the studio server (${err.message})`); }
  const data = await res.json().catch(() => null);
  if (res.ok) return data;
  const msg = data && data.error;  // every studio error answers {"error": "..."}
  throw Object.assign(new Error(msg || `${res.status} ${res.statusText}`), { status: res.status });
}

async function sceneDetail(key) {
  if (!S.sceneCache.has(key)) S.sceneCache.set(key, api('GET', `/api/scenes/${encodeURIComponent(key)}`));
  try { return await S.sceneCache.get(key); } catch (err) { S.sceneCache.delete(key); throw err; }
}

function saveHash() {
  const p = new URLSearchParams();
  if (S.sceneKey) p.set('scene', S.sceneKey);
  if (S.openJob) p.set('job', S.openJob.id);
  history.replaceState(null, '', p.toString() ? `#${p}` : location.pathname);
}

// ------------------------------------------------------------------ geometry: a view of the world on a canvas

/** A world-to-screen frame: centre (cx, cy) metres, `s` CSS pixels per metre; y points up. */
class Frame {
  constructor(cx = 0, cy = 0, s = 1) { Object.assign(this, { cx, cy, s }); }
  x(wx, w) { return w / 2 + (wx - this.cx) * this.s; }
  y(wy, hgt) { return hgt / 2 - (wy - this.cy) * this.s; }
  world(px, py, w, hgt) { return [this.cx + (px - w / 2) / this.s, this.cy - (py - hgt / 2) / this.s]; }
  /** Set ctx to draw in world metres (dpr: device pixels per CSS pixel). */
  apply(ctx, w, hgt, dpr) {
    ctx.setTransform(dpr * this.s, 0, 0, -dpr * this.s, dpr * (w / 2 - this.cx * this.s), dpr * (hgt / 2 + this.cy * this.s));
  }
  key(w, hgt) { return `${this.cx},${this.cy},${this.s},${w},${hgt}`; }
  static fit(box, w, hgt, pad = FIT_PAD_M) {
    let [x0, y0, x1, y1] = box;
    x0 -= pad; y0 -= pad; x1 += pad; y1 += pad;
    const ex = Math.max(x1 - x0, MIN_EXTENT_M);
    const ey = Math.max(y1 - y0, MIN_EXTENT_M);
    return new Frame((x0 + x1) / 2, (y0 + y1) / 2, Math.min(w / ex, hgt / ey));
  }
}

function boxOf(points) {
  let x0 = Infinity; let y0 = Infinity; let x1 = -Infinity; let y1 = -Infinity;
  for (const [x, y] of points) {
    if (!Number.isFinite(x) || !Number.isFinite(y)) continue;
    x0 = Math.min(x0, x); y0 = Math.min(y0, y); x1 = Math.max(x1, x); y1 = Math.max(y1, y);
  }
  return x0 <= x1 ? [x0, y0, x1, y1] : null;
}

/** A canvas that keeps its backing store at its CSS size times the device pixel ratio. */
class Surface {
  constructor(canvas) {
    this.canvas = canvas;
    this.ctx = canvas.getContext('2d');
    this.bg = document.createElement('canvas');
    this.bgKey = '';
    this.w = 0; this.hgt = 0; this.dpr = 1;
    this.measure();
  }
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
  /** The map (and whatever `extra` draws in world metres) as a bitmap, redrawn when the frame or size changed. */
  background(frame, paths, extra, extraKey = '') {
    const key = frame.key(this.w, this.hgt) + extraKey;
    if (key !== this.bgKey) {
      const ctx = this.bg.getContext('2d');
      ctx.setTransform(1, 0, 0, 1, 0, 0);
      ctx.fillStyle = MAP_BG;
      ctx.fillRect(0, 0, this.bg.width, this.bg.height);
      drawMap(ctx, paths, frame, this);
      if (extra) extra(ctx);
      this.bgKey = key;
    }
    this.ctx.setTransform(1, 0, 0, 1, 0, 0);
    this.ctx.drawImage(this.bg, 0, 0);
  }
}

// ------------------------------------------------------------------ the map

/** The map's polylines as Path2D objects in world metres, one per style (built once per scene). */
function mapPaths(scene) {
  if (S.mapCache.has(scene.key)) return S.mapCache.get(scene.key);
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
  S.mapCache.set(scene.key, P);
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
 * filled, stop signs as small red octagons. */
function drawMap(ctx, P, frame, surf) {
  if (!P) return;
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

function drawLights(ctx, lights, frame, surf) {
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

/** Normalize a target of either shape (the prompts endpoint's or the simulation's `to_json`) to
 * {agent, other, behaviour, path, stopAt, goal, conflict, first}. */
function normTarget(t) {
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

/** `path` up to its point nearest `at`, ending at `at` (as viz.marks.until). */
function until(path, at) {
  const { k } = nearestOnPath(path, at);
  const p = path[k];
  const q = path[k + 1];
  const past = q && (at[0] - p[0]) * (q[0] - p[0]) + (at[1] - p[1]) * (q[1] - p[1]) > 0;
  return [...path.slice(0, past ? k + 1 : k), at];
}

/** A dashed path in the highlight colour, a stop bar across it at the stop point, a star at a goal, a cross at
 * the conflict point, each labelled; drawn in CSS pixels. */
function drawTargets(ctx, targets, frame, surf) {
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

// ------------------------------------------------------------------ agents

/** One agent as an oriented box (at least a few pixels), with a nose tick; `mark`: outline colour. */
function drawAgent(ctx, a, x, y, heading, frame, surf, { alpha = 1, mark = null } = {}) {
  const sx = frame.x(x, surf.w);
  const sy = frame.y(y, surf.hgt);
  const len = Math.max((a.length || 4) * frame.s, 5);
  const wid = Math.max((a.width || 2) * frame.s, 4);
  ctx.save();
  ctx.translate(sx, sy);
  ctx.rotate(-(heading || 0));
  ctx.globalAlpha = alpha;
  ctx.fillStyle = a.sim === false ? LOGGED : COLOURS[a.type] || COLOURS.other;
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
    ctx.lineWidth = 3;
    ctx.strokeStyle = mark;
    ctx.strokeRect(-len / 2 - 3, -wid / 2 - 3, len + 6, wid + 6);
  }
  ctx.restore();
}

function drawLabel(ctx, text, x, y, frame, surf) {
  const sx = frame.x(x, surf.w) + 6;
  const sy = frame.y(y, surf.hgt) - 6;
  ctx.font = '11px system-ui, sans-serif';
  ctx.lineWidth = 3;
  ctx.strokeStyle = 'rgba(255,255,255,0.85)';
  ctx.strokeText(text, sx, sy);
  ctx.fillStyle = '#1d232b';
  ctx.fillText(text, sx, sy);
}

const agentById = (scene, id) => scene.agents.find((a) => String(a.id) === String(id));
const posAt = (a, step) => (a.track && a.track[step]) || null;

// ------------------------------------------------------------------ the scene view (pan, zoom, hover, click)

function initialFrame(scene, surf) {
  const cur = scene.current_step;
  const pts = scene.agents.map((a) => posAt(a, cur)).filter(Boolean);
  const box = boxOf(pts) || scene.bounds;
  return box ? Frame.fit(box, surf.w, surf.hgt) : new Frame(0, 0, 4);
}

function promptTargets() {
  return S.prompts.map((p) => p.result && p.result.target && normTarget(p.result.target)).filter(Boolean);
}

function promptedAgents() {
  const ids = new Set();
  for (const p of S.prompts) {
    const r = p.result && p.result.reading;
    if (r && r.agent !== null && r.agent !== undefined) ids.add(String(r.agent));
    if (r && r.other !== null && r.other !== undefined) ids.add(String(r.other));
  }
  return ids;
}

let sceneDrawQueued = false;
function drawScene() {
  if (sceneDrawQueued) return;
  sceneDrawQueued = true;
  requestAnimationFrame(() => { sceneDrawQueued = false; paintScene(); });
}

function paintScene() {
  const V = S.view;
  if (!V) return;
  V.surf.measure();
  const { surf } = V;
  const { ctx } = surf;
  const scene = S.scene;
  if (!scene) {
    ctx.setTransform(1, 0, 0, 1, 0, 0);
    ctx.fillStyle = MAP_BG;
    ctx.fillRect(0, 0, surf.canvas.width, surf.canvas.height);
    return;
  }
  if (!V.frame) V.frame = initialFrame(scene, surf);
  const frame = V.frame;
  surf.background(frame, mapPaths(scene));
  ctx.setTransform(surf.dpr, 0, 0, surf.dpr, 0, 0);
  const cur = scene.current_step;
  // the logged history as fading trails
  ctx.lineWidth = 2;
  ctx.lineCap = 'round';
  for (const a of scene.agents) {
    const colour = a.sim === false ? LOGGED : COLOURS[a.type] || COLOURS.other;
    ctx.strokeStyle = colour;
    for (let i = 1; i <= cur; i += 1) {
      const p = posAt(a, i - 1); const q = posAt(a, i);
      if (!p || !q) continue;
      ctx.globalAlpha = 0.1 + 0.6 * (i / cur);
      ctx.beginPath();
      ctx.moveTo(frame.x(p[0], surf.w), frame.y(p[1], surf.hgt));
      ctx.lineTo(frame.x(q[0], surf.w), frame.y(q[1], surf.hgt));
      ctx.stroke();
    }
  }
  ctx.globalAlpha = 1;
  drawTargets(ctx, promptTargets(), frame, surf);
  drawLights(ctx, scene.lights, frame, surf);
  const prompted = promptedAgents();
  const picked = new Set([$('adversary').value, $('target').value].filter(Boolean));
  for (const a of scene.agents) {
    const p = posAt(a, cur);
    if (!p) continue;
    const id = String(a.id);
    const mark = prompted.has(id) ? TARGET : picked.has(id) ? '#e5a50a' : V.hover === id ? '#1d232b' : null;
    drawAgent(ctx, a, p[0], p[1], p[2], frame, surf, { mark });
  }
  for (const a of scene.agents) {
    const p = posAt(a, cur);
    if (p) drawLabel(ctx, String(a.id), p[0], p[1], frame, surf);
  }
  if (V.hover !== null) {
    const a = agentById(scene, V.hover);
    const p = a && posAt(a, cur);
    if (p) tooltip(ctx, `@${a.id} ${a.type}${a.sdc ? ' (ego)' : ''}${a.sim ? '' : ' (log)'}`,
      frame.x(p[0], surf.w), frame.y(p[1], surf.hgt), surf);
  }
}

function tooltip(ctx, text, x, y, surf) {
  ctx.font = '600 12px system-ui, sans-serif';
  const w = ctx.measureText(text).width + 10;
  const bx = clamp(x + 10, 2, surf.w - w - 2);
  const by = clamp(y - 30, 2, surf.hgt - 22);
  ctx.fillStyle = 'rgba(29,35,43,0.92)';
  ctx.fillRect(bx, by, w, 20);
  ctx.fillStyle = '#fff';
  ctx.fillText(text, bx + 5, by + 14);
}

/** The agent under CSS pixel (px, py) of the scene canvas at the current step, or null. */
function agentAt(px, py) {
  const { frame, surf } = S.view;
  const scene = S.scene;
  if (!scene || !frame) return null;
  const [wx, wy] = frame.world(px, py, surf.w, surf.hgt);
  const tol = HIT_TOL_PX / frame.s;
  let best = null; let bestD = Infinity;
  for (const a of scene.agents) {
    const p = posAt(a, scene.current_step);
    if (!p) continue;
    const dx = wx - p[0]; const dy = wy - p[1];
    const c = Math.cos(-(p[2] || 0)); const s = Math.sin(-(p[2] || 0));
    const u = dx * c - dy * s; const v = dx * s + dy * c;
    const halfL = Math.max(a.length || 4, 5 / frame.s) / 2 + tol;
    const halfW = Math.max(a.width || 2, 4 / frame.s) / 2 + tol;
    const d = Math.hypot(dx, dy);
    if (Math.abs(u) <= halfL && Math.abs(v) <= halfW && d < bestD) { best = a; bestD = d; }
  }
  return best;
}

function setupSceneCanvas() {
  const canvas = $('scene-canvas');
  S.view = { surf: new Surface(canvas), frame: null, hover: null, drag: null };
  const V = S.view;
  const local = (e) => { const r = canvas.getBoundingClientRect(); return [e.clientX - r.left, e.clientY - r.top]; };
  canvas.addEventListener('pointerdown', (e) => {
    if (e.button !== 0 || !S.scene) return;
    const [x, y] = local(e);
    V.drag = { x, y, cx: V.frame.cx, cy: V.frame.cy, moved: false };
    canvas.setPointerCapture(e.pointerId);
    e.preventDefault(); // keep the prompt box's caret where it is
  });
  canvas.addEventListener('pointermove', (e) => {
    if (!S.scene) return;
    const [x, y] = local(e);
    if (V.drag) {
      if (Math.hypot(x - V.drag.x, y - V.drag.y) > 4) V.drag.moved = true;
      if (V.drag.moved) {
        canvas.classList.add('dragging');
        V.frame = new Frame(V.drag.cx - (x - V.drag.x) / V.frame.s, V.drag.cy + (y - V.drag.y) / V.frame.s, V.frame.s);
        drawScene();
      }
      return;
    }
    const a = agentAt(x, y);
    const id = a ? String(a.id) : null;
    if (id !== V.hover) {
      V.hover = id;
      $('hover-info').textContent = a
        ? `@${a.id}: ${a.type}${a.sdc ? ', the ego (SDC)' : ''}${a.sim ? '' : ', replayed from the log'} — click to insert @${a.id}`
        : 'Drag to pan, wheel to zoom; click an agent to insert its @id.';
      drawScene();
    }
  });
  const end = (e) => {
    if (!V.drag) return;
    const { moved } = V.drag;
    V.drag = null;
    canvas.classList.remove('dragging');
    if (e.type === 'pointerup' && !moved) {
      const [x, y] = local(e);
      const a = agentAt(x, y);
      if (a) insertAgent(a.id);
      else say('No agent there: click on an agent\'s box to insert its @id.');
    }
  };
  canvas.addEventListener('pointerup', end);
  canvas.addEventListener('pointercancel', end);
  canvas.addEventListener('pointerleave', () => { if (V.hover !== null && !V.drag) { V.hover = null; drawScene(); } });
  canvas.addEventListener('wheel', (e) => {
    if (!S.scene || !V.frame) return;
    e.preventDefault();
    const [x, y] = local(e);
    const { surf, frame } = V;
    const [wx, wy] = frame.world(x, y, surf.w, surf.hgt);
    const s = clamp(frame.s * Math.exp(-e.deltaY * 0.0015), 0.05, 200);
    // keep the world point under the cursor where it is
    V.frame = new Frame(wx - (x - surf.w / 2) / s, wy + (y - surf.hgt / 2) / s, s);
    drawScene();
  }, { passive: false });
  canvas.addEventListener('keydown', (e) => { // keyboard pan and zoom
    if (!S.scene || !V.frame) return;
    const f = V.frame; const step = 60 / f.s;
    const moves = { ArrowLeft: [-step, 0, 1], ArrowRight: [step, 0, 1], ArrowUp: [0, step, 1], ArrowDown: [0, -step, 1],
      '+': [0, 0, 1.25], '=': [0, 0, 1.25], '-': [0, 0, 0.8] };
    const m = moves[e.key];
    if (!m) return;
    e.preventDefault();
    V.frame = new Frame(f.cx + m[0], f.cy + m[1], f.s * m[2]);
    drawScene();
  });
  $('fit').addEventListener('click', () => { if (S.scene) { V.frame = initialFrame(S.scene, V.surf); drawScene(); } });
  new ResizeObserver(() => drawScene()).observe(canvas);
}

// ------------------------------------------------------------------ the scene picker

function sceneQuery() {
  const p = new URLSearchParams();
  const q = $('scene-search').value.trim();
  if (q) p.set('q', q);
  if ($('scene-kind').value) p.set('kind', $('scene-kind').value);
  if ($('min-agents').value !== '') p.set('min_agents', $('min-agents').value);
  if ($('max-agents').value !== '') p.set('max_agents', $('max-agents').value);
  return p.toString();
}

let scenesSeq = 0;
async function loadScenes() {
  const seq = ++scenesSeq;
  let data;
  try {
    const q = sceneQuery();
    data = await api('GET', `/api/scenes${q ? `?${q}` : ''}`);
  } catch (err) {
    if (seq === scenesSeq) showError(`Cannot list the scenes: ${err.message}`);
    return;
  }
  if (seq !== scenesSeq) return; // a newer filter answered first
  S.scenes = data.scenes || [];
  for (const s of S.scenes) {
    if (s.kind && !S.kinds.has(s.kind)) {
      S.kinds.add(s.kind);
      $('scene-kind').append(h('option', { value: s.kind }, s.kind));
    }
  }
  renderScenes();
  const errors = data.errors || [];
  $('scene-errors').hidden = errors.length === 0;
  $('scene-error-list').replaceChildren(...errors.map((e) => h('li', {},
    h('code', { title: e.file }, String(e.file).split('/').pop()), ': ', String(e.error).replace(`${e.file}: `, ''))));
}

function renderScenes() {
  $('scene-count').textContent = `${S.scenes.length} scene${S.scenes.length === 1 ? '' : 's'}`;
  $('scene-list').replaceChildren(...S.scenes.map((s) => {
    const file = String(s.file || '').split('/').pop();
    const window_ = s.window === null || s.window === undefined ? '' : ` · window ${s.window}`;
    return h('li', {}, h('button', {
      type: 'button', class: 'scene', 'data-key': s.key, 'aria-pressed': s.key === S.sceneKey ? 'true' : 'false',
      onclick: () => pickScene(s.key),
    }, h('strong', {}, s.scenario_id), h('small', {}, `${s.kind} · ${s.agents} agents (${s.sim_agents} simulated)${window_}`),
    h('small', {}, file)));
  }));
}

async function pickScene(key) {
  showError('');
  say('Loading the scene…');
  let scene;
  try { scene = await sceneDetail(key); } catch (err) { showError(`Cannot load the scene: ${err.message}`); say(''); return; }
  const switched = S.sceneKey !== null && S.sceneKey !== undefined && S.sceneKey !== key;
  const typed = S.prompts.some((p) => p.text.trim());
  S.sceneKey = key;
  S.scene = scene;
  S.view.frame = null;
  S.view.hover = null;
  for (const p of S.prompts) p.result = null;
  if (switched) {
    // the @ids of the old scene name other agents here (or none): never carry them over
    if (typed) S.prompts = [{ text: '', result: null }];
    S.active = 0;
    for (const id of ['run-error', 'read-error', 'case-error']) showIn(id, '');
  }
  $('scene-title').textContent = `Scene ${scene.scenario_id} (${scene.agents.length} agents)`;
  $('hover-info').textContent = 'Drag to pan, wheel to zoom; click an agent to insert its @id.';
  for (const b of $('scene-list').querySelectorAll('button.scene')) {
    b.setAttribute('aria-pressed', b.dataset.key === key ? 'true' : 'false');
  }
  const sim = scene.agents.filter((a) => a.sim);
  const options = (none) => [h('option', { value: '' }, none),
    ...sim.map((a) => h('option', { value: String(a.id) }, `@${a.id} ${a.type}${a.sdc ? ' (ego)' : ''}`))];
  $('adversary').replaceChildren(...options('none'));
  $('target').replaceChildren(...options('none'));
  $('insert-agent').replaceChildren(h('option', { value: '' }, 'Insert @id…'),
    ...scene.agents.map((a) => h('option', { value: String(a.id) }, `@${a.id} ${a.type}`)));
  saveHash();
  say(`Scene ${scene.scenario_id} loaded.${switched && typed ? ' The previous scene’s prompts were cleared: their @ids named its agents.' : ''}`);
  renderPrompts();
  readPrompts();
  drawScene();
}

// ------------------------------------------------------------------ prompts

function insertAgent(id) {
  const i = clamp(S.active, 0, S.prompts.length - 1);
  const box = $('prompts').querySelectorAll('textarea')[i];
  if (!box) return;
  const { value } = box;
  const start = box.selectionStart ?? value.length;
  const end = box.selectionEnd ?? value.length;
  const before = value.slice(0, start);
  const after = value.slice(end);
  const token = `${before && !/\s$/.test(before) ? ' ' : ''}@${id}${/^\s/.test(after) ? '' : ' '}`;
  box.value = before + token + after;
  const caret = (before + token).length;
  box.focus();
  box.setSelectionRange(caret, caret);
  S.prompts[i].text = box.value;
  say(`Inserted @${id} into prompt ${i + 1}.`);
  scheduleRead();
}

function renderPrompts() {
  const items = S.prompts.map((p, i) => {
    const box = h('textarea', { id: `prompt-${i}`, rows: 2, 'aria-label': `Prompt ${i + 1}`, 'aria-describedby': `reading-${i}`,
      placeholder: '@12 slows down', spellcheck: 'false' });
    box.value = p.text;
    box.addEventListener('input', () => { p.text = box.value; S.active = i; scheduleRead(); });
    box.addEventListener('focus', () => { S.active = i; });
    const remove = h('button', { type: 'button', class: 'remove', 'aria-label': `Remove prompt ${i + 1}`,
      disabled: S.prompts.length < 2, onclick: () => removePrompt(i) }, '✕');
    return h('li', { class: 'prompt' }, h('div', { class: 'prompt-edit' }, box, remove),
      h('div', { id: `reading-${i}`, class: 'reading', 'aria-live': 'polite' }, readingView(p)));
  });
  $('prompts').replaceChildren(...items);
}

function renderReadings() {
  S.prompts.forEach((p, i) => { const el = $(`reading-${i}`); if (el) el.replaceChildren(readingView(p)); });
}

/** How prompt `p` was read: the reader's description, whether the map allows it, the warning or error. */
function readingView(p) {
  if (!p.text.trim()) return h('span', { class: 'pending' }, 'Empty: write a prompt such as “@12 slows down”.');
  if (!S.scene) return h('span', { class: 'pending' }, 'Pick a scene to read it against.');
  const r = p.result;
  if (!r || p.pending) return h('span', { class: 'pending' }, 'Reading…');
  const out = h('span', { class: 'read' });
  const reading = r.reading;
  const read = Boolean(reading && reading.behaviour);
  if (!r.ok) {
    out.append(h('span', { class: 'pill bad' }, 'cannot run'), ' ');
    if (reading && reading.describe) out.append(h('span', { class: 'describe' }, reading.describe), ' ');
    out.append(h('span', { class: 'bad' }, r.error || 'The prompt cannot be run.'));
    return out;
  }
  if (!read) {
    out.append(h('span', { class: 'pill warn' }, 'not read'), ' ',
      h('span', { class: 'warn describe' }, (reading && reading.describe) || 'The reader did not read it; it steers by its text alone.'));
    return out;
  }
  out.append(h('span', { class: 'ok describe' }, reading.describe), ' ');
  if (r.feasible === true) out.append(h('span', { class: 'pill ok' }, 'feasible'));
  else if (r.feasible === false) out.append(h('span', { class: 'pill warn' }, 'the map rules it out'));
  if (r.warning) out.append(h('span', { class: 'warn' }, r.warning));
  return out;
}

function addPrompt() {
  S.prompts.push({ text: '', result: null });
  S.active = S.prompts.length - 1;
  renderPrompts();
  $(`prompt-${S.active}`).focus();
}

function removePrompt(i) {
  if (S.prompts.length < 2) return;
  S.prompts.splice(i, 1);
  S.active = clamp(S.active, 0, S.prompts.length - 1);
  renderPrompts();
  readPrompts();
}

const selected = (id) => ($(id).value === '' ? null : Number($(id).value));

/** The prompts survive a reload of the tab (sessionStorage: this tab only). */
function keepPrompts() {
  try { sessionStorage.setItem('studio.prompts', JSON.stringify(S.prompts.map((p) => p.text))); } catch { /* private mode */ }
}

function restorePrompts() {
  try {
    const texts = JSON.parse(sessionStorage.getItem('studio.prompts') || '[]');
    if (Array.isArray(texts) && texts.length) S.prompts = texts.map((text) => ({ text: String(text), result: null }));
  } catch { /* nothing kept */ }
}

let readTimer = null;
function scheduleRead() {
  keepPrompts();
  for (const p of S.prompts) if (p.text.trim()) p.pending = true;
  renderReadings();
  clearTimeout(readTimer);
  readTimer = setTimeout(readPrompts, READ_DEBOUNCE_MS);
}

/** Read every non-empty prompt against the scene; resolves to true when every prompt is read, understood and
 * not ruled out by the map (what Run requires). Older answers arriving late are dropped. */
function readPrompts() {
  clearTimeout(readTimer);
  keepPrompts();
  const seq = ++S.readSeq;
  showIn('read-error', '');
  const idx = S.prompts.map((p, i) => (p.text.trim() ? i : -1)).filter((i) => i >= 0);
  if (!S.scene || !idx.length) {
    for (const p of S.prompts) { p.result = null; p.pending = false; }
    renderReadings();
    drawScene();
    S.reading = Promise.resolve(false);
    return S.reading;
  }
  const body = {
    prompts: idx.map((i) => S.prompts[i].text), adversary: selected('adversary'), target: selected('target'),
    planner: $('planner').value || null,
  };
  S.reading = api('POST', `/api/scenes/${encodeURIComponent(S.sceneKey)}/prompts`, body).then((data) => {
    if (seq !== S.readSeq) return S.reading; // superseded
    const results = data.prompts || [];
    S.prompts.forEach((p) => { p.result = null; p.pending = false; });
    idx.forEach((i, k) => { S.prompts[i].result = results[k] || null; });
    if (data.error) showIn('read-error', data.error);
    else if (data.ok) showIn('run-error', ''); // the cause of a refused run is fixed: its message goes with it
    renderReadings();
    drawScene();
    return Boolean(data.ok) && idx.every((i) => {
      const r = S.prompts[i].result;
      return r && r.ok;
    });
  }, (err) => {
    if (seq !== S.readSeq) return S.reading;
    S.prompts.forEach((p) => { p.pending = false; p.result = null; });
    showIn('read-error', `The prompts cannot be read: ${err.message}`);
    renderReadings();
    drawScene();
    return false;
  });
  return S.reading;
}

// ------------------------------------------------------------------ run

/** Why the prompts cannot run as they are (one line), or null. */
function blocker() {
  if (!S.scene) return 'Pick a scene first.';
  const empty = S.prompts.findIndex((p) => !p.text.trim());
  if (empty >= 0) return `Prompt ${empty + 1} is empty: write it (e.g. “@12 slows down”) or remove it.`;
  for (const [i, p] of S.prompts.entries()) {
    const r = p.result;
    if (!r) continue;
    if (!r.ok) return `Prompt ${i + 1} cannot be run: ${r.error || 'it is not understood'}`;
  }
  return null;
}

async function run() {
  showIn('run-error', '');
  const rollouts = Number($('rollouts').value);
  if (!Number.isInteger(rollouts) || rollouts < 1 || rollouts > 16) {
    showIn('run-error', 'Rollouts must be a whole number from 1 to 16.'); return;
  }
  const seed = Number($('seed').value || 0);
  if (!Number.isInteger(seed)) { showIn('run-error', 'The seed must be a whole number.'); return; }
  let why = blocker();
  if (why) { showIn('run-error', why); return; }
  const button = $('run');
  button.disabled = true;
  $('run-status').textContent = 'Checking the prompts…';
  try {
    const ok = await readPrompts(); // the latest text, read now
    why = blocker() || (!ok && ($('read-error').textContent || 'The prompts cannot be run as they are.'));
    if (why) { showIn('run-error', why); return; }
    $('run-status').textContent = 'Starting…';
    const data = await api('POST', '/api/jobs', {
      scene: S.sceneKey, prompts: S.prompts.map((p) => p.text), rollouts, seed,
      adversary: selected('adversary'), target: selected('target'), compare: $('compare').checked,
      planner: $('planner').value || null,
    });
    const { job } = data;
    say(`Job ${job.id} ${job.status === 'queued' ? 'queued' : 'started'}: ${rollouts} rollout${rollouts === 1 ? '' : 's'} of ${job.scenario_id}.`);
    S.jobs = [job, ...S.jobs.filter((j) => j.id !== job.id)];
    renderJobs();
    pollJobs();
  } catch (err) {
    showIn('run-error', err.message);
  } finally {
    button.disabled = false;
    $('run-status').textContent = '';
  }
}

// ------------------------------------------------------------------ jobs

const active = (j) => j.status === 'queued' || j.status === 'running';

async function pollJobs() {
  clearTimeout(S.pollTimer);
  try {
    const data = await api('GET', '/api/jobs');
    const before = new Map(S.jobs.map((j) => [j.id, j.status]));
    S.jobs = data.jobs || [];
    renderJobs();
    for (const j of S.jobs) {
      if (before.get(j.id) && before.get(j.id) !== j.status && !active(j)) {
        say(`Job ${j.id} ${j.status}${j.status === 'done' ? ': open it to watch the rollouts.' : '.'}`);
      }
    }
  } catch (err) {
    say(`The jobs list could not be refreshed (${err.message}); retrying.`);
  }
  S.pollTimer = setTimeout(pollJobs, S.jobs.some(active) ? POLL_ACTIVE_MS : POLL_IDLE_MS);
}

function jobItem(id) {
  if (S.jobItems.has(id)) return S.jobItems.get(id);
  const el = {
    li: h('li', { class: 'job', 'data-id': id }),
    title: h('strong'), badge: h('span', { class: 'status-badge' }), prompts: h('p', { class: 'job-prompts' }),
    bar: h('progress', { max: 1, value: 0, 'aria-label': `Progress of job ${id}` }), stage: h('span', { class: 'job-stage' }),
    err: h('p', { class: 'job-error', role: 'note' }),
    open: h('button', { type: 'button', class: 'open', onclick: () => openJob(id) }, 'Open'),
    again: h('button', { type: 'button', class: 'again', onclick: () => resubmit(id) }, 'Run again'),
  };
  el.li.append(h('div', { class: 'job-head' }, el.title, el.badge), el.prompts, el.bar,
    h('div', { class: 'job-head' }, el.stage, el.open, el.again), el.err);
  S.jobItems.set(id, el);
  return el;
}

/** Update the jobs list in place (keyed by id), so focus and buttons survive each poll. */
function renderJobs() {
  $('jobs-empty').hidden = S.jobs.length > 0;
  const lis = S.jobs.map((j) => {
    const el = jobItem(j.id);
    el.li.classList.toggle('open', Boolean(S.openJob && S.openJob.id === j.id));
    const driver = j.planner ? `ego: ${j.planner}` : 'every agent simulated';
    el.title.textContent = `${j.scenario_id || j.scene} · ${j.rollouts} rollout${j.rollouts === 1 ? '' : 's'}, seed ${j.case.seeds[0]} · ${driver}`;
    el.badge.textContent = j.status;
    el.badge.className = `status-badge ${j.status}`;
    el.prompts.textContent = (j.case.prompts || []).join(' · ') || '(no prompt)';
    el.bar.value = clamp(Number(j.progress) || (j.status === 'done' ? 1 : 0), 0, 1);
    el.bar.hidden = !active(j);
    const pct = `${Math.round(el.bar.value * 100)}%`;
    el.stage.textContent = active(j) ? `${j.stage || j.status} (${pct})` : j.finished ? `finished ${time(j.finished)}` : j.stage || '';
    el.err.textContent = j.error || '';
    el.err.hidden = !j.error;
    el.open.hidden = j.status !== 'done';
    el.again.hidden = j.status !== 'interrupted' && j.status !== 'failed';
    if (j.status === 'queued') el.stage.textContent = `queued since ${time(j.created)}`;
    else if (j.status === 'running' && j.started) el.stage.textContent = `${j.stage || 'running'} (${pct}), started ${time(j.started)}`;
    el.open.setAttribute('aria-label', `Open job ${j.id}`);
    return el.li;
  });
  const list = $('jobs');
  const same = list.children.length === lis.length && lis.every((li, i) => list.children[i] === li);
  if (!same) list.replaceChildren(...lis);
}

async function resubmit(id) {
  try {
    const { job } = await api('POST', `/api/jobs/${encodeURIComponent(id)}/resubmit`);
    say(`Job ${id} submitted again as ${job.id}.`);
    S.jobs = [job, ...S.jobs.filter((j) => j.id !== job.id)];
    renderJobs();
    pollJobs();
  } catch (err) {
    showError(`Cannot run job ${id} again: ${err.message}`);
  }
}

function time(t) {  // an ISO time from the server
  const d = new Date(t);
  return Number.isNaN(d.getTime()) ? String(t) : d.toLocaleTimeString();
}

// ------------------------------------------------------------------ watch: the replay

async function openJob(id) {
  showError('');
  say(`Opening job ${id}…`);
  let job; let scene;
  try {
    job = await api('GET', `/api/jobs/${encodeURIComponent(id)}`);
    if (!job.result) throw new Error(`job ${id} has no result (${job.status})`);
    scene = await sceneDetail(job.scene);
  } catch (err) { showError(`Cannot open job ${id}: ${err.message}`); say(''); return; }
  stopReplay();
  S.openJob = job;
  saveHash();
  renderJobs();
  S.replay = buildReplay(job, scene);
  fillFollow(S.replay);
  $('replay').hidden = false;
  const res = job.result;
  const runs = res.runs || {};
  $('replay-meta').textContent = `Job ${job.id} · ${job.scenario_id} · ${job.rollouts} rollout${job.rollouts === 1 ? '' : 's'}, `
    + `seed ${job.case.seeds[0]}${runs.prompted && runs.prompted.seconds ? ` · simulated in ${fmt(runs.prompted.seconds, 1)} s` : ''}`;
  const which = $('which-rollout');
  which.replaceChildren(...Array.from({ length: S.replay.nRollouts }, (_, k) => h('option', { value: k }, `rollout ${k + 1}`)));
  const R = S.replay;
  $('scrub').max = R.total - 1;
  R.t = R.hist - 1;
  layoutReplay();
  renderResults(job);
  $('case-result').hidden = true;
  showIn('case-error', '');
  $('dl-npz').href = `/api/jobs/${encodeURIComponent(job.id)}/rollouts.npz`;
  $('dl-video').href = `/api/jobs/${encodeURIComponent(job.id)}/video.mp4`;
  say(`Job ${job.id} opened: press Play to watch.`);
  $('replay').scrollIntoView({ block: 'start' });
}

/** Per run and rollout, every agent's positions over the whole timeline (the logged history up to the start step,
 * then the simulated steps) as typed arrays; NaN where an agent is absent. */
function buildReplay(job, scene) {
  const res = job.result;
  const runs = [];
  for (const name of ['prompted', 'unprompted']) if (res.runs && res.runs[name]) runs.push({ name, run: res.runs[name] });
  const hist = clamp((res.start_step ?? scene.current_step) + 1, 1, scene.current_step + 1);
  const first = runs[0].run.rollouts[0] || { x: {} };
  const steps = Math.max(0, ...Object.values(first.x || {}).map((v) => v.length));
  const total = hist + steps;
  const byId = new Map(scene.agents.map((a) => [String(a.id), a]));
  const tracks = runs.map(({ name, run }) => run.rollouts.map((ro) => {
    const ids = new Set([...byId.keys(), ...Object.keys(ro.x || {})]);
    const agents = [];
    for (const id of ids) {
      const a = byId.get(id) || { id, type: 'other', length: 4, width: 2, sim: true };
      const X = new Float32Array(total).fill(NaN); const Y = new Float32Array(total).fill(NaN);
      const H = new Float32Array(total).fill(0);
      for (let i = 0; i < hist; i += 1) {
        const p = posAt(a, i);
        if (p) { X[i] = p[0]; Y[i] = p[1]; H[i] = p[2] || 0; }
      }
      const xs = ro.x && ro.x[id]; const ys = ro.y && ro.y[id]; const hs = ro.heading && ro.heading[id];
      if (xs && ys) {
        for (let k = 0; k < steps; k += 1) {
          if (xs[k] === null || ys[k] === null || xs[k] === undefined) continue;
          X[hist + k] = xs[k]; Y[hist + k] = ys[k]; H[hist + k] = hs && hs[k] !== null ? hs[k] : H[hist + k - 1];
        }
      }
      agents.push({ a, X, Y, H });
    }
    return { name, agents, collided: collidedIn(run, ro) };
  }));
  // one frame for every panel: the agents over the whole timeline
  const pts = [];
  for (const rollouts of tracks) {
    for (const r of rollouts) {
      for (const g of r.agents) {
        if (g.a.sim === false) continue;
        for (let i = 0; i < total; i += 4) if (!Number.isNaN(g.X[i])) pts.push([g.X[i], g.Y[i]]);
      }
    }
  }
  const box = boxOf(pts) || scene.bounds;
  const targets = (runs[0].name === 'prompted' ? runs[0].run.targets || [] : []).map(normTarget).filter(Boolean);
  const parked = new Set((runs[0].run.agents || []).filter((a) => a.parked).map((a) => String(a.id)));
  return { job, scene, runs, tracks, hist, steps, total, box, targets, nRollouts: runs[0].run.rollouts.length,
    t: 0, playing: false, last: null, raf: null, panels: [], parked,
    view: { zoom: 1, dx: 0, dy: 0, follow: '' } };
}

/** Agent id -> the future step of its first contact in rollout `ro` of `run` (outlined red from then on). */
function collidedIn(run, ro) {
  const k = run.rollouts.indexOf(ro);
  const out = new Map();
  for (const a of run.agents || []) {
    const contact = (a.collisions || []).find((c) => c.rollout === k);
    if (contact) out.set(String(a.id), contact.step);
  }
  return out;
}

/** The panels: all rollouts (prompted beside unprompted) or one rollout, each a canvas. */
function layoutReplay() {
  const R = S.replay;
  if (!R) return;
  const one = $('layout').value === 'one';
  $('which-rollout').disabled = !one;
  const ks = one ? [Number($('which-rollout').value || 0)] : Array.from({ length: R.nRollouts }, (_, k) => k);
  const grid = $('replay-grid');
  grid.classList.toggle('pairs', R.runs.length === 2);
  R.panels = [];
  const cells = [];
  for (const k of ks) {
    const figures = R.runs.map(({ name }, r) => {
      const canvas = h('canvas', { class: 'replay-canvas', 'data-run': name, 'data-rollout': k,
        'aria-label': `Replay of the ${name} run, rollout ${k + 1}` });
      const panel = { canvas, run: r, k, surf: null, visible: true };
      R.panels.push(panel);
      return h('figure', {}, h('figcaption', {}, h('strong', {}, name === 'prompted' ? 'with the prompts' : 'without prompts'),
        ` · rollout ${k + 1}`), h('div', { class: 'canvas-box' }, canvas));
    });
    cells.push(R.runs.length === 2 ? h('div', { class: 'pair' }, ...figures) : figures[0]);
  }
  grid.replaceChildren(...cells);
  if (R.observer) R.observer.disconnect();
  // only the panels on screen are painted while playing (16 rollouts side by side stay smooth)
  R.observer = new IntersectionObserver((entries) => {
    for (const e of entries) {
      const panel = R.panels.find((p) => p.canvas === e.target);
      if (panel) panel.visible = e.isIntersecting;
    }
    if (!R.playing) paintReplay();
  });
  for (const p of R.panels) { p.surf = new Surface(p.canvas); R.observer.observe(p.canvas); }
  paintReplay();
}

/** A panel's view at time `i`: the fit of every path, zoomed and panned as the user asked, or centred on the
 * followed agent (where it is valid in this panel's rollout). */
function replayFrame(R, panel, surf, i) {
  const base = Frame.fit(R.box, surf.w, surf.hgt, 6);
  const { zoom, dx, dy, follow } = R.view;
  if (follow) {
    const g = R.tracks[panel.run][panel.k].agents.find((t) => String(t.a.id) === follow);
    const j = Math.floor(i);
    if (g && !Number.isNaN(g.X[j])) return new Frame(g.X[j], g.Y[j], base.s * zoom);
  }
  return new Frame(base.cx + dx, base.cy + dy, base.s * zoom);
}

/** A scale bar bottom left: the roundest length of about a fifth of the panel, in metres. */
function drawScaleBar(ctx, frame, surf) {
  const lengths = [1, 2, 5, 10, 20, 50, 100, 200, 500, 1000];
  const metres = lengths.filter((m) => m * frame.s <= surf.w / 4).pop() || lengths[0];
  const px = metres * frame.s;
  const x0 = 10; const y0 = surf.hgt - 12;
  ctx.save();
  ctx.strokeStyle = '#222'; ctx.fillStyle = '#222'; ctx.lineWidth = 2;
  ctx.beginPath(); ctx.moveTo(x0, y0 - 4); ctx.lineTo(x0, y0); ctx.lineTo(x0 + px, y0); ctx.lineTo(x0 + px, y0 - 4); ctx.stroke();
  ctx.font = '11px system-ui, sans-serif';
  ctx.fillText(`${metres} m`, x0 + px + 4, y0);
  ctx.restore();
}

/** Zoom, pan and follow, shared by every panel: the wheel zooms, a drag pans, the Follow list centres an agent. */
function bindReplayView() {
  const grid = $('replay-grid');
  let drag = null;
  const scaleOf = (canvas) => {
    const R = S.replay;
    const panel = R && R.panels.find((p) => p.canvas === canvas);
    return panel && panel.surf ? replayFrame(R, panel, panel.surf, R.t).s : null;
  };
  grid.addEventListener('wheel', (e) => {
    if (!S.replay || e.target.tagName !== 'CANVAS') return;
    e.preventDefault();
    const v = S.replay.view;
    v.zoom = clamp(v.zoom * (e.deltaY < 0 ? 1.25 : 0.8), 1, 60);
    if (!S.replay.playing) paintReplay();
  }, { passive: false });
  grid.addEventListener('pointerdown', (e) => {
    if (!S.replay || e.target.tagName !== 'CANVAS') return;
    drag = { x: e.clientX, y: e.clientY, s: scaleOf(e.target) };
    e.target.setPointerCapture(e.pointerId);
  });
  grid.addEventListener('pointermove', (e) => {
    if (!drag || !S.replay || !drag.s) return;
    const v = S.replay.view;
    if (v.follow) { v.follow = ''; $('follow').value = ''; }
    v.dx -= (e.clientX - drag.x) / drag.s; v.dy += (e.clientY - drag.y) / drag.s;
    drag.x = e.clientX; drag.y = e.clientY;
    if (!S.replay.playing) paintReplay();
  });
  const end = () => { drag = null; };
  grid.addEventListener('pointerup', end);
  grid.addEventListener('pointercancel', end);
  $('follow').addEventListener('change', () => {
    if (!S.replay) return;
    S.replay.view.follow = $('follow').value;
    if (!S.replay.view.follow) { S.replay.view.dx = 0; S.replay.view.dy = 0; }
    if (!S.replay.playing) paintReplay();
  });
  $('replay-fit').addEventListener('click', () => {
    if (!S.replay) return;
    S.replay.view = { zoom: 1, dx: 0, dy: 0, follow: '' };
    $('follow').value = '';
    if (!S.replay.playing) paintReplay();
  });
}

/** The Follow list: the ego (under a planner) and the prompted agents first, then every simulated agent. */
function fillFollow(R) {
  const episodes = R.runs[0].run.episodes || [];
  const ego = episodes.length && episodes[0].ego !== null && episodes[0].ego !== undefined ? String(episodes[0].ego) : null;
  const prompted = [...promptedIdsOf(R)];
  const first = [...new Set([ego, ...prompted].filter(Boolean))];
  const rest = R.tracks[0][0].agents.filter((g) => g.a.sim !== false).map((g) => String(g.a.id)).filter((id) => !first.includes(id));
  $('follow').replaceChildren(h('option', { value: '' }, 'no agent'),
    ...first.map((id) => h('option', { value: id }, `@${id}${id === ego ? ' (ego)' : ' (prompted)'}`)),
    ...rest.map((id) => h('option', { value: id }, `@${id}`)));
}

function paintReplay() {
  const R = S.replay;
  if (!R) return;
  const i = clamp(R.t, 0, R.total - 1);
  const i0 = Math.floor(i); const i1 = Math.min(i0 + 1, R.total - 1); const f = i - i0;
  for (const panel of R.panels) {
    if (!panel.visible) continue;
    const { surf } = panel;
    surf.measure();
    const frame = replayFrame(R, panel, surf, i);
    const run = R.runs[panel.run];
    surf.background(frame, mapPaths(R.scene), (ctx) => {
      ctx.setTransform(surf.dpr, 0, 0, surf.dpr, 0, 0);
      if (run.name === 'prompted') drawTargets(ctx, R.targets, frame, surf);
    }, run.name);
    const { ctx } = surf;
    ctx.setTransform(surf.dpr, 0, 0, surf.dpr, 0, 0);
    if (i0 < R.hist) drawLights(ctx, R.scene.lights, frame, surf);
    const ro = R.tracks[panel.run][panel.k];
    ctx.lineWidth = 1.5;
    ctx.globalAlpha = 0.45;
    for (const g of ro.agents) { // the trail
      ctx.strokeStyle = g.a.sim === false ? LOGGED : COLOURS[g.a.type] || COLOURS.other;
      ctx.beginPath();
      let pen = false;
      for (let j = Math.max(0, i0 - TRAIL_STEPS); j <= i0; j += 1) {
        if (Number.isNaN(g.X[j])) { pen = false; continue; }
        const x = frame.x(g.X[j], surf.w); const y = frame.y(g.Y[j], surf.hgt);
        if (pen) ctx.lineTo(x, y); else ctx.moveTo(x, y);
        pen = true;
      }
      ctx.stroke();
    }
    ctx.globalAlpha = 1;
    const prompted = R.promptedIds || (R.promptedIds = promptedIdsOf(R));
    for (const g of ro.agents) {
      if (Number.isNaN(g.X[i0])) continue;
      let x = g.X[i0]; let y = g.Y[i0]; let hd = g.H[i0];
      if (f > 0 && !Number.isNaN(g.X[i1])) {
        x += (g.X[i1] - x) * f; y += (g.Y[i1] - y) * f;
        let dh = g.H[i1] - hd;
        dh = Math.atan2(Math.sin(dh), Math.cos(dh));
        hd += dh * f;
      }
      const id = String(g.a.id);
      const mark = ro.collided.has(id) && i0 >= R.hist + ro.collided.get(id) ? '#c01c28' : prompted.has(id) ? TARGET : null;
      drawAgent(ctx, g.a, x, y, hd, frame, surf, { mark, alpha: R.parked.has(id) && !mark ? 0.4 : 1 });
      if (frame.s > 2.2 || prompted.has(id) || id === R.view.follow) drawLabel(ctx, id, x, y, frame, surf);
    }
    drawScaleBar(ctx, frame, surf);
  }
  const k = Math.floor(i);
  const sim = k - (R.hist - 1);
  const dt = R.job.result.step_seconds || R.scene.step_seconds || 0.1;
  $('scrub').value = String(k);
  $('step-info').textContent = sim <= 0
    ? `logged history, step ${k + 1} of ${R.hist} (t = ${fmt(sim * dt, 1)} s)`
    : `simulated step ${sim} of ${R.steps} (t = ${fmt(sim * dt, 1)} s)`;
}

function promptedIdsOf(R) {
  const ids = new Set();
  for (const { run } of R.runs) {
    for (const p of run.prompts || []) {
      if (p.agent !== null && p.agent !== undefined) ids.add(String(p.agent));
      if (p.other !== null && p.other !== undefined) ids.add(String(p.other));
    }
  }
  for (const t of R.targets) if (t.agent !== null) ids.add(String(t.agent));
  return ids;
}

function tick(ts) {
  const R = S.replay;
  if (!R || !R.playing) return;
  const stats = window.studioStats;
  stats.frames.push(ts);
  if (stats.frames.length > MAX_STATS) stats.frames.splice(0, stats.frames.length - MAX_STATS);
  if (R.last !== null) {
    const dt = R.job.result.step_seconds || 0.1;
    R.t += ((ts - R.last) / 1000) * (Number($('speed').value) / dt);
  }
  R.last = ts;
  if (R.t >= R.total - 1) {
    R.t = R.total - 1;
    paintReplay();
    setPlaying(false);
    return;
  }
  paintReplay();
  R.raf = requestAnimationFrame(tick);
}

function setPlaying(on) {
  const R = S.replay;
  if (!R) return;
  if (on && R.t >= R.total - 1) R.t = 0; // from the start again
  R.playing = on;
  R.last = null;
  $('play').textContent = on ? 'Pause' : 'Play';
  $('play').setAttribute('aria-pressed', on ? 'true' : 'false');
  cancelAnimationFrame(R.raf);
  if (on) R.raf = requestAnimationFrame(tick);
}

function stopReplay() { if (S.replay) setPlaying(false); }

// ------------------------------------------------------------------ judge: the results tables

function cell(value, yes, no, na = 'not judged') {
  if (value === true) return h('td', { class: 'yes' }, yes);
  if (value === false) return h('td', { class: 'no' }, no);
  return h('td', { class: 'na' }, na);
}

function rate(values) {
  const judged = (values || []).filter((v) => v === true || v === false);
  if (!judged.length) return 'not judged';
  const n = judged.filter(Boolean).length;
  return `${n} of ${judged.length} (${Math.round((100 * n) / judged.length)}%)`;
}

function fmtRate(value, run) {
  if (value === null || value === undefined) return run && run.road_edges === null ? 'not measured' : '—';
  return fmt(value);
}

function renderResults(job) {
  const { prompted, unprompted } = job.result.runs;
  const n = prompted.rollouts.length;
  const heads = Array.from({ length: n }, (_, k) => h('th', { scope: 'col' }, `rollout ${k + 1}`));
  const out = [];
  // prompts followed
  const rows = (prompted.prompts || []).map((p, i) => {
    const base = unprompted && (unprompted.prompts || [])[i];  // both runs judge the same prompts, in order
    return h('tr', {}, h('th', { scope: 'row' }, p.text), h('td', {}, p.behaviour ? String(p.behaviour).replace(/_/g, ' ') : '—'),
      ...Array.from({ length: n }, (_, k) => cell((p.followed || [])[k], 'followed', 'not followed')),
      unprompted ? h('td', {}, base ? rate(base.followed) : '—') : null);
  });
  out.push(h('table', { id: 'followed-table' }, h('caption', {}, 'Prompts: followed per rollout'),
    h('thead', {}, h('tr', {}, h('th', { scope: 'col' }, 'prompt'), h('th', { scope: 'col' }, 'read as'), ...heads,
      unprompted ? h('th', { scope: 'col' }, 'without prompts (base rate)') : null)),
    h('tbody', {}, rows.length ? rows : h('tr', {}, h('td', { colspan: n + 2 }, 'No prompt was judged.')))));
  // collisions and off-road: each first contact with its time and partner (the realism rates' own computation)
  const stepSeconds = job.result.step_seconds || 0.1;
  for (const [name, run] of [['with the prompts', prompted], ['without prompts', unprompted]]) {
    if (!run) continue;
    const promptedIds = new Set((run.prompts || []).flatMap((p) => [p.agent, p.other]).filter((v) => v !== null && v !== undefined).map(String));
    const measured = run.road_edges !== null && run.road_edges !== undefined;
    const listed = (run.agents || []).filter((a) => promptedIds.has(String(a.id))
      || (a.collision || []).some(Boolean) || (a.offroad || []).some(Boolean));
    const parked = listed.filter((a) => a.parked && !promptedIds.has(String(a.id)));
    const agents = listed.filter((a) => !parked.includes(a));
    agents.sort((a, b) => Number(promptedIds.has(String(b.id))) - Number(promptedIds.has(String(a.id)))); // prompted first
    const body = agents.map((a) => h('tr', {}, h('th', { scope: 'row' }, `@${a.id}${promptedIds.has(String(a.id)) ? ' (prompted)' : ''}${a.evaluated ? '' : ' ·'}`), ...Array.from({ length: n }, (_, k) => {
      const contact = (a.collisions || []).find((c) => c.rollout === k);
      const ev = [];
      if (contact) ev.push(h('button', { type: 'button', class: 'event-jump', 'data-rollout': k, 'data-step': contact.step, title: 'jump to the moment' },
        `collision with @${contact.with} at ${((contact.step + 1) * stepSeconds).toFixed(1)} s`));
      if ((a.offroad || [])[k]) ev.push(h('span', {}, ev.length ? ', off-road' : 'off-road'));
      if (ev.length) return h('td', { class: 'event' }, ...ev);
      return h('td', { class: measured ? 'yes' : 'na' }, measured ? 'clear' : 'no collision; off-road not measured');
    })));
    const note = [`“·”: not scored by WOSAC (its rates cover the ${(run.realism || {}).evaluated ?? '?'} evaluated agents).`];
    if (!measured) note.push('Off-road is not measured: this map has no road edges.');
    else if (run.road_edges !== 'map') note.push(`Off-road is measured against road edges ${run.road_edges}.`);
    if (parked.length) note.push(`${parked.length} parked agent${parked.length === 1 ? '' : 's'} with events not listed: ${parked.map((a) => `@${a.id}`).join(', ')}.`);
    out.push(h('table', { class: 'events-table', 'data-run': run === prompted ? 'prompted' : 'unprompted' },
      h('caption', {}, `Collisions and off-road, ${name}`),
      h('thead', {}, h('tr', {}, h('th', { scope: 'col' }, 'agent'), ...heads.map((x) => x.cloneNode(true)))),
      h('tbody', {}, body.length ? body : h('tr', {}, h('td', { colspan: n + 1 }, 'No collision or off-road in any rollout.')))));
    out.push(h('p', { class: 'hint events-note' }, note.join(' ')));
  }
  // realism
  const keys = [...new Set([...Object.keys(prompted.realism || {}), ...Object.keys((unprompted && unprompted.realism) || {})])]
    .filter((key) => key !== 'note' && key !== 'evaluated');
  const tableRate = (run, key) => (run && run.rates ? run.rates[key] : null);
  if (keys.length) {
    out.push(h('table', { id: 'realism-table' }, h('caption', {}, 'Realism'),
      h('thead', {}, h('tr', {}, h('th', { scope: 'col' }, 'figure'), h('th', { scope: 'col' }, 'with the prompts'),
        unprompted ? h('th', { scope: 'col' }, 'without prompts') : null)),
      h('tbody', {}, keys.map((key) => h('tr', {}, h('th', { scope: 'row' }, key.replace(/_/g, ' ')),
        h('td', { class: 'num' }, fmt((prompted.realism || {})[key])),
        unprompted ? h('td', { class: 'num' }, fmt((unprompted.realism || {})[key])) : null)).concat(
        [['collision_all', 'collision rate, every agent in the events table'], ['offroad_all', 'off-road rate, every vehicle measured']]
          .map(([key, label]) => h('tr', {}, h('th', { scope: 'row' }, label),
            h('td', { class: 'num' }, fmtRate(tableRate(prompted, key), prompted)),
            unprompted ? h('td', { class: 'num' }, fmtRate(tableRate(unprompted, key), unprompted)) : null))))),
      h('p', { class: 'hint' }, `WOSAC's rates are over the ${(prompted.realism || {}).evaluated ?? '?'} agents it scores${(prompted.realism || {}).note ? ` (${prompted.realism.note})` : ''}; the last two rows are over every agent of the table.`));
  }
  const warnings = [...(prompted.warnings || []), ...((unprompted && unprompted.warnings) || [])];
  if (warnings.length) {
    out.push(h('div', { class: 'warnings' }, h('h3', {}, 'Warnings'), h('ul', {}, [...new Set(warnings)].map((w) => h('li', {}, w)))));
  }
  $('results').replaceChildren(...out);
  for (const b of $('results').querySelectorAll('button.event-jump')) b.addEventListener('click', () => jumpTo(Number(b.dataset.rollout), Number(b.dataset.step)));
  // every first contact of the prompted run as a tick on the scrubber, labelled with its pair and time
  const hist = (job.result.start_step ?? 0) + 1;
  $('scrub-events').replaceChildren(...(prompted.agents || []).flatMap((a) => (a.collisions || []).map((c) =>
    h('option', { value: String(hist + c.step), label: `@${a.id} × @${c.with}, rollout ${c.rollout + 1}` }))));
}

/** Show rollout `k` at future step `step` (an event's moment), paused. */
function jumpTo(k, step) {
  if (!S.replay) return;
  if ($('layout').value === 'one' && $('which-rollout').value !== String(k)) { $('which-rollout').value = String(k); layoutReplay(); }
  setPlaying(false);
  S.replay.t = S.replay.hist + step;
  S.replay.last = null;
  paintReplay();
  $('scrub').focus();
}

// ------------------------------------------------------------------ keep: save as a test case

async function saveCase(e) {
  e.preventDefault();
  if (!S.openJob) return;
  $('case-result').hidden = true;
  showIn('case-error', '');
  const criteria = {};
  if ($('case-ttc').value !== '') criteria.min_ttc = Number($('case-ttc').value);
  if ($('case-nocollision').checked) criteria.no_collision = true;
  const submit = $('case-form').querySelector('button[type="submit"]');
  submit.disabled = true;
  try {
    const r = await api('POST', `/api/jobs/${encodeURIComponent(S.openJob.id)}/case`,
      { suite: $('case-suite').value.trim(), name: $('case-name').value.trim(), criteria });
    $('case-result').textContent = `Saved case “${r.case}” in ${r.suite}; it replays these rollouts with: ${r.command}`;
    $('case-result').hidden = false;
    say(`Test case ${r.case} saved.`);
  } catch (err) {
    showIn('case-error', err.message);
  } finally {
    submit.disabled = false;
  }
}

// ------------------------------------------------------------------ start

function start() {
  setupSceneCanvas();
  restorePrompts();
  renderPrompts();
  const refilter = debounce(loadScenes, FILTER_DEBOUNCE_MS);
  for (const id of ['scene-search', 'min-agents', 'max-agents']) $(id).addEventListener('input', refilter);
  $('scene-kind').addEventListener('change', loadScenes);
  $('add-prompt').addEventListener('click', addPrompt);
  $('insert-agent').addEventListener('change', () => {
    const v = $('insert-agent').value;
    if (v) insertAgent(v);
    $('insert-agent').value = '';
  });
  for (const id of ['adversary', 'target']) $(id).addEventListener('change', () => { drawScene(); scheduleRead(); });
  $('planner').addEventListener('change', scheduleRead); // with a planner, a prompt of the ego is refused
  $('run').addEventListener('click', run);
  $('play').addEventListener('click', () => S.replay && setPlaying(!S.replay.playing));
  $('scrub').addEventListener('input', () => {
    if (!S.replay) return;
    S.replay.t = Number($('scrub').value);
    S.replay.last = null;
    if (!S.replay.playing) paintReplay();
  });
  $('layout').addEventListener('change', layoutReplay);
  bindReplayView();
  $('which-rollout').addEventListener('change', layoutReplay);
  $('case-form').addEventListener('submit', saveCase);
  new ResizeObserver(() => { if (S.replay && !S.replay.playing) paintReplay(); }).observe($('replay-grid'));
  const hash = new URLSearchParams(location.hash.slice(1));
  loadScenes().then(() => { if (hash.get('scene')) pickScene(hash.get('scene')); });
  pollJobs().then(() => { if (hash.get('job') && S.jobs.some((j) => j.id === hash.get('job') && j.status === 'done')) openJob(hash.get('job')); });
}

/** For tests and the curious: where agent `id` of the picked scene is drawn, in client (viewport) pixels. */
window.studio = {
  agentPoint(id) {
    const a = S.scene && agentById(S.scene, id);
    const p = a && posAt(a, S.scene.current_step);
    if (!p || !S.view.frame) return null;
    const r = S.view.surf.canvas.getBoundingClientRect();
    return { x: r.left + S.view.frame.x(p[0], S.view.surf.w), y: r.top + S.view.frame.y(p[1], S.view.surf.hgt) };
  },
  get replayFrames() { return S.replay ? S.replay.total : 0; },
  /** The first panel's view now: its centre (metres) and scale (pixels a metre). */
  replayView() {
    const R = S.replay;
    const panel = R && R.panels.find((p) => p.surf);
    if (!panel) return null;
    const f = replayFrame(R, panel, panel.surf, R.t);
    return { cx: f.cx, cy: f.cy, s: f.s, follow: R.view.follow };
  },
};

start();
