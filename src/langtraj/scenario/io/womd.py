"""Waymo Open Motion Dataset `Scenario` TFRecords, read and written without TensorFlow.

`scenario_from_proto` / `scenario_to_proto` map between the (wire-compatible) proto schema in
`proto/womd.proto` and our `Scenario`; `WomdFormat` frames them in TFRecord files. Lossy only where
our model is richer than WOMD: ROAD_EDGE_SIDEWALK is written as a boundary edge and lane polygons are
dropped (LangTraj's own extension fields keep events and metadata).

See docs/data.md.
"""

from __future__ import annotations

import json
import math
from collections.abc import Iterable, Iterator, Sequence
from pathlib import Path

import numpy as np
from google.protobuf.message import DecodeError

from langtraj.errors import InputError, ScenarioValidationError
from langtraj.scenario.io.base import ScenarioFormat, register_format
from langtraj.scenario.io.proto import womd_pb2 as pb
from langtraj.scenario.io.tfrecord import iter_records, looks_like_tfrecord, write_records
from langtraj.scenario.model import (
    Agents,
    BehaviorEvent,
    BoundarySegment,
    LaneNeighbor,
    MapFeature,
    RoadMap,
    Scenario,
    TrafficLights,
)
from langtraj.scenario.types import AgentType, MapFeatureType

# WOMD enum value <-> MapFeatureType, per oneof field of MapFeature.
_LANE_TYPES = {
    0: MapFeatureType.LANE_UNKNOWN,
    1: MapFeatureType.LANE_FREEWAY,
    2: MapFeatureType.LANE_SURFACE_STREET,
    3: MapFeatureType.LANE_BIKE_LANE,
}
_ROAD_LINE_TYPES = {v - MapFeatureType.ROAD_LINE_UNKNOWN: MapFeatureType(v) for v in range(10, 19)}
_ROAD_EDGE_TYPES = {
    0: MapFeatureType.ROAD_EDGE_UNKNOWN,
    1: MapFeatureType.ROAD_EDGE_BOUNDARY,
    2: MapFeatureType.ROAD_EDGE_MEDIAN,
}
_AREA_FIELDS = {
    "crosswalk": MapFeatureType.CROSSWALK,
    "speed_bump": MapFeatureType.SPEED_BUMP,
    "driveway": MapFeatureType.DRIVEWAY,
}


def _inverse(mapping: dict[int, MapFeatureType]) -> dict[MapFeatureType, int]:
    return {v: k for k, v in mapping.items()}


_LANE_VALUES = _inverse(_LANE_TYPES)
_ROAD_LINE_VALUES = _inverse(_ROAD_LINE_TYPES)
_ROAD_EDGE_VALUES = {**_inverse(_ROAD_EDGE_TYPES), MapFeatureType.ROAD_EDGE_SIDEWALK: 1}
_AREA_NAMES = {v: k for k, v in _AREA_FIELDS.items()}


# ---------------------------------------------------------------------------- proto -> model


def _points(points: Sequence[pb.MapPoint]) -> np.ndarray:
    return np.array([(p.x, p.y, p.z) for p in points], np.float64).reshape(-1, 3)


def _boundaries(segments: Sequence[pb.BoundarySegment]) -> tuple[BoundarySegment, ...]:
    return tuple(
        BoundarySegment(s.lane_start_index, s.lane_end_index, s.boundary_feature_id, _ROAD_LINE_TYPES[s.boundary_type])
        for s in segments
    )


def _neighbors(neighbors: Sequence[pb.LaneNeighbor]) -> tuple[LaneNeighbor, ...]:
    return tuple(
        LaneNeighbor(
            n.feature_id,
            n.self_start_index,
            n.self_end_index,
            n.neighbor_start_index,
            n.neighbor_end_index,
            _boundaries(n.boundaries),
        )
        for n in neighbors
    )


