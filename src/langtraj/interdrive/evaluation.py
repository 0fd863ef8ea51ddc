"""Agreement of predicted interaction labels with reference labels: per-type counts, precision, recall, F1.

A prediction matches a reference label of the same interaction TYPE with the same ordered (track_id, other_id)
pair whose steps overlap by at least `min_overlap_steps`; matching is one-to-one (largest overlap first), so
duplicates count as false positives. Subtypes are not compared.

See docs/interdrive.md.
"""

from __future__ import annotations

from collections import defaultdict
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass

from langtraj.interdrive.labels import InteractionLabel


@dataclass(frozen=True)
class TypeCounts:
    """Matched (tp), unmatched predicted (fp) and unmatched reference (fn) labels of one type."""

    tp: int = 0
    fp: int = 0
    fn: int = 0

    def __add__(self, other: TypeCounts) -> TypeCounts:
        return TypeCounts(self.tp + other.tp, self.fp + other.fp, self.fn + other.fn)

    @property
    def precision(self) -> float:
        return self.tp / (self.tp + self.fp) if self.tp + self.fp else 0.0

    @property
    def recall(self) -> float:
        return self.tp / (self.tp + self.fn) if self.tp + self.fn else 0.0

    @property
    def f1(self) -> float:
        p, r = self.precision, self.recall
        return 2 * p * r / (p + r) if p + r else 0.0


def _overlap(a: InteractionLabel, b: InteractionLabel) -> int:
    return min(a.end, b.end) - max(a.start, b.start)


def _matches(
    predicted: Sequence[InteractionLabel], truth: Sequence[InteractionLabel], min_overlap_steps: int
) -> list[tuple[int, int]]:
    """One-to-one (prediction, truth) index pairs of one type, largest overlap first."""
    candidates = sorted(
        (
            (-_overlap(p, t), i, j)
            for i, p in enumerate(predicted)
            for j, t in enumerate(truth)
            if (p.track_id, p.other_id) == (t.track_id, t.other_id) and _overlap(p, t) >= min_overlap_steps
        )
    )
    used_p: set[int] = set()
    used_t: set[int] = set()
    pairs = []
    for _, i, j in candidates:
        if i not in used_p and j not in used_t:
            used_p.add(i)
            used_t.add(j)
            pairs.append((i, j))
    return pairs


def match_interactions(
    predicted: Iterable[InteractionLabel], truth: Iterable[InteractionLabel], min_overlap_steps: int = 1
) -> dict[str, TypeCounts]:
    """Per interaction type (key), the counts of `predicted` against `truth` for one window."""
    by_type_p: dict[str, list[InteractionLabel]] = defaultdict(list)
    by_type_t: dict[str, list[InteractionLabel]] = defaultdict(list)
    for lab in predicted:
        by_type_p[lab.type.value].append(lab)
    for lab in truth:
        by_type_t[lab.type.value].append(lab)
    counts = {}
    for kind in sorted(set(by_type_p) | set(by_type_t)):
        tp = len(_matches(by_type_p[kind], by_type_t[kind], min_overlap_steps))
        counts[kind] = TypeCounts(tp, len(by_type_p[kind]) - tp, len(by_type_t[kind]) - tp)
    return counts


def add_counts(total: Mapping[str, TypeCounts], more: Mapping[str, TypeCounts]) -> dict[str, TypeCounts]:
    """Per-type sums of two count tables (to pool windows)."""
    return {k: total.get(k, TypeCounts()) + more.get(k, TypeCounts()) for k in sorted(set(total) | set(more))}


def macro_f1(counts: Mapping[str, TypeCounts]) -> float:
    """Mean F1 over the types present in the reference (tp + fn > 0); 0 when none is."""
    present = [c.f1 for c in counts.values() if c.tp + c.fn > 0]
    return sum(present) / len(present) if present else 0.0


def format_table(counts: Mapping[str, TypeCounts]) -> str:
    """A plain-text per-type table with the macro-F1 as last line."""
    rows = [f"{'type':<12} {'tp':>5} {'fp':>5} {'fn':>5} {'prec':>6} {'rec':>6} {'f1':>6}"]
    for kind, c in sorted(counts.items()):
        rows.append(f"{kind:<12} {c.tp:>5} {c.fp:>5} {c.fn:>5} {c.precision:>6.3f} {c.recall:>6.3f} {c.f1:>6.3f}")
    rows.append(f"macro-F1 over types present: {macro_f1(counts):.3f}")
    return "\n".join(rows)
