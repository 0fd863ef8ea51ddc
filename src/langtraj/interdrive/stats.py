"""Label statistics of an InterDrive dataset: counts per interaction type and subtype (by source) and per
single-agent label, printed as a table and plotted like the paper's Fig. 2. See docs/interdrive.md."""

from __future__ import annotations

from collections import Counter
from dataclasses import dataclass
from pathlib import Path

from langtraj.fileio import atomic_path
from langtraj.interdrive.dataset import iter_records
from langtraj.interdrive.taxonomy import SINGLE_AGENT_LABELS, SUBTYPES, InteractionType


@dataclass(frozen=True)
class DatasetStats:
    windows: int
    prompts: int
    interactions: Counter[tuple[str, str]]  # (source, subtype id) -> count
    agent_labels: Counter[str]  # label key -> count
    undecided: Counter[str]  # label key -> count

    def by_subtype(self, source: str | None = None) -> Counter[str]:
        counts: Counter[str] = Counter()
        for (src, sub), n in self.interactions.items():
            if source in (None, src):
                counts[sub] += n
        return counts

    def sources(self) -> list[str]:
        return sorted({src for src, _ in self.interactions})


def dataset_stats(dataset: Path) -> DatasetStats:
    windows = prompts = 0
    interactions: Counter[tuple[str, str]] = Counter()
    labels: Counter[str] = Counter()
    undecided: Counter[str] = Counter()
    for _, records in iter_records(dataset):
        for rec in records:
            windows += 1
            prompts += len(rec.prompts)
            interactions.update((i.source.value, i.subtype.id) for i in rec.labels.interactions)
            labels.update(lab.key for lab in rec.labels.agent_labels)
            undecided.update(u.key for u in rec.labels.undecided)
    return DatasetStats(windows, prompts, interactions, labels, undecided)


def format_stats(stats: DatasetStats) -> str:
    """A plain-text table: interaction counts per type and subtype and source, then single-agent labels."""
    sources = stats.sources()
    lines = [f"{stats.windows} windows, {stats.prompts} prompts", ""]
    lines.append(f"{'interaction type / subtype':58s}" + "".join(f"{s:>14s}" for s in sources))
    for kind in InteractionType:
        subs = [s for s in SUBTYPES if s.type is kind]
        totals = [sum(stats.interactions[(src, s.id)] for s in subs) for src in sources]
        lines.append(f"{kind.title:58s}" + "".join(f"{n:14d}" for n in totals))
        for sub in subs:
            counts = [stats.interactions[(src, sub.id)] for src in sources]
            if any(counts):
                lines.append(f"  {sub.name[:56]:56s}" + "".join(f"{n:14d}" for n in counts))
    lines += ["", f"{'single-agent label':30s}{'count':>10s}{'undecided':>12s}"]
    for label in SINGLE_AGENT_LABELS:
        lines.append(f"{label.name:30s}{stats.agent_labels[label.key]:10d}{stats.undecided[label.key]:12d}")
    return "\n".join(lines)


def plot_stats(stats: DatasetStats, path: Path, source: str | None = None) -> None:
    """Bar charts of interaction types and of subtypes grouped by type (paper Fig. 2), written atomically."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    counts = stats.by_subtype(source)
    kinds = [k for k in InteractionType if k is not InteractionType.OTHER]
    subs = [s for s in SUBTYPES if s.type in kinds]
    colours = {k: plt.cm.tab10(i) for i, k in enumerate(kinds)}
    fig, (top, bottom) = plt.subplots(2, 1, figsize=(12, 9), gridspec_kw={"height_ratios": [1, 2]})
    totals = [sum(counts[s.id] for s in subs if s.type is k) for k in kinds]
    top.bar([k.title.replace("/", "/\n") for k in kinds], totals, color=[colours[k] for k in kinds])
    top.set_ylabel("interactions")
    top.set_title(f"InterDrive interaction types ({source or 'all sources'}, {stats.windows} windows)")
    bottom.barh(
        [s.name for s in subs][::-1], [counts[s.id] for s in subs][::-1], color=[colours[s.type] for s in subs][::-1]
    )
    bottom.set_xlabel("interactions")
    bottom.tick_params(axis="y", labelsize=7)
    fig.tight_layout()
    with atomic_path(path) as tmp:
        fig.savefig(tmp, format="png", dpi=110)
    plt.close(fig)