def _map_feature(msg: pb.MapFeature) -> MapFeature:
    kind = msg.WhichOneof("feature_data")
    if kind == "lane":
        lane = msg.lane
        return MapFeature(
            id=msg.id,
            type=_LANE_TYPES[lane.type],
            points=_points(lane.polyline),
            entry_lanes=tuple(lane.entry_lanes),
            exit_lanes=tuple(lane.exit_lanes),
            left_neighbors=_neighbors(lane.left_neighbors),
            right_neighbors=_neighbors(lane.right_neighbors),
            left_boundaries=_boundaries(lane.left_boundaries),
            right_boundaries=_boundaries(lane.right_boundaries),
            speed_limit_mph=lane.speed_limit_mph if lane.HasField("speed_limit_mph") else math.nan,
            interpolating=lane.interpolating,
        )
    if kind == "road_line":
        return MapFeature(msg.id, _ROAD_LINE_TYPES[msg.road_line.type], _points(msg.road_line.polyline))
    if kind == "road_edge":
        return MapFeature(msg.id, _ROAD_EDGE_TYPES[msg.road_edge.type], _points(msg.road_edge.polyline))
    if kind == "stop_sign":
        sign = msg.stop_sign
        return MapFeature(msg.id, MapFeatureType.STOP_SIGN, _points([sign.position]), controlled_lanes=tuple(sign.lane))
    if kind in _AREA_FIELDS:
        return MapFeature(msg.id, _AREA_FIELDS[kind], _points(getattr(msg, kind).polygon))
    raise ScenarioValidationError("map feature has no feature data", where=f"map feature {msg.id}")


def _traffic_lights(states: Sequence[pb.DynamicMapState], num_steps: int) -> TrafficLights:
    """Dense [T, L] signal states; steps past the end of `states` have no valid lane."""
    if len(states) > num_steps:
        raise ScenarioValidationError(
            f"{len(states)} dynamic map states for {num_steps} timestamps", where="dynamic_map_states"
        )
    lane_index: dict[int, int] = {}
    stop_points: list[tuple[float, float, float]] = []
    for step in states:
        for lane in step.lane_states:
            if lane.lane not in lane_index:
                lane_index[lane.lane] = len(lane_index)
                sp = lane.stop_point
                stop_points.append((sp.x, sp.y, sp.z))
    values = np.zeros((num_steps, len(lane_index)), np.int8)
    valid = np.zeros((num_steps, len(lane_index)), bool)
    for t, step in enumerate(states):
        for lane in step.lane_states:
            values[t, lane_index[lane.lane]] = lane.state
            valid[t, lane_index[lane.lane]] = True
    return TrafficLights(
        np.fromiter(lane_index, np.int64, len(lane_index)), values, valid, np.reshape(stop_points, (-1, 3))
    )


def _agents(msg: pb.Scenario, num_steps: int) -> Agents:
    states = np.zeros((len(msg.tracks), num_steps, 9), np.float32)
    valid = np.zeros((len(msg.tracks), num_steps), bool)
    for a, track in enumerate(msg.tracks):
        if len(track.states) != num_steps:
            raise ScenarioValidationError(
                f"{len(track.states)} states for {num_steps} timestamps", where=f"track {track.id}"
            )
        if num_steps:
            states[a] = [
                (
                    s.center_x,
                    s.center_y,
                    s.center_z,
                    s.heading,
                    s.velocity_x,
                    s.velocity_y,
                    s.length,
                    s.width,
                    s.height,
                )
                for s in track.states
            ]
            valid[a] = [s.valid for s in track.states]
    ids = np.array([t.id for t in msg.tracks], np.int64)
    types = np.array([t.object_type or AgentType.OTHER for t in msg.tracks], np.int8)
    id_to_index = {int(i): n for n, i in enumerate(ids)}
    unknown = [i for i in msg.objects_of_interest if i not in id_to_index]
    if unknown:
        raise ScenarioValidationError(f"track ids {unknown} are not in the scene", where="objects_of_interest")
    return Agents(
        ids=ids,
        types=types,
        states=states,
        valid=valid,
        tracks_to_predict=[p.track_index for p in msg.tracks_to_predict],
        prediction_difficulty=[p.difficulty for p in msg.tracks_to_predict],
        objects_of_interest=[id_to_index[i] for i in msg.objects_of_interest],
    )


