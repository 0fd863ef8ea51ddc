"""What the studio's page draws of a scene: agents with their tracks up to the current step, the map as typed
polylines, and the traffic lights at the current step, in world coordinates (metres) rounded to centimetres
(docs/studio.md, 'GET /api/scenes/{key}')."""

from __future__ import annotations

from typing import Any

import numpy as np

from langtraj.rollouts.agents import sim_agent_indices
from langtraj.scenario.model import STEP_SECONDS, Scenario
from langtraj.scenario.types import AgentType, MapFeatureType, StateField, TrafficLightState

AGENT_TYPES = {
    AgentType.VEHICLE: "vehicle",
    AgentType.PEDESTRIAN: "pedestrian",
    AgentType.CYCLIST: "cyclist",
    AgentType.OTHER: "other",
}

_SPECIAL = {
    MapFeatureType.CROSSWALK: "crosswalk",
    MapFeatureType.STOP_SIGN: "stop_sign",
    MapFeatureType.SPEED_BUMP: "speed_bump",
    MapFeatureType.DRIVEWAY: "driveway",
}


def map_type(kind: MapFeatureType) -> str:
    """The page's name of a map feature type: lane, road_line, road_edge, or the special feature's own."""
    if kind.is_lane:
        return "lane"
    if kind.is_road_line:
        return "road_line"
    if kind.is_road_edge:
        return "road_edge"
    return _SPECIAL[kind]


def light_state(value: int) -> str:
    """stop, caution, go or unknown for a `TrafficLightState` value."""
    state = TrafficLightState(int(value))
    if state.is_stop:
        return "stop"
    if state.is_caution:
        return "caution"
    return "go" if state.is_go else "unknown"


def _round(values: np.ndarray, digits: int = 2) -> list:
    return np.round(np.asarray(values, np.float64), digits).tolist()


def scene_view(key: str, scenario: Scenario) -> dict[str, Any]:
    """The JSON of `GET /api/scenes/{key}`."""
    agents = scenario.agents
    c = scenario.current_index
    sim = set(sim_agent_indices(scenario).tolist())
    out_agents = []
    seen: list[np.ndarray] = []
    for row in range(scenario.num_agents):
        states = agents.states[row, : c + 1]
        valid = agents.valid[row, : c + 1]
        poses = np.round(states[:, [StateField.X, StateField.Y, StateField.HEADING]].astype(np.float64), 2)
        track = [p.tolist() if ok else None for p, ok in zip(poses, valid, strict=True)]
        if valid.any():
            seen.append(poses[valid, :2])
        size = agents.states[row, c] if agents.valid[row, c] else states[valid][-1] if valid.any() else states[-1]
        out_agents.append(
            {
                "id": int(agents.ids[row]),
                "type": AGENT_TYPES.get(AgentType(int(agents.types[row])), "other"),
                "length": round(float(size[StateField.LENGTH]), 2),
                "width": round(float(size[StateField.WIDTH]), 2),
                "sim": row in sim,
                "sdc": row == scenario.sdc_index,
                "track": track,
            }
        )
    features = []
    for feature in scenario.road_map:
        points = feature.points[:, :2]
        seen.append(points)
        features.append(
            {
                "type": map_type(feature.type),
                "dashed": feature.type.name.startswith("ROAD_LINE_BROKEN"),
                "points": _round(points),
            }
        )
    return {
        "key": key,
        "scenario_id": scenario.scenario_id,
        "current_step": c,
        "step_seconds": STEP_SECONDS,
        "bounds": _bounds(seen),
        "agents": out_agents,
        "map": features,
        "lights": _lights(scenario),
    }


def _bounds(parts: list[np.ndarray]) -> list[float]:
    """[xmin, ymin, xmax, ymax] of every point drawn ([0, 0, 0, 0] for an empty scene)."""
    points = np.concatenate([p.reshape(-1, 2) for p in parts]) if parts else np.zeros((0, 2))
    points = points[np.isfinite(points).all(-1)]
    if not len(points):
        return [0.0, 0.0, 0.0, 0.0]
    return _round(np.concatenate([points.min(0), points.max(0)]))


def _lights(scenario: Scenario) -> list[dict[str, Any]]:
    lights = scenario.traffic_lights
    if lights is None:
        return []
    states, known = lights.held_at(scenario.current_index)
    return [
        {"x": round(float(point[0]), 2), "y": round(float(point[1]), 2), "state": light_state(state)}
        for point, state, seen in zip(lights.stop_points, states, known, strict=True)
        if seen
    ]
