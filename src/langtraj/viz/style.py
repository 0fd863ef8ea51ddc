"""Colours, line styles and z-order of the top-down view, per agent, map feature and signal type.

One place for the look, so the renderer holds no magic colours. Widths and sizes are in points
(1/72 inch); the renderer's dpi turns them into pixels.
"""

from __future__ import annotations

from dataclasses import dataclass

from langtraj.scenario.types import AgentType, MapFeatureType, TrafficLightState

BACKGROUND = "#26292e"
"""Off-road colour (dark asphalt), so white and yellow markings stand out."""

TEXT = "#f2f2f2"
TEXT_BOX = "#000000"

# ----------------------------------------------------------------------------- agents
AGENT_COLORS: dict[AgentType, str] = {
    AgentType.VEHICLE: "#4f9de8",
    AgentType.PEDESTRIAN: "#ff9a1f",
    AgentType.CYCLIST: "#c678f0",
    AgentType.OTHER: "#c9b28f",
}
SDC_COLOR = "#19e0c0"
AGENT_EDGE = "#0d0f12"
AGENT_EDGE_WIDTH = 0.6
HEADING_COLOR = "#0d0f12"
HEADING_WIDTH = 1.0
HIGHLIGHT_EDGE = "#ffffff"
HIGHLIGHT_EDGE_WIDTH = 2.4
TRAIL_WIDTH = 2.2
TRAIL_MAX_ALPHA = 0.85
LABEL_SIZE = 6.5
MIN_BOX_PX = 5.0
"""Smallest drawn box side in pixels, so pedestrians stay visible in wide views."""

DEFAULT_SIZE_M: dict[AgentType, tuple[float, float]] = {
    AgentType.VEHICLE: (4.5, 2.0),
    AgentType.PEDESTRIAN: (0.6, 0.6),
    AgentType.CYCLIST: (1.8, 0.7),
    AgentType.OTHER: (1.0, 1.0),
}
"""Length and width (m) drawn when a state carries no usable size."""


def agent_color(agent_type: int) -> str:
    """Fill colour of an agent type (unknown values are drawn as OTHER)."""
    try:
        return AGENT_COLORS[AgentType(int(agent_type))]
    except ValueError:
        return AGENT_COLORS[AgentType.OTHER]


# ----------------------------------------------------------------------------- map
@dataclass(frozen=True)
class LineStyle:
    """How one group of map polylines is stroked."""

    color: str
    width: float
    dashes: tuple[float, float] | None = None  # (on, off) in points; None draws solid
    alpha: float = 1.0
    zorder: float = 2.0


LANE = LineStyle("#6d737b", 0.6, alpha=0.8, zorder=2.0)
BIKE_LANE = LineStyle("#3fa7a0", 0.8, dashes=(2.0, 2.0), alpha=0.9, zorder=2.1)
ROAD_EDGE = LineStyle("#0b0c0e", 2.2, zorder=3.0)
ROAD_EDGE_UNDERLAY = LineStyle("#8c929a", 3.4, alpha=0.55, zorder=2.9)
"""A lighter halo under road edges so the dark curb line stays visible on the dark background."""

_WHITE = "#eeeeee"
_YELLOW = "#f2c230"
_DASH = (4.0, 3.0)

ROAD_LINE_STYLES: dict[MapFeatureType, LineStyle] = {
    MapFeatureType.ROAD_LINE_UNKNOWN: LineStyle("#9aa0a6", 0.7, alpha=0.8, zorder=4.0),
    MapFeatureType.ROAD_LINE_BROKEN_SINGLE_WHITE: LineStyle(_WHITE, 0.9, _DASH, zorder=4.0),
    MapFeatureType.ROAD_LINE_SOLID_SINGLE_WHITE: LineStyle(_WHITE, 0.9, zorder=4.0),
    MapFeatureType.ROAD_LINE_SOLID_DOUBLE_WHITE: LineStyle(_WHITE, 1.8, zorder=4.0),
    MapFeatureType.ROAD_LINE_BROKEN_SINGLE_YELLOW: LineStyle(_YELLOW, 0.9, _DASH, zorder=4.1),
    MapFeatureType.ROAD_LINE_BROKEN_DOUBLE_YELLOW: LineStyle(_YELLOW, 1.8, _DASH, zorder=4.1),
    MapFeatureType.ROAD_LINE_SOLID_SINGLE_YELLOW: LineStyle(_YELLOW, 0.9, zorder=4.1),
    MapFeatureType.ROAD_LINE_SOLID_DOUBLE_YELLOW: LineStyle(_YELLOW, 1.8, zorder=4.1),
    MapFeatureType.ROAD_LINE_PASSING_DOUBLE_YELLOW: LineStyle(_YELLOW, 1.8, (6.0, 2.0), zorder=4.1),
}