def scenario_from_proto(msg: pb.Scenario) -> Scenario:
    """Our Scenario from a decoded WOMD `Scenario` message (raises ScenarioValidationError)."""
    num_steps = len(msg.timestamps_seconds)
    events = tuple(
        BehaviorEvent(
            e.kind,
            e.track_id,
            e.start_index,
            e.end_index,
            e.other_id if e.HasField("other_id") else -1,
            json.loads(e.attributes_json) if e.attributes_json else {},
        )
        for e in msg.langtraj_events
    )
    return Scenario(
        scenario_id=msg.scenario_id,
        timestamps=np.array(msg.timestamps_seconds, np.float64),
        current_index=msg.current_time_index,
        sdc_index=msg.sdc_track_index if msg.HasField("sdc_track_index") else -1,
        agents=_agents(msg, num_steps),
        road_map=RoadMap(tuple(_map_feature(f) for f in msg.map_features)),
        traffic_lights=_traffic_lights(msg.dynamic_map_states, num_steps),
        events=events,
        metadata=json.loads(msg.langtraj_metadata_json) if msg.langtraj_metadata_json else {},
        source_format=WomdFormat.name,
    )


def decode_scenario(payload: bytes) -> pb.Scenario:
    """Parse one record's bytes as a `Scenario` message (raises ScenarioValidationError)."""
    msg = pb.Scenario()
    try:
        msg.ParseFromString(payload)
    except DecodeError as exc:
        raise ScenarioValidationError(f"cannot decode a Scenario proto: {exc}") from None
    if not msg.scenario_id or not msg.timestamps_seconds:
        raise ScenarioValidationError("record holds no WOMD Scenario (no scenario_id or no timestamps)")
    return msg


# ---------------------------------------------------------------------------- model -> proto


def _set_points(target, points: np.ndarray) -> None:
    target.extend(pb.MapPoint(x=x, y=y, z=z) for x, y, z in points.tolist())


def _boundary_msgs(segments: Iterable[BoundarySegment]) -> list[pb.BoundarySegment]:
    return [
        pb.BoundarySegment(
            lane_start_index=s.lane_start_index,
            lane_end_index=s.lane_end_index,
            boundary_feature_id=s.boundary_feature_id,
            boundary_type=_ROAD_LINE_VALUES[s.boundary_type],
        )
        for s in segments
    ]


def _neighbor_msgs(neighbors: Iterable[LaneNeighbor]) -> list[pb.LaneNeighbor]:
    return [
        pb.LaneNeighbor(
            feature_id=n.feature_id,
            self_start_index=n.self_start_index,
            self_end_index=n.self_end_index,
            neighbor_start_index=n.neighbor_start_index,
            neighbor_end_index=n.neighbor_end_index,
            boundaries=_boundary_msgs(n.boundaries),
        )
        for n in neighbors
    ]


def _map_feature_msg(feature: MapFeature) -> pb.MapFeature:
    msg = pb.MapFeature(id=feature.id)
    ftype = feature.type
    if ftype.is_lane:
        lane = msg.lane
        lane.type = _LANE_VALUES[ftype]
        if not math.isnan(feature.speed_limit_mph):
            lane.speed_limit_mph = feature.speed_limit_mph
        lane.interpolating = feature.interpolating
        _set_points(lane.polyline, feature.points)
        lane.entry_lanes.extend(feature.entry_lanes)
        lane.exit_lanes.extend(feature.exit_lanes)
        lane.left_neighbors.extend(_neighbor_msgs(feature.left_neighbors))
        lane.right_neighbors.extend(_neighbor_msgs(feature.right_neighbors))
        lane.left_boundaries.extend(_boundary_msgs(feature.left_boundaries))
        lane.right_boundaries.extend(_boundary_msgs(feature.right_boundaries))
    elif ftype.is_road_line:
        msg.road_line.type = _ROAD_LINE_VALUES[ftype]
        _set_points(msg.road_line.polyline, feature.points)
    elif ftype.is_road_edge:
        msg.road_edge.type = _ROAD_EDGE_VALUES[ftype]
        _set_points(msg.road_edge.polyline, feature.points)
    elif ftype is MapFeatureType.STOP_SIGN:
        x, y, z = feature.points[0].tolist() if len(feature.points) else (0.0, 0.0, 0.0)
        msg.stop_sign.position.CopyFrom(pb.MapPoint(x=x, y=y, z=z))
        msg.stop_sign.lane.extend(feature.controlled_lanes)
    else:
        _set_points(getattr(msg, _AREA_NAMES[ftype]).polygon, feature.points)
    return msg


