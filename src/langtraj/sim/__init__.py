"""Closed-loop simulation: the rollout engine, policies, candidate selection and simulation summaries.

See docs/simulation.md.
"""

from langtraj.sim.config import SimConfig, SimRequest
from langtraj.sim.engine import SimResult, replan_schedule, simulate
from langtraj.sim.policies import (
    POLICIES,
    ConstantVelocityPolicy,
    GuidanceBaselinePolicy,
    LangTrajPolicy,
    LogReplayPolicy,
    Policy,
)
from langtraj.sim.selection import SELECTORS, CandidateSelector

__all__ = [
    "POLICIES",
    "SELECTORS",
    "CandidateSelector",
    "ConstantVelocityPolicy",
    "GuidanceBaselinePolicy",
    "LangTrajPolicy",
    "LogReplayPolicy",
    "Policy",
    "SimConfig",
    "SimRequest",
    "SimResult",
    "replan_schedule",
    "simulate",
]
