"""Targets and feasibility: where a behaviour asked of an agent takes it on the map, and whether it can do it there
(it can exactly when the map gives a target). Read from the scene at the current step only.

Modules, in the order they build on each other: `config` (`CounterfactualConfig`, how far the map is searched),
`lanes_ahead` (the agent on its lane, the next junction's branches, the road ahead; paths along the lane graph are
`roads.routes`), `target` (`BehaviourTarget`, `TargetUnavailable`), `context` (`TargetContext`: one scene's map read
once, and the geometry several behaviours share), `derive` (`derive_target`: the behaviour's own target, from its
module of `interdrive.behaviours`; `stop_after`), `feasibility` (`Feasibility`, `feasibility`,
`behaviour_feasibility`, `then_feasibility`). See docs/interdrive.md ('Targets and feasibility').
"""

from langtraj.interdrive.targets.config import CounterfactualConfig
from langtraj.interdrive.targets.context import LANE_CHANGE_S, SPEED_CHANGE, AgentHere, TargetContext
from langtraj.interdrive.targets.derive import derive_target, stop_after
from langtraj.interdrive.targets.feasibility import Feasibility, behaviour_feasibility, feasibility, then_feasibility
from langtraj.interdrive.targets.target import BehaviourTarget, Status, TargetUnavailable
from langtraj.roads.position import AgentOnLane

__all__ = [
    "LANE_CHANGE_S",
    "SPEED_CHANGE",
    "AgentHere",
    "AgentOnLane",
    "BehaviourTarget",
    "CounterfactualConfig",
    "Feasibility",
    "Status",
    "TargetContext",
    "TargetUnavailable",
    "behaviour_feasibility",
    "derive_target",
    "feasibility",
    "stop_after",
    "then_feasibility",
]
