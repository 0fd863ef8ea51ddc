"""The Scenario data model, its file formats, windowing and agent selection. See docs/data.md."""

from langtraj.scenario.model import (
    FUTURE_STEPS,
    HISTORY_STEPS,
    STEP_SECONDS,
    WINDOW_STEPS,
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
    "FUTURE_STEPS",
    "HISTORY_STEPS",
    "STEP_SECONDS",
    "WINDOW_STEPS",
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
