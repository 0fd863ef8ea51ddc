/* Speed and distance to the target over time for the prompted agents, beside the replay: the big view's rollout
 * bold, the run's other rollouts faint, the same rollout without the prompts dashed grey; a cursor at the
 * replay's time; a click moves the replay there. The series are the server's (`series` of a run: the speed the
 * adherence checker judges, the signed distance along the target's path). See docs/studio.md, 'The page'.
 */
import { h } from '/common/dom.js';
import { Surface } from './canvas.js';
import { TARGET } from './draw.js';

const PAD = { left: 38, right: 8, top: 8, bottom: 18 }; // CSS pixels around the plotting area
const QUANTITIES = [
  { key: 'speed', title: 'speed', unit: 'm/s' },
  { key: 'to_target', title: 'distance to', unit: 'm' },
];

/** The series of agent `id` in run `r` of the replay (or null). */
const seriesOf = (R, r, id) => ((R.runs[r] && R.runs[r].run.series) || {})[id] || null;

/** Build the plots of `R`'s prompted agents into `box` (emptied first); none where the job has no series. */
export function buildPlots(R, box) {
  R.plots = [];
  const figures = [];
  const series = R.runs[0].name === 'prompted' ? R.runs[0].run.series || {} : {};
  for (const [id, s] of Object.entries(series)) {
    const charts = [];
    for (const q of QUANTITIES) {
      if (!s[q.key]) continue;
      const title = q.key === 'to_target' ? `distance to ${s.goal || 'the target'} (${q.unit})` : `${q.title} (${q.unit})`;
      const canvas = h('canvas', { class: 'plot-canvas', 'data-agent': id, 'data-quantity': q.key,
        'aria-label': `@${id}: ${title} over time; click to move the replay there` });
      R.plots.push({ canvas, id, key: q.key, surf: null, range: null });
      charts.push(h('div', { class: 'plot' }, h('span', { class: 'plot-title' }, title), canvas));
    }
    figures.push(h('figure', { class: 'plots-agent' }, h('figcaption', {}, h('strong', {}, `@${id}`), ' (prompted)'), ...charts));
  }
  box.replaceChildren(...(figures.length ? [h('h3', {}, 'Prompted agents over time'), ...figures] : []));
  box.hidden = figures.length === 0;
  for (const p of R.plots) p.surf = new Surface(p.canvas);
}

/** Every value of the plot's lines (for its range). */
function lines(R, plot) {
  const out = [];
  const own = seriesOf(R, 0, plot.id);
  const rolls = (own && own[plot.key]) || [];
  rolls.forEach((values, k) => out.push({ values, style: k === R.main.k && R.main.run === 0 ? 'main' : 'other' }));
  const base = R.runs.length > 1 ? seriesOf(R, 1, plot.id) : null; // the same rollout without the prompts
  if (base && base[plot.key] && base[plot.key][R.main.k]) out.push({ values: base[plot.key][R.main.k], style: 'base' });
  if (R.main.run === 1) for (const l of out) if (l.style === 'base') l.style = 'main';
  return out;
}

function niceRange(values) {
  let lo = Infinity; let hi = -Infinity;
  for (const v of values) if (v !== null && Number.isFinite(v)) { lo = Math.min(lo, v); hi = Math.max(hi, v); }
  if (lo > hi) return [0, 1];
  lo = Math.min(lo, 0);
  if (hi - lo < 1) hi = lo + 1;
  return [lo, hi + (hi - lo) * 0.05];
}

