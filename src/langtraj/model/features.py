"""What the network sees of a scene: the scene frame, the agents' history and future, the nearby map as
fixed-size polylines, and the batching of such samples into a `SceneBatch` (docs/model.md, 'Inputs').

One sample is one scene in its own frame: the focal agent (the SDC, else the most important agent) at
the origin heading along +x, so every scene looks alike to the network. A sample holds the `max_agents`
most important agents valid at the current step (`prioritized_agents`), their history and future, and
the map. Which sentence each agent is conditioned on is not decided here: training draws it
(`langtraj.training.data`), simulation takes it from the user's prompt; `scene_sample` leaves every
agent without text.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, fields
from typing import Any

import numpy as np
import torch
from scipy.spatial import cKDTree

from langtraj.angles import wrap_angle
from langtraj.frames import Origin, points_to_frame
from langtraj.model.batch import AGENT_HISTORY_FEATURES, SceneBatch
from langtraj.model.config import SampleConfig
from langtraj.model.targets import TARGET_ARRAYS
from langtraj.scenario.model import STEP_SECONDS, RoadMap, Scenario
from langtraj.scenario.selection import prioritized_agents
from langtraj.scenario.types import MapFeatureType, StateField

MAP_TYPES = frozenset(
    {t for t in MapFeatureType if t.is_lane or t.is_road_line or t.is_road_edge}
    | {MapFeatureType.CROSSWALK, MapFeatureType.SPEED_BUMP, MapFeatureType.STOP_SIGN}
)
"""Map feature types a sample encodes (driveways are left out)."""

MAP_POINT_SPACING = 2.0
"""Largest gap (m) between consecutive resampled map points: a piece spans at most (P - 1) * 2 m."""

MOVING_SPEED = 0.5
"""Speed (m/s) from positions above which a near-zero reported velocity counts as missing."""

_STILL_SPEED = 0.05  # reported speeds below this (m/s) may be a source's placeholder for "unknown"


# ---------------------------------------------------------------- the scene frame


def scene_frame(scenario: Scenario) -> Origin:
    """World (x, y, heading) of the scene frame: the SDC at the current step when it is valid there,
    else the first of `prioritized_agents`; (0, 0, 0) when no agent is valid at the current step."""
    t = scenario.current_index
    agents = scenario.agents
    focal = scenario.sdc_index
    if focal < 0 or not agents.valid[focal, t]:
        order = prioritized_agents(scenario, 1)
        if not len(order):
            return 0.0, 0.0, 0.0
        focal = int(order[0])
    state = agents.states[focal, t]
    return float(state[StateField.X]), float(state[StateField.Y]), float(wrap_angle(state[StateField.HEADING]))


def _rotate(vec: np.ndarray, heading: float) -> np.ndarray:
    """World vectors [..., 2] (velocities) in a frame rotated by `heading`."""
    c, s = math.cos(heading), math.sin(heading)
    vec = np.asarray(vec, np.float64)
    return np.stack([c * vec[..., 0] + s * vec[..., 1], -s * vec[..., 0] + c * vec[..., 1]], axis=-1)


def _velocities(states: np.ndarray, valid: np.ndarray, timestamps: np.ndarray) -> np.ndarray:
    """World velocities [A, T, 2], with missing ones estimated from positions.

    A reported velocity counts as missing when it is not finite, or when it is (near) zero while the
    backward difference of positions says the agent moves faster than `MOVING_SPEED` (some sources
    write zeros for "unknown"). Missing velocities become that backward difference (previous step to
    this one; never a later step, so nothing leaks from the future) where both steps are valid, else 0.
    """
    vel = states[..., StateField.VX : StateField.VY + 1].astype(np.float64)
    xy = states[..., StateField.X : StateField.Y + 1].astype(np.float64)
    dt = np.diff(np.asarray(timestamps, np.float64))
    dt = np.where(dt > 0, dt, STEP_SECONDS)
    diff = np.zeros_like(vel)
    diff[:, 1:] = (xy[:, 1:] - xy[:, :-1]) / dt[None, :, None]
    have_diff = np.zeros(valid.shape, bool)
    have_diff[:, 1:] = valid[:, 1:] & valid[:, :-1]
    finite = np.isfinite(vel).all(axis=-1)
    speed = np.linalg.norm(np.where(finite[..., None], vel, 0.0), axis=-1)
    moving = have_diff & (np.linalg.norm(diff, axis=-1) > MOVING_SPEED)
    missing = ~finite | ((speed < _STILL_SPEED) & moving)
    fill = np.where(have_diff[..., None], diff, 0.0)
    return np.where(missing[..., None], fill, vel)


def _steps(start: int, count: int, num_steps: int) -> tuple[np.ndarray, np.ndarray]:
    """`count` step indices from `start` clipped into the scene, and which of them are inside it."""
    steps = np.arange(start, start + count)
    inside = (steps >= 0) & (steps < num_steps)
    return np.clip(steps, 0, max(num_steps - 1, 0)), inside


MapArrays = tuple[np.ndarray, np.ndarray, np.ndarray]
"""`map_polylines` output: points [M, P, 2], validity [M, P], types [M]."""


# ---------------------------------------------------------------- the map


def feature_pieces(xy: np.ndarray, kind: MapFeatureType, points: int) -> np.ndarray:
    """A map feature's points [N, 2] (area polygons closed first) cut as `_pieces` cuts them: [K, points, 2], or
    [1, 1, 2] for a feature of no length. The model's map and the environment's observation cut features alike."""
    if kind.is_area and len(xy) > 2:
        xy = np.concatenate([xy, xy[:1]])
    return _pieces(xy, points)


def _pieces(xy: np.ndarray, points: int) -> np.ndarray:
    """A polyline [N, 2] cut into equal pieces of at most (points - 1) * MAP_POINT_SPACING m, each
    resampled uniformly by arc length to `points` points: [K, points, 2]. A polyline of no length gives
    one piece holding only its first point (then padded, see `map_polylines`)."""
    seg = np.linalg.norm(np.diff(xy, axis=0), axis=-1)
    keep = np.concatenate([[True], seg > 1e-9])
    xy, seg = xy[keep], seg[seg > 1e-9]
    total = float(seg.sum())
    if len(xy) < 2 or total <= 1e-9:
        return xy[None, :1]
    count = math.ceil(total / ((points - 1) * MAP_POINT_SPACING) - 1e-9)
    cum = np.concatenate([[0.0], np.cumsum(seg)])
    s = (np.arange(count)[:, None] + np.linspace(0.0, 1.0, points)[None]) * (total / count)
    return np.stack([np.interp(s, cum, xy[:, 0]), np.interp(s, cum, xy[:, 1])], axis=-1)


ANCHOR_SPACING = 10.0
"""Metres between the anchor points laid along each agent's road ahead."""

