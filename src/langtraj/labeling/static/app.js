/* LangTraj labeling page: login, the InterDrive three-step protocol (pair, type, subtype) with a keyboard
 * shortcut for every choice, the reviewer's disagreement queue and agreement tables, and the admin's export.
 * Vanilla JS without a build step, served under a strict CSP (no inline code or style); all text coming from
 * users or the server is inserted with textContent / createElement, never as markup.
 * See docs/labeling.md ('Protocol'); the API is in src/langtraj/labeling/app.py.
 */
import { request } from '/common/api.js';
import { $, clamp, h, say, showError, sleep } from '/common/dom.js';

// ------------------------------------------------------------------ constants and state

const NEAR_PX = 25; // click-to-select radius in video pixels, as media.nearest_agent
const CONTROL_BAR_PX = 72; // clicks this close to the bottom edge are left to the native controls
const AGENT_KEYS = '123456789abcdefghijklmoqrstuvwxyz'; // no n (next task) or p (play)
const NONE = 'none'; // the direct "No interaction" choice of step 2
const NO_INTERACTION = 'other/no_interaction';
const UNDEFINED = 'other/undefined';
const STEPS = { pair: 'Interacting pair', type: 'Interaction type', subtype: 'Subtype' };
const VIEW_REGIONS = { label: ['video', 'protocol'], review: ['review'], admin: ['admin'] };

const S = {
  me: null, tax: null, subtypes: new Map(), titles: new Map(), view: null, busy: false,
  claim: null, positions: null, page: null, pair: [], pairTouched: false, choices: [], choicesFor: '',
  stepTimes: {}, pageSince: 0, submission: null, lastResult: null,
  queue: [], current: 0, agreement: null, exported: null,
};

const keymaps = {}; // region -> Map(key -> action)
const keyLabel = (key) => (/^[A-Z]$/.test(key) ? `Shift+${key}` : key);

/** A button of `region` whose shortcut `key` (if any) is shown on it and registered with it. */
function btn(region, text, key, action, attrs = {}) {
  if (key) keymaps[region].set(key, action);
  return h('button', { type: 'button', 'aria-keyshortcuts': key ? keyLabel(key) : null, ...attrs, onclick: action },
    key ? h('kbd', {}, keyLabel(key)) : null, text);
}

/** Rebuild `container` from `build()`, resetting the shortcuts of `region`. */
function render(region, container, build) {
  keymaps[region] = new Map();
  container.replaceChildren(...[build()].flat().filter(Boolean));
}

const badge = (text = 'machine suggestion') => h('span', { class: 'badge machine' }, text);
const agentName = (id) => `@${id}`;
const typeTitle = (kind) => (kind === NONE ? 'No interaction' : S.titles.get(kind) || kind);
const subtypeName = (id) => (S.subtypes.get(id) || { name: id }).name;
const kindOf = (subtype) => (subtype === NO_INTERACTION ? NONE : subtype.split('/')[0]);
const describe = (subtype) => `${typeTitle(subtype.split('/')[0])} – ${subtypeName(subtype)}`;

// ------------------------------------------------------------------ API

/** JSON request (the shared `request`, with the CSRF token once logged in); a 401 after login asks to log in
 * again. An HTTP error throws an Error with `status` and the server's `detail`; a network error has no `status`. */
async function api(method, path, body) {
  const headers = method !== 'GET' && S.me ? { 'X-CSRF-Token': S.me.csrf } : {};
  try {
    return await request(method, path, body, headers);
  } catch (err) {
    if (err.status === 401 && S.me && path !== '/api/login') showLogin('Your session ended; log in again.');
    throw err;
  }
}

/** Run `fn`, showing its error; the page ignores further actions until it is done. */
async function guarded(fn) {
  if (S.busy) return;
  S.busy = true;
  showError('');
  try { await fn(); } catch (err) { showError(err.message || String(err)); } finally { S.busy = false; }
}

/** 32 random hex digits: the id that makes a retried submission idempotent. */
const randomId = () => Array.from(crypto.getRandomValues(new Uint8Array(16)), (b) => b.toString(16).padStart(2, '0'))
  .join('');

