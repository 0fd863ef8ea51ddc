/* Judge: a job's results as tables — each prompt followed or not per rollout, asked beside realised numbers (with the base rate without the
 * prompts), each agent's first contact with its time and partner and its first step off the road (buttons that
 * jump the replay there), the realism figures beside the table's own rates — and the contacts as ticks on the scrubber.
 * See docs/studio.md, 'The page'.
 */
import { $, h } from '/common/dom.js';
import { fmt } from './state.js';

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

/** A rollout's verdict on a prompt: followed or not, with the asked and realised numbers of a behaviour judged by
 * numbers (one line each, as the suites' report writes them) and why not. */
function verdictCell(p, k) {
  const td = cell((p.followed || [])[k], 'followed', 'not followed');
  const measures = (p.measures || [])[k] || [];
  const why = (p.why || [])[k];
  if (measures.length) td.append(h('ul', { class: 'measures' }, measures.map((m) => h('li', { class: m.ok === false ? 'no' : '' }, m.describe))));
  if (why && (p.followed || [])[k] === false) td.append(h('div', { class: 'why' }, why));
  return td;
}

function followedTable(prompted, unprompted, heads, n) {
  const rows = (prompted.prompts || []).map((p, i) => {
    const base = unprompted && (unprompted.prompts || [])[i]; // both runs judge the same prompts, in order
    return h('tr', {}, h('th', { scope: 'row' }, p.text), h('td', {}, p.behaviour ? String(p.behaviour).replace(/_/g, ' ') : '—'),
      ...Array.from({ length: n }, (_, k) => verdictCell(p, k)),
      unprompted ? h('td', {}, base ? rate(base.followed) : '—') : null);
  });
  return h('table', { id: 'followed-table' }, h('caption', {}, 'Prompts: followed per rollout'),
    h('thead', {}, h('tr', {}, h('th', { scope: 'col' }, 'prompt'), h('th', { scope: 'col' }, 'read as'), ...heads,
      unprompted ? h('th', { scope: 'col' }, 'without prompts (base rate)') : null)),
    h('tbody', {}, rows.length ? rows : h('tr', {}, h('td', { colspan: n + 2 }, 'No prompt was judged.'))));
}

/** Collisions and off-road of `run`: each first contact with its time and partner (the realism rates' own
 * computation); parked agents listed apart. */
function eventsTable(name, run, which, heads, n, stepSeconds) {
  const promptedIds = new Set((run.prompts || []).flatMap((p) => [p.agent, p.other]).filter((v) => v !== null && v !== undefined).map(String));
  const measured = run.road_edges !== null && run.road_edges !== undefined;
  const listed = (run.agents || []).filter((a) => promptedIds.has(String(a.id))
    || (a.collision || []).some(Boolean) || (a.offroad || []).some(Boolean));
  const parked = listed.filter((a) => a.parked && !promptedIds.has(String(a.id)));
  const agents = listed.filter((a) => !parked.includes(a));
  agents.sort((a, b) => Number(promptedIds.has(String(b.id))) - Number(promptedIds.has(String(a.id)))); // prompted first
  const at = (step) => `${((step + 1) * stepSeconds).toFixed(1)} s`; // a future step's time (step 0: 0.1 s)
  const body = agents.map((a) => h('tr', {}, h('th', { scope: 'row' }, `@${a.id}${promptedIds.has(String(a.id)) ? ' (prompted)' : ''}${a.evaluated ? '' : ' ·'}`), ...Array.from({ length: n }, (_, k) => {
    const contact = (a.collisions || []).find((c) => c.rollout === k);
    const ev = [];
    if (contact) ev.push(h('button', { type: 'button', class: 'event-jump', 'data-run': which, 'data-rollout': k, 'data-step': contact.step, title: 'jump to the moment' },
      `collision with @${contact.with} at ${at(contact.step)}`));
    const leave = (a.offroads || []).find((o) => o.rollout === k);
    if (leave) ev.push(h('button', { type: 'button', class: 'event-jump', 'data-run': which, 'data-rollout': k, 'data-step': leave.step, title: 'jump to the moment' },
      `off-road at ${at(leave.step)}`));
    if (ev.length) return h('td', { class: 'event' }, ...ev);
    return h('td', { class: measured ? 'yes' : 'na' }, measured ? 'clear' : 'no collision; off-road not measured');
  })));
  const note = [`“·”: not scored by WOSAC (its rates cover the ${(run.realism || {}).evaluated ?? '?'} evaluated agents).`];
  if (!measured) note.push('Off-road is not measured: this map has no road edges.');
  else if (run.road_edges !== 'map') note.push(`Off-road is measured against road edges ${run.road_edges}.`);
  if (parked.length) note.push(`${parked.length} parked agent${parked.length === 1 ? '' : 's'} with events not listed: ${parked.map((a) => `@${a.id}`).join(', ')}.`);
  return [h('table', { class: 'events-table', 'data-run': which },
    h('caption', {}, `Collisions and off-road, ${name}`),
    h('thead', {}, h('tr', {}, h('th', { scope: 'col' }, 'agent'), ...heads.map((x) => x.cloneNode(true)))),
    h('tbody', {}, body.length ? body : h('tr', {}, h('td', { colspan: n + 1 }, 'No collision or off-road in any rollout.')))),
  h('p', { class: 'hint events-note' }, note.join(' '))];
}

