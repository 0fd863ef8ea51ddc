"""The LangTraj Gymnasium environment: a planner under test drives one ego, LangTraj every other agent
(docs/testing.md). Registered as `LangTraj-v0`: `gymnasium.make("langtraj.env:LangTraj-v0", scenario="FILE")`.
The environment itself (and torch with it) is imported on first use, so planners can read `env.spaces` cheaply."""

from __future__ import annotations

from typing import Any

import gymnasium

from langtraj.cases import EGO_PLACEHOLDER, EPISODE_STEPS

ENV_ID = "LangTraj-v0"

if ENV_ID not in gymnasium.registry:
    gymnasium.register(
        id=ENV_ID,
        entry_point="langtraj.env.environment:LangTrajEnv",
        max_episode_steps=EPISODE_STEPS,
        disable_env_checker=True,  # `check_env` passes (tests/env); the passive checker would re-check each step
    )

_LAZY = {
    "LangTrajEnv": "langtraj.env.environment",
    "RewardConfig": "langtraj.env.reward",
}


def __getattr__(name: str) -> Any:
    if name in _LAZY:
        import importlib

        return getattr(importlib.import_module(_LAZY[name]), name)
    raise AttributeError(f"module 'langtraj.env' has no attribute {name!r}")


__all__ = ["EGO_PLACEHOLDER", "ENV_ID", "EPISODE_STEPS", "LangTrajEnv", "RewardConfig"]
