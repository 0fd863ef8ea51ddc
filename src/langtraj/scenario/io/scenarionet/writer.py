"""The ScenarioNet writer: our Scenario -> a ScenarioNet scenario dict (`scenario_to_dict`), restoring
the source keys, type strings and metadata kept under metadata['scenarionet']. See docs/data.md.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np

from langtraj.scenario.io.scenarionet.common import (
    _AGENT_TYPES,
    _BOUNDARY_NAMES,
    _KMH_PER_MPH,
    _MAP_TYPE_NAMES,
    _MAP_TYPES,
    FORMAT_VERSION,
    _is_int_key,
)
from langtraj.scenario.model import BehaviorEvent, BoundarySegment, LaneNeighbor, MapFeature, Scenario
from langtraj.scenario.types import AgentType, MapFeatureType, StateField, TrafficLightState

# ---------------------------------------------------------------------------- model -> dict


def _restored(values: Any, count: int) -> list[str] | None:
    """A list of `count` strings kept in metadata['scenarionet'], or None when it does not fit."""
    if isinstance(values, list) and len(values) == count and all(isinstance(v, str) for v in values):
        return values
    return None


@dataclass(frozen=True)
class _KeyWriter:
    """Our map feature ids -> the keys written: the file's original keys where known."""

    key_of: Mapping[int, str]
    numeric: bool

    def key(self, fid: int) -> str:
        return self.key_of.get(fid, str(fid))

    def ref(self, fid: int) -> int | str:
        """A reference in a plain id list (entry/exit lanes, stop sign and signal lanes): an int for
        numeric keys, as ScenarioNet writes WOMD ids."""
        key = self.key(fid)
        return int(key) if self.numeric and _is_int_key(key) else key


def _boundary_dicts(segments: Iterable[BoundarySegment], keys: _KeyWriter) -> list[dict[str, str]]:
    return [
        {
            "lane_start_index": str(s.lane_start_index),
            "lane_end_index": str(s.lane_end_index),
            "boundary_type": _BOUNDARY_NAMES[s.boundary_type],
            "boundary_feature_id": keys.key(s.boundary_feature_id),
        }
        for s in segments
    ]


def _neighbor_dicts(neighbors: Iterable[LaneNeighbor], keys: _KeyWriter) -> list[dict[str, Any]]:
    return [
        {
            "feature_id": keys.key(n.feature_id),
            "self_start_index": str(n.self_start_index),
            "self_end_index": str(n.self_end_index),
            "neighbor_start_index": str(n.neighbor_start_index),
            "neighbor_end_index": str(n.neighbor_end_index),
            "boundaries": _boundary_dicts(n.boundaries, keys),
        }
        for n in neighbors
    ]


def _feature_dict(feature: MapFeature, type_string: str, keys: _KeyWriter) -> dict[str, Any]:
    out: dict[str, Any] = {"type": type_string}
    points = feature.points.copy()
    if feature.type is MapFeatureType.STOP_SIGN:
        out["lane"] = [keys.ref(i) for i in feature.controlled_lanes]
        out["position"] = points[0] if len(points) == 1 else points
        return out
    out["polygon" if feature.type.is_area else "polyline"] = points
    if not feature.type.is_lane:
        return out
    if feature.polygon is not None:
        out["polygon"] = feature.polygon.copy()
    if not math.isnan(feature.speed_limit_mph):
        out["speed_limit_mph"] = feature.speed_limit_mph
        out["speed_limit_kmh"] = feature.speed_limit_mph * _KMH_PER_MPH
    out.update(
        interpolating=feature.interpolating,
        entry_lanes=[keys.ref(i) for i in feature.entry_lanes],
        exit_lanes=[keys.ref(i) for i in feature.exit_lanes],
        left_boundaries=_boundary_dicts(feature.left_boundaries, keys),
        right_boundaries=_boundary_dicts(feature.right_boundaries, keys),
    )
    if feature.left_neighbors or feature.right_neighbors:
        # MetaDrive reads a lane's width from its 'width' array (not written) when both neighbour
        # lists are present but empty; without them it falls back to a default width.
        out["left_neighbor"] = _neighbor_dicts(feature.left_neighbors, keys)
        out["right_neighbor"] = _neighbor_dicts(feature.right_neighbors, keys)
    return out


def _map_dicts(scenario: Scenario, sn: Mapping) -> tuple[dict[str, Any], dict[str, Any]]:
    """map_features and dynamic_map_states, under the original keys and type strings where known."""
    features = scenario.road_map.features
    map_keys = _restored(sn.get("map_keys"), len(features)) or [str(f.id) for f in features]
    originals = _restored(sn.get("map_types"), len(features)) or [""] * len(features)
    keys = _KeyWriter({f.id: k for f, k in zip(features, map_keys, strict=True)}, all(map(_is_int_key, map_keys)))
    map_features = {
        key: _feature_dict(f, orig if _MAP_TYPES.get(orig) is f.type else _MAP_TYPE_NAMES[f.type], keys)
        for key, f, orig in zip(map_keys, features, originals, strict=True)
    }
    lights = scenario.traffic_lights
    dynamic = {}
    for n, lane in enumerate(lights.lane_ids.tolist()):
        key = keys.key(lane)
        dynamic[key] = {
            "type": "TRAFFIC_LIGHT",
            "state": {
                "object_state": [
                    f"LANE_STATE_{TrafficLightState(s).name}" if ok else None
                    for s, ok in zip(lights.states[:, n].tolist(), lights.valid[:, n].tolist(), strict=True)
                ]
            },
            "lane": keys.ref(lane),
            "stop_point": lights.stop_points[n].copy(),
            "metadata": {"track_length": scenario.num_steps, "type": "TRAFFIC_LIGHT", "object_id": key},
        }
    return map_features, dynamic