def scenario_to_proto(scenario: Scenario) -> pb.Scenario:
    """A WOMD `Scenario` message holding everything of `scenario` that WOMD can hold."""
    agents = scenario.agents
    msg = pb.Scenario(
        scenario_id=scenario.scenario_id,
        timestamps_seconds=scenario.timestamps.tolist(),
        current_time_index=scenario.current_index,
        objects_of_interest=agents.ids[agents.objects_of_interest].tolist(),
        tracks_to_predict=[
            pb.RequiredPrediction(track_index=i, difficulty=d)
            for i, d in zip(agents.tracks_to_predict.tolist(), agents.prediction_difficulty.tolist(), strict=True)
        ],
    )
    if scenario.sdc_index >= 0:
        msg.sdc_track_index = scenario.sdc_index
    for track_id, agent_type, states, valid in zip(
        agents.ids.tolist(), agents.types.tolist(), agents.states.tolist(), agents.valid.tolist(), strict=True
    ):
        track = msg.tracks.add(id=track_id, object_type=agent_type)
        track.states.extend(
            pb.ObjectState(
                center_x=s[0],
                center_y=s[1],
                center_z=s[2],
                heading=s[3],
                velocity_x=s[4],
                velocity_y=s[5],
                length=s[6],
                width=s[7],
                height=s[8],
                valid=v,
            )
            for s, v in zip(states, valid, strict=True)
        )
    msg.map_features.extend(_map_feature_msg(f) for f in scenario.road_map)
    lights = scenario.traffic_lights
    stop_points = [pb.MapPoint(x=x, y=y, z=z) for x, y, z in lights.stop_points.tolist()]
    for t in range(scenario.num_steps):
        step = msg.dynamic_map_states.add()
        for lane in np.flatnonzero(lights.valid[t]).tolist():
            step.lane_states.add(
                lane=int(lights.lane_ids[lane]),
                state=int(lights.states[t, lane]),
                stop_point=stop_points[lane],
            )
    for event in scenario.events:
        msg.langtraj_events.add(
            kind=event.kind,
            track_id=event.track_id,
            start_index=event.start,
            end_index=event.end,
            other_id=event.other_id,
            attributes_json=json.dumps(dict(event.attributes), sort_keys=True),
        )
    if scenario.metadata:
        msg.langtraj_metadata_json = json.dumps(scenario.metadata, sort_keys=True)
    return msg


# ---------------------------------------------------------------------------- the format


@register_format
class WomdFormat(ScenarioFormat):
    """TFRecord files of WOMD `Scenario` protos (one scenario per record)."""

    name = "womd"
    suffixes = (".tfrecord", ".tfrecords")

    @classmethod
    def sniff(cls, head: bytes) -> bool:
        return looks_like_tfrecord(head)

    def read(self, path: Path, *, start: int = 0) -> Iterator[Scenario]:
        for index, payload in enumerate(iter_records(path, start=start), start=start):
            yield self._decode(payload, path, index)

    def read_one(self, path: Path, index: int) -> Scenario:
        for scenario in self.read(path, start=index):
            return scenario
        raise InputError(f"no scenario at index {index}", path=path)

    @staticmethod
    def _decode(payload: bytes, path: Path, index: int) -> Scenario:
        try:
            return scenario_from_proto(decode_scenario(payload))
        except ScenarioValidationError as exc:
            raise exc.located(path=path, where=f"record {index}") from None

    def write(self, path: Path, scenarios: Iterable[Scenario], *, compress: bool = False) -> int:
        return write_records(path, (scenario_to_proto(s).SerializeToString() for s in scenarios), compress=compress)
