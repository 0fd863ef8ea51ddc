"""What the ScenarioNet reader and writer share: format constants, type-string tables, integer keys.

See docs/data.md.
"""

from __future__ import annotations

import re

from langtraj.scenario.model import HISTORY_STEPS, MPH_TO_MPS
from langtraj.scenario.types import AgentType, MapFeatureType, TrafficLightState

FORMAT_NAME = "scenarionet"
"""The name `ScenarioNetFormat` is registered under, and the `source_format` of what it reads."""

DEFAULT_CURRENT_INDEX = HISTORY_STEPS - 1
"""Current step when the source has no `current_time_index`: the WOMD convention (1 s of history at
10 Hz). nuScenes scenes are longer (about 20 s) and get windowed later."""

FORMAT_VERSION = "MetaDrive v0.3.0.1"
"""The `version` written when the scenario did not come from a ScenarioNet file."""

PICKLE_PROTOCOL = 4

# ---------------------------------------------------------------------------- type strings

_AGENT_TYPES = {t.name: t for t in AgentType}
"""Track type strings we keep; every other one (TRAFFIC_CONE, UNSET, ...) is read as OTHER."""

_MAP_TYPES: dict[str, MapFeatureType] = {
    **{t.name: t for t in MapFeatureType},
    "UNKNOWN": MapFeatureType.ROAD_EDGE_UNKNOWN,  # MetaDrive's BOUNDARY_UNKNOWN (WOMD unknown edges)
    "UNKNOWN_LINE": MapFeatureType.ROAD_LINE_UNKNOWN,  # MetaDrive's LINE_UNKNOWN
    "LANE_SURFACE_UNSTRUCTURE": MapFeatureType.LANE_SURFACE_STREET,  # nuPlan intersections
}
_MAP_TYPE_NAMES = {
    **{t: t.name for t in MapFeatureType},
    MapFeatureType.ROAD_EDGE_UNKNOWN: "UNKNOWN",
    MapFeatureType.ROAD_LINE_UNKNOWN: "UNKNOWN_LINE",
}
"""The type string written for each map feature type: the one MetaDrive knows."""

_BOUNDARY_TYPES = {**_MAP_TYPES, "UNKNOWN": MapFeatureType.ROAD_LINE_UNKNOWN}
_BOUNDARY_NAMES = {**_MAP_TYPE_NAMES, MapFeatureType.ROAD_LINE_UNKNOWN: "UNKNOWN"}
"""Lane boundary types: ScenarioNet writes WOMD's unknown road line type as 'UNKNOWN'."""

_LIGHT_STATES = {
    **{f"LANE_STATE_{s.name}": s for s in TrafficLightState},
    "TRAFFIC_LIGHT_GREEN": TrafficLightState.GO,
    "TRAFFIC_LIGHT_YELLOW": TrafficLightState.CAUTION,
    "TRAFFIC_LIGHT_RED": TrafficLightState.STOP,
    "TRAFFIC_LIGHT_UNKNOWN": TrafficLightState.UNKNOWN,
}

_KMH_PER_MPH = MPH_TO_MPS * 3.6

_DERIVED_METADATA = frozenset(
    {
        "ts", "sdc_id", "current_time_index", "sdc_track_index", "objects_of_interest",
        "tracks_to_predict", "track_length", "object_summary", "number_summary", "id", "scenario_id",
        "metadrive_processed", "langtraj",
    }
)  # fmt: skip
"""Source metadata the writer recomputes from the scenario, so it is not kept verbatim."""

_INT_KEY = re.compile(r"0|-?[1-9][0-9]{0,17}")


def _is_int_key(key: str) -> bool:
    """True for a canonical decimal integer that fits int64 (so str(int(key)) == key)."""
    return _INT_KEY.fullmatch(key) is not None
