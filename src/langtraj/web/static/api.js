/* The one JSON request of every LangTraj page. Each server answers an error with one line: the studio as
 * {"error": ...}, the labeling tool (FastAPI) as {"detail": ...}. See docs/studio.md, 'The page's code'.
 */

/** The one line an error answer `data` carries, or '' (FastAPI's validation list joined as "where: what"). */
export function errorLine(data) {
  if (!data) return '';
  if (typeof data.error === 'string') return data.error;
  const { detail } = data;
  if (Array.isArray(detail)) return detail.map((d) => `${(d.loc || []).slice(1).join('.')}: ${d.msg}`).join('; ');
  return typeof detail === 'string' ? detail : detail ? JSON.stringify(detail) : '';
}

/** `method path` with `body` as JSON; resolves to the answer's JSON. An HTTP error throws an Error with `status`
 * and the server's line as message; an unreachable server throws one without `status`. */
export async function request(method, path, body, headers = {}) {
  const init = { method, headers: { ...headers } };
  if (body !== undefined) { init.headers['Content-Type'] = 'application/json'; init.body = JSON.stringify(body); }
  let res;
  try { res = await fetch(path, init); } catch (err) { throw new Error(`cannot reach the server (${err.message})`); }
  const data = await res.json().catch(() => null);
  if (res.ok) return data;
  throw Object.assign(new Error(errorLine(data) || `${res.status} ${res.statusText}`), { status: res.status });
}
