"""The per-step series a job's result page plots for its prompted agents: speed and distance to the prompt's target
over the history and each rollout (docs/studio.md, 'GET /api/jobs/{id}', `series`)."""

from __future__ import annotations

import math
from collections.abc import Callable, Iterable, Sequence
from typing import Any

import numpy as np

from langtraj.metrics.instruction_following import rollout_scenario
from langtraj.polylines import project_on_polyline
from langtraj.rollouts.container import Rollouts
from langtraj.scenario.model import Scenario

Distance = Callable[[np.ndarray], np.ndarray]
"""Distances [T] of positions [T, 2] to a target's point (m)."""


def prompted_series(
    scenario: Scenario, rollouts: Rollouts, targets: Sequence[dict[str, Any]], agent_ids: Iterable[int]
) -> dict[str, dict[str, Any]]:
    """Per agent of `agent_ids` that the rollouts move (track id as text): per rollout, over steps 0 to the
    current one of the log then the rollout's simulated steps, its `speed` (m/s, `Agents.speed` of
    `rollout_scenario`: what the adherence checker judges) and `to_target` (m, to its first target's goal or
    conflict point: along the target's path where it has one, negative once past the point; straight-line
    otherwise), each to the centimetre and null where the agent is not valid; `to_target` and `goal` (what the
    distance is to) are null for an agent without a target or a target without a point."""
    present = {int(i) for i in rollouts.object_id}
    ids = list(dict.fromkeys(int(i) for i in agent_ids if int(i) in present))
    if not ids:
        return {}
    steps = min(rollouts.num_steps, scenario.num_steps - scenario.current_index - 1)
    end = scenario.current_index + 1 + steps
    rows = [scenario.agents.index_of(i) for i in ids]
    aims = {i: _aim(next((t for t in targets if _track(t) == i), None)) for i in ids}
    out: dict[str, dict[str, Any]] = {
        str(i): {"speed": [], "to_target": [] if aims[i][0] is not None else None, "goal": aims[i][1]} for i in ids
    }
    for r in range(rollouts.num_rollouts):
        agents = rollout_scenario(scenario, rollouts, r).agents
        speed, xy, valid = agents.speed[rows, :end], agents.xy[rows, :end], agents.valid[rows, :end]
        for k, i in enumerate(ids):
            entry = out[str(i)]
            entry["speed"].append(_rounded(speed[k], valid[k]))
            distance = aims[i][0]
            if distance is not None:
                entry["to_target"].append(_rounded(distance(xy[k]), valid[k]))
    return out


def _track(target: dict[str, Any]) -> int | None:
    track = target.get("track_id")
    return None if track is None else int(track)


def _aim(target: dict[str, Any] | None) -> tuple[Distance | None, str | None]:
    """How far positions [T, 2] are from a target's point (a function, None without one), and what the point is."""
    if target is None:
        return None, None
    if target.get("goal") is not None:
        point = np.asarray(target["goal"], np.float64)[:2]
        label = "the stop point" if target.get("stop") else "the goal"
    elif target.get("conflict") is not None:
        point = np.asarray(target["conflict"], np.float64)[:2]
        label = "the stop point" if target.get("stop") else "the conflict point"
    else:
        return None, None
    path = np.asarray(target.get("path") or [], np.float64)
    path = path[:, :2] if path.ndim == 2 else np.zeros((0, 2))
    if len(path) >= 2:
        goal_station = float(project_on_polyline(point, path).station)

        def along(xy: np.ndarray) -> np.ndarray:
            return np.asarray(goal_station - project_on_polyline(np.asarray(xy, np.float64), path).station)

        return along, label

    def straight(xy: np.ndarray) -> np.ndarray:
        return np.asarray(np.linalg.norm(np.asarray(xy, np.float64) - point, axis=-1))

    return straight, label


def _rounded(values: np.ndarray, valid: np.ndarray) -> list[float | None]:
    """Each value to 2 decimals, None where not valid or not finite (JSON has no NaN)."""
    return [
        round(float(v), 2) if ok and math.isfinite(float(v)) else None
        for v, ok in zip(values.tolist(), valid.tolist(), strict=True)
    ]
