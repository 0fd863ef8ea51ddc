/* Watch: a finished job's rollouts replayed from their positions — one large view of the chosen rollout with the
 * others as thumbnails (or every rollout side by side), zoom, pan and follow-an-agent shared by the large panels,
 * a scale bar, contacts outlined from their moment on, the prompted agents' plots beside it.
 * See docs/studio.md, 'The page'.
 */
import { request as api } from '/common/api.js';
import { $, clamp, h, say, showError, showIn } from '/common/dom.js';
import { Frame, Surface, boxOf } from './canvas.js';
import {
  COLLIDED, TARGET, colourOf, drawAgent, drawLabel, drawLights, drawScaleBar, drawTargets, normTarget,
  paintBackground, posAt,
} from './draw.js';
import { renderJobs } from './jobs.js';
import { sceneDetail } from './picker.js';
import { buildPlots, paintPlots, plotTime, plotValue } from './plots.js';
import { renderResults } from './results.js';
import { MAX_STATS, S, fmt, saveHash } from './state.js';

const TRAIL_STEPS = 10; // the replay's trail behind each agent
const RUN_TITLES = { prompted: 'with the prompts', unprompted: 'without prompts' };

export async function openJob(id) {
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
  const R = buildReplay(job, scene);
  S.replay = R;
  fillFollow(R);
  $('replay').hidden = false;
  const runs = job.result.runs || {};
  $('replay-meta').textContent = `Job ${job.id} · ${job.scenario_id} · ${job.rollouts} rollout${job.rollouts === 1 ? '' : 's'}, `
    + `seed ${job.case.seeds[0]}${runs.prompted && runs.prompted.seconds ? ` · simulated in ${fmt(runs.prompted.seconds, 1)} s` : ''}`;
  $('which-rollout').replaceChildren(...R.runs.flatMap(({ name }, r) => Array.from({ length: R.nRollouts }, (_, k) =>
    h('option', { value: `${r}:${k}` }, `${RUN_TITLES[name]} · rollout ${k + 1}`))));
  $('scrub').max = R.total - 1;
  R.t = R.hist - 1;
  buildPlots(R, $('replay-plots'));
  layoutReplay();
  renderResults(job, jumpTo);
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
  const tracks = runs.map(({ name, run }) => run.rollouts.map((ro, k) => {
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
        for (let j = 0; j < steps; j += 1) {
          if (xs[j] === null || ys[j] === null || xs[j] === undefined) continue;
          X[hist + j] = xs[j]; Y[hist + j] = ys[j]; H[hist + j] = hs && hs[j] !== null ? hs[j] : H[hist + j - 1];
        }
      }
      agents.push({ a, X, Y, H });
    }
    return { name, agents, collided: collidedIn(run, k) };
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
  const R = { job, scene, runs, tracks, hist, steps, total, box, targets, nRollouts: runs[0].run.rollouts.length,
    dt: res.step_seconds || scene.step_seconds || 0.1, t: 0, playing: false, last: null, raf: null, panels: [],
    parked, main: { run: 0, k: 0 }, view: { zoom: 1, dx: 0, dy: 0, follow: '' }, plots: [] };
  R.promptedIds = promptedIdsOf(R);
  return R;
}

/** Agent id -> the future step of its first contact in rollout `k` of `run` (outlined red from then on). */
function collidedIn(run, k) {
  const out = new Map();
  for (const a of run.agents || []) {
    const contact = (a.collisions || []).find((c) => c.rollout === k);
    if (contact) out.set(String(a.id), contact.step);
  }
  return out;
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

// ------------------------------------------------------------------ the panels

function panelFigure(R, r, k, cls) {
  const { name } = R.runs[r];
  const canvas = h('canvas', { class: `replay-canvas ${cls}`, 'data-run': name, 'data-rollout': k,
    'aria-label': `Replay of the ${name} run, rollout ${k + 1}` });
  const panel = { canvas, run: r, k, surf: null, visible: true, thumb: cls === 'thumb' };
  R.panels.push(panel);
  const caption = h('figcaption', {}, h('strong', {}, RUN_TITLES[name]), ` · rollout ${k + 1}`);
  if (!panel.thumb) return h('figure', {}, caption, h('div', { class: 'canvas-box' }, canvas));
  return h('figure', { class: 'thumb' }, h('button', { type: 'button', class: 'thumb-pick', 'data-pick': `${r}:${k}`,
    'aria-label': `Show ${RUN_TITLES[name]}, rollout ${k + 1} in the large view`, onclick: () => showMain(r, k) },
  h('div', { class: 'canvas-box' }, canvas), caption));
}

/** Make run `r`'s rollout `k` the large view. */
function showMain(r, k) {
  $('which-rollout').value = `${r}:${k}`;
  layoutReplay();
}

/** The panels: one large view of the chosen rollout and the others as thumbnails, or every rollout side by side
 * (prompted beside unprompted). */
export function layoutReplay() {
  const R = S.replay;
  if (!R) return;
  const focus = $('layout').value !== 'all';
  const [r, k] = String($('which-rollout').value || '0:0').split(':').map(Number);
  R.main = { run: clamp(r || 0, 0, R.runs.length - 1), k: clamp(k || 0, 0, R.nRollouts - 1) };
  $('which-rollout').disabled = !focus;
  const grid = $('replay-grid');
  grid.classList.toggle('focus', focus);
  grid.classList.toggle('pairs', !focus && R.runs.length === 2);
  R.panels = [];
  let cells;
  if (focus) {
    const main = panelFigure(R, R.main.run, R.main.k, 'main');
    const thumbs = [];
    for (let rr = 0; rr < R.runs.length; rr += 1) {
      for (let kk = 0; kk < R.nRollouts; kk += 1) if (rr !== R.main.run || kk !== R.main.k) thumbs.push(panelFigure(R, rr, kk, 'thumb'));
    }
    cells = [h('div', { class: 'main-view' }, main), thumbs.length ? h('div', { class: 'thumbs', 'aria-label': 'The other rollouts' }, ...thumbs) : null];
  } else {
    cells = Array.from({ length: R.nRollouts }, (_, kk) => {
      const figures = R.runs.map((_, rr) => panelFigure(R, rr, kk, 'grid'));
      return R.runs.length === 2 ? h('div', { class: 'pair' }, ...figures) : figures[0];
    });
  }
  grid.replaceChildren(...cells.filter(Boolean));
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
  for (const p of R.plots) p.surf.bgKey = ''; // the big view's rollout is drawn bold
  paintReplay();
}

/** A panel's view at time `i`: the fit of every path, zoomed and panned as the user asked, or centred on the
 * followed agent (where it is valid in this panel's rollout); a thumbnail always shows the fit. */
function replayFrame(R, panel, surf, i) {
  const base = Frame.fit(R.box, surf.w, surf.hgt, 6);
  if (panel.thumb) return base;
  const { zoom, dx, dy, follow } = R.view;
  if (follow) {
    const g = R.tracks[panel.run][panel.k].agents.find((t) => String(t.a.id) === follow);
    const j = Math.floor(i);
    if (g && !Number.isNaN(g.X[j])) return new Frame(g.X[j], g.Y[j], base.s * zoom);
  }
  return new Frame(base.cx + dx, base.cy + dy, base.s * zoom);
}

/** Zoom, pan and follow, shared by the large panels: the wheel zooms, a drag pans, the Follow list centres an
 * agent; a click on a plot moves the replay to its time. */
export function bindReplayView() {
  const grid = $('replay-grid');
  let drag = null;
  const large = (canvas) => {
    const R = S.replay;
    const panel = R && R.panels.find((p) => p.canvas === canvas);
    return panel && !panel.thumb && panel.surf ? panel : null;
  };
  grid.addEventListener('wheel', (e) => {
    if (!S.replay || !large(e.target)) return;
    e.preventDefault();
    const v = S.replay.view;
    v.zoom = clamp(v.zoom * (e.deltaY < 0 ? 1.25 : 0.8), 1, 60);
    if (!S.replay.playing) paintReplay();
  }, { passive: false });
  grid.addEventListener('pointerdown', (e) => {
    const panel = S.replay && large(e.target);
    if (!panel) return;
    drag = { x: e.clientX, y: e.clientY, s: replayFrame(S.replay, panel, panel.surf, S.replay.t).s };
    e.target.setPointerCapture(e.pointerId);
  });
  grid.addEventListener('pointermove', (e) => {
    if (!drag || !S.replay) return;
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
  $('replay-plots').addEventListener('click', (e) => {
    const R = S.replay;
    if (!R || !e.target.classList.contains('plot-canvas')) return;
    setPlaying(false);
    R.t = Math.round(plotTime(R, e.target, e.clientX));
    R.last = null;
    paintReplay();
  });
}

/** The Follow list: the ego (under a planner) and the prompted agents first, then every simulated agent. */
function fillFollow(R) {
  const episodes = R.runs[0].run.episodes || [];
  const ego = episodes.length && episodes[0].ego !== null && episodes[0].ego !== undefined ? String(episodes[0].ego) : null;
  const first = [...new Set([ego, ...R.promptedIds].filter(Boolean))];
  const rest = R.tracks[0][0].agents.filter((g) => g.a.sim !== false).map((g) => String(g.a.id)).filter((id) => !first.includes(id));
  $('follow').replaceChildren(h('option', { value: '' }, 'no agent'),
    ...first.map((id) => h('option', { value: id }, `@${id}${id === ego ? ' (ego)' : ' (prompted)'}`)),
    ...rest.map((id) => h('option', { value: id }, `@${id}`)));
}

function paintPanel(R, panel, i) {
  const i0 = Math.floor(i); const i1 = Math.min(i0 + 1, R.total - 1); const f = i - i0;
  const { surf } = panel;
  surf.measure();
  const frame = replayFrame(R, panel, surf, i);
  const run = R.runs[panel.run];
  paintBackground(surf, frame, R.scene, run.name === 'prompted' ? (ctx) => drawTargets(ctx, R.targets, frame, surf) : null, run.name);
  const { ctx } = surf;
  ctx.setTransform(surf.dpr, 0, 0, surf.dpr, 0, 0);
  if (i0 < R.hist) drawLights(ctx, R.scene.lights, frame, surf);
  const ro = R.tracks[panel.run][panel.k];
  ctx.lineWidth = 1.5;
  ctx.globalAlpha = 0.45;
  for (const g of ro.agents) { // the trail
    ctx.strokeStyle = colourOf(g.a);
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
  const prompted = R.promptedIds;
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
    const mark = ro.collided.has(id) && i0 >= R.hist + ro.collided.get(id) ? COLLIDED : prompted.has(id) ? TARGET : null;
    drawAgent(ctx, g.a, x, y, hd, frame, surf, { mark, markPx: panel.thumb ? 1.5 : 3, alpha: R.parked.has(id) && !mark ? 0.4 : 1 });
    if (!panel.thumb && (frame.s > 2.2 || prompted.has(id) || id === R.view.follow)) drawLabel(ctx, id, x, y, frame, surf);
  }
  if (!panel.thumb) drawScaleBar(ctx, frame, surf);
}

/** Paint every visible panel and the plots at the replay's time. */
export function paintReplay() {
  const R = S.replay;
  if (!R) return;
  const i = clamp(R.t, 0, R.total - 1);
  for (const panel of R.panels) if (panel.visible) paintPanel(R, panel, i);
  paintPlots(R, i);
  const k = Math.floor(i);
  const sim = k - (R.hist - 1);
  $('scrub').value = String(k);
  $('step-info').textContent = sim <= 0
    ? `logged history, step ${k + 1} of ${R.hist} (t = ${fmt(sim * R.dt, 1)} s)`
    : `simulated step ${sim} of ${R.steps} (t = ${fmt(sim * R.dt, 1)} s)`;
}

// ------------------------------------------------------------------ playing, scrubbing, jumping

function tick(ts) {
  const R = S.replay;
  if (!R || !R.playing) return;
  const stats = window.studioStats;
  stats.frames.push(ts);
  if (stats.frames.length > MAX_STATS) stats.frames.splice(0, stats.frames.length - MAX_STATS);
  if (R.last !== null) R.t += ((ts - R.last) / 1000) * (Number($('speed').value) / R.dt);
  R.last = ts;
  if (R.t >= R.total - 1) {
    R.t = R.total - 1;
    paintReplay();
    setPlaying(false);
    return;
  }
  const t0 = performance.now();
  paintReplay();
  stats.paint.push(performance.now() - t0);
  if (stats.paint.length > MAX_STATS) stats.paint.splice(0, stats.paint.length - MAX_STATS);
  R.raf = requestAnimationFrame(tick);
}

export function setPlaying(on) {
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

/** Show the scrubber's step, paused or playing on from it. */
export function scrubTo(step) {
  if (!S.replay) return;
  S.replay.t = step;
  S.replay.last = null;
  if (!S.replay.playing) paintReplay();
}

/** Show run `name`'s rollout `k` at future step `step` (an event's moment) in the large view, paused. */
function jumpTo(name, k, step) {
  const R = S.replay;
  if (!R) return;
  const r = Math.max(0, R.runs.findIndex((x) => x.name === name));
  if ($('layout').value !== 'all' && (R.main.run !== r || R.main.k !== k)) showMain(r, k);
  setPlaying(false);
  R.t = R.hist + step;
  R.last = null;
  paintReplay();
  $('scrub').focus();
}

/** For tests and the curious: the large view now (its centre in metres, its scale in pixels a metre, what it
 * follows and shows), and a plot's value at the replay's time. */
export const replayApi = {
  get replayFrames() { return S.replay ? S.replay.total : 0; },
  replayView() {
    const R = S.replay;
    const panel = R && R.panels.find((p) => p.surf && !p.thumb);
    if (!panel) return null;
    const f = replayFrame(R, panel, panel.surf, R.t);
    return { cx: f.cx, cy: f.cy, s: f.s, follow: R.view.follow, run: R.runs[panel.run].name, rollout: panel.k, step: Math.round(R.t) };
  },
  plotValue(id, key) { return S.replay ? plotValue(S.replay, String(id), key) : null; },
};
