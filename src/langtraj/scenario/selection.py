"""Choosing which agents a consumer works on: nearest to a point, tracks to predict, interest first.

See docs/data.md.
"""

from __future__ import annotations

import numpy as np

from langtraj.scenario.model import Scenario
from langtraj.scenario.types import AgentType


def _step(scenario: Scenario, step: int | None) -> int:
    return scenario.current_index if step is None else step


def closest_agents(
    scenario: Scenario,
    point: tuple[float, float] | np.ndarray,
    *,
    k: int | None = None,
    step: int | None = None,
    types: tuple[AgentType, ...] | None = None,
) -> np.ndarray:
    """Indices of agents valid at `step` (default: current), nearest to `point` first, at most `k`."""
    t = _step(scenario, step)
    agents = scenario.agents
    mask = agents.valid[:, t].copy()
    if types is not None:
        mask &= np.isin(agents.types, [int(x) for x in types])
    candidates = np.flatnonzero(mask)
    dist = np.linalg.norm(agents.xy[candidates, t] - np.asarray(point, np.float64)[:2], axis=-1)
    order = candidates[np.argsort(dist, kind="stable")]
    return order if k is None else order[:k]


def tracks_to_predict(scenario: Scenario) -> np.ndarray:
    """Indices of the tracks the source asks to predict (WOMD `tracks_to_predict`)."""
    return scenario.agents.tracks_to_predict.copy()


def prioritized_agents(
    scenario: Scenario,
    max_agents: int | None = None,
    *,
    center: tuple[float, float] | None = None,
    step: int | None = None,
) -> np.ndarray:
    """Indices of the agents to simulate, most important first, at most `max_agents`.

    Order: objects of interest, the SDC, tracks to predict, then every other agent valid at `step`
    (default: current) by distance to `center` (default: the SDC's position at that step, else the
    mean position of the valid agents). Agents not valid at `step` are left out.
    """
    t = _step(scenario, step)
    agents = scenario.agents
    valid_now = agents.valid[:, t]
    first = [*agents.objects_of_interest.tolist()]
    if scenario.sdc_index >= 0:
        first.append(scenario.sdc_index)
    first += agents.tracks_to_predict.tolist()
    ordered: list[int] = []
    for i in first:
        if valid_now[i] and i not in ordered:
            ordered.append(i)
    if center is None:
        if scenario.sdc_index >= 0 and valid_now[scenario.sdc_index]:
            center = tuple(agents.xy[scenario.sdc_index, t])
        elif valid_now.any():
            center = tuple(agents.xy[valid_now, t].mean(axis=0))
        else:
            center = (0.0, 0.0)
    chosen = set(ordered)
    ordered += [int(i) for i in closest_agents(scenario, center, step=t) if int(i) not in chosen]
    result = np.asarray(ordered, np.int64)
    return result if max_agents is None else result[:max_agents]


def deciders(scenario: Scenario) -> frozenset[int]:
    """Track ids of the agents that carry out a decision after the scene's current step (`decision` events of
    synthesized scenes, docs/data.md 'Intents')."""
    return frozenset(
        e.track_id
        for e in scenario.events
        if e.kind == "decision"
        and e.attributes.get("executed")
        and int(e.attributes.get("decision_step", -1)) >= scenario.current_index
    )
