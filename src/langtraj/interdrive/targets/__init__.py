"""Targets and feasibility: where a behaviour asked of an agent takes it on the map, and whether it can do it there
(it can exactly when the map gives a target). Read from the scene at the current step only.

Modules, in the order they build on each other: `config` (`CounterfactualConfig`, how far the map is searched),
`lanes_ahead` (the agent on its lane, the next junction's branches, the road ahead; paths along the lane graph are
`roads.routes`), `derive` (`BehaviourTarget`, `derive_target`, `TargetUnavailable`), `feasibility` (`Feasibility`,
`feasibility`, `behaviour_feasibility`, `then_feasibility`). See docs/interdrive.md ('Targets and feasibility').
"""

from langtraj.interdrive.targets.config import CounterfactualConfig
from langtraj.interdrive.targets.derive import (
    BRAKE_HARD_AFTER_S,
    CUT_IN_S,
    LANE_CHANGE_S,
    SPEED_CHANGE,
    BehaviourTarget,
    Status,
    TargetUnavailable,
    derive_target,
    stop_after,
)
from langtraj.interdrive.targets.feasibility import Feasibility, behaviour_feasibility, feasibility, then_feasibility
from langtraj.roads.position import AgentOnLane

__all__ = [
    "BRAKE_HARD_AFTER_S",
    "CUT_IN_S",
    "LANE_CHANGE_S",
    "SPEED_CHANGE",
    "AgentOnLane",
    "BehaviourTarget",
    "CounterfactualConfig",
    "Feasibility",
    "Status",
    "TargetUnavailable",
    "behaviour_feasibility",
    "derive_target",
    "feasibility",
    "stop_after",
    "then_feasibility",
]
