"""Planners: what drives the ego of the LangTraj environment under test (docs/testing.md, 'Planners').

The protocol (`Planner`, `PLANNERS`, `load_planner`), the built-in planners (IDM lane follower, the cautious one,
constant velocity, log replay) and the JSON-lines protocol for planners in another process. Importing this package
registers the built-in planners.
"""

from langtraj.planners.base import (
    PLANNERS,
    Planner,
    PlannerError,
    PlannerTimeout,
    load_planner,
    planner_action_kind,
    planner_reads_log,
    reset_planner,
)
from langtraj.planners.cautious import CautiousPlanner
from langtraj.planners.idm import IDMConfig, IDMPlanner
from langtraj.planners.jsonlines import SubprocessPlanner, decode_observation, encode_observation, serve
from langtraj.planners.simple import ConstantVelocityPlanner, LogReplayPlanner

__all__ = [
    "PLANNERS",
    "CautiousPlanner",
    "ConstantVelocityPlanner",
    "IDMConfig",
    "IDMPlanner",
    "LogReplayPlanner",
    "Planner",
    "PlannerError",
    "PlannerTimeout",
    "SubprocessPlanner",
    "decode_observation",
    "encode_observation",
    "load_planner",
    "planner_action_kind",
    "planner_reads_log",
    "reset_planner",
    "serve",
]