function realismTable(prompted, unprompted) {
  const keys = [...new Set([...Object.keys(prompted.realism || {}), ...Object.keys((unprompted && unprompted.realism) || {})])]
    .filter((key) => key !== 'note' && key !== 'evaluated');
  if (!keys.length) return [];
  const tableRate = (run, key) => (run && run.rates ? run.rates[key] : null);
  return [h('table', { id: 'realism-table' }, h('caption', {}, 'Realism'),
    h('thead', {}, h('tr', {}, h('th', { scope: 'col' }, 'figure'), h('th', { scope: 'col' }, 'with the prompts'),
      unprompted ? h('th', { scope: 'col' }, 'without prompts') : null)),
    h('tbody', {}, keys.map((key) => h('tr', {}, h('th', { scope: 'row' }, key.replace(/_/g, ' ')),
      h('td', { class: 'num' }, fmt((prompted.realism || {})[key])),
      unprompted ? h('td', { class: 'num' }, fmt((unprompted.realism || {})[key])) : null)).concat(
      [['collision_all', 'collision rate, every agent in the events table'], ['offroad_all', 'off-road rate, every vehicle measured']]
        .map(([key, label]) => h('tr', {}, h('th', { scope: 'row' }, label),
          h('td', { class: 'num' }, fmtRate(tableRate(prompted, key), prompted)),
          unprompted ? h('td', { class: 'num' }, fmtRate(tableRate(unprompted, key), unprompted)) : null))))),
  h('p', { class: 'hint' }, `WOSAC's rates are over the ${(prompted.realism || {}).evaluated ?? '?'} agents it scores${(prompted.realism || {}).note ? ` (${prompted.realism.note})` : ''}; the last two rows are over every agent of the table.`)];
}

/** Fill #results with `job`'s tables and #scrub-events with its prompted run's contacts; an event's button calls
 * `onJump(run, rollout, step)`. */
export function renderResults(job, onJump) {
  const { prompted, unprompted } = job.result.runs;
  const n = prompted.rollouts.length;
  const heads = Array.from({ length: n }, (_, k) => h('th', { scope: 'col' }, `rollout ${k + 1}`));
  const stepSeconds = job.result.step_seconds || 0.1;
  const out = [followedTable(prompted, unprompted, heads, n)];
  out.push(...eventsTable('with the prompts', prompted, 'prompted', heads, n, stepSeconds));
  if (unprompted) out.push(...eventsTable('without prompts', unprompted, 'unprompted', heads, n, stepSeconds));
  out.push(...realismTable(prompted, unprompted));
  const warnings = [...(prompted.warnings || []), ...((unprompted && unprompted.warnings) || [])];
  if (warnings.length) {
    out.push(h('div', { class: 'warnings' }, h('h3', {}, 'Warnings'), h('ul', {}, [...new Set(warnings)].map((w) => h('li', {}, w)))));
  }
  $('results').replaceChildren(...out);
  for (const b of $('results').querySelectorAll('button.event-jump')) {
    b.addEventListener('click', () => onJump(b.dataset.run, Number(b.dataset.rollout), Number(b.dataset.step)));
  }
  // every first contact and off-road of the prompted run as a tick on the scrubber, labelled
  const hist = (job.result.start_step ?? 0) + 1;
  $('scrub-events').replaceChildren(...(prompted.agents || []).flatMap((a) => [
    ...(a.collisions || []).map((c) => h('option', { value: String(hist + c.step), label: `@${a.id} × @${c.with}, rollout ${c.rollout + 1}` })),
    ...(a.offroads || []).map((o) => h('option', { value: String(hist + o.step), label: `@${a.id} off-road, rollout ${o.rollout + 1}` })),
  ]));
}
