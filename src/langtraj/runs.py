"""Runs in per-step series: the stretches where a mask holds or a value stays the same (events, labels)."""

from __future__ import annotations

import numpy as np


def value_runs(values: np.ndarray) -> list[tuple[int, int, int]]:
    """Maximal runs (value, start, end) of equal values in a 1-D integer array; end is exclusive."""
    if len(values) == 0:
        return []
    cuts = np.flatnonzero(values[1:] != values[:-1]) + 1
    starts = np.concatenate([[0], cuts])
    ends = np.concatenate([cuts, [len(values)]])
    return [(int(values[s]), int(s), int(e)) for s, e in zip(starts, ends, strict=True)]


def true_runs(mask: np.ndarray, min_len: int = 1, max_gap: int = 0) -> list[tuple[int, int]]:
    """[start, end) runs where `mask` is True, joining runs separated by at most `max_gap` False steps, then
    keeping those at least `min_len` long."""
    idx = np.flatnonzero(mask)
    if idx.size == 0:
        return []
    breaks = np.flatnonzero(np.diff(idx) > max_gap + 1)
    starts = np.concatenate([[idx[0]], idx[breaks + 1]])
    ends = np.concatenate([idx[breaks], [idx[-1]]]) + 1
    return [(int(s), int(e)) for s, e in zip(starts, ends, strict=True) if e - s >= min_len]
