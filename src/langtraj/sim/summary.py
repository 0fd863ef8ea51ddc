"""The JSON summary of a simulation: per agent, how often it collided or left the road and how far it went.

See docs/simulation.md.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from langtraj.metrics.controllability import agent_rates
from langtraj.sim.engine import SimResult


def simulation_summary(result: SimResult, policy: str, **settings: Any) -> dict[str, Any]:
    """Per-agent collision and offroad rates over the rollouts (offroad: vehicles only, null without road
    edges), mean distance travelled, what moved each agent (`policy` for the driven ones, the world's
    undriven rule for the others; `reads_future_log` when that is the log), and the timing; `settings`
    are echoed."""
    scenario, rollouts = result.world.scenario, result.rollouts
    collided, offroad = agent_rates(scenario, rollouts)
    steps = np.hypot(np.diff(rollouts.x, axis=-1), np.diff(rollouts.y, axis=-1)).sum(-1).mean(0)  # [A]
    driven = set(result.driven_ids.tolist())
    undriven = result.world.undriven
    moved_by = {int(t): policy if int(t) in driven else undriven for t in rollouts.object_id}
    agents = [
        {
            "id": int(track),
            "driven": int(track) in driven,
            "moved_by": moved_by[int(track)],
            "collision_rate": collided[int(track)],
            "offroad_rate": offroad.get(int(track)),
            "distance_m": float(steps[col]),
        }
        for col, track in enumerate(rollouts.object_id)
    ]
    return {
        "scenario_id": scenario.scenario_id,
        "rollouts": rollouts.num_rollouts,
        "policy": policy,
        "driven_ids": [int(i) for i in result.driven_ids],
        "agents_by_policy": {
            name: [track for track, by in moved_by.items() if by == name] for name in dict.fromkeys(moved_by.values())
        },
        "reads_future_log": rollouts.reads_future_log,
        "replans": [step for step, _ in result.schedule],
        "seconds": result.seconds,
        "seconds_per_replan": result.plan_seconds,
        "collision_rate": float(np.mean(list(collided.values()))),
        "offroad_rate": float(np.mean(list(offroad.values()))) if offroad else None,
        **result.report,
        "agents": agents,
        **settings,
    }
