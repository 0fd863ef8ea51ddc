"""The Scenario data model: the contract between readers, synthesis, labels, the model and metrics.

Typed, immutable dataclasses over numpy arrays (docs/design.md, 'The Scenario data model'). Arrays are validated and
coerced to their contract dtypes on construction, so every consumer can rely on shapes and dtypes.
Convert to tensors only at the model boundary.

See docs/data.md.
"""

from __future__ import annotations

import math
from collections import Counter
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field, replace
from functools import cached_property
from typing import Any

import numpy as np

from langtraj.angles import wrap_angle
from langtraj.errors import ScenarioValidationError
from langtraj.scenario.types import NUM_STATE_FIELDS, AgentType, MapFeatureType, StateField

STEP_SECONDS = 0.1
"""Scenario time step (10 Hz), as in WOMD."""

HISTORY_STEPS = 11
FUTURE_STEPS = 80
WINDOW_STEPS = HISTORY_STEPS + FUTURE_STEPS
"""WOMD's window at 10 Hz: 1.1 s of history including the current step, then 8 s of future (91 steps)."""

MPH_TO_MPS = 0.44704


def _array(value: Any, dtype: Any, name: str, ndim: int | None = None) -> np.ndarray:
    try:
        arr = np.asarray(value, dtype=dtype)
    except (TypeError, ValueError) as exc:
        raise ScenarioValidationError(f"cannot convert to {np.dtype(dtype).name}: {exc}", where=name) from None
    if ndim is not None and arr.ndim != ndim:
        raise ScenarioValidationError(f"expected {ndim} dimensions, got shape {arr.shape}", where=name)
    return arr


def _points(value: Any, name: str) -> np.ndarray:
    """Map points as float64 [N, 3]; 2-D input gets z = 0."""
    arr = _array(value, np.float64, name)
    if arr.size == 0:
        return np.zeros((0, 3), np.float64)
    if arr.ndim == 1 and arr.shape[0] in (2, 3):
        arr = arr[None]
    if arr.ndim != 2 or arr.shape[1] not in (2, 3):
        raise ScenarioValidationError(f"expected points of shape [N, 2|3], got {arr.shape}", where=name)
    if arr.shape[1] == 2:
        arr = np.concatenate([arr, np.zeros((arr.shape[0], 1))], axis=1)
    if not np.isfinite(arr).all():
        raise ScenarioValidationError("non-finite coordinate", where=name)
    return arr


