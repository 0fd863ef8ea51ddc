"""ScenarioNet / MetaDrive "scenario description" pickles: one scenario per file, loaded safely.

A ScenarioNet file is a pickled dict of dicts of numpy arrays ('tracks', 'map_features',
'dynamic_map_states', 'metadata'). Pickle can run code when loaded, so files are read with an
unpickler that admits numpy arrays and builtin containers and nothing else; the
`collections.defaultdict` (with a builtin default factory) and `collections.OrderedDict` that real
ScenarioNet files hold are rebuilt as plain dicts. docs/data.md describes the format and what is kept.

`scenario_from_dict` / `scenario_to_dict` map between that layout and our `Scenario`. Track and map
keys that are not all decimal integers (nuScenes tokens, UUIDs) are numbered 0..n-1 in file order and
kept, with type strings our enums do not hold (TRAFFIC_CONE, ...), under
`scenario.metadata["scenarionet"]`, so that reading then writing restores them. Events and other
metadata of our own travel in the pickle's `metadata["langtraj"]`.

Not kept: lane 'width' arrays, per-track metadata (nuScenes' fine-grained categories) and
'object_summary'. Map points are written as float64 [N, 3]. Under numpy 2 the written pickles name
`numpy._core`, which numpy >= 1.26.1 can load.
"""

from __future__ import annotations

import _compat_pickle
import itertools
import math
import pickle
import re
from collections.abc import Iterable, Iterator, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any, BinaryIO

import numpy as np

