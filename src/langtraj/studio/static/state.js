/* The studio page's state (one object, `S`), its timing constants and the address it keeps (#scene=..&job=..).
 * See docs/studio.md, 'The page's code'.
 */

export const READ_DEBOUNCE_MS = 300; // a prompt is read this long after the last keystroke
export const FILTER_DEBOUNCE_MS = 250;
export const POLL_ACTIVE_MS = 1000; // the jobs list while a job is queued or running
export const POLL_IDLE_MS = 4000; // otherwise (jobs started in other tabs appear)
export const MAX_STATS = 4000;

export const S = {
  scenes: [], kinds: new Set(), sceneKey: null, scene: null, sceneCache: new Map(),
  view: null, prompts: [{ text: '', result: null }], active: 0, readSeq: 0, reading: null,
  jobs: [], jobItems: new Map(), pollTimer: null, openJob: null, replay: null,
  stagings: null, staged: null, // the picked ego's stagings ({ego, stagings}) and the agent of the one clicked
};

/** The replay's frame times (requestAnimationFrame timestamps, ms) and how long each frame took to paint (ms), for
 * measuring smoothness (benchmarks/studio_replay.py). */
window.studioStats = { frames: [], paint: [] };

/** The picked scene and the open job in the address, so a reload or a shared link opens them again. */
export function saveHash() {
  const p = new URLSearchParams();
  if (S.sceneKey) p.set('scene', S.sceneKey);
  if (S.openJob) p.set('job', S.openJob.id);
  history.replaceState(null, '', p.toString() ? `#${p}` : location.pathname);
}

export const fmt = (x, digits = 3) => {
  if (typeof x === 'number') return Number.isFinite(x) ? x.toFixed(digits) : '—';
  return x === null || x === undefined || x === '' ? '—' : String(x);
};
