"""Per-step class sequences of the heuristic labeler: `INVALID` steps and `absorb_short_runs`
(docs/interdrive.md, 'Single-agent labels')."""

from __future__ import annotations

import numpy as np

from langtraj.runs import value_runs

INVALID = -99
"""Class of a step outside the agent's valid span in a per-step class sequence."""


def absorb_short_runs(classes: np.ndarray, min_len: int) -> np.ndarray:
    """Runs shorter than `min_len` (not INVALID) take the class of the run before them (or after, at the start)."""
    out = classes.copy()
    spans = value_runs(out)
    for i, (value, start, end) in enumerate(spans):
        if value == INVALID or end - start >= min_len:
            continue
        before = out[start - 1] if start > 0 else INVALID
        after = spans[i + 1][0] if i + 1 < len(spans) else INVALID
        fill = before if before != INVALID else after
        if fill != INVALID:
            out[start:end] = fill
    return out