LEAD_WEIGHT = 0.25
"""Cost per metre of lead: a piece near an anchor 40 m ahead of its agent ranks with one 10 m beside it."""

COVERAGE_RADIUS = 5.0
"""An agent is covered when a lane point of its sample lies within this distance (m)."""


@dataclass(frozen=True)
class MapAnchors:
    """World points the map must cover and how far ahead of its agent each lies (the selection's cost
    adds `LEAD_WEIGHT` per metre of lead, so an agent's surroundings come before its far road)."""

    points: np.ndarray  # float64 [K, 2], world
    lead: np.ndarray  # float64 [K], metres ahead of the anchor's agent

    @classmethod
    def origin(cls, origin: Origin) -> MapAnchors:
        """The scene origin alone: the nearest-to-origin crop."""
        return cls(np.asarray([origin[:2]], np.float64), np.zeros(1))


def map_anchors(scenario: Scenario, agents: np.ndarray, config: SampleConfig) -> MapAnchors:
    """Anchors covering each of `agents` (scenario rows, valid at the current step): its position, and
    points every `ANCHOR_SPACING` m straight ahead along its heading for max(`map_ahead_min`,
    speed x `map_ahead_s`) m. Only the current step is read (nothing of the future)."""
    t = scenario.current_index
    rows = np.asarray(agents, np.int64)
    if not len(rows):
        return MapAnchors(np.zeros((0, 2)), np.zeros(0))
    states = scenario.agents.states[rows]
    vel = _velocities(states, scenario.agents.valid[rows], scenario.timestamps)[:, t]
    speed = np.linalg.norm(vel, axis=-1)
    reach = np.maximum(config.map_ahead_min, speed * config.map_ahead_s)
    points, lead = [], []
    for row, length in zip(states[:, t], reach, strict=True):
        ahead = np.append(np.arange(0.0, length, ANCHOR_SPACING), length)
        heading = float(row[StateField.HEADING])
        direction = np.array([math.cos(heading), math.sin(heading)])
        points.append(row[StateField.X : StateField.Y + 1].astype(np.float64) + ahead[:, None] * direction)
        lead.append(ahead)
    return MapAnchors(np.concatenate(points), np.concatenate(lead))


