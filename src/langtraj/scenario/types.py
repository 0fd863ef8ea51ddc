"""Enumerations shared by every scenario source: agent types, map feature types, traffic-light states.

Integer values of `AgentType` and `TrafficLightState` equal the Waymo Open Motion proto enums; the
names of `MapFeatureType` equal ScenarioNet's (MetaDrive) type strings, so both formats map by lookup.

See docs/data.md.
"""

from __future__ import annotations

from enum import IntEnum


class AgentType(IntEnum):
    """Kind of road user (values as WOMD `Track.ObjectType`; UNSET is read as OTHER)."""

    VEHICLE = 1
    PEDESTRIAN = 2
    CYCLIST = 3
    OTHER = 4


class MapFeatureType(IntEnum):
    """Kind of map feature; the name is the ScenarioNet type string."""

    LANE_UNKNOWN = 1
    LANE_FREEWAY = 2
    LANE_SURFACE_STREET = 3
    LANE_BIKE_LANE = 4
    ROAD_LINE_UNKNOWN = 10
    ROAD_LINE_BROKEN_SINGLE_WHITE = 11
    ROAD_LINE_SOLID_SINGLE_WHITE = 12
    ROAD_LINE_SOLID_DOUBLE_WHITE = 13
    ROAD_LINE_BROKEN_SINGLE_YELLOW = 14
    ROAD_LINE_BROKEN_DOUBLE_YELLOW = 15
    ROAD_LINE_SOLID_SINGLE_YELLOW = 16
    ROAD_LINE_SOLID_DOUBLE_YELLOW = 17
    ROAD_LINE_PASSING_DOUBLE_YELLOW = 18
    ROAD_EDGE_UNKNOWN = 20
    ROAD_EDGE_BOUNDARY = 21
    ROAD_EDGE_MEDIAN = 22
    ROAD_EDGE_SIDEWALK = 23
    STOP_SIGN = 30
    CROSSWALK = 31
    SPEED_BUMP = 32
    DRIVEWAY = 33

    @property
    def is_lane(self) -> bool:
        return self.name.startswith("LANE_")

    @property
    def is_road_line(self) -> bool:
        return self.name.startswith("ROAD_LINE_")

    @property
    def is_road_edge(self) -> bool:
        return self.name.startswith("ROAD_EDGE_")

    @property
    def is_area(self) -> bool:
        """Features whose points are a polygon rather than a polyline."""
        return self in (MapFeatureType.CROSSWALK, MapFeatureType.SPEED_BUMP, MapFeatureType.DRIVEWAY)


class TrafficLightState(IntEnum):
    """Signal state of one controlled lane (values as WOMD `TrafficSignalLaneState.State`)."""

    UNKNOWN = 0
    ARROW_STOP = 1
    ARROW_CAUTION = 2
    ARROW_GO = 3
    STOP = 4
    CAUTION = 5
    GO = 6
    FLASHING_STOP = 7
    FLASHING_CAUTION = 8

    @property
    def is_stop(self) -> bool:
        return self in (TrafficLightState.STOP, TrafficLightState.ARROW_STOP, TrafficLightState.FLASHING_STOP)

    @property
    def is_caution(self) -> bool:
        return self in (
            TrafficLightState.CAUTION,
            TrafficLightState.ARROW_CAUTION,
            TrafficLightState.FLASHING_CAUTION,
        )

    @property
    def is_go(self) -> bool:
        return self in (TrafficLightState.GO, TrafficLightState.ARROW_GO)


RED_STATES = (TrafficLightState.STOP, TrafficLightState.ARROW_STOP)
"""The signal states a red-light violation counts (red and a red arrow, as WOSAC; not a flashing red, which is a stop
sign): red-light metrics, the ego's rules, the red-light runner's target and its judge."""


class StateField(IntEnum):
    """Column of `Agents.states` (units: m, rad, m/s)."""

    X = 0
    Y = 1
    Z = 2
    HEADING = 3
    VX = 4
    VY = 5
    LENGTH = 6
    WIDTH = 7
    HEIGHT = 8


NUM_STATE_FIELDS = len(StateField)