def _track_dict(key: str, type_string: str, states: np.ndarray, valid: np.ndarray) -> dict[str, Any]:
    return {
        "type": type_string,
        "state": {
            "position": states[:, StateField.X : StateField.Z + 1].copy(),
            "heading": states[:, StateField.HEADING].copy(),
            "velocity": states[:, StateField.VX : StateField.VY + 1].copy(),
            "length": states[:, StateField.LENGTH].copy(),
            "width": states[:, StateField.WIDTH].copy(),
            "height": states[:, StateField.HEIGHT].copy(),
            "valid": valid.copy(),
        },
        "metadata": {"track_length": len(valid), "type": type_string, "object_id": key},
    }


def _number_summary(track_types: list[str], num_lights: int, num_features: int) -> dict[str, Any]:
    counts = {t: track_types.count(t) for t in sorted(set(track_types))}
    return {
        "num_objects": len(track_types),
        "object_types": set(counts),
        "num_objects_each_type": counts,
        "num_traffic_lights": num_lights,
        "num_map_features": num_features,
    }


def _metadata_dict(scenario: Scenario, sn: Mapping, track_keys: list[str], track_types: list[str]) -> dict[str, Any]:
    """The file's metadata: the kept source scalars, then everything derived from the scenario."""
    agents = scenario.agents
    meta: dict[str, Any] = {"coordinate": "waymo", "dataset": scenario.source_format or "langtraj"}
    meta.update(sn.get("source_metadata") or {})
    meta.update(
        id=scenario.scenario_id,
        scenario_id=scenario.scenario_id,
        ts=scenario.timestamps.copy(),
        metadrive_processed=False,
        track_length=scenario.num_steps,
        current_time_index=scenario.current_index,
        objects_of_interest=[track_keys[i] for i in agents.objects_of_interest.tolist()],
        tracks_to_predict={
            track_keys[i]: {
                "track_index": i,
                "track_id": track_keys[i],
                "difficulty": d,
                "object_type": track_types[i],
            }
            for i, d in zip(agents.tracks_to_predict.tolist(), agents.prediction_difficulty.tolist(), strict=True)
        },
        number_summary=_number_summary(track_types, scenario.traffic_lights.num_lanes, len(scenario.road_map)),
    )
    if scenario.sdc_index >= 0:
        meta.update(sdc_id=track_keys[scenario.sdc_index], sdc_track_index=scenario.sdc_index)
    extra = {k: v for k, v in scenario.metadata.items() if k != "scenarionet"}
    if extra or scenario.events:
        meta["langtraj"] = {"metadata": extra, "events": [_event_dict(e) for e in scenario.events]}
    return meta


def _event_dict(event: BehaviorEvent) -> dict[str, Any]:
    """An event as the keyword arguments of BehaviorEvent, for metadata['langtraj']['events']."""
    fields = ("kind", "track_id", "start", "end", "other_id")
    return {**{name: getattr(event, name) for name in fields}, "attributes": dict(event.attributes)}


def scenario_to_dict(scenario: Scenario) -> dict[str, Any]:
    """A ScenarioNet scenario dict (plain dicts, lists and numpy arrays) holding `scenario`; keys,
    type strings and source metadata kept in metadata['scenarionet'] are restored when they fit."""
    sn = scenario.metadata.get("scenarionet") or {}
    agents = scenario.agents
    track_keys = _restored(sn.get("track_keys"), agents.num_agents) or [str(i) for i in agents.ids.tolist()]
    originals = _restored(sn.get("track_types"), agents.num_agents) or [""] * agents.num_agents
    track_types = [
        orig if orig and _AGENT_TYPES.get(orig, AgentType.OTHER) == t else AgentType(t).name
        for orig, t in zip(originals, agents.types.tolist(), strict=True)
    ]
    tracks = {
        key: _track_dict(key, type_string, agents.states[n], agents.valid[n])
        for n, (key, type_string) in enumerate(zip(track_keys, track_types, strict=True))
    }
    map_features, dynamic = _map_dicts(scenario, sn)
    return {
        "id": scenario.scenario_id,
        "version": str(sn.get("version") or FORMAT_VERSION),
        "length": scenario.num_steps,
        "tracks": tracks,
        "dynamic_map_states": dynamic,
        "map_features": map_features,
        "metadata": _metadata_dict(scenario, sn, track_keys, track_types),
    }