def _bbox_distances(xy: np.ndarray, anchors: np.ndarray) -> np.ndarray:
    """Distance from each anchor [K, 2] to the bounding box of points [N, 2] (a lower bound on the
    distance to the nearest point)."""
    lo, hi = xy.min(axis=0), xy.max(axis=0)
    gap = np.maximum(np.maximum(lo - anchors, anchors - hi), 0.0)
    return np.hypot(gap[:, 0], gap[:, 1])


def map_polylines(
    road_map: RoadMap, origin: Origin, config: SampleConfig, anchors: MapAnchors | None = None
) -> MapArrays:
    """Map points [M, P, 2] (scene frame), validity [M, P] and types [M] of the `max_polylines` pieces
    that best cover `anchors` (default: the scene origin alone).

    Features of `MAP_TYPES` are cut and resampled (`_pieces`; area polygons closed first). A piece costs
    min over anchors of (distance from the anchor to the piece's nearest point + `LEAD_WEIGHT` x the
    anchor's lead); pieces within `map_radius` of some anchor are kept, cheapest first. A single-point
    feature (a stop sign) is a polyline with only its first point valid. See docs/model.md, 'Inputs'.
    """
    anchors = MapAnchors.origin(origin) if anchors is None else anchors
    m, p = config.max_polylines, config.points_per_polyline
    ox, oy, _ = origin
    near = anchors.points - (ox, oy)  # anchors centred like the pieces
    found: list[tuple[float, int, int, np.ndarray]] = []  # (cost, order, type, points [P|1, 2] centred)
    for feature in road_map.features:
        if feature.type not in MAP_TYPES or not len(feature.points) or not len(near):
            continue
        xy = feature.points[:, :2] - (ox, oy)
        reach = _bbox_distances(xy, near) <= config.map_radius
        if not reach.any():
            continue
        pieces = feature_pieces(xy, feature.type, p)
        dist = np.linalg.norm(pieces[:, :, None, :] - near[reach], axis=-1).min(axis=1)  # [K_pieces, anchors]
        cost = (dist + LEAD_WEIGHT * anchors.lead[reach]).min(axis=-1)
        for k in np.flatnonzero(dist.min(axis=-1) <= config.map_radius):
            found.append((round(float(cost[k]), 6), len(found), int(feature.type), pieces[k]))  # ties: map order
    found.sort(key=lambda item: item[:2])
    points = np.zeros((m, p, 2), np.float32)
    valid = np.zeros((m, p), bool)
    types = np.zeros(m, np.int64)
    for row, (_, _, kind, piece) in enumerate(found[:m]):
        local = points_to_frame(piece + (ox, oy), origin)
        points[row, : len(local)] = local
        valid[row, : len(local)] = True
        types[row] = kind
    return points, valid, types


def sample_map(scenario: Scenario, agents: np.ndarray, origin: Origin, config: SampleConfig) -> MapArrays:
    """The map of a sample of `agents` in the frame of `origin`, chosen as `config.map_selection` says."""
    if config.map_selection == "origin":
        return map_polylines(scenario.road_map, origin, config)
    return map_polylines(scenario.road_map, origin, config, map_anchors(scenario, agents, config))


LANE_TYPES = tuple(int(t) for t in MapFeatureType if t.is_lane)
"""The MapFeatureType values of lane centre lines (map coverage, lane-relative inputs)."""


