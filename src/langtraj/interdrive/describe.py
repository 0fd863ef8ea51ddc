"""Human-readable lines for a window's labels and prompts (for annotated renders and the terminal).

See docs/interdrive.md.
"""

from __future__ import annotations

from collections.abc import Sequence

from langtraj.interdrive.dataset import WindowRecord
from langtraj.interdrive.labels import AgentLabel
from langtraj.interdrive.taxonomy import LABELS_BY_KEY
from langtraj.scenario.model import STEP_SECONDS


def _label_text(label: AgentLabel, current: int) -> str:
    name = LABELS_BY_KEY[label.key].name
    if label.key == "changing_lanes":
        name += f" {label.params['from']} -> {label.params['to']}"
    elif label.key == "lane_position":
        name += f": {label.params['position']}"
    t0, t1 = (label.start - current) * STEP_SECONDS, (label.end - current) * STEP_SECONDS
    return f"{name} ({t0:.1f}-{t1:.1f} s)"


def focus_agents(record: WindowRecord, limit: int = 4) -> tuple[int, ...]:
    """The agents worth showing: those of the best-sourced interactions first, then labelled ones."""
    ids: list[int] = []
    for inter in sorted(record.labels.interactions, key=lambda i: (i.source.value != "human", i.start)):
        for tid in (inter.track_id, inter.other_id):
            if tid >= 0 and tid not in ids:
                ids.append(tid)
    return tuple(ids[:limit])


def describe(record: WindowRecord, agents: Sequence[int] | None = None, prompts: int = 4) -> list[str]:
    """Lines listing the interactions, the labels of `agents` (default: `focus_agents`) and some prompts."""
    agents = tuple(agents) if agents is not None else focus_agents(record)
    lines = [f"window {record.scenario_id}  (future: {(record.num_steps - record.current_index - 1) / 10:.1f} s)", ""]
    lines.append("Interactions (agent -> other: type / subtype, source):")
    for inter in record.labels.interactions:
        if inter.track_id in agents or inter.other_id in agents:
            other = f"@{inter.other_id}" if inter.other_id >= 0 else "-"
            lines.append(
                f"  @{inter.track_id} -> {other}: {inter.type.title} / {inter.subtype.name} ({inter.source.value})"
            )
    lines.append("")
    for tid in agents:
        labels = [_label_text(lab, record.current_index) for lab in record.labels.labels_of(tid)]
        lines.append(f"@{tid}: " + ("; ".join(labels) if labels else "no single-agent label"))
        undecided = sorted({u.key for u in record.labels.undecided if u.track_id == tid})
        if undecided:
            lines.append(f"  undecided: {', '.join(undecided)}")
    lines += ["", "Prompts (and one role-rephrased sentence):"]
    shown = [p for p in record.prompts if set(p.mentions) & set(agents)][:prompts]
    for prompt in shown:
        lines.append(f"  {prompt.text}")
        target = prompt.mentions[0]
        lines.append(f"    as @{target}: {prompt.roles[target]}")
    return lines