@dataclass(frozen=True, eq=False)
class Agents:
    """All tracks of a scene over its time steps.

    `states[a, t]` holds the `StateField` columns (x, y, z, heading, vx, vy, length, width, height)
    of agent `a` at step `t`; the values where `valid[a, t]` is False are undefined.
    `tracks_to_predict` and `objects_of_interest` are indices into the agent axis.
    """

    ids: np.ndarray  # int64 [A]
    types: np.ndarray  # int8 [A], AgentType values
    states: np.ndarray  # float32 [A, T, 9]
    valid: np.ndarray  # bool [A, T]
    tracks_to_predict: np.ndarray = field(default_factory=lambda: np.zeros(0, np.int64))  # int64 [P]
    prediction_difficulty: np.ndarray | None = None  # int8 [P]; WOMD difficulty level, 0 when unknown
    objects_of_interest: np.ndarray = field(default_factory=lambda: np.zeros(0, np.int64))  # int64 [O]

    def __post_init__(self) -> None:
        ids = _array(self.ids, np.int64, "agents.ids", 1)
        types = _array(self.types, np.int8, "agents.types", 1)
        states = _array(self.states, np.float32, "agents.states", 3)
        valid = _array(self.valid, bool, "agents.valid", 2)
        ttp = _array(self.tracks_to_predict, np.int64, "agents.tracks_to_predict", 1)
        diff = self.prediction_difficulty
        diff = np.zeros(len(ttp), np.int8) if diff is None else _array(diff, np.int8, "agents.difficulty", 1)
        ooi = _array(self.objects_of_interest, np.int64, "agents.objects_of_interest", 1)
        num = len(ids)
        if states.shape[0] != num or states.shape[2] != NUM_STATE_FIELDS:
            raise ScenarioValidationError(
                f"expected shape [{num}, T, {NUM_STATE_FIELDS}], got {states.shape}", where="agents.states"
            )
        if valid.shape != states.shape[:2]:
            raise ScenarioValidationError(
                f"shape {valid.shape} does not match states {states.shape[:2]}", where="agents.valid"
            )
        if len(types) != num:
            raise ScenarioValidationError(f"{len(types)} types for {num} agents", where="agents.types")
        unique_ids, counts = np.unique(ids, return_counts=True)
        if len(unique_ids) != num:
            dup = unique_ids[counts > 1][:5].tolist()
            raise ScenarioValidationError(f"duplicate track ids {dup}", where="agents.ids")
        known = np.isin(types, [t.value for t in AgentType])
        if not known.all():
            raise ScenarioValidationError(f"unknown agent type {int(types[~known][0])}", where="agents.types")
        if len(diff) != len(ttp):
            raise ScenarioValidationError("one difficulty per track to predict", where="agents.difficulty")
        for name, idx in (("tracks_to_predict", ttp), ("objects_of_interest", ooi)):
            if len(idx) and (idx.min() < 0 or idx.max() >= num):
                raise ScenarioValidationError(f"index out of range [0, {num})", where=f"agents.{name}")
        pose = states[..., : StateField.HEADING + 1]
        bad = valid & ~np.isfinite(pose).all(axis=-1)
        if bad.any():
            a, t = np.argwhere(bad)[0]
            col = [f.name.lower() for f in StateField][int(np.argmin(np.isfinite(pose[a, t])))]
            raise ScenarioValidationError(
                f"non-finite {col} = {pose[a, t, StateField[col.upper()]]} for a valid state",
                where=f"track {int(ids[a])}, step {int(t)}",
            )
        for name, value in (
            ("ids", ids),
            ("types", types),
            ("states", states),
            ("valid", valid),
            ("tracks_to_predict", ttp),
            ("prediction_difficulty", diff),
            ("objects_of_interest", ooi),
        ):
            object.__setattr__(self, name, value)

    @property
    def num_agents(self) -> int:
        return len(self.ids)

    @staticmethod
    def write_poses(states: np.ndarray, poses: np.ndarray, *, wrap: bool = True) -> None:
        """Write poses [..., 4] (x, y, heading, speed) into the x, y, heading, vx, vy columns of a `states`
        block [..., NUM_STATE_FIELDS] of the same leading shape, in place: the velocity points along the
        heading, and the stored heading is wrapped to (-pi, pi] unless `wrap` is False (headings already
        wrapped by their source). The one place poses become state columns."""
        heading = poses[..., 2]
        states[..., StateField.X] = poses[..., 0]
        states[..., StateField.Y] = poses[..., 1]
        states[..., StateField.HEADING] = wrap_angle(heading) if wrap else heading
        states[..., StateField.VX] = poses[..., 3] * np.cos(heading)
        states[..., StateField.VY] = poses[..., 3] * np.sin(heading)

    @property
    def num_steps(self) -> int:
        return self.states.shape[1]

    @property
    def xy(self) -> np.ndarray:
        """Positions [A, T, 2] (a view)."""
        return self.states[..., StateField.X : StateField.Y + 1]

    @property
    def heading(self) -> np.ndarray:
        return self.states[..., StateField.HEADING]

    @property
    def velocity(self) -> np.ndarray:
        return self.states[..., StateField.VX : StateField.VY + 1]

    @property
    def speed(self) -> np.ndarray:
        return np.linalg.norm(self.velocity, axis=-1)

    @property
    def size(self) -> np.ndarray:
        """Length, width, height [A, T, 3] (a view)."""
        return self.states[..., StateField.LENGTH :]

    @cached_property
    def _index_of_id(self) -> dict[int, int]:
        return {int(i): n for n, i in enumerate(self.ids)}

    def index_of(self, track_id: int) -> int:
        """Agent index of a track id; raises KeyError naming the id when it is not in the scene."""
        try:
            return self._index_of_id[int(track_id)]
        except KeyError:
            raise KeyError(f"track id {track_id} is not in the scene") from None

    def type_counts(self) -> dict[str, int]:
        return {t.name.lower(): int((self.types == t).sum()) for t in AgentType}

    def select(self, indices: Sequence[int] | np.ndarray) -> Agents:
        """The agents at `indices`, in that order; prediction and interest lists are remapped."""
        idx = np.asarray(indices, np.int64)
        remap = np.full(self.num_agents, -1, np.int64)
        remap[idx] = np.arange(len(idx))
        ttp_new = remap[self.tracks_to_predict]
        keep_ttp = ttp_new >= 0
        ooi_new = remap[self.objects_of_interest]
        return Agents(
            ids=self.ids[idx],
            types=self.types[idx],
            states=self.states[idx],
            valid=self.valid[idx],
            tracks_to_predict=ttp_new[keep_ttp],
            prediction_difficulty=self.prediction_difficulty[keep_ttp],
            objects_of_interest=ooi_new[ooi_new >= 0],
        )

    def slice_steps(self, start: int, stop: int) -> Agents:
        return replace(self, states=self.states[:, start:stop], valid=self.valid[:, start:stop])


