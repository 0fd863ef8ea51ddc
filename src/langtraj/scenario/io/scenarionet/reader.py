"""The ScenarioNet reader: a ScenarioNet scenario dict -> our Scenario (`scenario_from_dict`), with
source keys, type strings and metadata kept under metadata['scenarionet']. See docs/data.md.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Mapping
from typing import Any

import numpy as np

from langtraj.errors import InputError, ScenarioValidationError
from langtraj.scenario.io.scenarionet.common import (
    _AGENT_TYPES,
    _BOUNDARY_TYPES,
    _DERIVED_METADATA,
    _KMH_PER_MPH,
    _LIGHT_STATES,
    _MAP_TYPE_NAMES,
    _MAP_TYPES,
    DEFAULT_CURRENT_INDEX,
    FORMAT_NAME,
    FORMAT_VERSION,
    _is_int_key,
)
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
from langtraj.scenario.types import AgentType, MapFeatureType, StateField

# ---------------------------------------------------------------------------- dict -> model


def _mapping(value: Any, path: str, where: str) -> Mapping:
    if not isinstance(value, Mapping):
        raise InputError(f"expected a dict, got {type(value).__name__}", path=path, where=where)
    return value


def _int(value: Any, path: str, where: str) -> int:
    """An integer from an int or a decimal string (ScenarioNet stores lane indices as strings)."""
    try:
        return int(value)
    except (TypeError, ValueError):
        raise InputError(f"expected an integer, got {value!r}", path=path, where=where) from None


def _floats(value: Any, path: str, where: str) -> np.ndarray:
    try:
        return np.asarray(value, np.float64)
    except (TypeError, ValueError) as exc:
        raise InputError(f"expected numbers: {exc}", path=path, where=where) from None


class _Keys:
    """Source keys and our integer ids for them: the keys themselves when all are canonical decimal
    integers, else positions 0..n-1 (and the keys then go to metadata)."""

    def __init__(self, keys: Iterable[Any]):
        self.keys = [str(k) for k in keys]
        self.numeric = all(_is_int_key(k) for k in self.keys)
        self.ids = [int(k) for k in self.keys] if self.numeric else list(range(len(self.keys)))
        self._by_key = dict(zip(self.keys, self.ids, strict=True))
        self.position_of = {key: n for n, key in enumerate(self.keys)}
        """Position of each key in file order (the agent index of a track key)."""

    def id_of(self, ref: Any) -> int | None:
        """Our id for a reference to a key (int or str); None when it resolves to nothing. With numeric
        keys a reference to an absent feature keeps its integer id, as WOMD does."""
        key = str(ref)
        found = self._by_key.get(key)
        if found is None and self.numeric and _is_int_key(key):
            return int(key)
        return found


def _check_top_level(d: Any, path: str) -> None:
    if not isinstance(d, Mapping):
        raise InputError(f"not a ScenarioNet scenario (top level is a {type(d).__name__}, not a dict)", path=path)
    for key in ("tracks", "map_features", "metadata"):
        if key not in d:
            raise InputError(f"not a ScenarioNet scenario (missing key {key!r})", path=path)


def _num_steps(d: Mapping, tracks: Mapping, meta: Mapping, path: str) -> int:
    """Steps of the scene: the top-level 'length', else the first track's, else the timestamps'."""
    if d.get("length") is not None:
        return _int(d["length"], path, "length")
    for track in tracks.values():
        if isinstance(track, Mapping) and isinstance(track.get("state"), Mapping):
            return len(_floats(track["state"].get("position", ()), path, "tracks"))
    return len(_floats(meta.get("ts", ()), path, "metadata.ts"))


def _state_column(
    state: Mapping, name: str, num_steps: int, widths: tuple[int, ...], path: str, where: str
) -> np.ndarray | None:
    """state[name] as [T, width] float64 ([T] and [T, 1] are both width 1), or None when absent."""
    if state.get(name) is None:
        return None
    arr = _floats(state[name], path, f"{where}.{name}")
    if arr.ndim == 1:
        arr = arr[:, None]
    if arr.ndim != 2 or arr.shape[0] != num_steps or arr.shape[1] not in widths:
        shapes = " or ".join(f"[{num_steps}, {w}]" for w in widths)
        raise InputError(f"expected shape {shapes}, got {list(arr.shape)}", path=path, where=f"{where}.{name}")
    return arr


def _track_states(state: Mapping, num_steps: int, path: str, where: str) -> tuple[np.ndarray, np.ndarray]:
    """One track's [T, 9] states and [T] valid flags. Position, heading and valid are required (as
    in ScenarioNet); missing velocity or sizes read as 0."""

    def optional(name: str, widths: tuple[int, ...]) -> np.ndarray | None:
        return _state_column(state, name, num_steps, widths, path, where)

    def required(name: str, widths: tuple[int, ...]) -> np.ndarray:
        arr = optional(name, widths)
        if arr is None:
            raise InputError(f"missing state field {name!r}", path=path, where=where)
        return arr

    out = np.zeros((num_steps, len(StateField)), np.float64)
    position = required("position", (2, 3))
    out[:, StateField.X : StateField.X + position.shape[1]] = position
    out[:, StateField.HEADING] = required("heading", (1,))[:, 0]
    valid = required("valid", (1,))[:, 0] != 0
    velocity = optional("velocity", (2, 3))
    if velocity is not None:
        out[:, StateField.VX : StateField.VY + 1] = velocity[:, :2]
    for field in (StateField.LENGTH, StateField.WIDTH, StateField.HEIGHT):
        size = optional(field.name.lower(), (1,))
        if size is not None:
            out[:, field] = size[:, 0]
    _check_pose(out, valid, path, where)
    return out, valid


def _check_pose(states: np.ndarray, valid: np.ndarray, path: str, where: str) -> None:
    """Reject a NaN or infinite position or heading on a valid step, naming the source track key
    (the model's own check could only name our renumbered id)."""
    pose = states[:, : StateField.HEADING + 1]
    bad = valid & ~np.isfinite(pose).all(axis=1)
    if bad.any():
        t = int(np.argmax(bad))
        field = StateField(int(np.argmin(np.isfinite(pose[t]))))
        raise ScenarioValidationError(
            f"non-finite {field.name.lower()} = {pose[t, field]} for a valid state",
            path=path,
            where=f"{where}, step {t}",
        )


def _track_index(ref: Any, index: Mapping[str, int], path: str, where: str) -> int:
    """The agent index of a track key named in metadata; an unknown key is an error, not skipped."""
    try:
        return index[str(ref)]
    except KeyError:
        raise InputError(f"unknown track key {ref!r}", path=path, where=where) from None


def _tracks_to_predict(raw: Any, index: Mapping[str, int], path: str) -> tuple[list[int], list[int]]:
    """Agent indices and difficulties of metadata['tracks_to_predict'] (a dict key -> info, or a list
    of keys)."""
    where = "metadata.tracks_to_predict"
    if raw is None:
        return [], []
    items = raw.items() if isinstance(raw, Mapping) else ((key, {}) for key in raw)
    indices, difficulty = [], []
    for key, info in items:
        indices.append(_track_index(key, index, path, where))
        info = _mapping(info, path, f"{where}[{key!r}]")
        difficulty.append(_int(info.get("difficulty", 0), path, f"{where}[{key!r}].difficulty"))
    return indices, difficulty


def _agents(tracks: Mapping, keys: _Keys, meta: Mapping, num_steps: int, path: str) -> tuple[Agents, list[str]]:
    """The agents, and each track's type string as in the file."""
    states = np.zeros((len(keys.keys), num_steps, len(StateField)), np.float32)
    valid = np.zeros((len(keys.keys), num_steps), bool)
    type_strings = []
    for n, (key, track) in enumerate(zip(keys.keys, tracks.values(), strict=True)):
        where = f"track {key!r}"
        track = _mapping(track, path, where)
        if track.get("type") is None:
            raise InputError("missing 'type'", path=path, where=where)
        type_strings.append(str(track["type"]))
        state = _mapping(track.get("state"), path, f"{where}.state")
        states[n], valid[n] = _track_states(state, num_steps, path, where)
    index = keys.position_of
    ttp, difficulty = _tracks_to_predict(meta.get("tracks_to_predict"), index, path)
    ooi = [_track_index(k, index, path, "metadata.objects_of_interest") for k in meta.get("objects_of_interest") or ()]
    agents = Agents(
        ids=np.array(keys.ids, np.int64),
        types=np.array([_AGENT_TYPES.get(s, AgentType.OTHER) for s in type_strings], np.int8),
        states=states,
        valid=valid,
        tracks_to_predict=np.array(ttp, np.int64),
        prediction_difficulty=np.array(difficulty, np.int8),
        objects_of_interest=np.array(ooi, np.int64),
    )
    return agents, type_strings


def _speed_limit_mph(raw: Mapping) -> float:
    """speed_limit_mph, else speed_limit_kmh converted (nuScenes has only that), else NaN."""
    if raw.get("speed_limit_mph") is not None:
        return float(raw["speed_limit_mph"])
    if raw.get("speed_limit_kmh") is not None:
        return float(raw["speed_limit_kmh"]) / _KMH_PER_MPH
    return math.nan


def _light_states(raw: Any, num_steps: int, path: str, where: str) -> tuple[np.ndarray, np.ndarray]:
    """[T] state values and valid flags from a light's 'object_state' (strings, ints, or None for
    steps the source did not report)."""
    values = _mapping(raw, path, f"{where}.state").get("object_state")
    where = f"{where}.state.object_state"
    if values is None or len(values) != num_steps:
        count = "missing" if values is None else f"{len(values)} entries"
        raise InputError(f"expected {num_steps} states, got {count}", path=path, where=where)
    states = np.zeros(num_steps, np.int8)
    valid = np.zeros(num_steps, bool)
    for t, value in enumerate(values):
        if value is None:
            continue
        if isinstance(value, str):
            state = _LIGHT_STATES.get(value)
        else:
            state = int(value) if isinstance(value, int | np.integer) and 0 <= value <= 8 else None
        if state is None:
            raise InputError(f"unknown traffic light state {value!r}", path=path, where=f"{where}[{t}]")
        states[t], valid[t] = state, True
    return states, valid


class _MapReader:
    """Converts map features and traffic lights, resolving references through the map's keys and
    counting those that resolve to nothing (they are dropped)."""

    def __init__(self, features: Mapping, path: str):
        self.features = features
        self.path = path
        self.keys = _Keys(features)
        self.dropped = 0

    def road_map(self) -> tuple[RoadMap, list[str]]:
        """The road map, and each feature's type string as in the file."""
        out, type_strings = [], []
        for key, fid, raw in zip(self.keys.keys, self.keys.ids, self.features.values(), strict=True):
            where = f"map feature {key!r}"
            raw = _mapping(raw, self.path, where)
            ftype = _MAP_TYPES.get(str(raw.get("type")))
            if ftype is None:
                raise InputError(f"unknown map feature type {raw.get('type')!r}", path=self.path, where=f"{where}.type")
            type_strings.append(str(raw["type"]))
            try:
                out.append(self._feature(fid, ftype, raw, where))
            except ScenarioValidationError as exc:
                raise exc.located(path=self.path, where=where) from None
        return RoadMap(tuple(out)), type_strings

    def _feature(self, fid: int, ftype: MapFeatureType, raw: Mapping, where: str) -> MapFeature:
        if ftype is MapFeatureType.STOP_SIGN:
            points = self._points(raw, ("position",), where)
            return MapFeature(fid, ftype, points, controlled_lanes=self._refs(raw.get("lane"), f"{where}.lane"))
        if ftype.is_lane:
            names: tuple[str, ...] = ("polyline",)
        else:
            names = ("polygon", "polyline") if ftype.is_area else ("polyline", "polygon")
        points = self._points(raw, names, where)
        if not ftype.is_lane:
            return MapFeature(fid, ftype, points)
        polygon = self._points(raw, ("polygon",), where) if raw.get("polygon") is not None else None
        return MapFeature(
            fid,
            ftype,
            points,
            entry_lanes=self._refs(raw.get("entry_lanes"), f"{where}.entry_lanes"),
            exit_lanes=self._refs(raw.get("exit_lanes"), f"{where}.exit_lanes"),
            left_neighbors=self._neighbors(raw.get("left_neighbor"), f"{where}.left_neighbor"),
            right_neighbors=self._neighbors(raw.get("right_neighbor"), f"{where}.right_neighbor"),
            left_boundaries=self._boundaries(raw.get("left_boundaries"), f"{where}.left_boundaries"),
            right_boundaries=self._boundaries(raw.get("right_boundaries"), f"{where}.right_boundaries"),
            speed_limit_mph=_speed_limit_mph(raw),
            interpolating=bool(raw.get("interpolating", False)),
            polygon=polygon,
        )

    def _points(self, raw: Mapping, names: tuple[str, ...], where: str) -> np.ndarray:
        """The first of raw[names] present, as float64 (the model checks shape and finiteness)."""
        for name in names:
            if raw.get(name) is not None:
                return _floats(raw[name], self.path, f"{where}.{name}")
        raise InputError(f"missing {' or '.join(repr(n) for n in names)}", path=self.path, where=where)

    def _ref(self, ref: Any) -> int | None:
        fid = self.keys.id_of(ref)
        if fid is None:
            self.dropped += 1
        return fid

    def _refs(self, refs: Any, where: str) -> tuple[int, ...]:
        if refs is None:
            return ()
        if isinstance(refs, str | bytes) or not isinstance(refs, Iterable):
            raise InputError(f"expected a list of feature ids, got {refs!r}", path=self.path, where=where)
        return tuple(fid for fid in map(self._ref, refs) if fid is not None)

    def _boundaries(self, items: Any, where: str) -> tuple[BoundarySegment, ...]:
        out = []
        for n, item in enumerate(items or ()):
            at = f"{where}[{n}]"
            item = _mapping(item, self.path, at)
            btype = _BOUNDARY_TYPES.get(str(item.get("boundary_type")))
            if btype is None:
                raise InputError(
                    f"unknown boundary type {item.get('boundary_type')!r}",
                    path=self.path,
                    where=f"{at}.boundary_type",
                )
            fid = self._ref(item.get("boundary_feature_id"))
            if fid is not None:
                start = _int(item.get("lane_start_index"), self.path, f"{at}.lane_start_index")
                end = _int(item.get("lane_end_index"), self.path, f"{at}.lane_end_index")
                out.append(BoundarySegment(start, end, fid, btype))
        return tuple(out)

    def _neighbors(self, items: Any, where: str) -> tuple[LaneNeighbor, ...]:
        out = []
        for n, item in enumerate(items or ()):
            at = f"{where}[{n}]"
            item = _mapping(item, self.path, at)
            fid = self._ref(item.get("feature_id"))
            if fid is None:
                continue
            spans = [
                _int(item.get(name), self.path, f"{at}.{name}")
                for name in (
                    "self_start_index",
                    "self_end_index",
                    "neighbor_start_index",
                    "neighbor_end_index",
                )
            ]
            out.append(
                LaneNeighbor(fid, *spans, boundaries=self._boundaries(item.get("boundaries"), f"{at}.boundaries"))
            )
        return tuple(out)

    def traffic_lights(self, states: Mapping, num_steps: int) -> TrafficLights:
        """One light per dynamic map state; a light whose lane resolves to nothing is dropped."""
        lanes, values, valid, stops = [], [], [], []
        for key, raw in states.items():
            where = f"dynamic_map_states[{str(key)!r}]"
            raw = _mapping(raw, self.path, where)
            if raw.get("type", "TRAFFIC_LIGHT") != "TRAFFIC_LIGHT":
                raise InputError(
                    f"unsupported dynamic state type {raw['type']!r}", path=self.path, where=f"{where}.type"
                )
            lane = self._ref(raw.get("lane"))
            if lane is None:
                continue
            stop = _floats(raw.get("stop_point", ()), self.path, f"{where}.stop_point").ravel()
            if stop.shape not in ((2,), (3,)):
                raise InputError(
                    f"expected 2 or 3 coordinates, got {stop.shape}",
                    path=self.path,
                    where=f"{where}.stop_point",
                )
            light_states, light_valid = _light_states(raw.get("state"), num_steps, self.path, where)
            lanes.append(lane)
            values.append(light_states)
            valid.append(light_valid)
            stops.append(np.pad(stop, (0, 3 - len(stop))))
        if not lanes:
            return TrafficLights.empty(num_steps)
        return TrafficLights(np.array(lanes), np.stack(values, axis=1), np.stack(valid, axis=1), np.stack(stops))


def _source_metadata(meta: Mapping) -> dict[str, Any]:
    """The JSON-compatible scalars of the source metadata that the writer does not recompute."""
    out = {}
    for key, value in meta.items():
        value = value.item() if isinstance(value, np.generic) else value
        scalar = (
            value is None or isinstance(value, str | bool | int) or (isinstance(value, float) and math.isfinite(value))
        )
        if scalar and key not in _DERIVED_METADATA:
            out[str(key)] = value
    return out


def _langtraj_section(raw: Any, path: str) -> tuple[dict[str, Any], tuple[BehaviorEvent, ...]]:
    """Metadata and events that `scenario_to_dict` stored under metadata['langtraj']."""
    if raw is None:
        return {}, ()
    raw = _mapping(raw, path, "metadata.langtraj")
    events = []
    for n, item in enumerate(raw.get("events") or ()):
        try:
            events.append(BehaviorEvent(**_mapping(item, path, f"metadata.langtraj.events[{n}]")))
        except TypeError as exc:
            raise InputError(str(exc), path=path, where=f"metadata.langtraj.events[{n}]") from None
    return dict(_mapping(raw.get("metadata") or {}, path, "metadata.langtraj.metadata")), tuple(events)


def _timestamps(meta: Mapping, num_steps: int, path: str) -> np.ndarray:
    if meta.get("ts") is None:
        return np.arange(num_steps) * STEP_SECONDS
    ts = _floats(meta["ts"], path, "metadata.ts").ravel()
    if len(ts) != num_steps:
        raise InputError(f"{len(ts)} timestamps for {num_steps} steps", path=path, where="metadata.ts")
    return ts


def _differs(originals: list[str], canonical: list[str]) -> list[str] | None:
    """The file's strings when any differs from what the writer would write, else None."""
    return originals if originals != canonical else None


def _scenarionet_metadata(
    d: Mapping,
    meta: Mapping,
    *,
    track_keys: _Keys,
    map_reader: _MapReader,
    track_types: list[str] | None,
    map_types: list[str] | None,
) -> dict[str, Any]:
    """metadata['scenarionet']: what the writer needs to restore the file's keys, types and metadata."""
    out: dict[str, Any] = {
        "version": str(d.get("version") or FORMAT_VERSION),
        "source_metadata": _source_metadata(meta),
    }
    optional = {
        "track_keys": None if track_keys.numeric else track_keys.keys,
        "track_types": track_types,
        "map_keys": None if map_reader.keys.numeric else map_reader.keys.keys,
        "map_types": map_types,
        "dropped_references": map_reader.dropped or None,
    }
    out.update((k, v) for k, v in optional.items() if v is not None)
    return out


def _current_index(meta: Mapping, num_steps: int, path: str) -> int:
    """metadata['current_time_index'], else DEFAULT_CURRENT_INDEX (clipped to short scenes)."""
    if meta.get("current_time_index") is None:
        return min(DEFAULT_CURRENT_INDEX, max(num_steps - 1, 0))
    return _int(meta["current_time_index"], path, "metadata.current_time_index")


def scenario_from_dict(d: Any, *, where: str) -> Scenario:
    """Our Scenario from a ScenarioNet scenario dict. `where` (the file) starts every error message,
    which also names the track, map feature or field at fault."""
    path = where
    _check_top_level(d, path)
    meta = _mapping(d["metadata"], path, "metadata")
    tracks = _mapping(d["tracks"], path, "tracks")
    dynamic = _mapping(d.get("dynamic_map_states") or {}, path, "dynamic_map_states")
    try:
        num_steps = _num_steps(d, tracks, meta, path)
        track_keys = _Keys(tracks)
        agents, track_types = _agents(tracks, track_keys, meta, num_steps, path)
        map_reader = _MapReader(_mapping(d["map_features"], path, "map_features"), path)
        road_map, map_types = map_reader.road_map()
        lights = map_reader.traffic_lights(dynamic, num_steps)
        sdc = meta.get("sdc_id")
        sdc_index = -1 if sdc is None else _track_index(sdc, track_keys.position_of, path, "metadata.sdc_id")
        extra_metadata, events = _langtraj_section(meta.get("langtraj"), path)
        sn_metadata = _scenarionet_metadata(
            d,
            meta,
            track_keys=track_keys,
            map_reader=map_reader,
            track_types=_differs(track_types, [AgentType(t).name for t in agents.types.tolist()]),
            map_types=_differs(map_types, [_MAP_TYPE_NAMES[f.type] for f in road_map]),
        )
        return Scenario(
            scenario_id=str(d.get("id") or meta.get("scenario_id") or ""),
            timestamps=_timestamps(meta, num_steps, path),
            current_index=_current_index(meta, num_steps, path),
            sdc_index=sdc_index,
            agents=agents,
            road_map=road_map,
            traffic_lights=lights,
            events=events,
            metadata={**extra_metadata, "scenarionet": sn_metadata},
            source_format=FORMAT_NAME,
        )
    except ScenarioValidationError as exc:
        raise exc.located(path=path) from None
