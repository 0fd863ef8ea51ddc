"""Metrics: WOSAC realism (agreeing with the official implementation), controllability and safety.

`evaluate_scenario` scores one scenario's rollouts; `metrics.corpus` scores many in parallel;
`metrics.controllability` gives minADE with and without text and adversary-target collision rates;
`metrics.submission` writes the challenge's submission protos. See docs/metrics.md.
"""

from langtraj.metrics.config import WOSAC_2024, WOSAC_2025, WosacConfig, wosac_config
from langtraj.metrics.controllability import (
    collision_rate,
    controllability,
    min_ade,
    offroad_rate,
    pair_collision,
    pair_collision_rate,
    safety,
)
from langtraj.metrics.wosac import ScenarioMetrics, evaluate_scenario

__all__ = [
    "WOSAC_2024",
    "WOSAC_2025",
    "ScenarioMetrics",
    "WosacConfig",
    "collision_rate",
    "controllability",
    "evaluate_scenario",
    "min_ade",
    "offroad_rate",
    "pair_collision",
    "pair_collision_rate",
    "safety",
    "wosac_config",
]