// ------------------------------------------------------------------ login, views, progress

function showLogin(message = '') {
  Object.assign(S, { me: null, claim: null, positions: null, page: null, lastResult: null, queue: [], current: 0,
    agreement: null, exported: null });
  for (const id of ['label-view', 'review-view', 'admin-view', 'tabs', 'who']) $(id).hidden = true;
  $('progress').textContent = '';
  $('video').removeAttribute('src');
  $('login-view').hidden = false;
  say(message);
  $('login-name').focus();
}

async function login(event) {
  event.preventDefault();
  await guarded(async () => {
    S.me = await api('POST', '/api/login', { name: $('login-name').value, password: $('login-password').value });
    $('login-password').value = '';
    await enter();
  });
}

async function logout() {
  await guarded(async () => {
    await api('POST', '/api/logout');
    showLogin('Logged out.');
  });
}

/** After login: the taxonomy, the header, and the view of the user's role. */
async function enter() {
  if (!S.tax) {
    S.tax = await api('GET', '/api/taxonomy');
    for (const t of S.tax.types) S.titles.set(t.key, t.title);
    for (const s of S.tax.subtypes) S.subtypes.set(s.id, s);
  }
  $('login-view').hidden = true;
  $('who').hidden = false;
  $('who-name').textContent = `${S.me.name} (${S.me.role})`;
  say('');
  const role = S.me.role;
  await show(role === 'admin' ? 'admin' : role === 'reviewer' ? 'review' : 'label');
}

function views() {
  const role = S.me.role;
  return [['label', 'Label', 'L'], ['review', 'Review', 'R'], ['admin', 'Admin', 'A']].filter(
    ([v]) => v === 'label' || (v === 'review' && role !== 'annotator') || (v === 'admin' && role === 'admin'));
}

async function show(view) {
  S.view = view;
  const tabs = views();
  $('tabs').hidden = tabs.length < 2;
  render('tabs', $('tabs'), () => tabs.map(([v, title, key]) =>
    btn('tabs', title, key, () => guarded(() => show(v)), { 'aria-current': v === view ? 'page' : null })));
  for (const v of ['label', 'review', 'admin']) $(`${v}-view`).hidden = v !== view;
  if (view === 'label') renderLabel();
  if (view === 'review') await loadReview();
  if (view === 'admin') renderAdmin();
  refreshProgress();
}

/** Update the progress line in the background (not awaited, so it never holds the page busy). */
function refreshProgress() {
  api('GET', '/api/progress').then((p) => {
    if (!S.me) return; // logged out meanwhile
    const mine = (p.per_annotator || {})[S.me.name] || 0;
    $('progress').textContent =
      `you: ${mine} done, overall: ${p.slots_done}/${p.slots} slots, ${p.tasks_accepted} windows accepted`;
  }).catch((err) => showError(err.message));
}

// ------------------------------------------------------------------ keyboard

/** Run the action of shortcut `key` in the current view; true when it has one (swallowed while busy). */
function runKey(key) {
  const region = ['tabs', ...(VIEW_REGIONS[S.view] || [])].find((r) => keymaps[r] && keymaps[r].has(key));
  if (region && !S.busy) keymaps[region].get(key)();
  return Boolean(region);
}

document.addEventListener('keydown', (e) => {
  if (e.ctrlKey || e.metaKey || e.altKey || e.isComposing || !S.me) return;
  const t = e.target;
  if (t instanceof HTMLElement && (t.matches('input, textarea, select') || t.isContentEditable)) {
    if (e.key === 'Escape') { t.blur(); e.preventDefault(); }
    if (e.key === 'Enter' && t.matches('textarea') && !e.shiftKey) { e.preventDefault(); runKey('Enter'); }
    return; // typing: no other shortcut
  }
  if (/^[a-z]$/i.test(e.key) && /[A-Z]/.test(e.key) !== e.shiftKey) return; // Caps Lock: no shortcut
  if (runKey(e.key)) e.preventDefault();
});

// ------------------------------------------------------------------ annotator: task, video, click-to-select

