/* The scene view: the picked scene at its current step (the map, the logged history as fading trails, the
 * prompts' targets, lights, every agent labelled), with pan, zoom, hover and click-to-pick. What it marks comes
 * from the state (`S.marks`, set by prompts.js; `S.staged`, the agent of the staging clicked, by stagings.js). See
 * docs/studio.md, 'The page'.
 */
import { $, clamp, say } from '/common/dom.js';
import { Frame, Surface, boxOf } from './canvas.js';
import {
  PICKED, TARGET, agentById, colourOf, drawAgent, drawLabel, drawLights, drawTargets, paintBackground, paintBlank,
  posAt, tooltip,
} from './draw.js';
import { S } from './state.js';

const HIT_TOL_PX = 6; // a click this close to an agent's box picks it
const STAGED_PX = 6; // the outline of the staging's agent: twice a prompted agent's
const HINT = 'Drag to pan, wheel to zoom; click an agent to insert its @id.';

function initialFrame(scene, surf) {
  const cur = scene.current_step;
  const pts = scene.agents.map((a) => posAt(a, cur)).filter(Boolean);
  const box = boxOf(pts) || scene.bounds;
  return box ? Frame.fit(box, surf.w, surf.hgt) : new Frame(0, 0, 4);
}

let queued = false;
/** Redraw the scene view on the next animation frame (once, however often asked). */
export function drawScene() {
  if (queued) return;
  queued = true;
  requestAnimationFrame(() => { queued = false; paintScene(); });
}

/** A new scene is shown: the view fits it again. */
export function resetSceneView() {
  S.view.frame = null;
  S.view.hover = null;
  $('hover-info').textContent = HINT;
}

function paintScene() {
  const V = S.view;
  if (!V) return;
  V.surf.measure();
  const { surf } = V;
  const { ctx } = surf;
  const scene = S.scene;
  if (!scene) { paintBlank(surf); return; }
  if (!V.frame) V.frame = initialFrame(scene, surf);
  const frame = V.frame;
  paintBackground(surf, frame, scene);
  ctx.setTransform(surf.dpr, 0, 0, surf.dpr, 0, 0);
  const cur = scene.current_step;
  // the logged history as fading trails
  ctx.lineWidth = 2;
  ctx.lineCap = 'round';
  for (const a of scene.agents) {
    ctx.strokeStyle = colourOf(a);
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
  const { targets, prompted } = S.marks;
  drawTargets(ctx, targets, frame, surf);
  drawLights(ctx, scene.lights, frame, surf);
  const picked = new Set([$('adversary').value, $('target').value].filter(Boolean));
  for (const a of scene.agents) {
    const p = posAt(a, cur);
    if (!p) continue;
    const id = String(a.id);
    const mark = prompted.has(id) ? TARGET : picked.has(id) ? PICKED : V.hover === id ? '#1d232b' : null;
    if (id === S.staged) drawAgent(ctx, a, p[0], p[1], p[2], frame, surf, { mark: TARGET, markPx: STAGED_PX });
    else drawAgent(ctx, a, p[0], p[1], p[2], frame, surf, { mark });
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

/** Bind the scene canvas: a drag pans, the wheel and +/- zoom, arrows pan, a click on an agent calls
 * `onPick(id)`. */
export function setupSceneCanvas(onPick) {
  const canvas = $('scene-canvas');
  S.view = { surf: new Surface(canvas), frame: null, hover: null, drag: null };
  S.marks = { targets: [], prompted: new Set() };
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
        : HINT;
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
      if (a) onPick(a.id);
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

/** Where agent `id` of the picked scene is drawn, in client (viewport) pixels, or null. */
export function agentPoint(id) {
  const a = S.scene && agentById(S.scene, id);
  const p = a && posAt(a, S.scene.current_step);
  if (!p || !S.view.frame) return null;
  const r = S.view.surf.canvas.getBoundingClientRect();
  return { x: r.left + S.view.frame.x(p[0], S.view.surf.w), y: r.top + S.view.frame.y(p[1], S.view.surf.hgt) };
}
