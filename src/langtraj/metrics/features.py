"""WOSAC features of a scene's tracks: kinematics, interactions, map, for logged or simulated futures.

`SceneTracks` holds the sim agents over history + future ([N, A, T], N = 1 for the log, R for
rollouts), built as the challenge builds them: the simulated future is appended to the logged
history, and box sizes over the future are those of the current step. `compute_features` returns
every per-step feature of the evaluated agents over the future steps.

See docs/metrics.md.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from langtraj.metrics.interaction import distance_to_nearest_object, time_to_collision
from langtraj.metrics.kinematics import kinematic_features
from langtraj.metrics.road import RoadEdgeIndex, distance_to_road_edge, road_edge_index
from langtraj.metrics.traffic_lights import SignalLanes, red_light_violations
from langtraj.rollouts.agents import evaluated_agent_indices, sim_agent_indices
from langtraj.rollouts.container import Rollouts
from langtraj.scenario.drivable import measured_road_edges
from langtraj.scenario.model import FUTURE_STEPS, STEP_SECONDS, Scenario
from langtraj.scenario.types import AgentType, StateField

COLLISION_THRESHOLD = 0.0
"""Objects closer than this (m, signed) collide."""

OFFROAD_THRESHOLD = 0.0
"""A box whose most off-road corner is farther than this (m) outside the road edge is off road."""


@dataclass(frozen=True)
class SceneMap:
    """The map pieces the features need, built once per scenario. The road edges are those off-road is measured
    against everywhere (`scenario.drivable.measured_road_edges`: derived from the lanes on a map without any)."""

    road_edges: RoadEdgeIndex | None
    signals: SignalLanes | None

    @classmethod
    def from_scenario(cls, scenario: Scenario) -> SceneMap:
        edges = road_edge_index([f.points for f in measured_road_edges(scenario)])
        return cls(edges, SignalLanes.from_scenario(scenario))


@dataclass(frozen=True)
class SceneTracks:
    """Sim-agent tracks over history and future; fields are [N, A, T] with T = current + 1 + 80."""

    object_id: np.ndarray  # int64 [A]
    is_vehicle: np.ndarray  # bool [A]
    evaluated: np.ndarray  # int64 [E], indices into A
    current: int  # index of the current step
    x: np.ndarray
    y: np.ndarray
    z: np.ndarray
    heading: np.ndarray
    length: np.ndarray
    width: np.ndarray
    height: np.ndarray
    valid: np.ndarray  # bool

    @property
    def future(self) -> slice:
        return slice(self.current + 1, self.current + 1 + FUTURE_STEPS)


def _history_and_log(scenario: Scenario, agents: np.ndarray):
    states = scenario.agents.states[agents].astype(np.float64)
    valid = scenario.agents.valid[agents]
    end = scenario.current_index + 1 + FUTURE_STEPS
    return states[:, :end], valid[:, :end]


def log_tracks(scenario: Scenario) -> SceneTracks:
    """The logged future of the sim agents as one "rollout" (N = 1), with the log's validity."""
    agents = sim_agent_indices(scenario)
    states, valid = _history_and_log(scenario, agents)
    c = scenario.current_index
    dims = states[..., [StateField.LENGTH, StateField.WIDTH, StateField.HEIGHT]].copy()
    dims[:, c + 1 :] = dims[:, c : c + 1]
    return _tracks(scenario, agents, states[None, ..., : StateField.HEADING + 1], dims[None], valid[None])


def rollout_tracks(scenario: Scenario, rollouts: Rollouts, agents: np.ndarray) -> SceneTracks:
    """Simulated futures appended to the logged history; `agents` are the scenario indices of the
    rollout's objects (as returned by `check_rollouts`), reordered here to sim-agent order."""
    sim = sim_agent_indices(scenario)
    column = {int(a): i for i, a in enumerate(agents)}
    order = np.array([column[int(a)] for a in sim], np.int64)
    states, valid = _history_and_log(scenario, sim)
    c = scenario.current_index
    num = rollouts.num_rollouts
    hist = np.broadcast_to(states[None, :, : c + 1, : StateField.HEADING + 1], (num, len(sim), c + 1, 4))
    fut = np.stack([getattr(rollouts, f)[:, order].astype(np.float64) for f in ("x", "y", "z", "heading")], -1)
    pose = np.concatenate([hist, fut], axis=2)
    dims = states[..., [StateField.LENGTH, StateField.WIDTH, StateField.HEIGHT]].copy()
    dims[:, c + 1 :] = dims[:, c : c + 1]
    full_valid = valid.copy()
    full_valid[:, c + 1 :] = True
    return _tracks(scenario, sim, pose, np.broadcast_to(dims[None], (num, *dims.shape)), full_valid[None])


