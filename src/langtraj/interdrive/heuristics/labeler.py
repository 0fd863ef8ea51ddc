"""`label_agents`, the heuristic labeler's entry point: every rule of `LABEL_RULES` over one scene
(docs/interdrive.md, 'Single-agent labels')."""

from __future__ import annotations

from langtraj.interdrive.heuristics.config import HeuristicConfig
from langtraj.interdrive.heuristics.context import LabelContext
from langtraj.interdrive.heuristics.kinematics import Kinematics
from langtraj.interdrive.heuristics.rules import LABEL_RULES
from langtraj.interdrive.labels import AgentLabel, Undecided
from langtraj.roads import MapIndex
from langtraj.scenario.model import Scenario


def label_agents(
    scenario: Scenario, config: HeuristicConfig | None = None, map_index: MapIndex | None = None
) -> tuple[tuple[AgentLabel, ...], tuple[Undecided, ...]]:
    """Heuristic single-agent labels of `scenario`'s future window, and the labels the map could not decide;
    each sorted by agent order, start step and key. `map_index` may be passed to reuse one across windows."""
    config = config or HeuristicConfig()
    if map_index is None:
        map_index = MapIndex.build(scenario.road_map, infer_neighbors=config.infer_neighbors)
    ctx = LabelContext(scenario, config, map_index, Kinematics.compute(scenario, config))
    labels: list[AgentLabel] = []
    undecided: dict[tuple[int, str], Undecided] = {}
    for name in LABEL_RULES.names():
        for item in LABEL_RULES.create(name).apply(ctx):
            if isinstance(item, Undecided):
                undecided.setdefault((item.track_id, item.key), item)
            else:
                labels.append(item)
    order = {int(t): i for i, t in enumerate(scenario.agents.ids)}
    labels.sort(key=lambda lab: (order[lab.track_id], lab.start, lab.key, lab.end))
    kept = sorted(undecided.values(), key=lambda u: (order[u.track_id], u.key))
    return tuple(labels), tuple(kept)
