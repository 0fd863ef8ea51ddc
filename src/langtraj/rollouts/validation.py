"""Checks that rollouts fit their scenario under the WOSAC rules, with errors that say what is wrong.

See docs/metrics.md.
"""

from __future__ import annotations

import numpy as np

from langtraj.errors import InputError
from langtraj.rollouts.agents import sim_agent_indices
from langtraj.rollouts.container import Rollouts
from langtraj.scenario.model import FUTURE_STEPS, Scenario


def _ids(values: np.ndarray, limit: int = 8) -> str:
    shown = ", ".join(str(int(v)) for v in values[:limit])
    return shown + (f", ... ({len(values)} in all)" if len(values) > limit else "")


def check_rollouts(scenario: Scenario, rollouts: Rollouts, *, num_rollouts: int | None = None) -> np.ndarray:
    """Validate `rollouts` against `scenario` and return the scenario track index of each rollout agent.

    Rules (those of the challenge): the scenario id matches when the rollouts carry one; the object ids
    are exactly the sim agents (every track valid at the current step), in any order; there are
    `FUTURE_STEPS` steps and, when `num_rollouts` is given, that many rollouts; every value is finite.
    """
    if rollouts.scenario_id and rollouts.scenario_id != scenario.scenario_id:
        raise InputError(
            f"rollouts are for scenario {rollouts.scenario_id!r}, not {scenario.scenario_id!r}", where="scenario_id"
        )
    if rollouts.num_steps != FUTURE_STEPS:
        raise InputError(f"{rollouts.num_steps} steps per rollout, expected {FUTURE_STEPS}", where="steps")
    if num_rollouts is not None and rollouts.num_rollouts != num_rollouts:
        raise InputError(f"{rollouts.num_rollouts} rollouts, expected {num_rollouts}", where="rollouts")
    if rollouts.num_rollouts == 0:
        raise InputError("no rollouts", where="rollouts")
    sim_ids = scenario.agents.ids[sim_agent_indices(scenario)]
    missing = np.setdiff1d(sim_ids, rollouts.object_id)
    extra = np.setdiff1d(rollouts.object_id, sim_ids)
    if len(missing) or len(extra):
        parts = []
        if len(missing):
            parts.append(f"missing sim agents {_ids(missing)}")
        if len(extra):
            parts.append(f"objects that are not sim agents (unknown or invalid at the current step) {_ids(extra)}")
        raise InputError(
            "; ".join(parts) + f" (scenario {scenario.scenario_id} has {len(sim_ids)} sim agents)",
            where="object_id",
        )
    rollouts.check_finite()
    return np.array([scenario.agents.index_of(int(i)) for i in rollouts.object_id], np.int64)
