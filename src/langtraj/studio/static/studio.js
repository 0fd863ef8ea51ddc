/* LangTraj Studio: pick a scene, write @id prompts and see how each is read, run the simulation as a job, watch
 * the rollouts replayed from their positions, judge them, keep one as a test case (docs/studio.md, 'The page').
 * Vanilla JS in ES modules without a build step, one module per concern (docs/studio.md, 'The page's code'),
 * served under a strict CSP (no inline code or style); all text coming from the server or the user is inserted
 * with textContent / createElement, never as markup. This module wires the page's controls to them.
 */
import { $, debounce } from '/common/dom.js';
import { onOpen, pollJobs, run } from './jobs.js';
import { loadScenes, pickScene } from './picker.js';
import { addPrompt, insertAgent, renderPrompts, restorePrompts, scheduleRead } from './prompts.js';
import { bindReplayView, layoutReplay, openJob, paintReplay, replayApi, scrubTo, setPlaying } from './replay.js';
import { saveCase } from './keep.js';
import { loadStagings, renderStagings } from './stagings.js';
import { agentPoint, drawScene, setupSceneCanvas } from './scene.js';
import { FILTER_DEBOUNCE_MS, S } from './state.js';

function start() {
  setupSceneCanvas(insertAgent);
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
  $('staging-ego').addEventListener('change', () => loadStagings());
  $('staging-behaviour').addEventListener('change', renderStagings);
  onOpen(openJob);
  $('play').addEventListener('click', () => S.replay && setPlaying(!S.replay.playing));
  $('scrub').addEventListener('input', () => scrubTo(Number($('scrub').value)));
  $('layout').addEventListener('change', layoutReplay);
  $('which-rollout').addEventListener('change', layoutReplay);
  bindReplayView();
  $('case-form').addEventListener('submit', saveCase);
  new ResizeObserver(() => { if (S.replay && !S.replay.playing) paintReplay(); }).observe($('replay-grid'));
  const hash = new URLSearchParams(location.hash.slice(1));
  loadScenes().then(() => { if (hash.get('scene')) pickScene(hash.get('scene')); });
  pollJobs().then(() => { if (hash.get('job') && S.jobs.some((j) => j.id === hash.get('job') && j.status === 'done')) openJob(hash.get('job')); });
}

/** For tests and the curious: where agent `id` of the picked scene is drawn (client pixels), the replay's view. */
window.studio = Object.assign(Object.create(replayApi), { agentPoint });

start();