def line_style(feature_type: MapFeatureType) -> LineStyle | None:
    """Stroke of a polyline feature type, or None for types that are not polylines."""
    if feature_type == MapFeatureType.LANE_BIKE_LANE:
        return BIKE_LANE
    if feature_type.is_lane:
        return LANE
    if feature_type.is_road_edge:
        return ROAD_EDGE
    return ROAD_LINE_STYLES.get(feature_type)


@dataclass(frozen=True)
class AreaStyle:
    """How one group of map polygons is filled."""

    face: str
    edge: str
    width: float = 0.5
    hatch: str | None = None
    alpha: float = 1.0
    zorder: float = 1.0


LANE_SURFACE = AreaStyle("#363a40", "none", 0.0, zorder=0.5)
"""Lane outline polygons (nuScenes), filled as road surface."""

AREA_STYLES: dict[MapFeatureType, AreaStyle] = {
    MapFeatureType.DRIVEWAY: AreaStyle("#3a3f46", "#4a5058", 0.4, zorder=0.8),
    MapFeatureType.CROSSWALK: AreaStyle("#30343a", "#d9d9d9", 0.6, hatch="////", zorder=1.2),
    MapFeatureType.SPEED_BUMP: AreaStyle("#5c4a2a", "#f0a030", 0.6, hatch="xx", zorder=1.3),
}

STOP_SIGN_COLOR = "#e02424"
STOP_SIGN_EDGE = "#ffffff"
STOP_SIGN_SIZE = 55.0  # marker area, points^2
STOP_SIGN_ZORDER = 5.0

# ----------------------------------------------------------------------------- traffic lights
LIGHT_RED = "#ff3b30"
LIGHT_YELLOW = "#ffd60a"
LIGHT_GREEN = "#30d158"
LIGHT_UNKNOWN = "#8e8e93"
LIGHT_SIZE = 45.0  # marker area, points^2, of a signal whose lane direction is unknown
LIGHT_BAR_WIDTH = 3.5  # points
LIGHT_BAR_LENGTH_M = 3.0
LIGHT_EDGE = "#0d0f12"
LIGHT_ZORDER = 6.0


def light_color(state: int) -> str:
    """Marker colour of a signal state: red, yellow, green, or grey when unknown (arrows share)."""
    try:
        s = TrafficLightState(int(state))
    except ValueError:
        return LIGHT_UNKNOWN
    if s.is_stop:
        return LIGHT_RED
    if s.is_caution:
        return LIGHT_YELLOW
    if s.is_go:
        return LIGHT_GREEN
    return LIGHT_UNKNOWN


# ----------------------------------------------------------------------------- target marks
MARK_COLOR = HIGHLIGHT_EDGE
"""A prompted agent's target path is drawn in the colour that outlines the prompted agents."""
MARK_UNDERLAY = "#0d0f12"
"""A dark halo under the target path, so it is not mistaken for a white lane marking."""
MARK_PATH_WIDTH = 4.0
MARK_PATH_UNDERLAY_WIDTH = 7.0
MARK_PATH_DASHES = (1.2, 1.6)  # (on, off) in line widths: short round dashes, unlike the thin lane markings
MARK_PATH_ALPHA = 0.85
MARK_STOP_COLOR = "#ff453a"
MARK_STOP_BAR_M = 3.5
"""Length of the bar drawn across a target path where the agent must stand still (m)."""
MARK_STOP_BAR_WIDTH = 5.0
MARK_STOP_SIZE = 260.0  # marker area, points^2 (larger than a map stop sign, which it must not be taken for)
MARK_GOAL_COLOR = MARK_COLOR
MARK_GOAL_SIZE = 420.0
MARK_CONFLICT_COLOR = "#ff9f0a"
MARK_CONFLICT_SIZE = 260.0
MARK_EDGE = "#0d0f12"
MARK_EDGE_WIDTH = 0.8
MARK_LABEL_SIZE = 7.0
MARK_ZORDER = 6.5
"""Over the map and signals' stop points, under trails and agents (marks are static: drawn with the map)."""

# ----------------------------------------------------------------------------- dynamic layers
TRAIL_ZORDER = 7.0
AGENT_ZORDER = 8.0
HEADING_ZORDER = 8.5
LABEL_ZORDER = 9.0
CAPTION_ZORDER = 10.0
CAPTION_SIZE = 9.0