from langtraj.errors import InputError, ScenarioValidationError
from langtraj.fileio import atomic_open, open_input
from langtraj.scenario.io.base import ScenarioFormat, register_format
from langtraj.scenario.io.tfrecord import looks_like_tfrecord
from langtraj.scenario.model import (
    MPH_TO_MPS,
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

try:
    from numpy._core import multiarray as _multiarray
    from numpy._core import numeric as _numeric
except ImportError:  # numpy < 2
    from numpy.core import multiarray as _multiarray  # type: ignore[no-redef]
    from numpy.core import numeric as _numeric  # type: ignore[no-redef]

DEFAULT_CURRENT_INDEX = 10
"""Current step when the source has no `current_time_index`: the WOMD convention (1 s of history at
10 Hz). nuScenes scenes are longer (about 20 s) and get windowed later."""

FORMAT_VERSION = "MetaDrive v0.3.0.1"
"""The `version` written when the scenario did not come from a ScenarioNet file."""

PICKLE_PROTOCOL = 4

# ---------------------------------------------------------------------------- safe unpickling


def _encode_latin1(text: str, encoding: str = "latin1") -> bytes:
    """`_codecs.encode` as protocol 2 uses it to rebuild bytes; only latin-1 is accepted."""
    if encoding not in ("latin1", "latin-1"):
        raise pickle.UnpicklingError(f"refused _codecs.encode with encoding {encoding!r}")
    return text.encode("latin1")


_ALLOWED_GLOBALS: dict[tuple[str, str], Any] = {
    **{(f"numpy.{core}.multiarray", "_reconstruct"): _multiarray._reconstruct for core in ("core", "_core")},
    **{(f"numpy.{core}.multiarray", "scalar"): _multiarray.scalar for core in ("core", "_core")},
    **{(f"numpy.{core}.numeric", "_frombuffer"): _numeric._frombuffer for core in ("core", "_core")},
    ("numpy", "ndarray"): np.ndarray,
    ("numpy", "dtype"): np.dtype,
    ("_codecs", "encode"): _encode_latin1,
    ("builtins", "set"): set,
    ("builtins", "frozenset"): frozenset,
}
"""Every global a ScenarioNet pickle may name as a callable: what numpy arrays, numpy scalars and
(protocol 2) bytes and sets need to be rebuilt. None of them can import anything or run code of the
file's choosing. `collections.defaultdict` and `collections.OrderedDict` are admitted too, but rebuilt
as plain dicts (see `_RestrictedUnpickler`)."""

_DEFAULT_FACTORIES = frozenset(
    ("builtins", name) for name in ("list", "dict", "int", "float", "str", "tuple", "set", "frozenset")
) | {("collections", "OrderedDict"), ("collections", "defaultdict")}
"""The default factories a `collections.defaultdict` in a ScenarioNet file may name (protocol 2 spells
some the Python 2 way: `__builtin__.long`, `__builtin__.unicode`). Those that are not also in
`_ALLOWED_GLOBALS` resolve to a `_FactoryName` that cannot be called."""


@dataclass(frozen=True)
class _FactoryName:
    """A global admitted only as a defaultdict's default factory: calling it (a pickle REDUCE) is
    refused."""

    name: str
    path: Path

    def __call__(self, *args: Any, **kwargs: Any) -> Any:
        raise InputError(
            f"refused to call {self.name} from pickle (admitted only as a defaultdict's default factory)",
            path=self.path,
        )


def _python3_name(module: str, name: str) -> tuple[str, str]:
    """The Python 3 name of a global that protocol 2 spells the Python 2 way (`__builtin__.set`,
    `commands.Popen`), translated as the stock `Unpickler.find_class` does."""
    if (module, name) in _compat_pickle.NAME_MAPPING:
        return _compat_pickle.NAME_MAPPING[(module, name)]
    return _compat_pickle.IMPORT_MAPPING.get(module, module), name


class _RestrictedUnpickler(pickle.Unpickler):
    """An unpickler that resolves only `_ALLOWED_GLOBALS`, the two container classes and the default
    factories; any other global raises InputError.

    ScenarioNet writes some metadata, track and map dicts as `collections.defaultdict` or
    `collections.OrderedDict`. Both are rebuilt as plain dicts (the default factory is checked, then
    dropped), so the reader sees what a file of plain dicts gives and nothing of the file's choosing
    is ever called on a missing key.
    """

    def __init__(self, fh: BinaryIO, path: Path):
        super().__init__(fh)
        self._path = path
        self._resolved: dict[tuple[str, str], Any] = {}
        """Each global resolved so far: the same object every time the file names it."""

    def find_class(self, module: str, name: str) -> Any:
        key = _python3_name(module, name)
        if key not in self._resolved:
            self._resolved[key] = self._resolve(key)
        return self._resolved[key]

    def _resolve(self, key: tuple[str, str]) -> Any:
        if key == ("collections", "OrderedDict"):
            return self._ordered_dict
        if key == ("collections", "defaultdict"):
            return self._defaultdict
        if key in _ALLOWED_GLOBALS:
            return _ALLOWED_GLOBALS[key]
        if key in _DEFAULT_FACTORIES:
            return _FactoryName(".".join(key), self._path)
        raise InputError(
            f"refused to load global {key[0]}.{key[1]} from pickle "
            "(only numpy arrays and builtin containers are allowed)",
            path=self._path,
        )

    @staticmethod
    def _ordered_dict(*args: Any) -> dict:
        """`collections.OrderedDict(...)` as a plain dict (dicts keep insertion order)."""
        return dict(*args)

    def _defaultdict(self, default_factory: Any = None, *args: Any) -> dict:
        """`collections.defaultdict(factory, ...)` as a plain dict, once the factory is found to be one
        of `_DEFAULT_FACTORIES` (or None)."""
        if default_factory is None or any(default_factory is self._resolved.get(k) for k in _DEFAULT_FACTORIES):
            return dict(*args)
        named = (".".join(k) for k, v in self._resolved.items() if v is default_factory)
        what = next(named, f"a {type(default_factory).__name__}")
        raise InputError(
            f"refused collections.defaultdict with default factory {what} from pickle "
            "(only builtin containers and numbers are allowed)",
            path=self._path,
        )


def load_pickle(path: str | Path) -> Any:
    """The object pickled in `path`, loaded with the restricted unpickler (InputError when the file
    names a global other than numpy's array machinery and builtin containers, or is truncated or
    corrupt)."""
    path = Path(path)
    with open_input(path) as fh:
        try:
            return _RestrictedUnpickler(fh, path).load()
        except InputError:
            raise
        except Exception as exc:  # corrupt bytes can fail anywhere in the pickle machine
            raise InputError(f"corrupt or truncated pickle ({type(exc).__name__}: {exc})", path=path) from None


def looks_like_scenarionet(head: bytes) -> bool:
    """True when `head` starts a protocol 2-5 pickle. A TFRecord whose first record is 0x0N80 bytes
    long starts the same way, so a head whose TFRecord length checksum holds is left to that format."""
    return len(head) >= 2 and head[0] == 0x80 and 2 <= head[1] <= 5 and not looks_like_tfrecord(head)


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
            source_format=ScenarioNetFormat.name,
        )
    except ScenarioValidationError as exc:
        raise exc.located(path=path) from None


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


# ---------------------------------------------------------------------------- the format


@register_format
class ScenarioNetFormat(ScenarioFormat):
    """ScenarioNet / MetaDrive scenario description pickles (exactly one scenario per file)."""

    name = "scenarionet"
    suffixes = (".pkl", ".pickle")

    @classmethod
    def sniff(cls, head: bytes) -> bool:
        return looks_like_scenarionet(head)

    def read(self, path: Path) -> Iterator[Scenario]:
        path = Path(path)
        yield scenario_from_dict(load_pickle(path), where=str(path))

    def write(self, path: Path, scenarios: Iterable[Scenario], *, compress: bool = False) -> int:
        first_two = list(itertools.islice(scenarios, 2))
        if len(first_two) != 1:
            count = "none" if not first_two else "more than one"
            raise InputError(f"a ScenarioNet file holds exactly one scenario; got {count}", path=path)
        data = scenario_to_dict(first_two[0])
        with atomic_open(path, "wb", compress=compress) as fh:
            pickle.dump(data, fh, protocol=PICKLE_PROTOCOL)
        return 1
