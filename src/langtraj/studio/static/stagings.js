/* What the picked scene can stage against an ego: the list of `GET /api/scenes/{key}/stagings` (the search
 * `langtraj suggest` runs), most natural first as the server sorts it, filtered by behaviour; the ego is the
 * planner's until another is picked. Clicking a staging writes its prompt into the prompt box (prompts.js) and
 * outlines its agent in the scene (`S.staged`). A late answer (another scene or ego picked since) is dropped. See
 * docs/studio.md, 'The page'.
 */
import { request as api } from '/common/api.js';
import { $, h, say, showIn } from '/common/dom.js';
import { fillPrompt } from './prompts.js';
import { drawScene } from './scene.js';
import { S } from './state.js';

const UNITS = { gap: (v) => `${v} m gap`, deceleration: (v) => `${v} m/s²` };
const words = (name) => String(name).replace(/_/g, ' ');
const plural = (n, one) => `${n} ${one}${n === 1 ? '' : 's'}`;

/** A staging's parameters as words ("10 m gap", "4 m/s²"); '' for none. */
export function parameterText(parameters) {
  return Object.entries(parameters || {}).map(([k, v]) => (UNITS[k] ? UNITS[k](v) : `${words(k)} ${v}`)).join(', ');
}

let seq = 0; // the newest request; older answers are dropped
let picked = null; // the staging clicked last

/** A new scene is picked: its simulated vehicles (the self-driving car first) are the egos offered, and its list is
 * asked for the planner's ego. */
export function showStagings() {
  const vehicles = S.scene.agents.filter((a) => a.sim && a.type === 'vehicle').sort((a, b) => Number(b.sdc) - Number(a.sdc));
  $('staging-ego').replaceChildren(...vehicles.map((a) => egoOption(a.id, a.sdc)));
  loadStagings(null);
}

function egoOption(id, sdc) {
  return h('option', { value: String(id) }, `@${id}${sdc ? ' (ego)' : ''}`);
}

/** Ask what the scene can stage against `ego` (the picked one by default; null: the planner's ego). */
export async function loadStagings(ego = $('staging-ego').value === '' ? null : Number($('staging-ego').value)) {
  const n = ++seq;
  S.stagings = null;
  forget();
  showIn('staging-error', '');
  $('stagings').replaceChildren();
  $('staging-count').textContent = `Searching what the scene can stage${ego === null ? '' : ` against @${ego}`}…`;
  const query = ego === null ? '' : `?ego=${encodeURIComponent(ego)}`;
  let data;
  try {
    data = await api('GET', `/api/scenes/${encodeURIComponent(S.sceneKey)}/stagings${query}`);
  } catch (err) {
    if (n !== seq) return;
    $('staging-count').textContent = '';
    showIn('staging-error', `Cannot list what the scene can stage: ${err.message}`);
    return;
  }
  if (n !== seq) return;
  S.stagings = data;
  const egoSelect = $('staging-ego');
  if (![...egoSelect.options].some((o) => o.value === String(data.ego))) egoSelect.append(egoOption(data.ego, false));
  egoSelect.value = String(data.ego);
  behaviourFilter(data.stagings);
  renderStagings();
}

/** The behaviour filter: every behaviour the list holds, with its count (the one chosen kept where it still is). */
function behaviourFilter(stagings) {
  const select = $('staging-behaviour');
  const was = select.value;
  const counts = new Map();
  for (const s of stagings) counts.set(s.behaviour, (counts.get(s.behaviour) || 0) + 1);
  select.replaceChildren(h('option', { value: '' }, `every behaviour (${stagings.length})`),
    ...[...counts].map(([b, k]) => h('option', { value: b }, `${words(b)} (${k})`)));
  select.value = counts.has(was) ? was : '';
}

/** The list as answered, the behaviour filter applied; the staging clicked last is pressed. */
export function renderStagings() {
  const data = S.stagings;
  if (!data) return;
  const only = $('staging-behaviour').value;
  const shown = data.stagings.map((s, i) => [s, i]).filter(([s]) => !only || s.behaviour === only);
  $('staging-count').textContent = data.stagings.length
    ? `${plural(shown.length, 'staging')} against @${data.ego}, most natural first.`
    : `Nothing the map allows against @${data.ego} at the current step.`;
  $('stagings').replaceChildren(...shown.map(([s, i]) => {
    const params = parameterText(s.parameters);
    return h('li', {}, h('button', {
      type: 'button', class: 'staging', 'data-index': i, 'data-agent': s.agent, 'data-behaviour': s.behaviour,
      'aria-pressed': s === picked ? 'true' : 'false',
      title: `${s.typed_prompt} (score ${s.score}: a change of ${s.change} m/s, ${s.distance_m} m from @${s.other})`,
      onclick: () => stage(s),
    }, h('span', { class: 'staging-head' }, h('strong', {}, words(s.behaviour)), ' ', h('code', {}, `@${s.agent}`),
      params ? ` · ${params}` : ''), h('small', {}, s.reason)));
  }));
}

/** A staging clicked: its prompt (the ego named by its @id, as the prompt boxes name agents) is written into the
 * prompt box and read, and its agent outlined in the scene. */
function stage(s) {
  picked = s;
  S.staged = String(s.agent);
  for (const b of $('stagings').querySelectorAll('button.staging')) {
    b.setAttribute('aria-pressed', S.stagings.stagings[Number(b.dataset.index)] === s ? 'true' : 'false');
  }
  drawScene();
  const i = fillPrompt(s.typed_prompt);
  say(`Prompt ${i + 1} is “${s.typed_prompt}”; @${s.agent} is outlined in the scene.`);
}

function forget() {
  picked = null;
  if (S.staged !== null) { S.staged = null; drawScene(); }
}