@dataclass(frozen=True)
class BoundarySegment:
    """A stretch of a lane (point indices, inclusive) bounded by one road line or edge."""

    lane_start_index: int
    lane_end_index: int
    boundary_feature_id: int
    boundary_type: MapFeatureType  # a ROAD_LINE_* type


@dataclass(frozen=True)
class LaneNeighbor:
    """A lane beside this one over a stretch of both (point indices, inclusive)."""

    feature_id: int
    self_start_index: int
    self_end_index: int
    neighbor_start_index: int
    neighbor_end_index: int
    boundaries: tuple[BoundarySegment, ...] = ()


@dataclass(frozen=True, eq=False)
class MapFeature:
    """One map element.

    `points` is float64 [N, 3]: the centerline of a lane, the polyline of a road line or edge, the
    polygon of a crosswalk, speed bump or driveway, and the single position of a stop sign. Lane
    connectivity and neighbours are present where the source has them; `controlled_lanes` is the list
    of lanes a stop sign governs. `polygon` is an optional lane outline (nuScenes). `derived_from` is empty for a
    feature the source holds and names what LangTraj derived it from otherwise (road edges of a map that has none:
    `scenario.drivable`), so that a page or report can say so.
    """

    id: int
    type: MapFeatureType
    points: np.ndarray
    entry_lanes: tuple[int, ...] = ()
    exit_lanes: tuple[int, ...] = ()
    left_neighbors: tuple[LaneNeighbor, ...] = ()
    right_neighbors: tuple[LaneNeighbor, ...] = ()
    left_boundaries: tuple[BoundarySegment, ...] = ()
    right_boundaries: tuple[BoundarySegment, ...] = ()
    speed_limit_mph: float = math.nan
    interpolating: bool = False
    controlled_lanes: tuple[int, ...] = ()
    polygon: np.ndarray | None = None
    derived_from: str = ""

    def __post_init__(self) -> None:
        where = f"map feature {self.id}"
        object.__setattr__(self, "id", int(self.id))
        try:
            object.__setattr__(self, "type", MapFeatureType(self.type))
        except ValueError:
            raise ScenarioValidationError(f"unknown map feature type {self.type!r}", where=where) from None
        object.__setattr__(self, "points", _points(self.points, where))
        if self.polygon is not None:
            object.__setattr__(self, "polygon", _points(self.polygon, f"{where} polygon"))
        for name in ("entry_lanes", "exit_lanes", "controlled_lanes"):
            object.__setattr__(self, name, tuple(int(v) for v in getattr(self, name)))

    @property
    def speed_limit_mps(self) -> float:
        return self.speed_limit_mph * MPH_TO_MPS


@dataclass(frozen=True, eq=False)
class RoadMap:
    """All map features of a scene, in source order."""

    features: tuple[MapFeature, ...] = ()

    def __post_init__(self) -> None:
        object.__setattr__(self, "features", tuple(self.features))
        ids = [f.id for f in self.features]
        if len(set(ids)) != len(ids):
            dup = next(i for i, n in Counter(ids).items() if n > 1)
            raise ScenarioValidationError(f"duplicate map feature id {dup}", where="road_map")

    def __len__(self) -> int:
        return len(self.features)

    def __iter__(self):
        return iter(self.features)

    @cached_property
    def by_id(self) -> Mapping[int, MapFeature]:
        return {f.id: f for f in self.features}

    def of_type(self, *types: MapFeatureType) -> list[MapFeature]:
        return [f for f in self.features if f.type in types]

    @property
    def lanes(self) -> list[MapFeature]:
        return [f for f in self.features if f.type.is_lane]

    @property
    def road_lines(self) -> list[MapFeature]:
        return [f for f in self.features if f.type.is_road_line]

    @property
    def road_edges(self) -> list[MapFeature]:
        return [f for f in self.features if f.type.is_road_edge]

    def type_counts(self) -> dict[str, int]:
        counts: dict[str, int] = {}
        for f in self.features:
            counts[f.type.name.lower()] = counts.get(f.type.name.lower(), 0) + 1
        return counts