async function nextTask() {
  await guarded(async () => {
    const r = await api('POST', '/api/tasks/next');
    S.lastResult = null;
    if (!r.task) {
      S.claim = null;
      S.page = { step: 'empty' };
    } else {
      const task = r.task;
      S.claim = { slot_id: r.slot_id, task, receivedAt: performance.now() }; // the lead time starts here
      Object.assign(S, { pair: task.pair_source === 'none' ? [] : [...task.pair], pairTouched: false, choicesFor: '',
        submission: null, positions: null, page: { step: 'pair' }, pageSince: performance.now() });
      S.stepTimes = { pair: 0, type: 0, subtype: 0 };
      $('video').src = `/api/tasks/${task.task_id}/video`;
      S.positions = await api('GET', `/api/tasks/${task.task_id}/positions`);
    }
    renderLabel();
    refreshProgress();
  });
}


/** The scenario step the video shows: round(currentTime * fps), clamped to the window. */
const currentStep = () => (S.positions
  ? clamp(Math.round($('video').currentTime * S.positions.fps), 0, S.positions.steps - 1) : 0);

function stepFrame(delta) {
  if (!S.positions) return;
  $('video').pause();
  $('video').currentTime = clamp(currentStep() + delta, 0, S.positions.steps - 1) / S.positions.fps;
}

function togglePlay() {
  const v = $('video');
  if (v.paused) v.play().catch((err) => showError(`cannot play the video: ${err.message}`));
  else v.pause();
}

function renderFrameInfo() {
  const info = $('frame-info');
  if (info && S.positions) info.textContent = `step ${currentStep()} / ${S.positions.steps - 1}`;
}

/** The agent nearest to (x, y) video pixels at `step`, within NEAR_PX (as media.nearest_agent). */
function nearestAgent(step, x, y) {
  let best = null;
  let bestD = Infinity;
  for (const agent of S.positions.agents) {
    const pos = agent.px[step];
    if (!pos) continue;
    const d = Math.hypot(pos[0] - x, pos[1] - y);
    if (d <= NEAR_PX && d < bestD) { best = agent.id; bestD = d; }
  }
  return best;
}

function videoClick(e) {
  const v = $('video');
  const r = v.getBoundingClientRect();
  if (!S.positions || !S.claim || e.clientY > r.bottom - CONTROL_BAR_PX) return;
  e.preventDefault(); // a click selects; it does not toggle playback
  const n = S.positions.size_px;
  const vw = v.videoWidth || n;
  const vh = v.videoHeight || n;
  const scale = Math.min(r.width / vw, r.height / vh); // the frame is letterboxed into the element
  const x = ((e.clientX - r.left - (r.width - vw * scale) / 2) / scale) * (n / vw);
  const y = ((e.clientY - r.top - (r.height - vh * scale) / 2) / scale) * (n / vh);
  const id = nearestAgent(currentStep(), x, y);
  if (id === null) say(`No agent within ${NEAR_PX} px of the click.`);
  else selectAgent(id, true);
}

const agentType = (id) => (S.claim.task.agents.find((a) => a.id === id) || { type: '?' }).type;

/** Toggle agent `id` in the pair (step 1); from the video a click only adds. */
function selectAgent(id, fromVideo = false) {
  if (!S.page || S.page.step !== 'pair') {
    say(`That is ${agentName(id)} (${agentType(id)}); go back to step 1 to change the pair.`);
    return;
  }
  const at = S.pair.indexOf(id);
  if (at >= 0 && fromVideo) { say(`${agentName(id)} is selected already.`); return; }
  if (at >= 0) S.pair.splice(at, 1);
  else if (S.pair.length >= 2) { say('Two agents are chosen already: deselect one first.'); return; }
  else S.pair.push(id);
  S.pairTouched = true;
  say(at >= 0 ? `${agentName(id)} deselected.` : `${agentName(id)} (${agentType(id)}) selected.`);
  renderProtocol();
}

// ------------------------------------------------------------------ annotator: the protocol

