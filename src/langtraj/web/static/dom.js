/* The DOM helpers of every LangTraj page (the studio, the labeling tool): elements built from text only, never
 * from markup (the pages run under a strict CSP and insert what users and the server send as text), and the
 * page's status line and error box. See docs/studio.md, 'The page's code'.
 */

export const $ = (id) => document.getElementById(id);

/** `<tag attrs...>kids</tag>`: `class` sets the class name, `on...` adds a listener, a true value an empty
 * attribute; null, undefined and false attributes and kids are left out; kids that are not nodes become text. */
export function h(tag, attrs = {}, ...kids) {
  const el = document.createElement(tag);
  for (const [k, v] of Object.entries(attrs)) {
    if (v === null || v === undefined || v === false) continue;
    if (k === 'class') el.className = v;
    else if (k.startsWith('on')) el.addEventListener(k.slice(2), v);
    else el.setAttribute(k, v === true ? '' : String(v));
  }
  for (const kid of kids.flat()) {
    if (kid !== null && kid !== undefined && kid !== false) el.append(kid instanceof Node ? kid : String(kid));
  }
  return el;
}

/** Show `text` in element `id` (hidden while there is none). */
export function showIn(id, text) {
  $(id).textContent = text || '';
  $(id).hidden = !text;
}

/** The page's status line (`#status`) and error box (`#error`). */
export const say = (text) => { $('status').textContent = text; };
export const showError = (text) => showIn('error', text);

export const clamp = (x, lo, hi) => Math.min(Math.max(x, lo), hi);
export const sleep = (ms) => new Promise((resolve) => setTimeout(resolve, ms));

/** `fn` called `ms` after the last of a burst of calls. */
export const debounce = (fn, ms) => {
  let t = null;
  return (...a) => { clearTimeout(t); t = setTimeout(() => fn(...a), ms); };
};
