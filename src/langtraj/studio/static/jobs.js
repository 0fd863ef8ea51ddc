/* Run and the jobs list: a run is checked (the latest text read again) before its job is submitted; the list is
 * polled (fast while a job is active), updated in place so focus survives, with Open for a finished job and Run
 * again for an interrupted or failed one. See docs/studio.md, 'The page'.
 */
import { request as api } from '/common/api.js';
import { $, clamp, h, say, showError, showIn } from '/common/dom.js';
import { blocker, readPrompts, selected } from './prompts.js';
import { POLL_ACTIVE_MS, POLL_IDLE_MS, S } from './state.js';

const active = (j) => j.status === 'queued' || j.status === 'running';

let openJob = () => {};
/** What the Open button of a job calls (the replay's `openJob`). */
export function onOpen(fn) { openJob = fn; }

export async function run() {
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

export async function pollJobs() {
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

const time = (t) => { // an ISO time from the server
  const d = new Date(t);
  return Number.isNaN(d.getTime()) ? String(t) : d.toLocaleTimeString();
};

/** Update the jobs list in place (keyed by id), so focus and buttons survive each poll. */
export function renderJobs() {
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
    if (j.status === 'queued') el.stage.textContent = `queued since ${time(j.created)}`;
    else if (j.status === 'running' && j.started) el.stage.textContent = `${j.stage || 'running'} (${pct}), started ${time(j.started)}`;
    else el.stage.textContent = active(j) ? `${j.stage || j.status} (${pct})` : j.finished ? `finished ${time(j.finished)}` : j.stage || '';
    el.err.textContent = j.error || '';
    el.err.hidden = !j.error;
    el.open.hidden = j.status !== 'done';
    el.again.hidden = j.status !== 'interrupted' && j.status !== 'failed';
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