function resetChoices() {
  const [a, b] = S.pair;
  S.choicesFor = `${a},${b}`;
  S.choices = [[a, b], [b, a]].map(([track, other]) => {
    const s = S.claim.task.suggestions.find((x) => x.track_id === track && x.other_id === other);
    const c = { track, other, kind: null, subtype: null, text: '', sug: s ? s.subtype : null };
    c.typeSug = c.subtypeSug = Boolean(s);
    if (s) Object.assign(c, { kind: kindOf(s.subtype), subtype: s.subtype });
    return c;
  });
}

/** The pages of the protocol: the pair, each agent's type, then the subtype of each that needs one. */
function pages() {
  const out = [{ step: 'pair' }, { step: 'type', dir: 0 }, { step: 'type', dir: 1 }];
  for (const dir of [0, 1]) {
    if (S.choices[dir] && S.choices[dir].kind !== NONE) out.push({ step: 'subtype', dir });
  }
  return out;
}

const pageIndex = () => pages().findIndex((p) => p.step === S.page.step && p.dir === S.page.dir);

function goTo(page) {
  const now = performance.now();
  if (S.stepTimes[S.page.step] !== undefined) S.stepTimes[S.page.step] += now - S.pageSince;
  S.page = page;
  S.pageSince = now;
  say('');
  showError('');
  renderProtocol();
}

const back = () => pageIndex() > 0 && goTo(pages()[pageIndex() - 1]);

function forward() {
  const page = S.page;
  if (page.step === 'pair') {
    if (S.pair.length !== 2) { showError('Choose two agents first.'); return; }
    S.pairTouched = true;
    if (S.choicesFor !== S.pair.join(',')) resetChoices();
  } else {
    const c = S.choices[page.dir];
    if (page.step === 'type') {
      if (!c.kind) { showError('Choose an interaction type (or No interaction) first.'); return; }
      c.typeSug = false;
    } else {
      if (!c.subtype) { showError('Choose a subtype first.'); return; }
      if (c.subtype === UNDEFINED && !c.text.trim()) {
        showError('Describe the undefined behaviour (required).');
        $('free-text').focus();
        return;
      }
      c.subtypeSug = false;
    }
  }
  const all = pages();
  const i = pageIndex();
  if (i === all.length - 1) guarded(submit);
  else goTo(all[i + 1]);
}

function pickKind(c, kind) {
  c.typeSug = false;
  if (kind !== c.kind) {
    c.kind = kind;
    c.text = '';
    const suggested = c.sug && kindOf(c.sug) === kind;
    c.subtype = suggested ? c.sug : kind === NONE ? NO_INTERACTION : null;
    c.subtypeSug = Boolean(suggested);
  }
  renderProtocol();
}

function pickSubtype(c, id) {
  c.subtype = id;
  c.subtypeSug = false;
  if (id !== UNDEFINED) c.text = '';
  renderProtocol();
  if (id === UNDEFINED) $('free-text').focus();
}

const labelsBody = () => ({
  pair: [...S.pair],
  choices: S.choices.map((c) => ({ track_id: c.track, other_id: c.other, subtype: c.subtype,
    text: c.subtype === UNDEFINED ? c.text.trim() : '' })),
});

/** Submit the labels; a network error (or 5xx) retries with the same submission id, which the server
 * deduplicates; a 4xx shows the server's detail. */
async function submit() {
  const now = performance.now();
  S.stepTimes[S.page.step] += now - S.pageSince;
  S.pageSince = now;
  const labels = labelsBody();
  const key = JSON.stringify(labels);
  if (!S.submission || S.submission.key !== key) S.submission = { id: randomId(), key };
  const stepTimes = Object.fromEntries(Object.entries(S.stepTimes).map(([k, v]) => [k, Math.floor(v)]));
  const body = { ...labels, submission_id: S.submission.id, lead_time_ms: Math.floor(now - S.claim.receivedAt),
    step_times_ms: stepTimes };
  for (let attempt = 1; ; attempt++) {
    try {
      say(attempt === 1 ? 'Submitting…' : `Submitting again (attempt ${attempt})…`);
      const result = await api('POST', `/api/slots/${S.claim.slot_id}/submit`, body);
      S.lastResult = result;
      S.claim = null;
      S.page = { step: 'done' };
      $('video').pause();
      say('');
      break;
    } catch (err) {
      const retry = err.status === undefined || err.status >= 500;
      if (!retry || attempt >= 5) {
        say('');
        if ([403, 404, 409].includes(err.status)) { S.claim = null; S.page = { step: 'lost' }; }
        renderLabel();
        throw err; // shown by guarded(); Enter retries with the same submission id
      }
      await sleep(300 * 2 ** (attempt - 1));
    }
  }
  renderLabel();
  refreshProgress();
}

