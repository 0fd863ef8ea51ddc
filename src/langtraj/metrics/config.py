"""WOSAC metric configurations: one estimator and meta-metric weight per feature (docs/design.md, 'WOSAC metric
configuration').

`WOSAC_2025` is the 2025 Sim Agents Challenge configuration; `WOSAC_2024` differs only in two
weights (road edge 0.10, traffic lights 0). Custom configurations are plain dataclasses.

See docs/metrics.md.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field, replace
from types import MappingProxyType

from langtraj.errors import InputError
from langtraj.metrics.estimators import BernoulliEstimator, Estimator, HistogramEstimator

BUCKETS: Mapping[str, tuple[str, ...]] = MappingProxyType(
    {
        "kinematic": ("linear_speed", "linear_acceleration", "angular_speed", "angular_acceleration"),
        "interactive": ("distance_to_nearest_object", "collision_indication", "time_to_collision"),
        "map_based": ("distance_to_road_edge", "offroad_indication", "traffic_light_violation"),
    }
)
"""The three score buckets and their features, in report order."""

FEATURES: tuple[str, ...] = tuple(name for names in BUCKETS.values() for name in names)


@dataclass(frozen=True)
class FeatureConfig:
    """How one feature is scored: its estimator and its weight in the meta-metric."""

    estimator: Estimator
    weight: float


@dataclass(frozen=True)
class WosacConfig:
    """Estimators and weights for every feature in `FEATURES`."""

    name: str
    features: Mapping[str, FeatureConfig] = field(default_factory=dict)

    def __post_init__(self) -> None:
        missing = [f for f in FEATURES if f not in self.features]
        if missing:
            raise InputError(f"no configuration for {', '.join(missing)}", where=f"metrics config {self.name}")

    def weight(self, feature: str) -> float:
        return self.features[feature].weight

    def with_weights(self, name: str, **weights: float) -> WosacConfig:
        """A copy named `name` with some weights changed."""
        features = dict(self.features)
        for key, value in weights.items():
            features[key] = replace(features[key], weight=value)
        return WosacConfig(name, MappingProxyType(features))


def _hist(low: float, high: float, bins: int, weight: float) -> FeatureConfig:
    return FeatureConfig(HistogramEstimator(low, high, bins, pseudocount=0.1), weight)


def _bern(weight: float) -> FeatureConfig:
    return FeatureConfig(BernoulliEstimator(pseudocount=0.001), weight)


WOSAC_2025 = WosacConfig(
    "2025",
    MappingProxyType(
        {
            "linear_speed": _hist(0.0, 25.0, 10, 0.05),
            "linear_acceleration": _hist(-12.0, 12.0, 11, 0.05),
            "angular_speed": _hist(-0.628, 0.628, 11, 0.05),
            "angular_acceleration": _hist(-3.14, 3.14, 11, 0.05),
            "distance_to_nearest_object": _hist(-5.0, 40.0, 10, 0.10),
            "collision_indication": _bern(0.25),
            "time_to_collision": _hist(0.0, 5.0, 10, 0.10),
            "distance_to_road_edge": _hist(-20.0, 40.0, 10, 0.05),
            "offroad_indication": _bern(0.25),
            "traffic_light_violation": _bern(0.05),
        }
    ),
)

WOSAC_2024 = WOSAC_2025.with_weights("2024", distance_to_road_edge=0.10, traffic_light_violation=0.0)

CONFIGS: Mapping[str, WosacConfig] = MappingProxyType({"2025": WOSAC_2025, "2024": WOSAC_2024})


def wosac_config(name: str | WosacConfig) -> WosacConfig:
    """The configuration called `name` ("2025" or "2024"), or `name` itself when it is one."""
    if isinstance(name, WosacConfig):
        return name
    try:
        return CONFIGS[str(name)]
    except KeyError:
        raise InputError(f"unknown WOSAC config {name!r}; known: {', '.join(CONFIGS)}", where="config") from None
