/* The prompts: typed, read against the picked scene by the server's one prompt check as they are typed
 * (debounced; a late answer is dropped), each shown with its reading, and kept in the tab over a reload. What the
 * readings name and target is drawn on the scene (`S.marks`). See docs/studio.md, 'The page'.
 */
import { request as api } from '/common/api.js';
import { $, clamp, h, say, showIn } from '/common/dom.js';
import { normTarget } from './draw.js';
import { drawScene } from './scene.js';
import { READ_DEBOUNCE_MS, S } from './state.js';

/** The value of select `id` as an agent id, or null for none. */
export const selected = (id) => ($(id).value === '' ? null : Number($(id).value));

/** What the scene marks: the readings' targets and the agents the prompts name. */
function updateMarks() {
  const results = S.prompts.map((p) => p.result).filter(Boolean);
  const targets = results.flatMap((r) => r.targets || (r.target ? [r.target] : [])).map(normTarget).filter(Boolean);
  const prompted = new Set();
  for (const r of results.flatMap((x) => x.readings || (x.reading ? [x.reading] : []))) {
    if (r.behaviour && r.agent !== null && r.agent !== undefined) prompted.add(String(r.agent));
    if (r.behaviour && r.other !== null && r.other !== undefined) prompted.add(String(r.other));
  }
  S.marks = { targets, prompted };
  drawScene();
}

/** Insert `@id` where the caret is in the prompt being written. */
export function insertAgent(id) {
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

/** Write `text` into the prompt box last edited when it is empty or still holds what an earlier fill wrote, else
 * into a new box (a typed prompt is never overwritten); the prompts are then read. Returns the box's index. */
export function fillPrompt(text) {
  let i = clamp(S.active, 0, S.prompts.length - 1);
  const p = S.prompts[i];
  if (p.text.trim() && p.text !== p.filled) {
    S.prompts.push({ text: '', result: null });
    i = S.prompts.length - 1;
  }
  Object.assign(S.prompts[i], { text, filled: text, result: null });
  S.active = i;
  renderPrompts();
  const box = $(`prompt-${i}`);
  box.focus();
  box.setSelectionRange(text.length, text.length);
  scheduleRead();
  return i;
}

export function renderPrompts() {
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

/** How prompt `p` was read: the reader's description (clause by clause where it has several), whether the map
 * allows it, the warning or error. */
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
  const clauses = r.readings || [];
  if (clauses.length > 1) { // each clause as the simulation reads it, one per line
    out.append(h('ol', { class: 'clauses', 'aria-label': 'Clause by clause' }, clauses.map((c) => h('li', { 'data-clause': c.clause || '' },
      c.behaviour ? h('span', { class: 'ok describe' }, c.describe)
        : [h('span', { class: 'pill warn' }, 'not read'), ' ', h('span', { class: 'warn describe' }, c.describe)]))));
  } else {
    out.append(h('span', { class: 'ok describe' }, reading.describe), ' ');
  }
  if (r.feasible === true) out.append(h('span', { class: 'pill ok' }, 'feasible'));
  else if (r.feasible === false) out.append(h('span', { class: 'pill warn' }, 'the map rules it out'));
  if (r.warning) out.append(h('span', { class: 'warn' }, r.warning));
  return out;
}

export function addPrompt() {
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

/** A new scene: its readings are unknown; typed prompts are cleared when the scene switches (`clear`), since their
 * @ids name the old scene's agents. */
export function resetPrompts(clear) {
  for (const p of S.prompts) p.result = null;
  if (clear) S.prompts = [{ text: '', result: null }];
  S.active = 0;
}

/** The prompts survive a reload of the tab (sessionStorage: this tab only). */
function keepPrompts() {
  try { sessionStorage.setItem('studio.prompts', JSON.stringify(S.prompts.map((p) => p.text))); } catch { /* private mode */ }
}

export function restorePrompts() {
  try {
    const texts = JSON.parse(sessionStorage.getItem('studio.prompts') || '[]');
    if (Array.isArray(texts) && texts.length) S.prompts = texts.map((text) => ({ text: String(text), result: null }));
  } catch { /* nothing kept */ }
}

let readTimer = null;
/** Read the prompts a moment after the last change. */
export function scheduleRead() {
  keepPrompts();
  for (const p of S.prompts) if (p.text.trim()) p.pending = true;
  renderReadings();
  clearTimeout(readTimer);
  readTimer = setTimeout(readPrompts, READ_DEBOUNCE_MS);
}

/** Read every non-empty prompt against the scene; resolves to true when every prompt is read, understood and
 * not ruled out by the map (what Run requires). Older answers arriving late are dropped. */
export function readPrompts() {
  clearTimeout(readTimer);
  keepPrompts();
  const seq = ++S.readSeq;
  showIn('read-error', '');
  const idx = S.prompts.map((p, i) => (p.text.trim() ? i : -1)).filter((i) => i >= 0);
  if (!S.scene || !idx.length) {
    for (const p of S.prompts) { p.result = null; p.pending = false; }
    renderReadings();
    updateMarks();
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
    updateMarks();
    return Boolean(data.ok) && idx.every((i) => {
      const r = S.prompts[i].result;
      return r && r.ok;
    });
  }, (err) => {
    if (seq !== S.readSeq) return S.reading;
    S.prompts.forEach((p) => { p.pending = false; p.result = null; });
    showIn('read-error', `The prompts cannot be read: ${err.message}`);
    renderReadings();
    updateMarks();
    return false;
  });
  return S.reading;
}

/** Why the prompts cannot run as they are (one line), or null. */
export function blocker() {
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