def _tracks(scenario: Scenario, agents: np.ndarray, pose: np.ndarray, dims: np.ndarray, valid: np.ndarray):
    num = pose.shape[0]
    evaluated_scene = evaluated_agent_indices(scenario)
    position = {int(a): i for i, a in enumerate(agents)}
    return SceneTracks(
        object_id=scenario.agents.ids[agents],
        is_vehicle=scenario.agents.types[agents] == AgentType.VEHICLE,
        evaluated=np.array([position[int(a)] for a in evaluated_scene], np.int64),
        current=scenario.current_index,
        x=pose[..., 0],
        y=pose[..., 1],
        z=pose[..., 2],
        heading=pose[..., 3],
        length=dims[..., 0],
        width=dims[..., 1],
        height=dims[..., 2],
        valid=np.broadcast_to(valid, (num, *valid.shape[1:])),
    )


@dataclass(frozen=True)
class Features:
    """Per-step features of the E evaluated agents over the 80 future steps, each [N, E, 80]."""

    linear_speed: np.ndarray
    linear_acceleration: np.ndarray
    angular_speed: np.ndarray
    angular_acceleration: np.ndarray
    distance_to_nearest_object: np.ndarray
    time_to_collision: np.ndarray
    distance_to_road_edge: np.ndarray
    traffic_light_violation: np.ndarray  # bool
    average_displacement_error: np.ndarray | None = None  # [N, E], rollouts only

    @property
    def collision(self) -> np.ndarray:
        return self.distance_to_nearest_object < COLLISION_THRESHOLD

    @property
    def offroad(self) -> np.ndarray:
        return self.distance_to_road_edge > OFFROAD_THRESHOLD


_CHUNK_ROLLOUTS = 8


def _chunks(num: int) -> list[slice]:
    return [slice(i, min(i + _CHUNK_ROLLOUTS, num)) for i in range(0, num, _CHUNK_ROLLOUTS)]


def compute_features(tracks: SceneTracks, scene_map: SceneMap, log: SceneTracks | None = None) -> Features:
    """All features of `tracks`; with `log`, also each rollout's average displacement error."""
    ev, fut, c = tracks.evaluated, tracks.future, tracks.current
    t = tracks
    speed, accel, yaw_rate, yaw_accel = kinematic_features(
        t.x[:, ev], t.y[:, ev], t.z[:, ev], t.heading[:, ev], STEP_SECONDS
    )
    planar_speed = kinematic_features(t.x, t.y, np.zeros_like(t.x), t.heading, STEP_SECONDS)[0]
    nearest, ttc = [], []
    for chunk in _chunks(t.x.shape[0]):  # pairwise arrays are [N, E, A, T]: bound their memory
        box = tuple(a[chunk][..., fut] for a in (t.x, t.y, t.heading, t.length, t.width))
        valid = t.valid[chunk][..., fut]
        nearest.append(distance_to_nearest_object(*box, valid, ev))
        ttc.append(time_to_collision(*box, planar_speed[chunk][..., fut], valid, ev))
    nearest, ttc = np.concatenate(nearest), np.concatenate(ttc)
    if scene_map.road_edges is not None:
        road = distance_to_road_edge(
            scene_map.road_edges,
            t.x[:, ev, fut],
            t.y[:, ev, fut],
            t.z[:, ev, fut],
            t.heading[:, ev, fut],
            t.length[:, ev, fut],
            t.width[:, ev, fut],
            t.height[:, ev, fut],
            t.valid[:, ev, fut],
        )
    else:
        road = np.full(nearest.shape, np.nan)
    window = slice(c, c + 1 + FUTURE_STEPS)
    lights = red_light_violations(scene_map.signals, t.x[:, ev, window], t.y[:, ev, window], t.valid[:, ev, window])
    ade = None
    if log is not None:
        err = np.sqrt(
            (t.x[:, ev] - log.x[:, ev]) ** 2 + (t.y[:, ev] - log.y[:, ev]) ** 2 + (t.z[:, ev] - log.z[:, ev]) ** 2
        )
        log_valid = log.valid[:, ev]
        ade = np.where(log_valid, err, 0.0).sum(-1) / log_valid.sum(-1)
    return Features(
        linear_speed=speed[..., fut],
        linear_acceleration=accel[..., fut],
        angular_speed=yaw_rate[..., fut],
        angular_acceleration=yaw_accel[..., fut],
        distance_to_nearest_object=nearest,
        time_to_collision=ttc,
        distance_to_road_edge=road,
        traffic_light_violation=lights[..., 1:],
        average_displacement_error=ade,
    )