@dataclass(frozen=True, eq=False)
class TrafficLights:
    """Per-step signal state of each controlled lane.

    `states[t, l]` is a `TrafficLightState` value for lane `lane_ids[l]`; `valid[t, l]` is False where
    the source reports nothing for that lane at that step (the state there is UNKNOWN).
    `stop_points[l]` is where traffic on the lane stops (x, y, z).
    """

    lane_ids: np.ndarray  # int64 [L]
    states: np.ndarray  # int8 [T, L]
    valid: np.ndarray  # bool [T, L]
    stop_points: np.ndarray  # float64 [L, 3]

    def __post_init__(self) -> None:
        lane_ids = _array(self.lane_ids, np.int64, "traffic_lights.lane_ids", 1)
        states = _array(self.states, np.int8, "traffic_lights.states", 2)
        valid = _array(self.valid, bool, "traffic_lights.valid", 2)
        stops = _array(self.stop_points, np.float64, "traffic_lights.stop_points", 2)
        num = len(lane_ids)
        if states.shape[1] != num or valid.shape != states.shape or stops.shape != (num, 3):
            raise ScenarioValidationError(
                f"inconsistent shapes: {num} lanes, states {states.shape}, valid {valid.shape}, "
                f"stop points {stops.shape}",
                where="traffic_lights",
            )
        if len(np.unique(lane_ids)) != num:
            raise ScenarioValidationError("duplicate lane id", where="traffic_lights.lane_ids")
        if states.size and (states.min() < 0 or states.max() > 8):
            raise ScenarioValidationError("state out of range [0, 8]", where="traffic_lights.states")
        if not np.isfinite(stops).all():
            raise ScenarioValidationError("non-finite stop point", where="traffic_lights.stop_points")
        if (states[~valid] != 0).any():
            states = np.where(valid, states, np.int8(0))
        for name, value in (
            ("lane_ids", lane_ids),
            ("states", states),
            ("valid", valid),
            ("stop_points", stops),
        ):
            object.__setattr__(self, name, value)

    @classmethod
    def empty(cls, num_steps: int) -> TrafficLights:
        return cls(
            np.zeros(0, np.int64),
            np.zeros((num_steps, 0), np.int8),
            np.zeros((num_steps, 0), bool),
            np.zeros((0, 3)),
        )

    @property
    def num_lanes(self) -> int:
        return len(self.lane_ids)

    def held_at(self, step: int) -> tuple[np.ndarray, np.ndarray]:
        """Each lane's light at `step`, the one rule wherever a light is read at a step (the env's observation, the
        studio, a simulation's lights after its start): its state int8 [L] at its last valid step up to `step` (a
        source that skips a step does not turn a red light off), and bool [L] whether it was ever valid by then
        (UNKNOWN where not). Never reads past `step`."""
        known = self.valid[: step + 1]
        seen = known.any(axis=0)
        last = known.shape[0] - 1 - np.argmax(known[::-1], axis=0)
        states = np.where(seen, self.states[np.where(seen, last, 0), np.arange(self.num_lanes)], np.int8(0))
        return states.astype(np.int8), seen

    def slice_steps(self, start: int, stop: int) -> TrafficLights:
        return replace(self, states=self.states[start:stop], valid=self.valid[start:stop])


@dataclass(frozen=True)
class BehaviorEvent:
    """A ground-truth behaviour event of one agent over steps [start, end) (e.g. from SUMO).

    `kind` names the event (e.g. "lane_change", "yield"); `other_id` is the track id of the other
    agent involved, or -1. `attributes` holds kind-specific JSON-compatible values.
    """

    kind: str
    track_id: int
    start: int
    end: int
    other_id: int = -1
    attributes: Mapping[str, Any] = field(default_factory=dict)

    def shifted(self, offset: int) -> BehaviorEvent:
        return replace(self, start=self.start + offset, end=self.end + offset)


