/* Keep: save the open job as a test case of a suite, with its criteria; the server answers with the command that
 * replays it. See docs/studio.md, 'The page'.
 */
import { request as api } from '/common/api.js';
import { $, say, showIn } from '/common/dom.js';
import { S } from './state.js';

export async function saveCase(e) {
  e.preventDefault();
  if (!S.openJob) return;
  $('case-result').hidden = true;
  showIn('case-error', '');
  const criteria = {};
  if ($('case-ttc').value !== '') criteria.min_ttc = Number($('case-ttc').value);
  if ($('case-nocollision').checked) criteria.no_collision = true;
  const submit = $('case-form').querySelector('button[type="submit"]');
  submit.disabled = true;
  try {
    const r = await api('POST', `/api/jobs/${encodeURIComponent(S.openJob.id)}/case`,
      { suite: $('case-suite').value.trim(), name: $('case-name').value.trim(), criteria });
    $('case-result').textContent = `Saved case “${r.case}” in ${r.suite}; it replays these rollouts with: ${r.command}`;
    $('case-result').hidden = false;
    say(`Test case ${r.case} saved.`);
  } catch (err) {
    showIn('case-error', err.message);
  } finally {
    submit.disabled = false;
  }
}
