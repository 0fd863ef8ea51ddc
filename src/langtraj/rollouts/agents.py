"""Which tracks of a scene are simulated and which are scored (the WOSAC rules). See docs/metrics.md."""

from __future__ import annotations

import numpy as np

from langtraj.scenario.model import Scenario


def sim_agent_indices(scenario: Scenario) -> np.ndarray:
    """Indices of the sim agents: every track valid at the current step, in track order."""
    return np.flatnonzero(scenario.agents.valid[:, scenario.current_index]).astype(np.int64)


def evaluated_agent_indices(scenario: Scenario) -> np.ndarray:
    """Indices of the evaluated agents: the SDC plus the tracks to predict, in track order.

    Only sim agents can be evaluated; a track to predict that is invalid at the current step is left
    out (the official implementation requires it to be a sim agent too).
    """
    chosen = set(int(i) for i in scenario.agents.tracks_to_predict)
    if scenario.sdc_index >= 0:
        chosen.add(scenario.sdc_index)
    sim = set(sim_agent_indices(scenario).tolist())
    return np.array(sorted(chosen & sim), np.int64)