def map_coverage(
    map_arrays: MapArrays, positions: np.ndarray, valid: np.ndarray, radius: float = COVERAGE_RADIUS
) -> np.ndarray:
    """Which positions [..., 2] (scene frame, as the map) have a lane point of the sample's map within
    `radius`: bool [...], False where `valid` is False. Reported as map coverage by training and
    simulation (docs/model.md, 'Inputs')."""
    points, point_valid, types = map_arrays
    lane = point_valid & np.isin(types, LANE_TYPES)[:, None]
    lane_xy = np.asarray(points, np.float64)[lane]  # [L, 2]
    flat = np.asarray(positions, np.float64).reshape(-1, 2)
    if not len(lane_xy) or not len(flat):
        return np.zeros(np.shape(valid), bool)
    dist, _ = cKDTree(lane_xy).query(flat, k=1)
    return (dist.reshape(np.shape(valid)) <= radius) & np.asarray(valid, bool)


# ---------------------------------------------------------------- one sample


def scene_sample(
    scenario: Scenario,
    config: SampleConfig,
    *,
    agents: np.ndarray | None = None,
    origin: Origin | None = None,
    map_arrays: MapArrays | None = None,
) -> dict[str, Any]:
    """One scene row of a `SceneBatch` as numpy arrays (no batch axis), keyed by `SceneBatch` field names,
    with no agent conditioned on text (`text` all None, `interaction_labelled` False).

    `agents` (scenario rows, at most `max_agents`), `origin` and `map_arrays` (from `map_polylines` for
    that origin) override the choices below: closed-loop simulation keeps them fixed across replans.

    Agents: `prioritized_agents(scenario, max_agents)` (all valid at the current step), padded to
    `max_agents` (padding: invalid, type 0, id -1, zeros). History is the `history_steps` steps ending
    at the current one; future the `future_steps` after it; steps outside the scene are invalid. Values
    are in the scene frame (`scene_frame`); headings are wrapped to (-pi, pi]; invalid steps are zeros.
    `current_state` speed is |v| of the reported velocity, or of the backward position difference where
    the velocity is missing (`_velocities`); history vx, vy use the same velocities.
    """
    a_max, h, f = config.max_agents, config.history_steps, config.future_steps
    t0 = scenario.current_index
    origin = scene_frame(scenario) if origin is None else origin
    heading0 = origin[2]
    chosen = prioritized_agents(scenario, a_max) if agents is None else np.asarray(agents, np.int64)
    if len(chosen) > a_max:
        raise ValueError(f"{len(chosen)} agents given, the sample holds at most {a_max}")
    n = len(chosen)
    agents = scenario.agents
    states = agents.states[chosen]
    valid = agents.valid[chosen]
    vel = _velocities(states, valid, scenario.timestamps)
    xy = points_to_frame(states[..., StateField.X : StateField.Y + 1], origin)
    heading = wrap_angle(states[..., StateField.HEADING].astype(np.float64) - heading0)
    vel_local = _rotate(vel, heading0)

    hist_steps, hist_inside = _steps(t0 - h + 1, h, scenario.num_steps)
    hist_valid = np.zeros((a_max, h), bool)
    hist_valid[:n] = valid[:, hist_steps] & hist_inside[None]
    history = np.zeros((a_max, h, AGENT_HISTORY_FEATURES), np.float32)
    hh = heading[:, hist_steps]
    history[:n] = np.concatenate(
        [xy[:, hist_steps], np.cos(hh)[..., None], np.sin(hh)[..., None], vel_local[:, hist_steps], np.ones((n, h, 1))],
        axis=-1,
    )
    history[~hist_valid] = 0.0

    fut_steps, fut_inside = _steps(t0 + 1, f, scenario.num_steps)
    fut_valid = np.zeros((a_max, f), bool)
    fut_valid[:n] = valid[:, fut_steps] & fut_inside[None]
    future = np.zeros((a_max, f, 3), np.float32)
    future[:n] = np.concatenate([xy[:, fut_steps], heading[:, fut_steps, None]], axis=-1)
    future[~fut_valid] = 0.0

    current = np.zeros((a_max, 4), np.float32)
    current[:n, :2] = xy[:, t0]
    current[:n, 2] = heading[:, t0]
    current[:n, 3] = np.linalg.norm(vel[:, t0], axis=-1)
    size = np.zeros((a_max, 2), np.float32)
    size[:n] = states[:, t0, StateField.LENGTH : StateField.WIDTH + 1]
    agent_type = np.zeros(a_max, np.int64)
    agent_type[:n] = agents.types[chosen]
    agent_id = np.full(a_max, -1, np.int64)
    agent_id[:n] = agents.ids[chosen]
    agent_valid = np.zeros(a_max, bool)
    agent_valid[:n] = True

    map_points, map_valid, map_type = map_arrays or sample_map(scenario, chosen, origin, config)
    arrays = {
        "agent_history": history,
        "history_valid": hist_valid,
        "agent_type": agent_type,
        "agent_size": size,
        "agent_valid": agent_valid,
        "current_state": current,
        "future": future,
        "future_valid": fut_valid,
        "map_points": map_points,
        "map_valid": map_valid,
        "map_type": map_type,
        "origin": np.asarray(origin, np.float32),
        "agent_id": agent_id,
    }
    return sample_of(arrays, scenario.scenario_id)


