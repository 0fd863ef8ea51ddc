"""Which agents are parked, judged from the history alone: the heuristic labeler's parked rule
(`interdrive.heuristics`, `ParkedRule`) applied to the steps up to the current one, so a simulation may use it
(to keep parked agents parked) and the failure analysis may ask whether a simulation moved a parked car
(`sim.failures`) without reading the logged future (docs/design.md, 'Closed-loop simulation')."""

from __future__ import annotations

import numpy as np

from langtraj.interdrive.heuristics.config import HeuristicConfig
from langtraj.interdrive.heuristics.context import LabelContext
from langtraj.interdrive.heuristics.kinematics import Kinematics
from langtraj.roads import MapIndex
from langtraj.scenario.model import Scenario


def parked_in_history(
    scenario: Scenario, config: HeuristicConfig | None = None, map_index: MapIndex | None = None
) -> np.ndarray:
    """bool [A]: each agent is a vehicle parked at the current step, judged from steps 0..current only.

    The labeler's rule (`LabelContext.parked`) on the scene cut at its current step: stopped over every valid
    history step (smoothed speed at most `static_speed`, moving at most `parked_max_displacement`) and at the
    road side at the current step (`MapIndex.parked_decision`: off every drivable lane, beside the lane centre,
    or at the kerb and not queued). The logged speed (vx, vy) at each valid history step must be at most
    `static_speed` too, so an agent seen at one step only is not taken for still. Undecided (a map without lanes,
    or a car on a lane centre where the map has no road edges) counts as not parked; so does every agent that is
    no vehicle or is invalid at the current step. `map_index` may be passed to reuse one built for the scene."""
    config = config or HeuristicConfig()
    current = scenario.current_index
    history = scenario.slice_steps(0, current + 1, current)
    if map_index is None:
        map_index = MapIndex.build(scenario.road_map, infer_neighbors=config.infer_neighbors)
    context = LabelContext(history, config, map_index, Kinematics.compute(history, config))
    agents = history.agents
    logged_speed = np.where(agents.valid, agents.speed, 0.0).max(axis=1, initial=0.0)
    out = np.zeros(scenario.num_agents, bool)
    for agent, (decision, _) in context.parked.items():  # eligible vehicles only
        out[agent] = decision is True and logged_speed[agent] <= config.static_speed
    return out