// ------------------------------------------------------------------ annotator: rendering

function renderLabel() {
  const task = S.claim && S.claim.task;
  $('media').hidden = !task;
  $('summary').hidden = !task;
  render('video', $('video-controls'), () => task && [
    btn('video', 'Play / pause', 'p', togglePlay),
    btn('video', 'Previous frame', ',', () => stepFrame(-1)),
    btn('video', 'Next frame', '.', () => stepFrame(1)),
    h('span', { id: 'frame-info', class: 'frame-info', 'aria-live': 'off' }),
  ]);
  renderFrameInfo();
  renderProtocol();
}

function stepper(current) {
  return h('ol', { class: 'steps', 'aria-label': 'Protocol steps' }, Object.entries(STEPS).map(([step, title]) =>
    h('li', { 'aria-current': step === current ? 'step' : null }, title)));
}

function renderProtocol() {
  const page = S.page || { step: 'start' };
  render('protocol', $('protocol'), () => {
    if (!S.claim) return idlePage(page.step);
    const task = S.claim.task;
    const head = h('p', { class: 'task-meta' }, 'Window ', h('code', {}, task.scenario_id), ` (task ${task.task_id})`);
    const body = { pair: pairPage, type: typePage, subtype: subtypePage }[page.step](page.dir);
    const last = pageIndex() === pages().length - 1;
    const confirm = page.step === 'pair' && !S.pairTouched && task.pair_source === 'detector';
    const nav = h('div', { class: 'nav' }, pageIndex() > 0 ? btn('protocol', 'Back', 'Backspace', back) : null,
      btn('protocol', last ? 'Submit' : confirm ? 'Confirm pair' : 'Continue', 'Enter', forward, { class: 'primary' }));
    return [head, stepper(page.step), body, nav];
  });
  renderSummary();
}

function idlePage(step) {
  const text = {
    start: 'Press Next task to get a window to label.',
    empty: 'Nothing left to label for you right now.',
    done: `Submitted as annotation ${S.lastResult && S.lastResult.annotation_id}. Take the next window when ready.`,
    lost: 'This task cannot be submitted any more (see the message above); take the next one.',
  }[step] || '';
  return [h('p', { class: 'idle' }, text),
    btn('protocol', step === 'empty' ? 'Check again' : 'Next task', 'n', nextTask, { class: 'primary' })];
}

function pairPage() {
  const task = S.claim.task;
  const intro = {
    objects_of_interest: 'Pre-selected from the scene\'s objects of interest; change it if it is wrong.',
    detector: 'The detector suggests this pair: confirm it or change it.',
    none: 'Choose the two interacting agents: press their keys, or click them in the video.',
  }[task.pair_source] || '';
  const suggested = task.pair_source === 'detector' && !S.pairTouched;
  return h('div', {},
    h('h2', {}, 'Step 1 of 3: which two agents interact?'),
    h('p', {}, intro, suggested ? ' ' : null, suggested ? badge() : null),
    h('ul', { class: 'options agents', 'aria-label': 'Agents of the window' }, task.agents.map((a, i) => {
      const at = S.pair.indexOf(a.id);
      const pick = btn('protocol', `${agentName(a.id)} ${a.type}`, AGENT_KEYS[i] || null, () => selectAgent(a.id),
        { 'aria-pressed': String(at >= 0), id: `agent-${a.id}` });
      return h('li', {}, pick, at >= 0 ? h('span', { class: 'order' }, at === 0 ? 'first' : 'second') : null);
    })));
}