def sample_of(arrays: dict[str, np.ndarray], scenario_id: str) -> dict[str, Any]:
    """A `scene_sample` dict from its `SAMPLE_ARRAYS` arrays (taken as they are) and its scene's id: no agent
    conditioned on text, not interaction-labelled. What `scene_sample` returns and a feature store reads back."""
    sample: dict[str, Any] = dict(arrays)
    sample["text"] = [None] * len(arrays["agent_id"])
    sample["interaction_labelled"] = np.bool_(False)
    sample["scenario_id"] = scenario_id
    return sample


def apply_history_dropout(sample: dict[str, Any]) -> None:
    """Training's history dropout, in place: only the current step of each agent's history stays valid
    (the rest zeroed), so the model learns scenes started from one observed frame."""
    sample["history_valid"][:, :-1] = False
    sample["agent_history"][~sample["history_valid"]] = 0.0


SAMPLE_ARRAYS: dict[str, type[np.generic]] = {
    "agent_history": np.float32,
    "history_valid": np.bool_,
    "agent_type": np.int64,
    "agent_size": np.float32,
    "agent_valid": np.bool_,
    "current_state": np.float32,
    "future": np.float32,
    "future_valid": np.bool_,
    "map_points": np.float32,
    "map_valid": np.bool_,
    "map_type": np.int64,
    "origin": np.float32,
    "agent_id": np.int64,
}
"""The fixed-size arrays of a `scene_sample` and their dtypes: what a sample holds besides text, labels and id."""

FEATURES_VERSION = 2
"""Bumped whenever `scene_sample` would give different arrays for the same scene and config, so stored
samples (`langtraj.training.store`) built by older code are refused rather than silently reused."""

AUGMENTATION_FIELDS = frozenset(
    {"text", "text_dropout", "history_dropout", "heuristic_label_fraction", "interaction_fraction", "decision_first"}
)
"""`SampleConfig` fields that `scene_sample` never reads: they only steer training's text and augmentation
(`langtraj.training.data.augment_sample`) and batch mixing, so they stay out of `features_key`. Every other
field is part of the key: a new field changes stored samples unless it is declared here."""


def features_key(config: SampleConfig) -> dict[str, Any]:
    """Everything that fixes `scene_sample`'s arrays for a scene: every `SampleConfig` field but the
    `AUGMENTATION_FIELDS`, and `FEATURES_VERSION`. Two configs with equal keys give equal samples."""
    keyed = (f.name for f in fields(config) if f.name not in AUGMENTATION_FIELDS)
    return {"version": FEATURES_VERSION} | {name: getattr(config, name) for name in keyed}


_TORCH_DTYPES = {np.float32: torch.float32, np.bool_: torch.bool, np.int64: torch.long}


def collate_scenes(samples: Sequence[dict[str, Any]]) -> SceneBatch:
    """Stack samples of one `SampleConfig` (equal sizes) into a `SceneBatch`; usable as a DataLoader
    `collate_fn`. Stored target actions (`model.targets.TARGET_ARRAYS`) come along when every sample has them."""
    if not samples:
        raise ValueError("cannot collate an empty list of samples")
    arrays = SAMPLE_ARRAYS | {"interaction_labelled": np.bool_}
    if all(name in s for s in samples for name in TARGET_ARRAYS):
        arrays = arrays | TARGET_ARRAYS
    tensors = {
        name: torch.as_tensor(np.stack([s[name] for s in samples]), dtype=_TORCH_DTYPES[dtype])
        for name, dtype in arrays.items()
    }
    return SceneBatch(
        **tensors,
        text=[list(s["text"]) for s in samples],
        scenario_id=[str(s["scenario_id"]) for s in samples],
    )