function paintAxes(ctx, R, plot, surf, ls) {
  const [lo, hi] = plot.range;
  const w = surf.w - PAD.left - PAD.right; const hgt = surf.hgt - PAD.top - PAD.bottom;
  const X = (i) => PAD.left + (i / Math.max(R.total - 1, 1)) * w;
  const Y = (v) => PAD.top + (1 - (v - lo) / (hi - lo)) * hgt;
  ctx.fillStyle = '#fff';
  ctx.fillRect(0, 0, surf.w, surf.hgt);
  ctx.strokeStyle = '#c9d0d8'; ctx.lineWidth = 1;
  ctx.strokeRect(PAD.left, PAD.top, w, hgt);
  ctx.font = '10px system-ui, sans-serif'; ctx.fillStyle = '#5b6570';
  const dt = R.dt;
  for (let s = Math.ceil(-(R.hist - 1) * dt / 2) * 2; s <= R.steps * dt + 1e-9; s += 2) { // a tick every 2 s
    const x = X(R.hist - 1 + s / dt);
    ctx.beginPath(); ctx.moveTo(x, PAD.top + hgt); ctx.lineTo(x, PAD.top + hgt + 3); ctx.stroke();
    ctx.fillText(`${s}`, x - 4, surf.hgt - 4);
  }
  for (const v of [lo, 0, hi].filter((x, k, a) => a.indexOf(x) === k)) {
    ctx.fillText(v.toFixed(Math.abs(hi - lo) < 10 ? 1 : 0), 2, Y(v) + 3);
    if (v === 0) { ctx.beginPath(); ctx.moveTo(PAD.left, Y(0)); ctx.lineTo(PAD.left + w, Y(0)); ctx.stroke(); }
  }
  const x0 = X(R.hist - 1); // the current step: the simulation starts here
  ctx.setLineDash([2, 3]); ctx.beginPath(); ctx.moveTo(x0, PAD.top); ctx.lineTo(x0, PAD.top + hgt); ctx.stroke();
  ctx.setLineDash([]);
  const order = { other: 0, base: 1, main: 2 };
  for (const l of [...ls].sort((a, b) => order[a.style] - order[b.style])) {
    ctx.strokeStyle = l.style === 'main' ? TARGET : l.style === 'base' ? '#77767b' : 'rgba(224,27,143,0.3)';
    ctx.lineWidth = l.style === 'main' ? 2 : 1.25;
    ctx.setLineDash(l.style === 'base' ? [5, 3] : []);
    ctx.beginPath();
    let pen = false;
    l.values.forEach((v, i) => {
      if (v === null || !Number.isFinite(v)) { pen = false; return; }
      if (pen) ctx.lineTo(X(i), Y(v)); else ctx.moveTo(X(i), Y(v));
      pen = true;
    });
    ctx.stroke();
  }
  ctx.setLineDash([]);
}

/** Paint every plot at replay time `i` (the lines cached; the cursor and the value drawn each frame). */
export function paintPlots(R, i) {
  for (const plot of R.plots || []) {
    const { surf } = plot;
    surf.measure();
    const ls = lines(R, plot);
    const key = `${R.main.run}:${R.main.k}:${surf.w}x${surf.hgt}`;
    surf.background(key, (ctx) => {
      plot.range = niceRange(ls.flatMap((l) => l.values));
      ctx.setTransform(surf.dpr, 0, 0, surf.dpr, 0, 0);
      paintAxes(ctx, R, plot, surf, ls);
    });
    const { ctx } = surf;
    ctx.setTransform(surf.dpr, 0, 0, surf.dpr, 0, 0);
    const w = surf.w - PAD.left - PAD.right;
    const x = PAD.left + (i / Math.max(R.total - 1, 1)) * w;
    ctx.strokeStyle = '#1d232b'; ctx.lineWidth = 1;
    ctx.beginPath(); ctx.moveTo(x, PAD.top); ctx.lineTo(x, surf.hgt - PAD.bottom); ctx.stroke();
    const v = plotValue(R, plot.id, plot.key);
    if (v !== null) {
      ctx.font = '600 11px system-ui, sans-serif'; ctx.fillStyle = '#1d232b';
      const text = v.toFixed(1);
      ctx.fillText(text, Math.min(x + 4, surf.w - PAD.right - ctx.measureText(text).width), PAD.top + 11);
    }
  }
}

/** The value agent `id`'s `key` series has in the big view's rollout at the replay's time (null where none). */
export function plotValue(R, id, key) {
  const s = seriesOf(R, R.main.run, id);
  const values = s && s[key] && s[key][R.main.k];
  const v = values ? values[Math.round(R.t)] : null;
  return v === undefined || v === null ? null : v;
}

/** The replay time a click at client x on `plot`'s canvas points at. */
export function plotTime(R, canvas, clientX) {
  const r = canvas.getBoundingClientRect();
  const w = r.width - PAD.left - PAD.right;
  return Math.min(Math.max(((clientX - r.left - PAD.left) / w) * (R.total - 1), 0), R.total - 1);
}
