"""Rollouts: the simulated futures of a scene (what the simulator produces and the metrics score).

`Rollouts` is the container (saved as `.npz`), `agents` says which tracks are simulated and which are
evaluated (the WOSAC rules), and `baselines` generates reference rollouts (constant velocity, log
replay, stationary) to calibrate the metrics against.

See docs/metrics.md.
"""

from langtraj.rollouts.agents import evaluated_agent_indices, sim_agent_indices
from langtraj.rollouts.baselines import (
    BASELINES,
    ConstantVelocity,
    LogReplay,
    RolloutBaseline,
    Stationary,
    generate_baseline,
)
from langtraj.rollouts.container import WOSAC_ROLLOUTS, Rollouts

__all__ = [
    "BASELINES",
    "WOSAC_ROLLOUTS",
    "ConstantVelocity",
    "LogReplay",
    "RolloutBaseline",
    "Rollouts",
    "Stationary",
    "evaluated_agent_indices",
    "generate_baseline",
    "sim_agent_indices",
]