const towards = (c) => `${agentName(c.track)} towards ${agentName(c.other)}`;

function option(region, key, text, pressed, suggested, action, detail) {
  return h('li', {}, btn(region, h('span', {}, text, detail ? h('small', {}, detail) : null), key, action,
    { 'aria-pressed': String(pressed) }), suggested ? badge() : null);
}

function typePage(dir) {
  const c = S.choices[dir];
  const kinds = S.tax.types.map((t) => t.key);
  return h('div', {},
    h('h2', {}, `Step 2 of 3: interaction type of ${towards(c)} (${dir + 1} of 2)`),
    !c.sug ? null : c.typeSug
      ? h('p', {}, badge(), ` ${describe(c.sug)}: Enter keeps it, a key changes it.`)
      : h('p', { class: 'muted' }, `The detector suggested ${describe(c.sug)}.`),
    h('ul', { class: 'options' },
      kinds.map((kind, i) => option('protocol', i < 9 ? String(i + 1) : null, typeTitle(kind), c.kind === kind,
        c.typeSug && c.kind === kind, () => pickKind(c, kind))),
      option('protocol', '0', 'No interaction', c.kind === NONE, c.typeSug && c.kind === NONE,
        () => pickKind(c, NONE))));
}

function subtypePage(dir) {
  const c = S.choices[dir];
  const subs = S.tax.subtypes.filter((s) => s.type === c.kind);
  const box = c.subtype === UNDEFINED && h('div', { class: 'free' },
    h('label', { for: 'free-text' }, 'Describe the behaviour (required)'),
    h('textarea', { id: 'free-text', rows: 3, maxlength: 2000, required: true,
      oninput: (e) => { c.text = e.target.value; renderSummary(); } }));
  if (box) box.querySelector('textarea').value = c.text;
  return h('div', {},
    h('h2', {}, `Step 3 of 3: subtype of ${towards(c)} (${typeTitle(c.kind)})`),
    h('ul', { class: 'options' }, subs.map((s, i) => option('protocol', i < 9 ? String(i + 1) : null, s.name,
      c.subtype === s.id, c.subtypeSug && c.subtype === s.id, () => pickSubtype(c, s.id), s.definition))),
    box || null);
}

function renderSummary() {
  const el = $('summary');
  if (!S.claim) { el.replaceChildren(); return; }
  const rows = [h('dt', {}, 'Pair'), h('dd', {}, S.pair.length ? S.pair.map(agentName).join(' and ') : '–')];
  if (S.choicesFor && S.choicesFor === S.pair.join(',')) {
    for (const c of S.choices) {
      const what = !c.kind ? '–' : c.kind === NONE || !c.subtype ? typeTitle(c.kind)
        : `${typeTitle(c.kind)} – ${subtypeName(c.subtype)}`;
      rows.push(h('dt', {}, towards(c)), h('dd', {}, what, c.typeSug || c.subtypeSug ? ' ' : null,
        c.typeSug || c.subtypeSug ? badge() : null, c.subtype === UNDEFINED && c.text ? h('q', {}, c.text) : null));
    }
  }
  el.replaceChildren(h('h2', {}, 'Your labels'), h('dl', {}, rows));
}

// ------------------------------------------------------------------ reviewer

async function loadReview() {
  [S.queue, S.agreement] = await Promise.all([api('GET', '/api/review/queue'), api('GET', '/api/review/agreement')]);
  S.current = clamp(S.current, 0, Math.max(S.queue.length - 1, 0));
  renderReview();
}

async function accept(taskId, annotationId) {
  await api('POST', `/api/review/${taskId}/accept`, { annotation_id: annotationId });
  say(`Accepted annotation ${annotationId} for task ${taskId}.`);
  await loadReview();
  refreshProgress();
}

function choiceText(choice) {
  return h('li', {}, h('strong', {}, `${agentName(choice.track_id)} → ${agentName(choice.other_id)}: `),
    describe(choice.subtype), choice.text ? h('p', { class: 'free-text' }, choice.text) : null);
}

