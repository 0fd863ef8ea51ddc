"""Agent boxes checked as a scene is read: a vehicle whose box is wider than long has its length and width swapped,
with a `DataWarning` naming the file and the tracks. nuScenes' ego, converted by ScenarioNet, is 1.73 m long and
4.08 m wide in every mini scene; left as read, its box lies across its lane and touches cars beside it that it
never meets (docs/data.md, 'Checks on read')."""

from __future__ import annotations

import warnings
from dataclasses import replace

import numpy as np

from langtraj.errors import DataWarning
from langtraj.scenario.model import Scenario
from langtraj.scenario.types import AgentType, StateField

SHOWN = 5
"""Tracks a warning names (then how many more)."""


def median_sizes(scenario: Scenario) -> tuple[np.ndarray, np.ndarray]:
    """Each agent's median length and width over its valid steps up to the current one: the history alone, so no
    simulation's input depends on the logged future (NaN for a track not seen by then)."""
    agents = scenario.agents
    seen = agents.valid.copy()
    seen[:, scenario.current_index + 1 :] = False
    states = agents.states.astype(np.float64)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)  # a track never valid: an all-NaN median
        return tuple(  # type: ignore[return-value]
            np.nanmedian(np.where(seen, states[..., f], np.nan), axis=1) for f in (StateField.LENGTH, StateField.WIDTH)
        )


def fix_box_sizes(scenario: Scenario, where: str) -> Scenario:
    """`scenario` with the length and width swapped at every step of each vehicle whose median width exceeds its
    median length in the history (one `DataWarning` naming `where`, the file), or as it is when none does."""
    length, width = median_sizes(scenario)
    rows = np.flatnonzero((width > length) & (scenario.agents.types == AgentType.VEHICLE))
    if not len(rows):
        return scenario
    states = scenario.agents.states.copy()
    fields = [StateField.LENGTH, StateField.WIDTH]
    states[rows[:, None], :, fields] = scenario.agents.states[rows[:, None], :, fields[::-1]]
    shown = ", ".join(
        f"@{int(scenario.agents.ids[r])} ({length[r]:.2f} m long, {width[r]:.2f} m wide)" for r in rows[:SHOWN]
    )
    more = f" and {len(rows) - SHOWN} more" if len(rows) > SHOWN else ""
    warnings.warn(
        f"{where}: scenario {scenario.scenario_id}: vehicle {shown}{more} wider than long: length and width swapped",
        DataWarning,
        stacklevel=2,
    )
    return replace(scenario, agents=replace(scenario.agents, states=states))
