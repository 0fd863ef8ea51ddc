/* The scene picker: the catalog's scenes filtered as typed (a late answer is dropped), the files that failed to
 * load, and picking one (its detail fetched once and cached). See docs/studio.md, 'The page'.
 */
import { request as api } from '/common/api.js';
import { $, h, say, showError, showIn } from '/common/dom.js';
import { readPrompts, renderPrompts, resetPrompts } from './prompts.js';
import { drawScene, resetSceneView } from './scene.js';
import { showStagings } from './stagings.js';
import { S, saveHash } from './state.js';

/** The detail of scene `key` (fetched once). */
export async function sceneDetail(key) {
  if (!S.sceneCache.has(key)) S.sceneCache.set(key, api('GET', `/api/scenes/${encodeURIComponent(key)}`));
  try { return await S.sceneCache.get(key); } catch (err) { S.sceneCache.delete(key); throw err; }
}

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
export async function loadScenes() {
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

/** Show scene `key`: the view fits it, the agent lists are its own, the prompts are read against it (and cleared,
 * with the old scene's errors, when another scene was picked before), and what it can stage is listed. */
export async function pickScene(key) {
  showError('');
  say('Loading the scene…');
  let scene;
  try { scene = await sceneDetail(key); } catch (err) { showError(`Cannot load the scene: ${err.message}`); say(''); return; }
  const switched = S.sceneKey !== null && S.sceneKey !== undefined && S.sceneKey !== key;
  const typed = S.prompts.some((p) => p.text.trim());
  S.sceneKey = key;
  S.scene = scene;
  resetSceneView();
  resetPrompts(switched && typed);
  if (switched) for (const id of ['run-error', 'read-error', 'case-error']) showIn(id, '');
  $('scene-title').textContent = `Scene ${scene.scenario_id} (${scene.agents.length} agents)`;
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
  showStagings();
  drawScene();
}
