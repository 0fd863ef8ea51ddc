"""The Scenario data model, its file formats, windowing and agent selection. See docs/data.md."""

from langtraj.scenario.model import (
    STEP_SECONDS,
    Agents,
    BehaviorEvent,
    BoundarySegment,
    LaneNeighbor,
    MapFeature,
    RoadMap,
    Scenario,
    TrafficLights,
)
from langtraj.scenario.types import AgentType, MapFeatureType, StateField, TrafficLightState

__all__ = [
    "STEP_SECONDS",
    "AgentType",
    "Agents",
    "BehaviorEvent",
    "BoundarySegment",
    "LaneNeighbor",
    "MapFeature",
    "MapFeatureType",
    "RoadMap",
    "Scenario",
    "StateField",
    "TrafficLightState",
    "TrafficLights",
]