@dataclass(frozen=True, eq=False)
class Scenario:
    """One driving scene: agents over time, the road map, traffic lights and optional events.

    `current_index` is the last observed ("current") step; `sdc_index` indexes the self-driving car in
    `agents`, or is -1 when the source has none. `metadata` carries JSON-compatible, source-specific
    values through conversions (e.g. ScenarioNet's original track keys). `source_format` names the
    reader that produced the scenario ("womd", "scenarionet", ...), or "" for one built in memory.
    """

    scenario_id: str
    timestamps: np.ndarray  # float64 [T], seconds
    current_index: int
    sdc_index: int
    agents: Agents
    road_map: RoadMap = field(default_factory=RoadMap)
    traffic_lights: TrafficLights | None = None
    events: tuple[BehaviorEvent, ...] = ()
    metadata: Mapping[str, Any] = field(default_factory=dict)
    source_format: str = ""

    def __post_init__(self) -> None:
        ts = _array(self.timestamps, np.float64, "timestamps", 1)
        num_steps = self.agents.num_steps
        if len(ts) != num_steps:
            raise ScenarioValidationError(f"{len(ts)} timestamps for {num_steps} steps", where="timestamps")
        if not np.isfinite(ts).all():
            raise ScenarioValidationError("non-finite timestamp", where="timestamps")
        if not 0 <= int(self.current_index) < max(num_steps, 1):
            raise ScenarioValidationError(f"{self.current_index} is outside [0, {num_steps})", where="current_index")
        if not -1 <= int(self.sdc_index) < self.agents.num_agents:
            raise ScenarioValidationError(
                f"{self.sdc_index} is outside [-1, {self.agents.num_agents})", where="sdc_index"
            )
        lights = self.traffic_lights if self.traffic_lights is not None else TrafficLights.empty(num_steps)
        if lights.states.shape[0] != num_steps:
            raise ScenarioValidationError(
                f"{lights.states.shape[0]} steps of states for {num_steps} scenario steps",
                where="traffic_lights",
            )
        object.__setattr__(self, "timestamps", ts)
        object.__setattr__(self, "current_index", int(self.current_index))
        object.__setattr__(self, "sdc_index", int(self.sdc_index))
        object.__setattr__(self, "traffic_lights", lights)
        object.__setattr__(self, "events", tuple(self.events))
        object.__setattr__(self, "scenario_id", str(self.scenario_id))

    # ------------------------------------------------------------------ sizes
    @property
    def num_agents(self) -> int:
        return self.agents.num_agents

    @property
    def num_steps(self) -> int:
        return self.agents.num_steps

    @property
    def sdc_id(self) -> int | None:
        return None if self.sdc_index < 0 else int(self.agents.ids[self.sdc_index])

    def logs_future(self, steps: int = FUTURE_STEPS) -> bool:
        """True when the scene logs at least `steps` steps after the current one (default: WOMD's 8 s)."""
        return self.num_steps - self.current_index - 1 >= steps

    # ------------------------------------------------------------------ derived scenes
    def select_agents(self, indices: Sequence[int] | np.ndarray) -> Scenario:
        """The scene with only the agents at `indices` (in that order); the SDC index is remapped (-1 if
        dropped) and events of dropped agents are removed."""
        idx = np.asarray(indices, np.int64)
        if len(idx) and (idx.min() < 0 or idx.max() >= self.num_agents):
            raise IndexError(f"agent index out of range [0, {self.num_agents})")
        hits = np.flatnonzero(idx == self.sdc_index) if self.sdc_index >= 0 else np.zeros(0, np.int64)
        agents = self.agents.select(idx)
        kept = {int(i) for i in agents.ids}
        events = tuple(e for e in self.events if e.track_id in kept)
        return replace(self, agents=agents, sdc_index=int(hits[0]) if len(hits) else -1, events=events)

    def slice_steps(self, start: int, stop: int, current_index: int) -> Scenario:
        """Steps [start, stop) of the scene, with `current_index` relative to `start`. Events are
        clipped to the slice and shifted; events wholly outside it are dropped."""
        if not 0 <= start < stop <= self.num_steps:
            raise IndexError(f"step slice [{start}, {stop}) outside [0, {self.num_steps})")
        events = tuple(
            replace(e, start=max(e.start, start) - start, end=min(e.end, stop) - start)
            for e in self.events
            if e.end > start and e.start < stop
        )
        return replace(
            self,
            timestamps=self.timestamps[start:stop],
            current_index=current_index,
            agents=self.agents.slice_steps(start, stop),
            traffic_lights=self.traffic_lights.slice_steps(start, stop),
            events=events,
        )