function renderReview() {
  const move = (d) => { S.current = clamp(S.current + d, 0, S.queue.length - 1); renderReview(); };
  render('review', $('queue'), () => {
    const tools = h('div', { class: 'nav' }, btn('review', 'Reload', 'r', () => guarded(loadReview)),
      S.queue.length > 1 ? btn('review', 'Next window', 'j', () => move(1)) : null,
      S.queue.length > 1 ? btn('review', 'Previous window', 'k', () => move(-1)) : null);
    if (!S.queue.length) return [h('p', { class: 'idle' }, 'No disagreements waiting for review.'), tools];
    return [tools, ...S.queue.map((item, i) => {
      const current = i === S.current;
      return h('section', { class: current ? 'window current' : 'window', 'aria-current': current ? 'true' : null },
        h('h3', {}, 'Window ', h('code', {}, item.scenario_id), ` (task ${item.task_id})`),
        h('div', { class: 'side-by-side' }, item.annotations.map((a, j) => h('article', { class: 'annotation' },
          h('h4', {}, a.annotator),
          h('p', {}, `Pair ${a.pair.map(agentName).join(' and ')}`),
          h('ul', {}, a.choices.map(choiceText)),
          btn('review', `Accept ${a.annotator}'s labels`, current && j < 9 ? String(j + 1) : null,
            () => guarded(() => accept(item.task_id, a.annotation_id)))))));
    })];
  });
  renderAgreement();
}

const percent = (x) => (x === null || x === undefined ? '–' : `${Math.round(x * 100)} %`);

function table(caption, head, rows) {
  return h('table', {}, h('caption', {}, caption),
    h('thead', {}, h('tr', {}, head.map((t) => h('th', { scope: 'col' }, t)))),
    h('tbody', {}, rows.map((r) => h('tr', {}, r.map((cell) => h('td', {}, cell))))));
}

function renderAgreement() {
  const a = S.agreement || { windows: [], annotators: {} };
  $('agreement').replaceChildren(
    table('Per window', ['Window', 'Task', 'Annotations', 'Agreement', 'Status'], a.windows.map((w) =>
      [w.scenario_id, String(w.task_id), String(w.annotations), percent(w.agreement), w.status])),
    table('Per annotator', ['Annotator', 'Pairwise agreement', 'Agreement with accepted', 'Comparisons'],
      Object.entries(a.annotators).map(([name, x]) =>
        [name, percent(x.pairwise), percent(x.with_accepted), String(x.compared)])));
}

// ------------------------------------------------------------------ admin

async function exportLabels() {
  say('Exporting…');
  S.exported = await api('POST', '/api/export', { into_dataset: true });
  say('Export finished.');
  renderAdmin();
  refreshProgress();
}

function renderAdmin() {
  render('admin', $('admin'), () => {
    const out = [h('p', {}, 'Write the accepted labels as InterDrive JSON with an audit file, and import them into '
      + 'the dataset as human labels.'), btn('admin', 'Export', 'e', () => guarded(exportLabels), { class: 'primary' })];
    const r = S.exported;
    if (r) {
      out.push(h('dl', { class: 'result', id: 'export-result' },
        [['Folder', r.folder], ['Files written', r.written], ['Windows pending', r.pending],
          ['Windows imported', r.imported]].flatMap(([k, v]) => [h('dt', {}, k), h('dd', {}, String(v))])));
    }
    return out;
  });
}

// ------------------------------------------------------------------ start

function init() {
  $('login-form').addEventListener('submit', login);
  $('logout').addEventListener('click', logout);
  const v = $('video');
  v.addEventListener('click', videoClick);
  for (const event of ['timeupdate', 'seeked', 'loadedmetadata']) v.addEventListener(event, renderFrameInfo);
  // Chrome's native controls swallow key presses while one of their buttons has focus: give it back to the page
  for (const event of ['play', 'pause', 'seeked']) v.addEventListener(event, () => v.blur());
  api('GET', '/api/me')
    .then((me) => { S.me = me; return enter(); })
    .catch((err) => (err.status === 401 ? showLogin() : showError(err.message)));
}

init();
